"""URDF loading: the shipped robot, chains with fixed joints folded in, collision shapes read
as capsules and boxes, and every bad input reported at its file and line."""

from __future__ import annotations

import textwrap
import warnings
from pathlib import Path

import pytest
import trimesh
from numpy.testing import assert_allclose

from handover.geometry.urdf import (
    DEFAULT_VELOCITY,
    RobotModelError,
    VelocityLimitWarning,
    load_urdf,
)

ROBOT = Path(__file__).resolve().parents[2] / "kb" / "robots" / "idro_arms.urdf"

# Franka's published limits for the Panda ("Limits for Panda", rad).
PANDA_LOWER = [-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]
PANDA_UPPER = [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]


def _write(tmp_path: Path, body: str, name: str = "r.urdf") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(body).lstrip())
    return path


def _line_of(path: Path, needle: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if needle in line)


TWO_LINK = """\
    <?xml version="1.0"?>
    <robot name="two">
      <link name="base"/>
      <link name="a"><collision><origin xyz="0.2 0 0" rpy="0 1.5707963267948966 0"/>
        <geometry><cylinder radius="0.05" length="0.4"/></geometry></collision></link>
      <link name="b"/>
      <link name="mount"/>
      <link name="tip"/>
      <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
        <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
      <joint name="fix" type="fixed"><parent link="a"/><child link="mount"/>
        <origin xyz="0.4 0 0"/></joint>
      <joint name="j2" type="revolute"><parent link="mount"/><child link="b"/>
        <axis xyz="0 0 1"/><limit lower="-2" upper="2"/></joint>
      <joint name="tipj" type="fixed"><parent link="b"/><child link="tip"/>
        <origin xyz="0.3 0 0"/></joint>
    </robot>
    """


def test_shipped_robot_has_two_panda_arms_with_published_limits():
    robot = load_urdf(ROBOT)
    assert robot.root_link == "base_link"
    for side in ("left", "right"):
        chain = robot.chain("base_link", f"{side}_flange")
        assert chain.dof == 7
        assert chain.joint_names == tuple(f"{side}_joint{i}" for i in range(1, 8))
        assert set(chain.kinds) == {"revolute"}
        assert_allclose(chain.lower, PANDA_LOWER)
        assert_allclose(chain.upper, PANDA_UPPER)
    assert len(robot.content_hash) == 64


def test_shipped_robot_shoulders_left_and_right_at_shoulder_height():
    robot = load_urdf(ROBOT)
    left = robot.fixed_pose("left_link0")
    right = robot.fixed_pose("right_link0")
    assert left[1, 3] > 0 > right[1, 3]
    for pose in (left, right):
        assert 1.1 <= pose[2, 3] <= 1.3
    # The first joint's axis (link0's z) points out of the torso on each side.
    assert_allclose(left[:3, 2], [0, 1, 0], atol=1e-12)
    assert_allclose(right[:3, 2], [0, -1, 0], atol=1e-12)


def test_shipped_robot_collision_geometry_is_primitives_on_every_moving_link():
    robot = load_urdf(ROBOT)
    assert not robot.mesh_files
    chain = robot.chain("base_link", "left_flange")
    shapes = robot.shapes(chain.links)
    carried = {chain.links[i] for i in shapes.cap_link} | {chain.links[i] for i in shapes.box_link}
    assert {f"left_link{i}" for i in range(1, 8)} <= carried
    torso = robot.shapes(["base_link", "torso", "head"])
    assert len(torso.box_link) == 2 and len(torso.cap_link) == 1


def test_chain_folds_fixed_joints_into_origins_and_tip_offset(tmp_path):
    robot = load_urdf(_write(tmp_path, TWO_LINK))
    chain = robot.chain("base", "tip")
    assert chain.joint_names == ("j1", "j2")
    assert_allclose(chain.origins[0][:3, 3], [0, 0, 0.1])
    assert_allclose(chain.origins[1][:3, 3], [0.4, 0, 0])  # the fixed joint folded in
    assert_allclose(chain.tip_offset[:3, 3], [0.3, 0, 0])
    assert chain.links == ("base", "a", "mount", "b", "tip")
    assert list(chain.link_joint) == [-1, 0, 0, 1, 1]
    assert chain.as_dict([0.5, -0.25]) == {"j1": 0.5, "j2": -0.25}


