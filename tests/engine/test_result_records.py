"""The result's typed records (robot grasp, receiver grasp, regrasp, arm joints) and the notes a
mode attempt carries: each record's ``to_dict()`` is its block of the JSON result (key order,
rounding), and what a mode noted is what the result reports.

Hand-made records check the serialisation against the JSON contract written here; real plans
check that the records the facade hands out are the ones the JSON is written from, and that
the notes of H2G1 and H2G2 say what the plan did (computed here from the plan's poses).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from handover import Planner
from handover.engine.plan.arms.stages import MIDAIR_BACKOFF
from handover.engine.plan.jsonable import dumps, to_jsonable
from handover.engine.plan.records import (
    ArmJoints,
    GraspSupport,
    HandBox,
    HumanGrasp,
    PlacementSite,
    RobotGrasp,
)
from handover.engine.report.result import Regrasp

TURN = np.array([[0.0, -1.0, 0.0, 0.01], [1.0, 0.0, 0.0, 0.02], [0.0, 0.0, 1.0, 0.03],
                 [0.0, 0.0, 0.0, 1.0]])  # a quarter turn about z, moved by (1, 2, 3) cm


def _grasp(**changes) -> RobotGrasp:
    fields = dict(gripper="right", pose=np.eye(4), pose_world=TURN, width=0.0301234567,
                  contacts=np.array([[0.0, -0.015, 0.0], [0.0, 0.015, 0.0]]),
                  parts=("handle", "handle"), score=0.87654321, id=7, quality=0.5,
                  roll_deg=-0.0)
    fields.update(changes)
    return RobotGrasp(**fields)


@pytest.fixture(scope="module")
def planner() -> Planner:
    return Planner()


def test_a_one_stage_grasp_lists_the_contract_s_keys_in_order_without_a_stage():
    g = _grasp().to_dict()
    assert list(g) == ["hand", "id", "pose", "pose_world", "width", "contacts", "parts",
                       "score", "quality", "roll_deg"]
    # Micrometres and microradians; no negative zero; JSON-able as it is.
    assert g["width"] == 0.030123 and g["score"] == 0.876543 and g["roll_deg"] == 0.0
    assert g["parts"] == ["handle", "handle"] and g["pose_world"][0] == [0.0, -1.0, 0.0, 0.01]
    assert json.loads(json.dumps(g)) == g


def test_an_arm_s_joints_follow_the_grasp_and_a_staged_grasp_names_its_stage_last():
    held = ArmJoints("left", {"pickup": {"j1": 0.1, "j2": -0.2}, "midair": {"j1": 0.3,
                                                                           "j2": 0.4}},
                     fingers_swapped=("midair",))
    g = _grasp(stage="pick", staged=True, arm_joints=held)
    out = g.to_dict()
    assert list(out)[-5:] == ["roll_deg", "arm", "joints", "fingers_swapped", "stage"]
    assert out["stage"] == "pick" and out["fingers_swapped"] == ["midair"]
    assert list(out["joints"]) == ["pickup", "midair"]  # the order the grasp is held in
    assert (g.arm, g.fingers_swapped, g.joints["midair"]["j2"]) == ("left", ("midair",), 0.4)
    assert g.picks_up
    # Without a swapped stage, the key is left out; without an arm, arm and joints are.
    assert "fingers_swapped" not in ArmJoints("left", {"pickup": {"j1": 0.0}}).to_dict()
    plain = _grasp()
    assert (plain.arm, plain.joints, plain.fingers_swapped) == (None, {}, ())
    assert plain.stage == "handover" and plain.picks_up


def test_a_supporting_gripper_names_its_stage_after_its_id_and_ends_with_what_it_supports():
    support = GraspSupport(gripper="right", grasp=3, at="wrist", point=np.array([0.1, 0, 0]),
                           point_world=np.array([0.5, 0.1, 1.0]), clear_of=("object",))
    g = _grasp(gripper="left", id=None, contacts=np.zeros((0, 3)), parts=(), score=None,
               quality=None, roll_deg=None, stage="support", staged=True, supports=support)
    out = g.to_dict()
    assert list(out) == ["hand", "id", "stage", "pose", "pose_world", "width", "contacts",
                         "parts", "score", "quality", "roll_deg", "supports"]
    assert out["contacts"] == [] and out["supports"] == {
        "hand": "right", "grasp": 3, "at": "wrist", "point": [0.1, 0.0, 0.0],
        "point_world": [0.5, 0.1, 1.0], "clear_of": ["object"]}
    assert not g.picks_up


def test_a_regrasp_gives_the_first_gripper_at_the_midair_pose():
    first = _grasp(pose=TURN, stage="pick", staged=True)
    second = _grasp(gripper="left", id=8, staged=True)
    midair = np.eye(4)
    midair[:3, 3] = [0.4, 0.0, 1.1]
    out = Regrasp(first, midair, second).to_dict()
    assert list(out) == ["first", "midair_pose", "midair_lift", "second"]
    assert out["midair_lift"] == 0.0
    assert list(out["first"])[-2:] == ["stage", "pose_midair"]
    # The first gripper's pose at the midair pose: the object's pose there times the grasp's.
    expected = TURN.copy()
    expected[:3, 3] += [0.4, 0.0, 1.1]
    np.testing.assert_allclose(out["first"]["pose_midair"], expected)
    assert out["second"] == second.to_dict()


def test_receiver_grasps_keep_their_key_orders():
    box = HandBox("palm", np.array([0.08, 0.09, 0.03]), np.eye(4))
    held = HumanGrasp("right", np.array([-0.06, 0, 0]), np.array([0.44, 0, 1.0]), "handle",
                      (box,))
    assert list(held.to_dict()) == ["hand", "position", "position_world", "part", "model"]
    assert held.to_dict()["model"] == [{"name": "palm", "extents": [0.08, 0.09, 0.03],
                                        "pose": np.eye(4).tolist()}]
    placed = PlacementSite("right", np.zeros(3), np.array([0.7, 0.1, 0.76]), "handle")
    assert list(placed.to_dict()) == ["hand", "position", "part", "model", "position_world"]
    assert placed.to_dict()["model"] == []


def test_to_jsonable_is_idempotent_and_rounds_to_micrometres():
    data = {"a": np.float32(1.23456789), 2: [np.int64(3), -1e-9, float("nan")],
            "b": (np.bool_(True), np.array([[0.1234567]]))}
    once = to_jsonable(data)
    assert once == {"a": 1.234568, "2": [3, 0.0, None], "b": [True, [[0.123457]]]}
    assert to_jsonable(once) == once


def _indented(data) -> str:
    return json.dumps(data, indent=2, ensure_ascii=False) + "\n"


def test_the_json_text_is_json_s_own_indented_text_byte_for_byte(planner):
    """``dumps`` writes its text itself (json's indented encoder is pure Python, slow): the
    same bytes as json's, for a real plan and for the corners of JSON text."""
    plan = planner.plan("knife")
    assert plan.to_json() == dumps(plan.to_dict(), jsonable=True) == _indented(plan.to_dict())
    corners = {
        "empty": [[], {}, [[]], [{}], {"a": {}, "b": []}, ""],
        "text": ["é ü 😀 \u2028", 'a "quoted" \\ back\\slash', "\x00\x1f\t\n\r\x7f /",
                 "\ud800"],
        'key "with" \\ and\n and é': None,
        "ints": [0, -1, 10**40, -(10**30)],
        "floats": [-0.0, 0.0, 1e-07, 1e16, 1.5e-300, 5e-324, 1.7976931348623157e308, -2.5],
        "not finite": [float("nan"), float("inf"), -float("inf"), 1.0, 2],
        "mixed": [1, 2.0, True, False, None, "x", [1.0, 2], {"k": [[1, 2.5], [3, 4.0]]}],
        "tables": [[[0.1, 0.2], [0.3, 0.4]], [[1.0], [float("nan")]], [[1.0, 2.0], [3.0]],
                   [[1.0], []], [[True], [False]]],
        "tuples": (1, (2.0, "x"), ()),
        "deep": [[[[{"x": [[[1.0]]], "y": {"z": {}}}]]]],
    }
    for data in (corners, [], {}, "a\"b", 1.0, float("nan"), 3, None, True, [corners, []]):
        assert dumps(data, jsonable=True) == _indented(data)
    # What JSON-able data does not hold is json's to write, or to refuse.
    keys = {1: 2.0, "a": {None: [1]}}
    assert dumps(keys, jsonable=True) == _indented(keys) and '"1": 2.0' in dumps(keys, True)
    with pytest.raises(TypeError, match="not JSON serializable"):
        dumps([1.0, {"a": np.int64(3)}], jsonable=True)


def test_the_facade_hands_out_the_records_the_json_is_written_from(planner):
    plan = planner.plan("knife")
    data = json.loads(plan.to_json())
    assert all(isinstance(g, RobotGrasp) for g in plan.robot_grasps)
    assert all(isinstance(h, HumanGrasp) for h in plan.human_grasps)
    assert [g.to_dict() for g in plan.robot_grasps] == data["robot_grasps"]
    assert [h.to_dict() for h in plan.human_grasps] == data["human_grasps"]
    g = plan.robot_grasps[0]
    # The record's pose is the candidate's: ``o`` closes from contact 0 to contact 1, and the
    # point midway between the contacts lies on the approach axis through the pose's origin.
    closing = (g.contacts[1] - g.contacts[0]) / np.linalg.norm(g.contacts[1] - g.contacts[0])
    np.testing.assert_allclose(closing, g.pose[:3, 1], atol=1e-9)
    np.testing.assert_allclose(np.cross(g.contacts.mean(axis=0) - g.pose[:3, 3], g.pose[:3, 2]),
                               0.0, atol=1e-9)
    np.testing.assert_allclose(g.pose_world, plan.object_pose @ g.pose)


def test_h2g1_s_notes_are_what_the_result_counts(planner):
    plan = planner.plan("tray")
    assert plan.mode == "H2G1"
    notes = plan.attempt.notes
    cands = plan.to_dict()["candidates"]
    assert (notes.pairs.checked, notes.pairs.colliding, notes.pairs.not_liftable) == (
        cands["pairs_checked"], cands["pairs_colliding"], cands["pairs_not_liftable"])
    assert 0 <= notes.pairs.colliding <= notes.pairs.checked
    assert notes.receiver_hands.count == cands["receiver_hands"] == 2  # a large object
    assert list(notes.two_handed.pickup_hands) == cands["pickup_hands"]
    assert set(notes.two_handed.pickup_hands) <= {"left", "right"}
    # The balance offset: the centre of mass's distance to the line between the grasps.
    left, right = (plan.context.candidates.centre[c.grasp] for c in plan.attempt.chosen)
    com = np.asarray(plan.context.part_mesh.mass_centre, dtype=float)
    line = (right - left) / np.linalg.norm(right - left)
    off = np.linalg.norm(np.cross(line, com - left))
    assert notes.two_handed.balance_offset_m == pytest.approx(off, abs=1e-9)
    assert notes.first is None and notes.midair is None


def test_h2g2_s_midair_pose_is_the_handover_pose_nearer_the_robot(planner):
    plan = planner.plan("book", mode="h2g2")
    assert plan.mode == "H2G2"
    midair = plan.attempt.notes.midair.pose
    toward = plan.context.situation.toward
    np.testing.assert_allclose(midair[:3, :3], plan.object_pose[:3, :3])
    np.testing.assert_allclose(plan.object_pose[:3, 3] - midair[:3, 3],
                               MIDAIR_BACKOFF * toward, atol=1e-12)
    first, second = plan.robot_grasps
    assert (first.stage, second.stage) == ("pick", "handover")
    # The first gripper is given where it picks: the object at its initial pose.
    np.testing.assert_allclose(first.pose_world, plan.context.initial @ first.pose)
    assert plan.attempt.notes.first.feasible > 0
    assert plan.to_dict()["candidates"]["first_feasible"] == plan.attempt.notes.first.feasible


def test_an_array_rounds_as_each_of_its_numbers_does():
    """The JSON's numbers are Python's ``round(x, 6)`` of each value (no -0.0, NaN and
    infinities null), whether a record holds an array or a list: ties, values a hair either
    side of a tie, negatives, tiny and huge values, in any shape."""

    rng = np.random.default_rng(7)
    ties = (np.arange(-20000, 20000) + 0.5) / 1e6
    arrays = [ties, np.nextafter(ties, 1.0), np.nextafter(ties, -1.0), ties * 1e3,
              rng.normal(size=(50, 7)) * 1e-7, rng.normal(size=(3, 4, 5)),
              rng.normal(size=200) * 1e9,
              np.array([0.0078125, -0.0078125, -0.0, -1e-9, 2.675, np.nan, np.inf, -np.inf])]
    for a in arrays:
        each = [None if not np.isfinite(x) else (round(x, 6) or 0.0) for x in a.ravel().tolist()]
        got = to_jsonable(a)
        flat = np.asarray(got, dtype=object).ravel().tolist()
        assert np.shape(got) == a.shape
        assert [repr(v) for v in flat] == [repr(v) for v in each]
