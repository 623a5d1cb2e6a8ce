"""Rerun recordings of a plan, read back with rerun's own reader (``rerun.chunk.RrdReader``).

A small hand-made plan (six grasps, two presentations, three hard rules, a decision table
written by hand) gives outcomes known in advance; the real pipeline (knife, and H2G2 on the
hammer by the wall) gives recordings whose counts must agree with the JSON result.
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from handover.engine.errors import UsageError
from handover.engine.plan.attempt import Attempt
from handover.engine.plan.compiler import CompiledRule
from handover.engine.plan.context import PlanContext
from handover.engine.plan.evaluate import Decision
from handover.engine.plan.phase import Hands, Phase
from handover.engine.plan.receiver_sites import ReceiverRegion, ReceiverSites
from handover.engine.plan.records import ArmJoints, HumanGrasp, RobotGrasp
from handover.engine.report.rerun.bodies import ARM_COLOURS
from handover.engine.report.rerun.reader import read_recording
from handover.engine.report.rerun.stages import (
    CLASS_ALIVE,
    CLASS_CHOSEN,
    CLASS_GENERATED,
    CLASS_KEPT,
    CLASS_RULE_BASE,
    ENTITY_CENTRES,
    ENTITY_LOG,
    OUTCOME_COLOURS,
    stage_classes,
)
from handover.engine.report.rerun.writer import write_recording
from handover.engine.report.result import PlanResult, Regrasp
from handover.engine.spec.kinds import KINDS
from handover.engine.spec.schema import RULE_KINDS, parse_rule
from handover.geometry.candidates import SOURCE_FACET, CandidateSet
from handover.geometry.gripper import Gripper
from handover.geometry.hand import HumanHand

N, K = 6, 2
HARD = [
    parse_rule(dict(id="giver_no_blade", kind="contact", who="giver", forbid_tags=["blade"],
         why="The robot holds the handle.")),
    parse_rule(dict(id="tip_away", kind="axis", axis="tip", toward="toward_receiver", min_deg=90,
         why="The tip never points at the receiver.")),
    parse_rule(dict(id="gripper_free", kind="collision", against=["scene", "receiver_hand"],
         why="The gripper touches nothing but the object.")),
]  # fmt: skip
SOFT = [parse_rule(dict(id="good_grip", kind="quality", hard=False, weight=1.0, min_quality=0.0,
             why="Firm grasps are better."))]  # fmt: skip


def rgb(colour: tuple[int, int, int]) -> int:
    """rerun's packed colour 0xRRGGBBAA for an opaque RGB."""
    r, g, b = colour
    return (r << 24) | (g << 16) | (b << 8) | 0xFF


def _candidates() -> CandidateSet:
    """Six grasps across a 0.2 x 0.03 x 0.02 m bar, approached from above (-z in the object
    frame), closing along y; grasps 0-2 on the handle (x < 0), 3-5 on the blade."""
    x = np.linspace(-0.08, 0.08, N)
    centre = np.stack([x, np.zeros(N), np.zeros(N)], axis=1)
    o = np.tile([0.0, 1.0, 0.0], (N, 1))
    a = np.tile([0.0, 0.0, -1.0], (N, 1))
    n = np.cross(o, a)
    contacts = np.stack([centre - [0, 0.015, 0], centre + [0, 0.015, 0]], axis=1)
    parts = np.repeat((x > 0).astype(np.int64)[:, None], 2, axis=1)
    return CandidateSet(
        centre=centre, n=n, o=o, a=a, width=np.full(N, 0.03), contacts=contacts,
        normals=np.stack([-o, o], axis=1), faces=np.zeros((N, 2), dtype=np.int64), parts=parts,
        site=np.arange(N), roll=np.zeros(N), overlap_area=np.zeros(N),
        source=np.full(N, SOURCE_FACET, dtype=np.int8), quality=np.linspace(1.0, 0.5, N),
        com_distance=np.zeros(N), part_names=["handle", "blade"],
    )  # fmt: skip


def _decision(feasible: bool) -> Decision:
    """Rows grasp-major (row = 2 i + k). In presentation 0: grasps 0 and 1 pass every hard
    rule, 2 fails the contact rule, 3 the axis rule, 4 collides, 5 fails the contact rule.
    In presentation 1 every row fails the axis rule. Infeasible: grasps 0 and 1 collide
    too."""
    gi = np.repeat(np.arange(N), K)
    pk = np.tile(np.arange(K), N)
    fails = np.zeros((N * K, 3), dtype=bool)
    fails[pk == 1, 1] = True
    fails[2 * 2, 0] = True
    fails[2 * 3, 1] = True
    fails[2 * 4, 2] = True
    fails[2 * 5, 0] = True
    if not feasible:
        fails[[0, 2], 2] = True
    checked = np.ones_like(fails)
    kept = ~fails.any(axis=1)
    score = np.where(kept, np.where(gi == 0, 0.9, 0.6), np.nan)
    first_fail = np.where(fails.any(axis=1), np.argmax(fails, axis=1), -1)
    return Decision(
        gi=gi, pk=pk, hard=[CompiledRule(r, "common") for r in HARD],
        soft=[CompiledRule(r, "common") for r in SOFT], fails=fails, checked=checked,
        kept=kept, score=score, first_fail=first_fail, soft_scores=score[:, None],
    )  # fmt: skip