def test_cylinder_reads_as_capsule_sphere_inside_capsule_dropped_box_kept(tmp_path):
    path = _write(tmp_path, """\
        <robot name="s">
          <link name="l">
            <collision><origin xyz="0 0 0.5"/><geometry><cylinder radius="0.1" length="0.6"/>
              </geometry></collision>
            <collision><origin xyz="0 0 0.8"/><geometry><sphere radius="0.1"/></geometry>
              </collision>
            <collision><origin xyz="1 0 0"/><geometry><sphere radius="0.2"/></geometry>
              </collision>
            <collision><origin xyz="0 2 0" rpy="0 0 1"/><geometry><box size="1 2 3"/></geometry>
              </collision>
          </link>
        </robot>
        """)
    shapes = load_urdf(path).shapes(["l"])
    # The cylinder's axis is its local z: end points 0.3 m either side of the centre.
    assert_allclose(shapes.cap_a, [[0, 0, 0.2], [1, 0, 0]])
    assert_allclose(shapes.cap_b, [[0, 0, 0.8], [1, 0, 0]])
    assert_allclose(shapes.cap_radius, [0.1, 0.2])  # the capped sphere at z 0.8 is dropped
    assert_allclose(shapes.box_extents, [[1, 2, 3]])
    assert_allclose(shapes.box_pose[0][:3, 3], [0, 2, 0])


def test_mesh_collision_becomes_its_bounding_box(tmp_path):
    trimesh.creation.box(extents=(0.2, 0.4, 0.6)).apply_translation((1, 0, 0)).export(
        tmp_path / "part.stl"
    )
    path = _write(tmp_path, """\
        <robot name="m"><link name="l"><collision><origin xyz="0 0 1"/>
          <geometry><mesh filename="package://demo/part.stl" scale="2 2 2"/></geometry>
        </collision></link></robot>
        """)
    shapes = load_urdf(path).shapes(["l"])
    # STL stores float32: micrometre tolerance.
    assert_allclose(shapes.box_extents, [[0.4, 0.8, 1.2]], atol=1e-6)
    assert_allclose(shapes.box_pose[0][:3, 3], [2, 0, 1], atol=1e-6)


def test_missing_mesh_is_an_error_at_its_line(tmp_path):
    path = _write(tmp_path, """\
        <robot name="m">
          <link name="l">
            <visual><geometry><mesh filename="package://robot/meshes/arm.dae"/></geometry></visual>
          </link>
        </robot>
        """)
    with pytest.raises(RobotModelError, match="arm.dae.*not found") as info:
        load_urdf(path)
    assert info.value.line == _line_of(path, "arm.dae")
    assert str(info.value).startswith(f"{path}:{info.value.line}: ")


@pytest.mark.parametrize(
    ("joint", "message"),
    [
        ('type="floating"', "floating joints are not supported"),
        ('type="planar"', "planar joints are not supported"),
        ('type="revolute"><mimic joint="j1"/', "mimic joints are not supported"),
    ],
)
def test_unsupported_joints_in_a_chain_are_errors_at_their_line(tmp_path, joint, message):
    path = _write(tmp_path, f"""\
        <robot name="u">
          <link name="base"/><link name="a"/><link name="b"/>
          <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
            <axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint>
          <joint name="bad" {joint}><parent link="a"/><child link="b"/>
            <axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint>
        </robot>
        """)
    robot = load_urdf(path)
    robot.chain("base", "a")  # the chain that avoids the joint is fine
    with pytest.raises(RobotModelError, match=message) as info:
        robot.chain("base", "b")
    assert info.value.line == _line_of(path, 'name="bad"')


def test_unknown_links_and_unrelated_links_are_errors(tmp_path):
    robot = load_urdf(_write(tmp_path, TWO_LINK))
    with pytest.raises(RobotModelError, match="tip link 'hand' is not in the URDF"):
        robot.chain("base", "hand")
    with pytest.raises(RobotModelError, match="not an ancestor"):
        robot.chain("tip", "base")
    with pytest.raises(RobotModelError, match="moves relative to"):
        robot.fixed_pose("tip")


