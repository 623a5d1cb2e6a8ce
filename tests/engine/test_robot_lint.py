"""Bad robot files: each a KB error at the robot YAML's line (with the URDF's own file:line
where the URDF is at fault), exit 3 from ``handover kb validate``, never a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from handover.engine.errors import KBError
from handover.engine.load.loader import load_kb

HANDOVER = Path(sys.executable).parent / "handover"

ARM_URDF = """\
<?xml version="1.0"?>
<robot name="arm">
  <link name="base"><collision><geometry><box size="0.3 0.3 0.3"/></geometry></collision></link>
  <link name="l1"/>
  <link name="l2"/>
  <link name="tip"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/><origin xyz="0 0 0.5"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2"/>
  </joint>
  <joint name="j3" type="fixed">
    <parent link="l2"/><child link="tip"/><origin xyz="0.3 0 0"/>
  </joint>
</robot>
"""

ROBOT = """\
id: arm
name: Arm
payload_per_hand: 1.0
gripper: jaw
reach: 0.5
urdf: arm.urdf
arms:
  right:
    base_link: base
    tip_link: tip
"""


def line_of(text: str, needle: str) -> int:
    return next(i + 1 for i, line in enumerate(text.splitlines()) if needle in line)


def errors(root: Path) -> list:
    with pytest.raises(KBError) as info:
        load_kb(root)
    return [i for i in info.value.issues if i.file == "robots/arm.yaml"]


def the_error(root: Path) -> object:
    found = errors(root)
    assert len(found) == 1, [str(i) for i in found]
    return found[0]


def test_a_good_arm_loads_clean(make_kb):
    kb = load_kb(make_kb({"robots/arm.yaml": ROBOT, "robots/arm.urdf": ARM_URDF}))
    assert kb.warnings == []
    assert kb.robot("arm").hands == ["right"]
    assert kb.robot("arm").arms["right"].gripper == "jaw"


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("missing.urdf", "URDF file 'missing.urdf' does not exist (looked for robots/missing"),
        ("../../outside.urdf", "URDF file '../../outside.urdf' leaves the KB folder"),
        ("/etc/hosts", "is an absolute path"),
    ],
)
def test_urdf_file_missing_or_outside_the_kb(make_kb, name, expected):
    text = ROBOT.replace("urdf: arm.urdf", f'urdf: "{name}"')
    root = make_kb({"robots/arm.yaml": text})
    (root.parent / "outside.urdf").write_text(ARM_URDF)
    issue = the_error(root)
    assert issue.line == line_of(text, "urdf:")
    assert expected in issue.message


def test_malformed_urdf_names_both_files_and_lines(make_kb):
    broken = ARM_URDF.replace('<link name="l2"/>', '<link name="l2">')
    issue = the_error(make_kb({"robots/arm.yaml": ROBOT, "robots/arm.urdf": broken}))
    assert (issue.file, issue.line) == ("robots/arm.yaml", line_of(ROBOT, "urdf:"))
    assert "malformed XML" in issue.message
    assert "robots/arm.urdf:" in issue.message


def test_xacro_is_not_supported(make_kb):
    xacro = ARM_URDF.replace('<robot name="arm">',
                             '<robot name="arm" xmlns:xacro="http://www.ros.org/wiki/xacro">')
    issue = the_error(make_kb({"robots/arm.yaml": ROBOT, "robots/arm.urdf": xacro}))
    assert issue.line == line_of(ROBOT, "urdf:")
    assert "xacro is not supported" in issue.message


def test_missing_mesh_in_the_urdf(make_kb):
    with_mesh = ARM_URDF.replace('<link name="l1"/>', (
        '<link name="l1"><collision><geometry><mesh filename="package://arm/l1.stl"/>'
        "</geometry></collision></link>"))  # fmt: skip
    issue = the_error(make_kb({"robots/arm.yaml": ROBOT, "robots/arm.urdf": with_mesh}))
    assert issue.line == line_of(ROBOT, "urdf:")
    assert "mesh file 'package://arm/l1.stl' not found" in issue.message
    assert f"robots/arm.urdf:{line_of(with_mesh, 'l1.stl')}" in issue.message


@pytest.mark.parametrize("role", ["base_link", "tip_link"])
def test_an_arm_naming_a_link_the_urdf_lacks(make_kb, role):
    old = {"base_link": "base_link: base", "tip_link": "tip_link: tip"}[role]
    text = ROBOT.replace(old, f"{role}: hand")
    issue = the_error(make_kb({"robots/arm.yaml": text, "robots/arm.urdf": ARM_URDF}))
    assert issue.line == line_of(text, f"{role}:")
    assert f"right arm's {role} 'hand' is not a link of arm.urdf" in issue.message


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ('type="revolute">\n    <parent link="l1"/>', 'type="floating">\n    <parent link="l1"/>',
         "floating joints are not supported"),
        ("<limit lower=\"-2\" upper=\"2\"/>",
         '<limit lower="-2" upper="2"/><mimic joint="j1"/>', "mimic joints are not supported"),
    ],
)  # fmt: skip
def test_a_chain_with_unsupported_joints(make_kb, old, new, expected):
    urdf = ARM_URDF.replace(old, new)
    assert urdf != ARM_URDF
    issue = the_error(make_kb({"robots/arm.yaml": ROBOT, "robots/arm.urdf": urdf}))
    assert issue.line == line_of(ROBOT, "base_link:")  # the arm's block
    assert expected in issue.message
    joint_line = line_of(urdf, '<joint name="j2"')
    assert f"robots/arm.urdf:{joint_line}" in issue.message


def test_a_chain_that_does_not_move(make_kb):
    text = ROBOT.replace("base_link: base", "base_link: l2")
    issue = the_error(make_kb({"robots/arm.yaml": text, "robots/arm.urdf": ARM_URDF}))
    assert issue.line == line_of(text, "base_link:")  # the arm's block
    assert "has no moving joint" in issue.message


def test_an_arm_based_on_a_moving_link(make_kb):
    text = ROBOT.replace("base_link: base", "base_link: l1")
    issue = the_error(make_kb({"robots/arm.yaml": text, "robots/arm.urdf": ARM_URDF}))
    assert issue.line == line_of(text, "base_link:")
    assert "link 'l1' moves relative to 'base' (joint 'j1'): it has no fixed pose" in issue.message


def test_an_arm_gripper_that_does_not_exist(make_kb):
    text = ROBOT + "    gripper: claw\n"
    issue = the_error(make_kb({"robots/arm.yaml": text, "robots/arm.urdf": ARM_URDF}))
    assert issue.line == line_of(text, "gripper: claw")
    assert "right arm's gripper 'claw' does not exist" in issue.message


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (ROBOT.replace("urdf: arm.urdf\n", ""), "arms need a 'urdf' file"),
        (ROBOT.replace("reach: 0.5\n", "reach: 0.5\nhands: [left, right]\n"),
         "differ from the arms' sides"),
        (ROBOT + "body:\n  - {id: torso, shape: box, radius: 0.1}\n", "a box needs extents"),
    ],
)  # fmt: skip
def test_robot_documents_that_contradict_themselves(make_kb, text, expected):
    found = errors(make_kb({"robots/arm.yaml": text, "robots/arm.urdf": ARM_URDF}))
    assert any(expected in i.message for i in found), [str(i) for i in found]


def test_reach_beyond_the_arms_is_a_warning(make_kb):
    text = ROBOT.replace("reach: 0.5", "reach: 2.0")
    kb = load_kb(make_kb({"robots/arm.yaml": text, "robots/arm.urdf": ARM_URDF}))
    (warning,) = [w for w in kb.warnings if w.file == "robots/arm.yaml"]
    assert warning.line == line_of(text, "reach:")
    assert "reach 2 m exceeds what its arms can reach at full stretch (0.60 m" in warning.message


def test_validate_exits_3_without_a_traceback(make_kb):
    broken = ARM_URDF.replace('type="fixed"', 'type="planar"')
    root = make_kb({"robots/arm.yaml": ROBOT, "robots/arm.urdf": broken})
    env = dict(os.environ, HANDOVER_KB=str(root))
    proc = subprocess.run([str(HANDOVER), "kb", "validate"], capture_output=True, text=True,
                          env=env, timeout=120)  # fmt: skip
    assert proc.returncode == 3, proc.stderr
    assert f"robots/arm.yaml:{line_of(ROBOT, 'base_link:')}:" in proc.stderr
    assert "planar joints are not supported" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize(("old", "new", "expected"), [
    ('<origin xyz="0 0 0.3"/>', '<origin xyz="0 0 nan"/>',
     "<origin xyz='0 0 nan'>: expected three finite numbers"),
    ('<box size="0.3 0.3 0.3"/>', '<box size="0.3 -0.3 0.3"/>',
     "<box size='0.3 -0.3 0.3'>: expected 3 finite lengths > 0"),
])
def test_numbers_a_plan_cannot_use(make_kb, old, new, expected):
    # A NaN in a joint's origin, a box of negative size: a KB error at the URDF's line (a
    # plan with them would compute NaN poses, or crash), not a plan.
    urdf = ARM_URDF.replace(old, new)
    issue = the_error(make_kb({"robots/arm.yaml": ROBOT, "robots/arm.urdf": urdf}))
    assert issue.line == line_of(ROBOT, "urdf:")
    assert expected in issue.message
    assert f"robots/arm.urdf:{line_of(urdf, new)}" in issue.message


TWO_ARMS_ON_A_WAIST = """\
<?xml version="1.0"?>
<robot name="waist">
  <link name="base"/><link name="torso"/>
  <link name="la"/><link name="ltip"/><link name="ra"/><link name="rtip"/>
  <joint name="waist" type="revolute">
    <parent link="base"/><child link="torso"/><origin xyz="0 0 0.8"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1"/>
  </joint>
  <joint name="lj" type="revolute">
    <parent link="torso"/><child link="la"/><origin xyz="0 0.2 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2"/>
  </joint>
  <joint name="lt" type="fixed"><parent link="la"/><child link="ltip"/>
    <origin xyz="0.4 0 0"/></joint>
  <joint name="rj" type="revolute">
    <parent link="torso"/><child link="ra"/><origin xyz="0 -0.2 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2"/>
  </joint>
  <joint name="rt" type="fixed"><parent link="ra"/><child link="rtip"/>
    <origin xyz="0.4 0 0"/></joint>