def _context(cands: CandidateSet) -> PlanContext:
    from handover.geometry.mesh import PartMesh, box

    mesh = box([0.2, 0.03, 0.02])
    face_part = (np.asarray(mesh.triangles_center)[:, 0] > 0).astype(np.int64)
    part_mesh = PartMesh(mesh, face_part, ["handle", "blade"], np.zeros(3))
    rotations = np.stack([np.eye(3), np.diag([-1.0, -1.0, 1.0])])
    poses = np.tile(np.eye(4), (K, 1, 1))
    poses[:, :3, :3] = rotations
    poses[:, :3, 3] = [0.5, 0.0, 1.0]
    initial = np.eye(4)
    initial[:3, 3] = [0.5, 0.0, 0.76]
    table = np.eye(4)
    table[:3, 3] = [0.6, 0.0, 0.725]
    sites = ReceiverSites(site=np.array([[-0.06, 0.0, 0.0], [0.06, 0.0, 0.0]]),
                          part=np.zeros(K, dtype=np.int64), thickness=np.full(K, 0.02),
                          valid=np.ones(K, dtype=bool))  # fmt: skip
    region = ReceiverRegion(points=np.zeros((2, 3)), parts=np.zeros(2, dtype=np.int64),
                            axis=np.array([1.0, 0.0, 0.0]), tags=("handle",))  # fmt: skip
    situation = SimpleNamespace(
        obj=SimpleNamespace(id="bar", axes={"tip": (1.0, 0.0, 0.0), "up": (0.0, 0.0, 1.0)}),
        toward=np.array([1.0, 0.0, 0.0]),
    )
    ctx = PlanContext(
        situation=situation, part_mesh=part_mesh, part_tags=[{"handle"}, {"blade", "sharp"}],
        candidates=cands, generation={"facet_pairs": 3}, gripper=Gripper.default(),
        hand=HumanHand(palm=(0.08, 0.09, 0.03), finger_length=0.08, finger_thickness=0.02,
                       grip_width=0.08),
        rotations=rotations, initial=initial, scene=None,
        scene_box_list=[("table", np.array([0.8, 1.2, 0.05]), table)],
        facts=None,
    )  # fmt: skip
    hands = Hands(key=("test", 1), region=region, sites=(sites,), s_range=np.zeros((K, 2)),
                  poses=poses, location=np.zeros(K, dtype=np.int64), located=np.ones(K, bool),
                  measured={}, hits=((),) * K)
    return ctx, hands


def _grasp(cands: CandidateSet, i: int, hand: str, score: float,
           stage: str | None = None) -> RobotGrasp:
    pose = cands.poses()[i]
    return RobotGrasp(gripper=hand, pose=pose, pose_world=pose, width=float(cands.width[i]),
                      contacts=cands.contacts[i],
                      parts=tuple(cands.part_names[p] for p in cands.parts[i]), score=score,
                      stage=stage or "handover", id=i, quality=float(cands.quality[i]),
                      staged=stage is not None)  # fmt: skip


def _trace(grasp: int, hand: str, stage: str | None = None) -> list[dict]:
    entries = []
    for r, status in zip(HARD + SOFT, ["pass", "pass", "pass", "scored"], strict=True):
        entries.append({"grasp": grasp, "hand": hand, "rule": r.id, "kind": r.kind,
                        "hard": r.hard, "status": status, "measured": 0.0, "unit": "",
                        "threshold": "-", "score": 1.0, "weight": None if r.hard else r.weight,
                        "why": r.why, "source": "etiquette/common.yaml:1", "culture": "common",
                        "overrides": [], "safety": False, "note": None})  # fmt: skip
    entries.append({"grasp": grasp, "hand": hand, "rule": "elder_two_hands", "kind": "mode",
                    "hard": True, "status": "not_applicable", "measured": None, "unit": "",
                    "threshold": "", "score": None, "weight": None,
                    "why": "Elders receive with two hands.", "source": "x.yaml:3",
                    "culture": "common", "overrides": [], "safety": False,
                    "note": "the receiver is not an elder"})  # fmt: skip
    if stage:
        for e in entries:
            e["stage"] = stage
    return entries


def synthetic_plan(feasible: bool = True, h2g2: bool = False):
    """(result, ctx, attempt) of the hand-made plan described in :func:`_decision`."""
    cands = _candidates()
    ctx, hands = _context(cands)
    decision = _decision(feasible)
    mode = "H2G2" if h2g2 else "H1G1"
    attempt = Attempt(mode, feasible,
                      None if feasible else "H1G1: no candidate passes every hard rule",
                      None, decision, Phase(mode, hands=hands))  # fmt: skip
    grasps, trace, regrasp = [], [], None
    if feasible and not h2g2:
        grasps = [_grasp(cands, 0, "right", 0.9)]
        trace = _trace(0, "right")
    elif feasible:
        first = _grasp(cands, 5, "left", 0.9, "pick")
        second = _grasp(cands, 0, "right", 0.9, "handover")
        grasps = [first, second]
        trace = _trace(5, "left", "pick") + _trace(0, "right", "handover")
        midair = hands.poses[0].copy()
        midair[0, 3] -= 0.2
        regrasp = Regrasp(first, midair, second)
    result = PlanResult(
        object="bar",
        query={"object": "bar", "task": None, "receiver": "adult", "culture": "common",
               "scene": "table", "mode": "auto"},
        mode=("H2G2" if h2g2 else "H1G1") if feasible else None,
        feasible=feasible,
        reason=None if feasible else attempt.reason,
        object_pose=hands.poses[0] if feasible else None,
        receiver={"position": [1.0, 0.0, 0.0], "facing": [-1.0, 0.0, 0.0],
                  "hand_height": 1.0, "role": "adult", "dominant_hand": "right"},
        robot_grasps=grasps,
        human_grasps=[HumanGrasp("right", np.array([-0.06, 0, 0]), np.array([0.44, 0.0, 1.0]),
                                 "handle")] if feasible else [],
        gripper={}, candidates={"generated": N * K, "kept": int(decision.kept.sum()),
                                "rejected_by": decision.rejected_by(),
                                "blocking_sets": [] if feasible else
                                [{"rules": ["gripper_free"], "candidates": 2}]},
        trace=trace, regrasp=regrasp, initial_pose=ctx.initial,
        modes_tried=[{"mode": "H1G1", "feasible": feasible, "reason": attempt.reason}],
        mode_reason="one hand, one grasp is tried first",
        presentation={"index": 0, "axes_world": {"tip": [1, 0, 0], "up": [0, 0, 1]}}
        if feasible else None,
    )  # fmt: skip
    return result, ctx, attempt