def test_xacro_and_malformed_xml_and_missing_links_are_errors(tmp_path):
    xacro = _write(tmp_path, """\
        <robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro">
          <xacro:property name="l" value="1"/>
          <link name="a"/>
        </robot>
        """)
    with pytest.raises(RobotModelError, match="xacro is not supported; expand it with xacro"):
        load_urdf(xacro)
    broken = _write(tmp_path, '<robot name="b">\n  <link name="a">\n</robot>\n', "b.urdf")
    with pytest.raises(RobotModelError, match="malformed XML") as info:
        load_urdf(broken)
    assert info.value.line == 3
    dangling = _write(tmp_path, """\
        <robot name="d">
          <link name="a"/>
          <joint name="j" type="fixed"><parent link="a"/><child link="ghost"/></joint>
        </robot>
        """, "d.urdf")
    with pytest.raises(RobotModelError, match="child link 'ghost' is not defined") as info:
        load_urdf(dangling)
    assert info.value.line == 3
    with pytest.raises(RobotModelError, match="not found"):
        load_urdf(tmp_path / "nothing.urdf")


def test_shipped_robot_velocity_limits_are_frankas_without_a_warning():
    # Franka's "Limits for Panda": 2.175 rad/s for joints 1-4, 2.61 rad/s for joints 5-7.
    chain = load_urdf(ROBOT).chain("base_link", "left_flange")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert_allclose(chain.velocity_limits(), [2.175] * 4 + [2.61] * 3)


def test_joint_without_velocity_limit_gets_the_default_and_a_warning_naming_it(tmp_path):
    # TWO_LINK's joints give lower and upper but no velocity; j1 is declared on line 9.
    path = _write(tmp_path, TWO_LINK.replace('<limit lower="-2" upper="2"/>',
                                             '<limit lower="-2" upper="2" velocity="1.5"/>'))
    chain = load_urdf(path).chain("base", "tip")
    with pytest.warns(VelocityLimitWarning, match=rf"j1 \({path}:9\)") as record:
        limits = chain.velocity_limits()
    assert "j2" not in str(record[0].message)
    assert_allclose(limits, [DEFAULT_VELOCITY, 1.5])


def test_revolute_joint_without_limits_is_an_error(tmp_path):
    path = _write(tmp_path, """\
        <robot name="n"><link name="a"/><link name="b"/>
          <joint name="j" type="revolute"><parent link="a"/><child link="b"/></joint>
        </robot>
        """)
    with pytest.raises(RobotModelError, match="needs <limit"):
        load_urdf(path).chain("a", "b")


@pytest.mark.parametrize(("bad", "message"), [
    ('<origin xyz="0 0 0.1"/>', None),  # the joint's origin, well formed: loads
    ('<origin xyz="0 0 nan"/>', r"<origin xyz='0 0 nan'>: expected three finite numbers"),
    ('<origin xyz="0 0"/>', r"<origin xyz='0 0'>: expected three finite numbers"),
    ('<origin rpy="0 inf 0"/>', r"<origin rpy='0 inf 0'>: expected three finite numbers"),
])
def test_a_joint_origin_that_is_not_three_finite_numbers_is_an_error_at_its_line(
        tmp_path, bad, message):
    path = _write(tmp_path, TWO_LINK.replace('<origin xyz="0 0 0.1"/>', bad))
    if message is None:
        load_urdf(path)
        return
    with pytest.raises(RobotModelError, match=message) as info:
        load_urdf(path)
    assert info.value.line == _line_of(path, bad)


@pytest.mark.parametrize(("geometry", "message"), [
    ('<cylinder radius="-0.05" length="0.4"/>', r"<cylinder radius='-0.05'>: expected a finite "
     r"length > 0"),
    ('<cylinder radius="0.05" length="-1"/>', r"<cylinder length='-1'>: expected a finite "
     r"length >= 0"),
    ('<sphere radius="0"/>', r"<sphere radius='0'>: expected a finite length > 0"),
    ('<box size="0.1 0 0.1"/>', r"<box size='0.1 0 0.1'>: expected 3 finite lengths > 0"),
    ('<box size="0.1 0.1"/>', r"<box size='0.1 0.1'>: expected 3 finite lengths > 0"),
    ('<mesh filename="m.stl" scale="1 0 1"/>', r"<mesh scale='1 0 1'>: expected three finite, "
     "non-zero numbers"),
])
def test_a_collision_shape_of_no_size_is_an_error_at_its_line(tmp_path, geometry, message):
    trimesh.creation.box((0.1, 0.1, 0.1)).export(tmp_path / "m.stl")
    path = _write(tmp_path, TWO_LINK.replace('<cylinder radius="0.05" length="0.4"/>', geometry))
    with pytest.raises(RobotModelError, match=message) as info:
        load_urdf(path)
    assert info.value.line == _line_of(path, geometry)
