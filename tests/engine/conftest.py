"""Fixtures of the engine's tests: ``ur5``, a user's own robot written by the tests (one
UR5-like 6-DOF arm on a mobile base, its URDF and robot YAML) with a forward kinematics of its
own (the textbook DH product) to check the planner's against."""

from __future__ import annotations

import textwrap
from dataclasses import dataclass

import numpy as np
import pytest

# A UR5-like 6-DOF arm from Universal Robots' published DH parameters (standard DH,
# universal-robots.com "DH parameters for calculations of kinematics and dynamics"), on a
# mobile base: a 0.5 x 0.5 x 0.4 m box with a post to the arm's mount at 0.45 m.
UR5_DH = {  # d, a, alpha per joint (m, m, rad)
    "d": [0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823],
    "a": [0.0, -0.425, -0.39225, 0.0, 0.0, 0.0],
    "alpha": [np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0],
}
MOUNT_Z = 0.45
JOINTS = tuple(f"joint{i}" for i in range(1, 7))
LIMIT = 6.283185  # every joint turns +-2 pi, as the UR5's do


def ur5_urdf() -> str:
    """The URDF text of the arm on its base (root link ``base_footprint``, tip ``tool0``)."""
    d, a, alpha = UR5_DH["d"], UR5_DH["a"], UR5_DH["alpha"]
    names = ["shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link",
             "wrist_3_link"]  # fmt: skip
    out = ['<robot name="ur5_on_base">',
           '<link name="base_footprint"><collision><origin xyz="0 0 0.2"/>'
           '<geometry><box size="0.5 0.5 0.4"/></geometry></collision></link>',
           '<link name="ur_base"><collision><origin xyz="0 0 -0.03"/>'
           '<geometry><cylinder radius="0.06" length="0.06"/></geometry></collision></link>',
           '<joint name="mount" type="fixed"><parent link="base_footprint"/>'
           f'<child link="ur_base"/><origin xyz="0 0 {MOUNT_Z}"/></joint>']  # fmt: skip
    parent = "ur_base"
    for i, link in enumerate(names):
        # Link i's frame turns with joint i; its body runs to the next joint: d along z, then
        # a along x (the DH offset, which the next joint's origin carries).
        if a[i]:
            geometry = (f'<origin xyz="{a[i] / 2} 0 0" rpy="0 1.5707963267948966 0"/>'
                        f'<geometry><cylinder radius="0.05" length="{abs(a[i])}"/></geometry>')
        else:
            geometry = (f'<origin xyz="0 0 {d[i] / 2}"/>'
                        f'<geometry><cylinder radius="0.045" length="{d[i]}"/></geometry>')
        out.append(f'<link name="{link}"><collision>{geometry}</collision></link>')
        origin = "0 0 0" if i == 0 else f"{a[i - 1]} 0 {d[i - 1]}"
        rpy = "0 0 0" if i == 0 else f"{alpha[i - 1]} 0 0"
        out.append(f'<joint name="{JOINTS[i]}" type="revolute"><parent link="{parent}"/>'
                   f'<child link="{link}"/><origin xyz="{origin}" rpy="{rpy}"/>'
                   f'<axis xyz="0 0 1"/><limit lower="-{LIMIT}" upper="{LIMIT}" effort="150" '
                   'velocity="3.15"/></joint>')  # fmt: skip
        parent = link
    out.append('<link name="tool0"/>')
    out.append(f'<joint name="tool_fixed" type="fixed"><parent link="{parent}"/>'
               f'<child link="tool0"/><origin xyz="{a[5]} 0 {d[5]}" rpy="{alpha[5]} 0 0"/>'
               '</joint>')  # fmt: skip
    out.append("</robot>")
    return "\n".join(out) + "\n"


def dh_fk(q: np.ndarray) -> np.ndarray:
    """(4, 4) tool0 in ur_base for joint values q (6,) rad, by the textbook product of
    standard DH transforms (independent of the planner's URDF kinematics)."""
    out = np.eye(4)
    for theta, d, a, alpha in zip(q, UR5_DH["d"], UR5_DH["a"], UR5_DH["alpha"], strict=True):
        ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
        out = out @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                              [0, sa, ca, d], [0, 0, 0, 1]])  # fmt: skip
    return out


def robot_yaml(position=(0.1, -0.2, 0.0), yaw_deg: float = 30.0, side: str = "right",
               payload: float = 3.0, tcp_z: float = 0.12, tcp_yaw_deg: float = 90.0,
               robot_id: str = "rover", gripper: str = "jaw") -> str:
    """The robot document of the one-arm robot: its base at ``position`` (m, world) turned
    ``yaw_deg`` about z, its arm named ``side``, the gripper ``tcp_z`` in front of tool0."""
    x, y, z = position
    return textwrap.dedent(f"""\
        id: {robot_id}
        name: One UR5-like arm on a mobile base
        payload_per_hand: {payload}
        gripper: {gripper}
        reach: 0.8
        urdf: rover.urdf
        base_pose: {{position: [{x}, {y}, {z}], rotation_deg: [0, 0, {yaw_deg}]}}
        arms:
          {side}:
            base_link: base_footprint
            tip_link: tool0
            tcp: {{position: [0, 0, {tcp_z}], rotation_deg: [0, 0, {tcp_yaw_deg}]}}
        """)


@dataclass(frozen=True)
class UR5:
    """The test's own robot: ``urdf`` (text), ``yaml(...)`` (its robot document), ``dh_fk``,
    ``mount_z`` (m, the arm's base above the robot's root link), ``joints`` (names)."""

    dh: dict
    mount_z: float
    joints: tuple[str, ...]
    limit: float

    @staticmethod
    def urdf() -> str:
        return ur5_urdf()

    @staticmethod
    def yaml(**kwargs) -> str:
        return robot_yaml(**kwargs)

    @staticmethod
    def dh_fk(q: np.ndarray) -> np.ndarray:
        return dh_fk(q)


@pytest.fixture(scope="session")
def ur5() -> UR5:
    """The UR5-like one-arm robot (see the module docstring)."""
    return UR5(UR5_DH, MOUNT_Z, JOINTS, LIMIT)