def read_columns(path: Path) -> dict[str, list[dict]]:
    """Every non-static row of every entity: {entity: [{column: value}]}, plus static rows
    under their entity with ``static`` True. Read with rerun's RrdReader."""
    from rerun.chunk import RrdReader

    out: dict[str, list[dict]] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        rb = chunk.to_record_batch()
        cols = {name: rb.column(name).to_pylist() for name in rb.schema.names}
        for i in range(rb.num_rows):
            row = {name: values[i] for name, values in cols.items()}
            row["static"] = chunk.is_static
            out.setdefault(chunk.entity_path.lstrip("/"), []).append(row)
    return out


def by_stage(rows: list[dict], column: str) -> dict[int, list]:
    return {r["stage"]: r[column] for r in rows if not r["static"] and r.get(column) is not None}


# ------------------------------------------------------------------ pure outcome classes


def test_stage_classes_follow_the_decision_table():
    decision = _decision(True)
    classes = stage_classes(decision, N, 0, chosen=[0])
    contact, axis, collision = (CLASS_RULE_BASE + h for h in range(3))
    assert classes[0].tolist() == [CLASS_GENERATED] * N
    assert classes[1].tolist() == [CLASS_ALIVE, CLASS_ALIVE, contact, axis, CLASS_ALIVE, contact]
    assert classes[2].tolist() == [CLASS_ALIVE, CLASS_ALIVE, contact, axis, collision, contact]
    assert classes[3].tolist() == [CLASS_KEPT, CLASS_KEPT, contact, axis, collision, contact]
    assert classes[4].tolist() == [CLASS_CHOSEN, CLASS_KEPT, contact, axis, collision, contact]
    # In presentation 1 every grasp fails the axis rule first.
    assert stage_classes(decision, N, 1)[1].tolist() == [axis] * N


KIND_COLOURS = {name: kind.colour for name, kind in KINDS.items()}


def test_every_rule_kind_has_its_own_colour():
    assert set(KIND_COLOURS) == set(RULE_KINDS)
    colours = list(KIND_COLOURS.values()) + list(OUTCOME_COLOURS.values())
    assert len(set(colours)) == len(colours)


# ------------------------------------------------------------------ a feasible plan


@pytest.fixture(scope="module")
def feasible_rrd(tmp_path_factory) -> Path:
    result, ctx, attempt = synthetic_plan(feasible=True)
    path = tmp_path_factory.mktemp("rrd") / "bar.rrd"
    write_recording(result, ctx, path, attempt)
    return path


def test_recording_has_the_scene_object_candidates_grippers_and_trace(feasible_rrd):
    entities = {e["path"] for e in read_recording(feasible_rrd)["entities"]}
    expected = {
        "world", "world/scene", "world/people", "world/initial", "world/initial/object",
        "world/handover", "world/handover/object", "world/handover/axes",
        "world/handover/candidates", ENTITY_CENTRES, "world/handover/candidates/approach",
        "world/handover/grippers", "world/initial/grippers", "world/receiver/hands",
        "world/receiver/sites", "trace/summary", ENTITY_LOG,
    }  # fmt: skip
    assert expected <= entities
    assert not any(e.startswith("world/regrasp") for e in entities)  # H1G1: no regrasp


def test_candidates_are_one_batch_per_stage_coloured_by_outcome(feasible_rrd):
    rows = read_columns(feasible_rrd)[ENTITY_CENTRES]
    assert all(not r["static"] for r in rows)
    positions = by_stage(rows, "Points3D:positions")
    assert list(positions) == [0] and len(positions[0]) == N  # positions once
    colours = by_stage(rows, "Points3D:colors")
    assert sorted(colours) == [0, 1, 2, 3, 4]
    contact, axis, coll = (rgb(KIND_COLOURS[k]) for k in ("contact", "axis", "collision"))
    alive, kept, chosen = (rgb(OUTCOME_COLOURS[k]) for k in ("alive", "kept", "chosen"))
    assert colours[0] == [rgb(OUTCOME_COLOURS["generated"])] * N
    assert colours[1] == [alive, alive, contact, axis, alive, contact]
    assert colours[2] == [alive, alive, contact, axis, coll, contact]
    assert colours[3] == [kept, kept, contact, axis, coll, contact]
    assert colours[4] == [chosen, kept, contact, axis, coll, contact]