</robot>
"""


@pytest.mark.parametrize(("left", "right", "shared"), [
    ("{base_link: base, tip_link: ltip}", "{base_link: base, tip_link: ltip}",
     "'waist', 'lj'"),  # one arm named twice
    ("{base_link: base, tip_link: ltip}", "{base_link: base, tip_link: rtip}",
     "'waist'"),  # both chains through the waist: each arm would turn it its own way
])
def test_two_arms_that_share_a_joint(make_kb, left, right, shared):
    text = ROBOT.replace("urdf: arm.urdf", "urdf: waist.urdf").replace(
        "arms:\n  right:\n    base_link: base\n    tip_link: tip\n",
        f"arms:\n  left: {left}\n  right: {right}\n")
    issue = the_error(make_kb({"robots/arm.yaml": text, "robots/waist.urdf": TWO_ARMS_ON_A_WAIST}))
    assert issue.line == line_of(text, "  right:")
    assert "the right arm's chain moves with the left arm's joint" in issue.message
    assert shared in issue.message and "make it fixed in the URDF" in issue.message
    # The waist fixed, the chains from the torso: two arms.
    fixed = TWO_ARMS_ON_A_WAIST.replace('name="waist" type="revolute"', 'name="waist" type="fixed"')
    good = text.replace("{base_link: base, tip_link: ltip}", "{base_link: torso, tip_link: ltip}"
                        ).replace("{base_link: base, tip_link: rtip}",
                                  "{base_link: torso, tip_link: rtip}")
    if "rtip" in right:
        kb = load_kb(make_kb({"robots/arm.yaml": good, "robots/waist.urdf": fixed}))
        assert sorted(kb.robot("arm").arms) == ["left", "right"]


@pytest.mark.parametrize(("rest", "expected"), [
    ("{j1: 0.5, j2: 0.1}", None),
    ("{j1: 0.5}", "every joint of the chain needs a value; missing j2"),
    ("{j1: 0.5, j2: 0.1, elbow: 1}", "'elbow' not a joint of the chain (joints: j1, j2)"),
    ("{j1: 0.5, j2: 2.5}", "beyond the joint limits: j2 2.5 not in [-2, 2]"),
    ("{j1: 0.5, j2: .nan}", "arms.right.rest.j2: must be a finite number, not nan"),
])
def test_an_arm_s_rest(make_kb, rest, expected):
    text = ROBOT + f"    rest: {rest}\n"
    root = make_kb({"robots/arm.yaml": text, "robots/arm.urdf": ARM_URDF})
    if expected is None:
        arm = load_kb(root).robot("arm").arms["right"]
        assert arm.rest == {"j1": 0.5, "j2": 0.1}
        return
    issue = the_error(root)
    assert issue.line == line_of(text, "rest:")
    assert expected in issue.message


def test_a_rest_inside_the_robot(make_kb):
    # The arm's second link (a 0.7 m cylinder) turned straight down at rest reaches into a
    # pedestal fixed to the base (z 0.25-0.45 m): it could never wait there. Level, it is
    # clear.
    urdf = ARM_URDF.replace('<link name="l2"/>', (
        '<link name="l2"><collision><origin xyz="0.35 0 0" rpy="0 1.5707963267948966 0"/>'
        '<geometry><cylinder radius="0.03" length="0.7"/></geometry></collision></link>'
        '<link name="pedestal"><collision><origin xyz="0 0 0.35"/>'
        '<geometry><box size="0.1 0.1 0.2"/></geometry></collision></link>'
        '<joint name="fixed_pedestal" type="fixed"><parent link="base"/>'
        '<child link="pedestal"/></joint>'))
    down = ROBOT + "    rest: {j1: 0.0, j2: 1.5707963}\n"
    issue = the_error(make_kb({"robots/arm.yaml": down, "robots/arm.urdf": urdf}))
    assert issue.line == line_of(down, "rest:")
    assert "the right arm's rest puts its links into the robot: l2 hits pedestal" in \
        issue.message
    level = ROBOT + "    rest: {j1: 0.0, j2: 0.0}\n"
    load_kb(make_kb({"robots/arm.yaml": level, "robots/arm.urdf": urdf}))
