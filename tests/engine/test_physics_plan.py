"""The physics check of plans through the facade and the CLI: ``handover plan --physics`` and
``handover verify PLAN.json`` (grasps simulated in MuJoCo, engine/plan/physics.py)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from handover import Planner
from handover.engine.cli.app import main
from handover.engine.errors import UnknownIdError, UsageError
from handover.engine.load.loader import load_kb
from handover.engine.plan.physics import check_plan, object_model


@pytest.fixture(scope="module")
def kb():
    return load_kb(None)


@pytest.fixture(scope="module")
def hammer_plan() -> dict:
    return Planner(db=False).plan("hammer").to_dict()


@pytest.fixture(scope="module")
def tray_plan() -> dict:
    return Planner(db=False).plan("tray").to_dict()


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def _hammer_handle_grasp(plan: dict, x: float) -> dict:
    """The plan with its grasp moved onto the hammer's handle at ``x`` (m from the head's
    centre along the handle), the jaws closing across its 24 mm thickness (object z), the
    fingers coming from the claw side (object y): the weight's torque is about the closing
    axis once the hammer is presented with its handle level."""
    edited = copy.deepcopy(plan)
    g = edited["robot_grasps"][0]
    g["pose"] = [[-1.0, 0.0, 0.0, x], [0.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 0.0],
                 [0.0, 0.0, 0.0, 1.0]]
    g["width"] = 0.024  # the handle box's extent along z (kb/objects/hammer.yaml)
    return edited


def test_hammer_held_at_its_centre_of_mass_holds_and_at_the_handle_end_drops(kb, hammer_plan):
    com = object_model(kb, kb.objects["hammer"]).centre_of_mass()
    # the handle (0.28 m box from x = 0.01) carries most of the volume: the centre of mass
    # lies on it, 11 cm from the head's centre
    assert 0.09 < com[0] < 0.13
    at_com = check_plan(kb, _hammer_handle_grasp(hammer_plan, float(com[0])))
    assert at_com.passed
    assert at_com.checked.result.nominal.max_translation_mm < 5.0
    at_end = check_plan(kb, _hammer_handle_grasp(hammer_plan, 0.27))
    assert not at_end.passed  # 16 cm from the centre of mass: ~0.9 N m about the jaws' axis
    assert at_end.checked.result.nominal.max_rotation_deg > 5.0


def test_the_same_check_twice_gives_identical_numbers(kb, hammer_plan):
    first = check_plan(kb, hammer_plan).to_dict()
    second = check_plan(kb, hammer_plan).to_dict()
    assert first == second  # no wall-clock time in the block


def test_the_receiver_takes_the_hammer_by_its_handle_and_holds_it(kb, hammer_plan):
    assert hammer_plan["human_grasps"][0]["part"] == "handle"
    checked = check_plan(kb, hammer_plan, receiver=True)
    block = checked.to_dict()["chosen"]
    assert block["receiver_held"] is True and checked.passed
    # the grippers let go and the receiver holds it alone, measured in their hand's frame
    alone = [p for p in block["slip"] if p["phase"] == "handover_hold"]
    assert [p["holder"] for p in alone] == ["receiver"]
    assert alone[0]["translation_mm"] < 5.0 and not alone[0]["dropped"]
    assert check_plan(kb, hammer_plan).to_dict()["chosen"]["receiver_held"] is None


def test_a_tray_held_by_one_gripper_at_its_rim_drops_and_by_two_holds(kb, tray_plan):
    assert tray_plan["mode"] == "H2G1"
    both = check_plan(kb, tray_plan)
    assert both.passed and both.checked.hands == ("left", "right")
    one = copy.deepcopy(tray_plan)
    one["mode"], one["robot_grasps"] = "H1G1", one["robot_grasps"][:1]
    alone = check_plan(kb, one)
    assert not alone.passed and alone.checked.result.nominal.dropped


def test_plan_with_physics_has_its_block_in_the_json(capsys):
    code, out, _ = _run(capsys, "plan", "book", "--physics", "--json", "--no-db")
    assert code == 0
    data = json.loads(out)
    physics = data["physics"]
    chosen = physics["chosen"]
    assert physics["passed"] is chosen["passed"] is True  # a book held across its faces
    # the book is handed with a midair regrasp: both grasps checked, one after the other
    assert data["mode"] == chosen["mode"] == "H2G2"
    first, second = data["regrasp"]["first"], data["regrasp"]["second"]
    assert chosen["grasps"] == [{"hand": first["hand"], "id": first["id"]},
                                {"hand": second["hand"], "id": second["id"]}]
    held = {(p["phase"], p["holder"]) for p in chosen["slip"]}
    assert ("shake", first["hand"]) in held and ("regrasp_shake", second["hand"]) in held
    assert 0.0 <= chosen["margin"] <= 1.0 and len(chosen["ensemble"]) == 6


BUILT_IN = ("ball", "book", "bottle", "hammer", "knife", "mug", "pen", "scissors",
            "screwdriver", "tray")


@pytest.mark.parametrize("obj", BUILT_IN)
def test_every_built_in_default_plan_holds_in_physics(capsys, obj):
    """``handover plan OBJ --physics`` as a user runs it (the arms' motion planned, which can
    pass over grasps): a handover whose chosen grasps are the ones checked, each holder's
    slip in every phase within the pass thresholds."""
    from handover.geometry.physics import Thresholds

    code, out, _ = _run(capsys, "plan", obj, "--physics", "--json")
    data = json.loads(out)
    assert code == 0 and data["outcome"] == "handover"
    chosen = data["physics"]["chosen"]
    grasps = [data["regrasp"]["first"], data["regrasp"]["second"]] \
        if data["mode"] == "H2G2" else data["robot_grasps"]
    assert chosen["grasps"] == [{"hand": g["hand"], "id": g["id"]} for g in grasps]
    t = Thresholds()
    assert data["physics"]["passed"] and chosen["passed"] and chosen["dropped_in"] is None
    for slip in chosen["slip"]:
        assert slip["translation_mm"] <= t.max_slip_mm, slip
        assert slip["rotation_deg"] <= t.max_slip_deg, slip
    # robust in the ensemble, or the answer says it is not
    passing = sum(run["passed"] for run in chosen["ensemble"]) / len(chosen["ensemble"])
    assert chosen["robust"] == (passing >= t.ensemble_fraction)
    if not chosen["robust"]:
        assert any("not in the ensemble" in w for w in data["warnings"]), data["warnings"]


def test_the_hammer_s_default_plan_holds_carried_at_its_arm_s_own_pace(capsys, tmp_path: Path):
    """``handover plan hammer`` (no ``--physics``: the arms' motion planned) then ``handover
    verify`` of that plan: its chosen grasp, on the head, carried along the arm's trajectory
    at the trajectory's timing, holds (exit 0), no holder's slip past the thresholds. The
    check once moved the object along straight pieces between 24 of the arm's samples, at a
    pace of its own: every corner jerked it (482 m/s^2 where the arm's motion reaches 4) and
    this grasp dropped in the carry."""
    from handover.geometry.physics import Thresholds

    code, out, _ = _run(capsys, "plan", "hammer", "--json")
    assert code == 0
    path = tmp_path / "hammer.json"
    path.write_text(out)
    data = json.loads(out)
    assert data["motion"]["planned"]
    code, out, _ = _run(capsys, "verify", str(path), "--db", str(tmp_path / "db"), "--json")
    chosen = json.loads(out)["chosen"]
    assert code == 0 and chosen["passed"] and chosen["dropped_in"] is None
    assert chosen["grasps"] == [{"hand": g["hand"], "id": g["id"]} for g in data["robot_grasps"]]
    t = Thresholds()
    for slip in chosen["slip"]:
        assert slip["translation_mm"] <= t.max_slip_mm and slip["rotation_deg"] <= t.max_slip_deg


def test_a_grasp_that_holds_only_at_nominal_friction_is_passed_over_for_a_robust_one(
        capsys, tmp_path: Path, kb, hammer_plan):
    """The hammer's default grasp, on its head, holds at the gripper's own friction and
    force, but drops in the lift at 30 % less of either (half the ensemble fails). With
    ``--physics`` the plan takes a grasp that holds in the ensemble, and says which it
    passed over and why; ``handover verify`` finds that plan robust on its own."""
    from handover.geometry.physics import Thresholds

    default = check_plan(kb, hammer_plan)
    assert default.passed and not default.checked.result.robust
    code, out, _ = _run(capsys, "plan", "hammer", "--physics", "--json", "--no-motion")
    data = json.loads(out)
    assert code == 0 and data["physics"]["chosen"]["robust"]
    chosen = {g["id"] for g in data["robot_grasps"]}
    first = {g["id"] for g in hammer_plan["robot_grasps"]}
    assert not chosen & first
    said = next(w for w in data["warnings"] if "not in the ensemble" in w)
    assert all(f"grasp {i} passed over" in said for i in first)
    path = tmp_path / "robust.json"
    path.write_text(out)
    code, out, _ = _run(capsys, "verify", str(path), "--json")
    verified = json.loads(out)
    assert code == 0 and verified["chosen"]["margin"] >= Thresholds().ensemble_fraction


def test_plan_without_physics_has_no_block(capsys):
    code, out, _ = _run(capsys, "plan", "book", "--json", "--no-db")
    assert code == 0 and "physics" not in json.loads(out)


def test_verify_fails_a_plan_whose_grasp_was_moved_to_a_bad_place(capsys, tmp_path: Path,
                                                                  hammer_plan):
    good = tmp_path / "good.json"
    good.write_text(json.dumps(_hammer_handle_grasp(hammer_plan, 0.11)))
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(_hammer_handle_grasp(hammer_plan, 0.27)))
    db = str(tmp_path / "db")
    assert _run(capsys, "verify", str(good), "--db", db)[0] == 0
    code, out, _ = _run(capsys, "verify", str(bad), "--db", db, "--json")
    assert code == 4
    assert json.loads(out)["passed"] is False


@pytest.mark.parametrize("content, says", [
    ("not json {", "is not JSON"),
    ('{"a": 1}', "not a plan"),
    ("[1, 2]", "not a plan"),
])
def test_verify_refuses_what_is_not_a_plan(capsys, tmp_path: Path, content, says):
    path = tmp_path / "plan.json"
    path.write_text(content)
    code, _, err = _run(capsys, "verify", str(path), "--db", str(tmp_path / "db"))
    assert code == 2 and says in err and "Traceback" not in err


def test_verify_says_which_trajectory_it_cannot_follow(capsys, tmp_path: Path):
    """A plan whose arm trajectory was edited into nonsense is a usage error that says so,
    not a traceback (the check follows the arm's path where a plan has one)."""
    data = Planner(db=False).plan("knife", motion=True).to_dict()
    segment = next(s for s in data["robot_grasps"][0]["trajectory"]
                   if s["segment"] == "lift->approach")
    segment["positions"] = [["a"] * len(segment["joint_names"])]
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(data))
    code, _, err = _run(capsys, "verify", str(path), "--db", str(tmp_path / "db"))
    assert code == 2 and "trajectory cannot be followed" in err and "Traceback" not in err


def test_unknown_object_or_gripper_is_a_clear_error(kb, hammer_plan):
    other = dict(hammer_plan, object="anvil")
    with pytest.raises(UnknownIdError, match="object 'anvil'"):
        check_plan(kb, other)
    other = dict(hammer_plan, gripper=dict(hammer_plan["gripper"], id="claw_machine"))
    with pytest.raises(UnknownIdError, match="gripper 'claw_machine'"):
        check_plan(kb, other)
    broken = copy.deepcopy(hammer_plan)
    broken["robot_grasps"][0]["pose"] = np.diag([2.0, 1.0, 1.0, 1.0]).tolist()
    with pytest.raises(UsageError, match="not a rigid transform"):
        check_plan(kb, broken)


def test_the_recording_shows_the_simulated_object_from_pick_up_to_the_handover(capsys, tmp_path):
    from rerun.chunk import RrdReader

    rrd, out = tmp_path / "plan.rrd", tmp_path / "plan.json"
    code, _, _ = _run(capsys, "plan", "knife", "--physics", "--no-db", "--rrd", str(rrd),
                      "-o", str(out))
    assert code == 0
    data = json.loads(out.read_text())
    positions, times, fingers = [], [], 0
    for chunk in RrdReader(rrd).stream().to_chunks():
        batch = chunk.to_record_batch()
        if chunk.entity_path == "/world/physics/object":
            positions += [p[0] for p in batch.column("Transform3D:translation").to_pylist()]
            times += batch.column("physics").to_pylist()
        if chunk.entity_path == "/world/physics/gripper0/fingers":
            fingers += batch.num_rows
    order = np.argsort(times)
    positions = np.asarray(positions)[order]
    # from where it lay on the table to where it is handed over, at 50 Hz over the protocol
    np.testing.assert_allclose(positions[0], np.asarray(data["initial_pose"])[:3, 3], atol=0.005)
    np.testing.assert_allclose(positions[-1], np.asarray(data["object_pose"])[:3, 3], atol=0.01)
    assert len(positions) == fingers > 200


def test_when_the_chosen_grasp_fails_the_next_best_are_checked_until_one_holds(kb):
    from handover.engine.plan.physics import check_alternatives

    planned = Planner(db=False).plan("hammer")
    data = _hammer_handle_grasp(planned.to_dict(), 0.27)  # a chosen grasp that drops
    failed = check_plan(kb, data)
    assert not failed.passed
    physics = check_alternatives(kb, planned.context, data, failed, limit=3)
    assert physics.checked is failed.checked and not physics.passed
    tried = [c.ids[0] for c in physics.failed] + (
        [physics.holds.ids[0]] if physics.holds else [])
    # the next best candidates, best first, as the plan lists them, at most 3
    assert tried == [a["grasp"] for a in data["alternatives"]][:len(tried)]
    assert 1 <= len(tried) <= 3
    assert physics.holds is not None and physics.holds.passed
    block = physics.to_dict()
    assert block["alternative_holds"]["grasps"] == [{"hand": "left", "id": tried[-1]}]



# Objects of our own no single gripper holds through the check's shake: a 1.2 m broom
# handle and a 0.9 kg cutting board (36 x 25 x 2 cm) lying flat.
OWN = {
    # a broom handle lying across the table, along the robot's left and right
    "broom_across": "id: broom_across\nname: A long-handled broom, across the table\n"
                    "mass: 0.4\ngeometry:\n  primitives:\n"
                    "    - {shape: cylinder, part: handle, radius: 0.013, height: 1.2,\n"
                    "       position: [0, 0, 0], rotation_deg: [90, 0, 0]}\n"
                    "parts:\n  handle: {tags: [handle]}\naxes:\n  handle: [0, 1, 0]\n",
    # a kettle of hot water whose short top handle leaves no room for the gripper beside
    # the receiver's hand: the robot holds it by a handle post for a handover
    "kettle": "id: kettle\nname: Kettle of hot water\nmass: 1.3\ntags: [container]\n"
              "geometry:\n  primitives:\n"
              "    - {shape: cylinder, part: body, radius: 0.08, height: 0.18, "
              "position: [0, 0, 0.09]}\n"
              "    - {shape: box, part: handle, extents: [0.08, 0.025, 0.02], "
              "position: [0, 0, 0.23]}\n"
              "    - {shape: box, part: post_a, extents: [0.015, 0.02, 0.05], "
              "position: [0.035, 0, 0.2]}\n"
              "    - {shape: box, part: post_b, extents: [0.015, 0.02, 0.05], "
              "position: [-0.035, 0, 0.2]}\n"
              "    - {shape: cylinder, part: spout, radius: 0.012, height: 0.1, "
              "position: [0.11, 0, 0.12], rotation_deg: [0, 50, 0]}\n"
              "parts:\n  body: {tags: [hot]}\n  handle: {tags: [handle]}\n"
              "  post_a: {tags: [hot]}\n  post_b: {tags: [hot]}\n"
              "  spout: {tags: [hot, nozzle]}\n"
              "axes:\n  up: [0, 0, 1]\n  nozzle: [1, 0, 0]\n",
    "board": "id: board\nname: Cutting board\nmass: 0.9\ngeometry:\n  primitives:\n"
             "    - {shape: box, part: board, extents: [0.36, 0.25, 0.02], "
             "position: [0, 0, 0.01]}\n"
             "parts:\n  board: {tags: [body]}\n",
}


@pytest.fixture(scope="module")
def own_kb(tmp_path_factory) -> Path:
    import shutil

    from handover.engine.store.kb import builtin_kb_dir

    root = tmp_path_factory.mktemp("own") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    for name, text in OWN.items():
        (root / "objects" / f"{name}.yaml").write_text(text, encoding="utf-8")
    return root


def _checked(capsys, root: Path, obj: str, *more: str) -> tuple[int, str, dict]:
    """``handover plan OBJ --physics --json`` with the KB at ``root`` (and ``more``
    options): (exit code, output, its JSON)."""
    code, out, _ = _run(capsys, "--kb", str(root), "plan", obj, "--physics", "--json",
                        "--no-motion", "--no-db", *more)
    return code, out, json.loads(out)


def test_a_plan_whose_grasps_do_not_hold_exits_4_with_a_warning(capsys, tmp_path, own_kb):
    """A 1.2 m broom handle pinched by one gripper turns out of its fingers as the check
    carries it round (it held in the analytic rules), wherever it is pinched; with one hand
    forced (``--mode h1g1``), ``handover plan --physics`` says so in the JSON's warnings
    and exits 4, as ``handover verify`` does for a plan that does not hold, so a robot's
    script does not run it as if it were fine."""
    from handover.engine.tools.answer import PHYSICS_FAILED

    code, out, data = _checked(capsys, own_kb, "broom_across", "--mode", "h1g1")
    assert data["outcome"] == "handover" and not data["physics"]["passed"]
    assert code == 4 and PHYSICS_FAILED in data["warnings"]
    path = tmp_path / "broom.json"
    path.write_text(out, encoding="utf-8")
    assert _run(capsys, "--kb", str(own_kb), "verify", str(path))[0] == 4


def test_a_kettle_no_handover_grasp_holds_is_set_down_upright_by_a_grasp_that_holds(capsys,
                                                                                   own_kb):
    """A 1.3 kg kettle of hot water, its 8 cm top handle the receiver's: in every mode the
    gripper holds it by a handle post, 14 cm above its centre of mass, and it turns in the
    fingers in the check's shake. With the mode left to the planner, ``--physics`` then
    sets it down on the table within the receiver's reach, as a careful person would:
    upright, on the table top, the handle where the receiver takes it, carried there by a
    grasp the check holds (exit 0); the handover's failed checks stay in the answer."""
    code, _, data = _checked(capsys, own_kb, "kettle")
    assert code == 0 and data["outcome"] == "place"
    physics = data["physics"]
    assert physics["passed"]
    failed = physics["alternatives_failed"]
    assert failed and all(not g["passed"] for g in failed)
    assert any("set down within the receiver's reach instead" in w and "physics" in w
               for w in data["warnings"])
    assert "holds in the physics check" in data["reason"]
    pose = np.asarray(data["object_pose"], dtype=float)
    assert pose[:3, :3][2, 2] > 0.999  # its up axis is the world's: upright, nothing spills
    table = next(b for b in data["scene"]["boxes"] if b["id"] == "table")
    top = np.asarray(table["pose"])[2, 3] + table["extents"][2] / 2
    assert pose[2, 3] == pytest.approx(top, abs=0.002)  # its base (z = 0) on the table top
    (held,) = data["robot_grasps"]
    assert "spout" not in held["parts"]
    (site,) = data["human_grasps"]
    handle = np.linalg.inv(pose) @ np.r_[site["position_world"], 1.0]
    assert np.all(np.abs(handle[:3] - [0, 0, 0.23]) <= np.array([0.04, 0.0125, 0.01]) + 1e-6)


def test_a_board_no_single_gripper_holds_is_handed_in_a_mode_whose_grasps_hold(capsys,
                                                                               own_kb):
    """The cutting board can only be pinched at an edge, 12.5 cm or more from its centre of
    mass: held so by one gripper, it turns out of the fingers in the check's shake,
    whichever edge grasp is tried. With the mode left to the planner, ``--physics`` then
    hands it in another mode whose grasps the check holds, and says so."""
    from handover.geometry.physics import Thresholds

    code, _, data = _checked(capsys, own_kb, "board")
    assert code == 0 and data["outcome"] == "handover"
    physics = data["physics"]
    assert physics["passed"] and data["mode"] != "H1G1"
    failed_one_hand = [g for g in physics["alternatives_failed"] if g["mode"] == "H1G1"]
    assert failed_one_hand and all(not g["passed"] for g in failed_one_hand)
    assert any(w.startswith("physics: no grasp of the H1G1 plan holds") and data["mode"] in w
               for w in data["warnings"])
    t = Thresholds()
    for slip in physics["chosen"]["slip"]:
        assert slip["translation_mm"] <= t.max_slip_mm and slip["rotation_deg"] <= t.max_slip_deg


def test_a_broom_handle_no_single_gripper_holds_is_handed_with_both_arms(capsys, own_kb):
    """A 1.2 m broom handle lying across the table turns out of one gripper's fingers in the
    check's shake wherever it is pinched (its inertia about the fingers' axis asks more
    twist than the pads hold), as a person would not hold it in two fingers either. Its
    best-balanced pairs lie at its ends, out of the arms' reach on the table; with the mode
    left to the planner, ``--physics`` hands it with both arms, at a pair they reach, two
    grasps apart along the handle whose hold the check confirms."""
    from handover.geometry.physics import Thresholds

    code, _, data = _checked(capsys, own_kb, "broom_across")
    assert code == 0 and data["outcome"] == "handover" and data["mode"] == "H2G1"
    physics = data["physics"]
    assert physics["passed"]
    one_hand = [g for g in physics["alternatives_failed"] if g["mode"] == "H1G1"]
    assert one_hand and all(not g["passed"] for g in one_hand)
    assert sorted(g["arm"] for g in data["robot_grasps"]) == ["left", "right"]
    # two holds along the handle (object frame y), not one place: a couple against its turn
    along = [np.mean(np.asarray(g["contacts"], dtype=float)[:, 1]) for g in data["robot_grasps"]]
    assert abs(along[0] - along[1]) >= 0.1
    t = Thresholds()
    for slip in physics["chosen"]["slip"]:
        assert slip["translation_mm"] <= t.max_slip_mm and slip["rotation_deg"] <= t.max_slip_deg


def test_the_physics_check_carries_the_object_along_the_arm_s_planned_path(kb):
    """With the plan's motion, the physics check carries the object where the arm takes it:
    each pose of its carry, with the gripper on the object at the plan's grasp, is where
    yourdfpy's FK of some sample of the arm's trajectory from the lift to the handover puts
    the gripper; the last is the plan's handover pose; each is reached at its sample's time,
    and the carry lasts as long as those segments. Without the motion, the carry goes from
    the stages' poses alone."""
    from handover.engine.plan.carry import plan_motion
    from handover.engine.store.kb import builtin_kb_dir
    from tests.engine.test_robot_result import gripper_at, urdf_of

    data = Planner(db=False).plan("knife", motion=True).to_dict()
    assert data["motion"]["planned"]
    (grasp,) = data["robot_grasps"]
    urdf = urdf_of(builtin_kb_dir(), data["robot"])
    carried = [s for s in grasp["trajectory"]
               if s["segment"] in ("lift->approach", "approach->handover")]
    assert len(carried) == 2
    tools = np.array([gripper_at(urdf, data["robot"], grasp["arm"],
                                 dict(zip(s["joint_names"], q, strict=True)))
                      for s in carried for q in s["positions"]])
    held = np.asarray(grasp["pose"])
    if "handover" in grasp.get("fingers_swapped", []):  # held turned about a everywhere
        held = held @ np.diag([-1.0, -1.0, 1.0, 1.0])

    motion = plan_motion(data, kb)
    assert len(motion.carry) > 10
    np.testing.assert_allclose(motion.carry[-1], np.asarray(data["object_pose"]), atol=1e-6)
    for pose in motion.carry[:-1]:
        gripper = pose @ held
        gap = np.abs(tools - gripper).max(axis=(1, 2)).min()
        assert gap < 1e-3
    assert motion.carry_time == pytest.approx(sum(s["times"][-1] for s in carried))
    # every sample at its own time: the first segment's, then the second's after it
    first = np.asarray(carried[0]["times"])
    np.testing.assert_allclose(motion.carry_times[:len(first)], first)
    np.testing.assert_allclose(motion.carry_times[len(first):],
                               first[-1] + np.asarray(carried[1]["times"][1:]))
    staged = plan_motion(data)
    assert len(staged.carry) == 1 and staged.carry_time is None