def test_candidate_outcomes_are_labelled_per_stage(feasible_rrd):
    stages = {s["stage"]: s for s in read_recording(feasible_rrd)["stages"]}
    assert sorted(stages) == [0, 1, 2, 3, 4]
    assert all(s["candidates"] == N for s in stages.values())
    assert stages[0]["outcomes"] == {"generated": N}
    assert stages[1]["outcomes"] == {"alive": 3, "rejected by giver_no_blade (contact)": 2,
                                     "rejected by tip_away (axis)": 1}  # fmt: skip
    assert stages[2]["outcomes"]["rejected by gripper_free (collision)"] == 1
    assert stages[3]["outcomes"]["kept"] == 2
    assert stages[4]["outcomes"]["chosen"] == 1 and stages[4]["outcomes"]["kept"] == 1


def test_trace_is_one_log_line_per_rule_of_the_chosen_grasp(feasible_rrd):
    trace = read_recording(feasible_rrd)["trace"]
    assert len(trace) == len(HARD) + len(SOFT) + 1
    assert {t["stage"] for t in trace} == {4}
    for rule in HARD + SOFT:
        line = next(t for t in trace if rule.id in t["text"])
        assert line["level"] == "INFO" and rule.why in line["text"]
    na = next(t for t in trace if "elder_two_hands" in t["text"])
    assert na["level"] == "DEBUG" and "not an elder" in na["text"]


def test_each_stage_has_a_summary_document(feasible_rrd):
    docs = {d["stage"]: d["text"] for d in read_recording(feasible_rrd)["documents"]}
    assert sorted(docs) == [0, 1, 2, 3, 4]
    assert docs[0].startswith("# Stage 0: generated")
    assert "giver_no_blade" in docs[1] and "tip_away" in docs[1]
    assert "gripper_free" in docs[2]
    assert "Mode **H1G1**" in docs[4] and "handle" in docs[4]


def test_chosen_gripper_is_three_boxes_at_the_grasp(feasible_rrd):
    cols = read_columns(feasible_rrd)
    row = cols["world/handover/grippers"][0]
    assert row["stage"] == 4
    centres = np.array(row["Boxes3D:centers"])
    assert centres.shape == (3, 3)  # palm and two fingers
    # Fingers straddle the grasp centre of grasp 0 along y (closing direction o).
    grasp0 = _candidates().centre[0]
    assert np.allclose(centres[1:].mean(axis=0), grasp0, atol=1e-6)
    assert row["Boxes3D:colors"] == [rgb(OUTCOME_COLOURS["chosen"])] * 3


