"""Batched kinematics: FK against yourdfpy's own and against closed forms, the Jacobian
against finite differences, IK round trips within 1 mm / 1 degree inside the joint limits."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
import yourdfpy
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from handover.geometry.kinematics import Kinematics, rotation_angle
from handover.geometry.urdf import RobotModelError, load_urdf

ROBOT = Path(__file__).resolve().parents[2] / "kb" / "robots" / "idro_arms.urdf"


@pytest.fixture(scope="module")
def robot():
    return load_urdf(ROBOT)


@pytest.fixture(scope="module")
def left(robot):
    return Kinematics(robot.chain("base_link", "left_flange"))


# A planar arm: revolute (z) at the base, 0.4 m link, continuous (z), 0.3 m link, then a
# prismatic joint sliding along the last link's x.
PLANAR = """\
    <robot name="planar">
      <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="tip"/>
      <joint name="shoulder" type="revolute"><parent link="base"/><child link="l1"/>
        <axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
      <joint name="elbow" type="continuous"><parent link="l1"/><child link="l2"/>
        <origin xyz="0.4 0 0"/><axis xyz="0 0 1"/></joint>
      <joint name="slide" type="prismatic"><parent link="l2"/><child link="l3"/>
        <origin xyz="0.3 0 0"/><axis xyz="1 0 0"/><limit lower="0" upper="0.2"/></joint>
      <joint name="end" type="fixed"><parent link="l3"/><child link="tip"/>
        <origin xyz="0.05 0 0" rpy="0 1.5707963267948966 0"/></joint>
    </robot>
    """


@pytest.fixture(scope="module")
def planar(tmp_path_factory):
    path = tmp_path_factory.mktemp("planar") / "planar.urdf"
    path.write_text(textwrap.dedent(PLANAR))
    return Kinematics(load_urdf(path).chain("base", "tip"))


def test_fk_matches_yourdfpy_for_every_link_of_both_arms(robot):
    urdf = yourdfpy.URDF.load(str(ROBOT))
    rng = np.random.default_rng(7)
    for side in ("left", "right"):
        kin = Kinematics(robot.chain("base_link", f"{side}_flange"))
        q = kin.random_configurations(4, rng)
        poses = kin.link_poses(q)
        tips = kin.fk(q)
        for i in range(len(q)):
            urdf.update_cfg(dict(zip(kin.chain.joint_names, q[i], strict=True)))
            for k, link in enumerate(kin.chain.links):
                assert_allclose(poses[i, k], urdf.get_transform(link, "base_link"), atol=1e-9)
            assert_allclose(tips[i], urdf.get_transform(f"{side}_flange", "base_link"),
                            atol=1e-9)  # fmt: skip


@settings(max_examples=40, deadline=None)
@given(
    st.floats(-3, 3), st.floats(-10, 10), st.floats(0, 0.2)
)
def test_fk_of_planar_arm_is_the_closed_form(planar, a, b, d):
    pose = planar.fk(np.array([[a, b, d]]))[0]
    reach = 0.3 + d + 0.05
    expected = [0.4 * np.cos(a) + reach * np.cos(a + b), 0.4 * np.sin(a) + reach * np.sin(a + b), 0]
    assert_allclose(pose[:3, 3], expected, atol=1e-12)
    # The tip's z axis is the last link's x axis (pitched by +90 degrees about y).
    assert_allclose(pose[:3, 2], [np.cos(a + b), np.sin(a + b), 0], atol=1e-12)


def test_jacobian_matches_finite_differences(left, planar):
    rng = np.random.default_rng(3)
    for kin in (left, planar):
        q = kin.random_configurations(5, rng)
        jac = kin.jacobian(q)
        eps = 1e-7
        base = kin.fk(q)
        for j in range(kin.dof):
            moved = q.copy()
            moved[:, j] += eps
            step = kin.fk(moved)
            v = (step[:, :3, 3] - base[:, :3, 3]) / eps
            w_hat = (step[:, :3, :3] @ np.swapaxes(base[:, :3, :3], 1, 2) - np.eye(3)) / eps
            w = np.stack([w_hat[:, 2, 1], w_hat[:, 0, 2], w_hat[:, 1, 0]], axis=1)
            assert_allclose(jac[:, :3, j], v, atol=1e-5)
            assert_allclose(jac[:, 3:, j], w, atol=1e-5)


def test_float32_fk_is_within_a_micrometre(left):
    q = left.random_configurations(100, np.random.default_rng(0))
    assert np.abs(left.fk(q, dtype=np.float32) - left.fk(q)).max() < 1e-5


def test_tcp_moves_the_tool_frame_along_the_flange(robot):
    chain = robot.chain("base_link", "right_flange")
    tcp = np.eye(4)
    tcp[2, 3] = 0.1
    q = Kinematics(chain).random_configurations(3, np.random.default_rng(1))
    flange = Kinematics(chain).fk(q)
    tool = Kinematics(chain, tcp).fk(q)
    assert_allclose(tool[:, :3, 3], flange[:, :3, 3] + 0.1 * flange[:, :3, 2], atol=1e-12)


def test_ik_round_trip_within_a_millimetre_and_a_degree_inside_limits(left):
    rng = np.random.default_rng(11)
    targets = left.fk(left.random_configurations(200, rng))
    result = left.ik(targets, restarts=5)
    assert result.success.mean() >= 0.9
    assert left.chain.within_limits(result.q).all()
    reached = left.fk(result.q[result.success])
    wanted = targets[result.success]
    assert np.linalg.norm(reached[:, :3, 3] - wanted[:, :3, 3], axis=1).max() <= 1e-3
    assert rotation_angle(reached[:, :3, :3], wanted[:, :3, :3]).max() <= np.radians(1)
    # The reported errors are what FK of the returned joints gives.
    assert_allclose(
        result.position_error, np.linalg.norm(left.fk(result.q)[:, :3, 3] - targets[:, :3, 3],
                                              axis=1), atol=1e-12,
    )  # fmt: skip


def test_restarts_only_help_and_the_answer_is_deterministic(left):
    targets = left.fk(left.random_configurations(100, np.random.default_rng(5)))
    once = left.ik(targets, restarts=0)
    more = left.ik(targets, restarts=5)
    again = left.ik(targets, restarts=5)
    assert more.success.sum() >= once.success.sum()
    assert (once.attempts == 1).all() and more.attempts.max() <= 6
    np.testing.assert_array_equal(more.q, again.q)


def test_a_joint_on_its_limit_does_not_slow_the_run(left, monkeypatch):
    # Targets whose joints put one joint on a limit, each from 0.1 rad away: the joint on
    # its limit sits out the steps that would push it out of range. (Before, the clamp cut
    # its share of every step: 53 of these 70 were reached, one at a time in 30 iterations
    # on average; now all 70, each within 8.)
    rng = np.random.default_rng(4)
    goal = left.random_configurations(70, rng)
    rows = np.arange(70)
    joint = rows % 7
    goal[rows, joint] = np.where(rng.random(70) < 0.5, left.upper[joint], left.lower[joint])
    starts = left.clamp(goal + rng.normal(0.0, 0.1, goal.shape))
    calls = []
    real = left._fk_jacobian
    monkeypatch.setattr(left, "_fk_jacobian", lambda q: calls.append(len(q)) or real(q))
    result = left.ik_from(left.fk(goal), starts[:, None, :])
    assert result.success.all()
    assert len(calls) <= 12
    assert left.chain.within_limits(result.q).all()


def test_a_target_s_answer_is_the_same_to_the_bit_in_any_batch(left):
    # Reachable targets, targets a joint limit keeps out of reach (the run presses against
    # it) and one far out of reach, from several starts each: one batch, then one at a time.
    rng = np.random.default_rng(8)
    goal = left.random_configurations(12, rng)
    goal[4:8, 3] = left.upper[3] + 0.05  # the elbow straighter than it can be
    goal[8:11, 1] = left.lower[1] - 0.05
    targets = left.fk(goal)
    targets[11, :3, 3] = [3.0, 0.5, 1.2]
    starts = left.clamp(goal[:, None, :] + rng.normal(0.0, 0.3, (12, 3, left.dof)))
    whole = left.ik_from(targets, starts)
    assert 0 < whole.success.sum() < 12
    for i in range(12):
        alone = left.ik_from(targets[i : i + 1], starts[i : i + 1])
        np.testing.assert_array_equal(alone.q[0], whole.q[i])
        assert alone.position_error[0] == whole.position_error[i]
        assert alone.rotation_error[0] == whole.rotation_error[i]
    shared = left.ik(targets, restarts=3, shared_restarts=True)
    for i in (0, 5, 9, 11):
        alone = left.ik(targets[i : i + 1], restarts=3, shared_restarts=True)
        np.testing.assert_array_equal(alone.q[0], shared.q[i])
        assert alone.position_error[0] == shared.position_error[i]


def test_target_three_metres_away_fails_and_stays_within_limits(left):
    target = np.eye(4)
    target[:3, 3] = [3.0, 0.5, 1.2]
    result = left.ik(target[None], restarts=3)
    assert not result.success[0]
    assert result.position_error[0] > 1.5
    assert result.attempts[0] == 4
    assert left.chain.within_limits(result.q).all()


def test_ik_of_planar_arm_reaches_a_point_by_hand(planar):
    # Shoulder 0, elbow 90 deg, slide 0.1: the tip at (0.4, 0.45, 0) pointing +y.
    target = planar.fk(np.array([[0.0, np.pi / 2, 0.1]]))
    assert_allclose(target[0, :3, 3], [0.4, 0.45, 0], atol=1e-12)
    result = planar.ik(target, q0=np.array([0.3, 1.0, 0.0]), restarts=3)
    assert result.success[0]
    assert_allclose(planar.fk(result.q)[0, :3, 3], [0.4, 0.45, 0], atol=1e-3)


def test_bad_joint_values_and_targets_raise_our_error(left):
    with pytest.raises(RobotModelError, match=r"shape \(n, 7\)"):
        left.fk(np.zeros((2, 6)))
    with pytest.raises(RobotModelError, match="finite"):
        left.fk(np.full(7, np.nan))
    with pytest.raises(RobotModelError, match=r"\(m, 4, 4\)"):
        left.ik(np.zeros((2, 3, 3)))