def test_blueprint_and_rerun_verify(feasible_rrd):
    assert read_recording(feasible_rrd)["blueprint"] is True
    rerun_bin = Path(sys.executable).parent / "rerun"
    done = subprocess.run([str(rerun_bin), "rrd", "verify", str(feasible_rrd)],
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    assert done.returncode == 0, done.stderr


# ------------------------------------------------------------------ infeasible and H2G2


def test_infeasible_plan_records_up_to_the_last_stage_with_candidates(tmp_path):
    result, ctx, attempt = synthetic_plan(feasible=False)
    path = tmp_path / "none.rrd"
    write_recording(result, ctx, path, attempt)
    summary = read_recording(path)
    stages = {s["stage"]: s for s in summary["stages"]}
    # Rows pass the cheap rules (stage 2 runs) but every one collides: no stage 3 or 4.
    assert sorted(stages) == [0, 1, 2]
    assert stages[2]["outcomes"]["rejected by gripper_free (collision)"] == 3
    docs = {d["stage"]: d["text"] for d in summary["documents"]}
    assert "No feasible handover" in docs[2] and result.reason in docs[2]
    errors = [t for t in summary["trace"] if t["level"] == "ERROR"]
    assert len(errors) == 1 and result.reason in errors[0]["text"]
    assert "world/handover/grippers" not in {e["path"] for e in summary["entities"]}


def test_plan_without_any_candidate_records_stage_0_and_the_reason(tmp_path):
    result, ctx, attempt = synthetic_plan(feasible=False)
    ctx.candidates = CandidateSet.empty(["handle", "blade"])
    empty = np.zeros(0, dtype=np.int64)
    attempt = replace(attempt, decision=Decision(
        gi=empty, pk=empty, hard=attempt.decision.hard, soft=attempt.decision.soft,
        fails=np.zeros((0, 3), dtype=bool), checked=np.zeros((0, 3), dtype=bool),
        kept=np.zeros(0, dtype=bool), score=np.zeros(0), first_fail=empty,
        soft_scores=np.zeros((0, 1)),
    ))  # fmt: skip
    result.reason = "H1G1: the object has no geometric grasp for this gripper"
    path = tmp_path / "empty.rrd"
    write_recording(result, ctx, path, attempt)
    summary = read_recording(path)
    assert [(s["stage"], s["candidates"]) for s in summary["stages"]] == [(0, 0)]
    assert result.reason in summary["documents"][-1]["text"]


def test_h2g2_plan_adds_pick_midair_and_handover(tmp_path):
    result, ctx, attempt = synthetic_plan(feasible=True, h2g2=True)
    path = tmp_path / "h2g2.rrd"
    write_recording(result, ctx, path, attempt)
    summary = read_recording(path)
    assert [s["stage"] for s in summary["stages"]] == list(range(8))
    cols = read_columns(path)
    grippers = {r["stage"]: len(r["Boxes3D:centers"]) for r in cols["world/regrasp/grippers"]}
    assert grippers == {5: 3, 6: 6}  # first hand alone, then both hands
    moves = by_stage(cols["world/regrasp"], "Transform3D:translation")
    assert np.allclose(moves[5][0], ctx.initial[:3, 3])
    assert np.allclose(moves[6][0], result.regrasp.midair_pose[:3, 3])
    # The handover grasp (0) is the chosen candidate; the pick grasp's trace lands on stage 5.
    colours = by_stage(cols[ENTITY_CENTRES], "Points3D:colors")
    assert colours[4][0] == rgb(OUTCOME_COLOURS["chosen"])
    stages = {t["stage"] for t in summary["trace"] if "grasp 5" in t["text"]}
    assert stages == {5}


class OneJointArm:
    """A robot with one arm on its ``right``, written here: a mount at (0.2, 0, 1) m; link
    ``l1`` turns about z by the joint's angle there and carries a 0.2 m capsule along its z;
    the tip link, 0.3 m along l1's x, carries a 0.1 x 0.04 x 0.02 m box 0.05 m further out.
    What :func:`write_recording` needs of :class:`~handover.engine.assets.robot.RobotArms`."""

    MOUNT = np.array([0.2, 0.0, 1.0])

    def __init__(self) -> None:
        from handover.geometry.urdf import LinkShapes

        box = np.eye(4)
        box[0, 3] = 0.05
        shapes = LinkShapes(
            links=("mount", "l1", "tip"), cap_link=np.array([1]), cap_a=np.zeros((1, 3)),
            cap_b=np.array([[0.0, 0.0, 0.2]]), cap_radius=np.array([0.03]),
            box_link=np.array([2]), box_pose=box[None], box_extents=np.array([[0.1, 0.04, 0.02]]))
        chain = SimpleNamespace(joint_names=("j1",), links=shapes.links, tip_link="tip",
                                link_joint=np.array([-1, 0, 0]))  # fmt: skip
        self._arm = SimpleNamespace(chain=chain, shapes=shapes)

    def arm(self, side: str):
        assert side == "right"
        return self._arm

    def link_poses(self, side: str, q: np.ndarray) -> np.ndarray:
        (angle,) = np.asarray(q, dtype=float).reshape(-1)
        mount, l1 = np.eye(4), np.eye(4)
        mount[:3, 3] = l1[:3, 3] = self.MOUNT
        c, s_ = np.cos(angle), np.sin(angle)
        l1[:2, :2] = [[c, -s_], [s_, c]]
        tip = l1.copy()
        tip[:3, 3] += 0.3 * l1[:3, 0]
        return np.stack([mount, l1, tip])[None]


def test_an_arm_with_boxes_is_drawn_at_each_stage_s_joints(tmp_path):
    """The hand-made plan held by :class:`OneJointArm`, at 0 rad at pick-up and at a quarter
    turn at the handover: its capsule, its box and its chain where the test puts them."""
    result, ctx, attempt = synthetic_plan()
    result.robot = {"id": "one_arm", "arms": {"right": {}}}
    result.robot_grasps[0] = replace(result.robot_grasps[0], arm_joints=ArmJoints(
        "right", {"pickup": {"j1": 0.0}, "handover": {"j1": np.pi / 2}}))
    ctx.memo.arms = OneJointArm()
    path = tmp_path / "arm.rrd"
    write_recording(result, ctx, path, attempt)
    cols = read_columns(path)
    mount = OneJointArm.MOUNT
    for stage, x_axis in (("pickup", [1.0, 0, 0]), ("handover", [0, 1.0, 0])):
        entity = f"world/robot/arms/{stage}"
        (capsule,) = [r for r in cols[f"{entity}/capsules"] if r["stage"] == 4]
        assert capsule["Capsules3D:labels"] == ["l1"]
        np.testing.assert_allclose(capsule["Capsules3D:translations"], [mount], atol=1e-6)
        assert capsule["Capsules3D:lengths"] == pytest.approx([0.2])
        (box,) = [r for r in cols[f"{entity}/boxes"] if r["stage"] == 4]
        assert box["Boxes3D:labels"] == ["tip"]
        np.testing.assert_allclose(box["Boxes3D:centers"], [mount + 0.35 * np.array(x_axis)],
                                   atol=1e-6)  # fmt: skip
        np.testing.assert_allclose(box["Boxes3D:half_sizes"], [[0.05, 0.02, 0.01]], atol=1e-6)
        (strip,) = by_stage(cols[f"{entity}/chain"], "LineStrips3D:strips")[4]
        # mount and l1 coincide: drawn once, then the tip
        np.testing.assert_allclose(strip, [mount, mount + 0.3 * np.array(x_axis)], atol=1e-6)
        assert capsule["Capsules3D:colors"] == box["Boxes3D:colors"] == [rgb(ARM_COLOURS["right"])]


# ------------------------------------------------------------------ file handling


def test_an_existing_file_is_replaced_whole_and_no_temporary_is_left(tmp_path):
    result, ctx, attempt = synthetic_plan()
    path = tmp_path / "plan.rrd"
    path.write_text("old")
    write_recording(result, ctx, path, attempt)
    assert read_recording(path)["stages"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.rrd"]
    plain = tmp_path / "plain"
    plain.write_text("")  # the mode any new file gets here (umask applied)
    assert path.stat().st_mode == plain.stat().st_mode


def test_failure_while_writing_leaves_the_old_file(tmp_path, monkeypatch):
    import handover.engine.report.rerun.writer as record

    result, ctx, attempt = synthetic_plan()
    path = tmp_path / "plan.rrd"
    path.write_text("old")

    def boom(*args, **kwargs):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(record, "_write", boom)
    with pytest.raises(RuntimeError):
        write_recording(result, ctx, path, attempt)
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.rrd"]


def test_folder_as_target_is_a_usage_error(tmp_path):
    result, ctx, attempt = synthetic_plan()
    with pytest.raises(UsageError, match="folder"):
        write_recording(result, ctx, tmp_path, attempt)


@pytest.mark.parametrize("content", [None, "not a recording\n", ""])
def test_reading_a_missing_or_foreign_file_is_a_usage_error(tmp_path, content):
    path = tmp_path / "x.rrd"
    if content is not None:
        path.write_text(content)
    with pytest.raises(UsageError):
        read_recording(path)


def test_recording_does_not_import_rerun_with_the_engine():
    code = ("import sys, handover.engine.report.rerun.writer, handover.engine.report.rerun.reader, "
            "handover.engine.planner, handover.engine.cli; "
            "print('rerun' in sys.modules)")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60)  # fmt: skip
    assert out.stdout.strip() == "False", out.stderr


# ------------------------------------------------------------------ the real pipeline


@pytest.fixture(scope="module")
def kb():
    from handover.engine.load.loader import load_kb

    return load_kb(None)


def _real(kb, tmp_path: Path, obj: str, mode: str, scene: str):
    from handover.engine.planner import plan
    from handover.engine.spec.query import Query

    planned = plan(kb, Query(object=obj, mode=mode, scene=scene))
    path = tmp_path / f"{obj}-{mode}.rrd"
    planned.record(path)
    return planned.result, planned.context, path


def _labels(cols: dict) -> dict[int, str]:
    row = next(r for r in cols["world/handover/candidates"] if "AnnotationContext:context" in r)
    return {
        item["class_id"]: item["class_description"]["info"]["label"]
        for context in row["AnnotationContext:context"]
        for item in context
    }


@pytest.mark.parametrize(
    ("obj", "mode", "scene"),
    [("knife", "auto", "table"), ("knife", "h1g1", "table"), ("hammer", "h2g2", "hammer_by_wall")],
)
def test_real_plan_recording_agrees_with_its_result(kb, tmp_path, obj, mode, scene):
    result, ctx, path = _real(kb, tmp_path, obj, mode, scene)
    summary = read_recording(path)
    stages = {s["stage"]: s for s in summary["stages"]}
    assert stages[0]["outcomes"] == {"generated": ctx.n}
    # Colours by outcome: every candidate at every stage has its class's fixed colour.
    cols = read_columns(path)
    labels = _labels(cols)
    fixed = {label: rgb(colour) for label, colour in OUTCOME_COLOURS.items()}
    rows = [r for r in cols[ENTITY_CENTRES] if r.get("Points3D:class_ids") is not None]
    for row in rows:
        for cid, colour in zip(row["Points3D:class_ids"], row["Points3D:colors"], strict=True):
            label = labels[cid]
            if cid >= CLASS_RULE_BASE:
                kind = label.rsplit("(", 1)[1].rstrip(")")
                assert colour == rgb(KIND_COLOURS[kind]), label
            else:
                assert colour == fixed[label], label
    # Rejections drawn (one presentation) never exceed the plan's row counts (all of them).
    last = stages[max(s for s in stages if s <= 4)]
    assert sum(last["outcomes"].values()) == ctx.n
    rejected_by = result.candidates["rejected_by"]
    for label, count in last["outcomes"].items():
        if label.startswith("rejected by "):
            assert count <= rejected_by[label.split()[2]]
    trace_text = "\n".join(t["text"] for t in summary["trace"])
    if result.feasible:
        assert 4 in stages
        chosen = {g.id for g in result.robot_grasps if g.stage != "pick"}
        final = by_stage(cols[ENTITY_CENTRES], "Points3D:class_ids")[4]
        assert {i for i, c in enumerate(final) if c == CLASS_CHOSEN} == chosen
        for entry in result.trace:
            assert f"{entry['rule']} ({entry['kind']}" in trace_text
        assert len([t for t in summary["trace"] if t["stage"] in (4, 5)]) == len(result.trace)
    else:
        assert 4 not in stages
        last_doc = summary["documents"][-1]["text"]
        assert "No feasible handover" in last_doc and result.reason in last_doc
        assert f"no feasible handover: {result.reason}" in trace_text


def _capsule_ends(rows: list[dict], stage: int) -> dict[str, list]:
    """The capsules logged at ``stage``: label -> sorted [(radius, end, end)] (world, m), each
    capsule's ends from its translation, quaternion and length (rerun's z along the axis)."""
    from scipy.spatial.transform import Rotation

    (row,) = [r for r in rows if r["stage"] == stage]
    out: dict[str, list] = {}
    for label, t, q, length, radius in zip(
            row["Capsules3D:labels"], row["Capsules3D:translations"],
            row["Capsules3D:quaternions"], row["Capsules3D:lengths"], row["Capsules3D:radii"],
            strict=True):  # fmt: skip
        t = np.asarray(t, dtype=float)
        end = t + length * Rotation.from_quat(q).as_matrix()[:, 2]
        out.setdefault(label, []).append((radius, *sorted([tuple(t), tuple(end)])))
    return {k: sorted(v) for k, v in out.items()}


def _urdf_capsules(urdf, base: np.ndarray, links: list[str]) -> dict[str, list]:
    """The URDF's cylinders and spheres of ``links`` at its current configuration, posed by
    yourdfpy, as :func:`_capsule_ends` gives them."""
    out: dict[str, list] = {}
    for link in links:
        at = base @ urdf.get_transform(link, urdf.base_link)
        for col in urdf.link_map[link].collisions:
            pose = at @ (np.eye(4) if col.origin is None else col.origin)
            g = col.geometry
            if g.cylinder is not None:
                half = 0.5 * g.cylinder.length * pose[:3, 2]
                ends, radius = (pose[:3, 3] - half, pose[:3, 3] + half), g.cylinder.radius
            elif g.sphere is not None:
                ends, radius = (pose[:3, 3], pose[:3, 3]), g.sphere.radius
            else:
                continue
            out.setdefault(link, []).append((radius, *sorted(tuple(e) for e in ends)))
    return {k: sorted(v) for k, v in out.items()}


def test_the_arm_is_drawn_at_its_joints_at_pick_up_and_at_the_handover(kb, tmp_path):
    """The knife's arm, read back from the recording, lies where yourdfpy's forward
    kinematics of the result's joint values put the URDF's links (from the JSON ``robot``
    block), and its tip link where the gripper pose minus the tcp offset is."""
    import yourdfpy

    from handover.engine.store.kb import builtin_kb_dir

    result, _, path = _real(kb, tmp_path, "knife", "auto", "table")
    data = result.to_dict()  # as the JSON gives it
    robot = data["robot"]
    (grasp,) = data["robot_grasps"]
    arm = robot["arms"][grasp["arm"]]
    base, tcp = np.asarray(robot["base_pose"]), np.asarray(arm["tcp"])
    urdf = yourdfpy.URDF.load(str(builtin_kb_dir() / robot["urdf"]))
    # The links the arm's joints move: below the first moving joint on the way to the tip.
    parent = {j.child: j for j in urdf.robot.joints}
    path_links, link = [], arm["tip_link"]
    while link != arm["base_link"]:
        path_links.append((link, parent[link].type != "fixed"))
        link = parent[link].parent
    path_links.reverse()
    first = next(n for n, (_, moving) in enumerate(path_links) if moving)
    moved = [name for name, _ in path_links[first:]]
    cols = read_columns(path)
    wanted = {"pickup": np.asarray(data["initial_pose"]) @ np.asarray(grasp["pose"]),
              "handover": np.asarray(grasp["pose_world"])}
    for stage, gripper in wanted.items():
        entity = f"world/robot/arms/{stage}"
        (strip,) = by_stage(cols[f"{entity}/chain"], "LineStrips3D:strips")[4]
        tip = np.asarray(strip[-1])
        np.testing.assert_allclose(tip, (gripper @ np.linalg.inv(tcp))[:3, 3], atol=1e-3)
        urdf.update_cfg(grasp["joints"][stage])
        np.testing.assert_allclose(
            tip, (base @ urdf.get_transform(arm["tip_link"], urdf.base_link))[:3, 3], atol=1e-3)
        drawn = _capsule_ends(cols[f"{entity}/capsules"], 4)
        expected = _urdf_capsules(urdf, base, moved)
        assert sorted(drawn) == sorted(expected)  # every moving link with a shape, no other
        for link, caps in expected.items():
            assert len(drawn[link]) == len(caps), link
            for (r0, a0, b0), (r1, a1, b1) in zip(drawn[link], caps, strict=True):
                assert r0 == pytest.approx(r1, abs=1e-6)
                np.testing.assert_allclose([a0, b0], [a1, b1], atol=1e-3, err_msg=link)
        colours = {c for c in cols[f"{entity}/capsules"][0]["Capsules3D:colors"]}
        assert len(colours) == 1  # one arm, one colour
    assert "world/robot/arms/midair/chain" not in cols  # H1G1: no midair regrasp


def test_real_h2g2_plan_records_pick_midair_and_handover(kb, tmp_path):
    result, ctx, path = _real(kb, tmp_path, "hammer", "h2g2", "hammer_by_wall")
    assert result.feasible, result.reason
    summary = read_recording(path)
    assert [s["stage"] for s in summary["stages"]] == list(range(8))
    cols = read_columns(path)
    grippers = {r["stage"]: len(r["Boxes3D:centers"]) for r in cols["world/regrasp/grippers"]}
    assert grippers == {5: 3, 6: 6}
    moves = by_stage(cols["world/regrasp"], "Transform3D:translation")
    assert np.allclose(moves[5][0], np.asarray(result.initial_pose)[:3, 3], atol=1e-6)
    assert np.allclose(moves[6][0], result.regrasp.midair_pose[:3, 3], atol=1e-6)
    first, second = result.regrasp.first, result.regrasp.second
    pick_lines = "\n".join(t["text"] for t in summary["trace"] if t["stage"] == 5)
    assert f"grasp {first.id} ({first.gripper} hand) [pick]" in pick_lines
    # The candidates are drawn at the handover: the second hand's grasp is the chosen one.
    final = by_stage(cols[ENTITY_CENTRES], "Points3D:class_ids")[4]
    assert final[second.id] == CLASS_CHOSEN
    # The arms: at pick-up and the handover (stage 4), then each stage's own: the first arm
    # at pick-up (5), both midair (6), the second at the handover (7), each in its colour.
    arms = "world/robot/arms"
    logged = {stage: sorted(by_stage(cols[f"{arms}/{stage}/chain"], "LineStrips3D:strips"))
              for stage in ("pickup", "midair", "handover")}
    assert logged == {"pickup": [4], "midair": [6], "handover": [4, 7]}
    midair = [r for r in cols[f"{arms}/midair/chain"] if r["stage"] == 6][0]
    assert len(midair["LineStrips3D:strips"]) == 2 and len(set(midair["LineStrips3D:colors"])) == 2
    cleared = {(r["stage"], e.rsplit("/", 1)[1]) for e in (f"{arms}/{s}" for s in
               ("pickup", "midair", "handover")) for r in cols.get(e, [])
               if r.get("Clear:is_recursive")}  # fmt: skip
    assert cleared == {(5, "handover"), (6, "pickup"), (7, "midair")}


def test_the_recording_draws_both_bodies_and_the_handover_locations(kb, tmp_path):
    from handover.engine.planner import plan
    from handover.engine.spec.query import Query

    # A mug: with the shipped arms no pair of arms holds the knife for a seated receiver
    # (its plan is infeasible, see test_world), and this test wants a handover to draw.
    planned = plan(kb, Query(object="mug", receiver="seated_adult"))
    assert planned.result.feasible, planned.result.reason
    path = tmp_path / "seated.rrd"
    planned.record(path)
    result = planned.result
    cols = read_columns(path)
    for who in ("receiver", "robot"):
        drawn = []
        for shape in ("capsules", "boxes"):
            for row in cols.get(f"world/bodies/{who}/{shape}", []):
                labels = row.get(f"{'Capsules3D' if shape == 'capsules' else 'Boxes3D'}:labels")
                drawn += list(labels or [])
        assert sorted(drawn) == sorted(p["name"] for p in result.bodies[who]), who
    assert "chair_seat" in {p["name"] for p in result.bodies["receiver"]}  # seated
    rows = cols["world/handover/locations"]
    assert [r["stage"] for r in rows] == [0]  # chosen before the grasps are judged
    points = np.asarray(rows[0]["Points3D:positions"])
    radii = np.asarray(rows[0]["Points3D:radii"])
    big = points[np.argmax(radii)]
    np.testing.assert_allclose(big, result.handover_point["position"], atol=1e-4)


FAR_APART = """\
id: far_apart
name: The gripper 10 m from the receiver's hand (no candidate can)
extends: common
why: A culture no plan satisfies, to look at an infeasible plan.
rules:
  - id: ten_metres_apart
    kind: clearance
    min_m: 10.0
    hard: true
    why: Nothing passes, so every presentation fails.
"""


def test_an_infeasible_plan_says_and_draws_the_same_handover_location(tmp_path):
    import shutil

    from handover.engine.load.loader import load_kb
    from handover.engine.planner import plan
    from handover.engine.spec.query import Query
    from handover.engine.store.kb import builtin_kb_dir

    root = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    (root / "etiquette" / "far_apart.yaml").write_text(FAR_APART, encoding="utf-8")
    planned = plan(load_kb(root), Query(object="knife", culture="far_apart", mode="h1g1"))
    result = planned.result
    assert not result.feasible and "ten_metres_apart" in result.reason
    point = result.handover_point
    # The presentation whose rows got furthest is the one drawn and the one described.
    decision = planned.attempt.decision
    k = decision.furthest_presentation(len(planned.context.rotations))
    assert k != 0 and point["presentation"] == k  # not simply the first one
    path = tmp_path / "far.rrd"
    planned.record(path)
    rows = read_columns(path)["world/handover/locations"]
    points = np.asarray(rows[0]["Points3D:positions"])
    radii = np.asarray(rows[0]["Points3D:radii"])
    np.testing.assert_allclose(points[np.argmax(radii)], point["position"], atol=1e-4)


def test_the_arm_that_waits_is_drawn_at_its_rest(kb, tmp_path):
    import yourdfpy

    from handover.engine.store.kb import builtin_kb_dir

    # The screwdriver is handed over by the right arm; the left waits at its rest, drawn at
    # both stages under .../rest, its chain ending where the URDF puts its flange there.
    result, ctx, path = _real(kb, tmp_path, "screwdriver", "h1g1", "table")
    assert [g.arm for g in result.robot_grasps] == ["right"]
    robot = result.robot
    urdf = yourdfpy.URDF.load(str(builtin_kb_dir() / robot["urdf"]))
    urdf.update_cfg(robot["arms"]["left"]["rest"])
    flange = (np.asarray(robot["base_pose"]) @ urdf.get_transform("left_flange",
                                                                  urdf.base_link))[:3, 3]
    cols = read_columns(path)
    for stage, words in (("pickup", "at pick-up"), ("handover", "at the handover")):
        (row,) = [r for r in cols[f"world/robot/arms/{stage}/rest/chain"] if r["stage"] == 4]
        assert row["LineStrips3D:labels"] == [f"left arm at rest, {words}"]
        (strip,) = row["LineStrips3D:strips"]
        np.testing.assert_allclose(strip[-1], flange, atol=1e-3)
        working = by_stage(cols[f"world/robot/arms/{stage}/chain"], "LineStrips3D:labels")[4]
        assert working == [f"right arm, {words}"]
