"""Outcomes beyond yes/no: a handover, the object set down on the table (``place``), a
refusal, or infeasible, through the real entry points (the Python facade, the CLI, batch,
the recording).

The knowledge base is the built-in one copied into a temporary folder with a new object, new
receivers and new cultures written here. The test object is a paring knife whose blade is
tagged ``edge`` (not ``sharp``): the rules that act on it are the ones written here, whatever
the default culture says about sharp things. Every expectation is computed in the test from
the YAML written here (the object's boxes, the table's height, the receiver's stature and
where they stand), not read from the planner's own numbers.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from handover import Planner
from handover.engine.cli.app import main
from handover.engine.store.kb import builtin_kb_dir

PARING_KNIFE = """\
id: paring_knife
name: Paring knife
mass: 0.08
tags: [kitchen, tool]
geometry:
  primitives:
    - {shape: box, part: handle, extents: [0.12, 0.024, 0.018], position: [-0.06, 0, 0]}
    - {shape: box, part: blade, extents: [0.08, 0.02, 0.0015], position: [0.04, 0, 0]}
parts:
  handle: {tags: [handle]}
  blade: {tags: [edge]}
axes:
  tip: [1, 0, 0]
  handle: [-1, 0, 0]
"""
# Boxes of the paring knife (centre, extents), object frame, m: the test's own model of it.
KNIFE_BOXES = {"handle": ((-0.06, 0.0, 0.0), (0.12, 0.024, 0.018)),
               "blade": ((0.04, 0.0, 0.0), (0.08, 0.02, 0.0015))}

SLUG = """\
id: slug
name: Lead slug
mass: 1.2
tags: [dense]
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.024, 0.024, 0.03]}
parts:
  body: {tags: []}
axes:
  up: [0, 0, 1]
"""
SLUG_BOXES = {"body": ((0.0, 0.0, 0.0), (0.024, 0.024, 0.03))}

TOY = """\
id: toy_block
name: Toy block
mass: 0.1
tags: [toy]
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.07, 0.07, 0.07]}
parts:
  body: {tags: []}
axes:
  up: [0, 0, 1]
"""

TODDLER = """\
id: toddler
name: Toddler
role: child
stature: 0.95
age: 3
hand: child_hand
"""
SITTER = """\
id: sitter
name: Seated adult
role: adult
posture: seated
stature: 1.7
age: 40
"""

EDGE_RULES = """\
  - id: edge_tip_away
    kind: axis
    axis: tip
    toward: toward_receiver
    min_deg: 100
    safety: true
    applies: {object_tags_any: [edge]}
    warn: Mind the edge when taking it.
    why: An edge's tip points away from the receiver.
  - id: edge_handle_first
    kind: axis
    axis: handle
    toward: toward_receiver
    max_deg: 60
    applies: {object_tags_any: [edge]}
    why: An edged tool goes handle first.
  - id: robot_off_the_edge
    kind: contact
    who: giver
    forbid_tags: [edge]
    why: The robot does not hold an edge.
  - id: no_edges_under_eight
    kind: refuse
    safety: true
    applies: {object_tags_any: [edge], receiver_age_below: 8}
"""
CAREFUL = ("id: careful\nname: Careful\nrules:\n" + EDGE_RULES
           + "    why: A child under 8 is not handed an edged tool.\n")
CAREFUL_PLACE = ("id: careful_place\nname: Careful, sets it down\nrules:\n" + EDGE_RULES
                 + "    fallback: place\n"
                 + "    why: A child under 8 is not handed an edged tool; it is set down.\n")
MIXED = (CAREFUL_PLACE.replace("id: careful_place", "id: mixed")
         + """  - id: no_edges_under_five
    kind: refuse
    applies: {object_tags_any: [edge], receiver_age_below: 5}
    why: Not even set down near a child under 5.
""")
# The default table with the receiver standing 1.6 m from the robot: 0.8 m beyond the
# table's edge, out of reach even leaning forward.
FAR_TABLE = """\
id: far_table
name: Receiver far from the table
why: Where the receiver stands too far away to take anything off the table.
support:
  position: [0.55, 0.0, 0.75]
  size: [0.5, 1.0]
  thickness: 0.03
receiver:
  position: [1.6, 0.0, 0.0]
  facing: [-1.0, 0.0, 0.0]
object:
  position: [0.33, 0.0]
"""
WEIGHTS = """\
id: weights
name: Weights with two hands or set down
rules:
  - id: dense_two_hands
    kind: mode
    mode: H2G1
    applies: {object_tags_any: [dense]}
    fallback: place
    why: A dense weight is handed with two hands, or set down.
"""


@pytest.fixture(scope="module")
def kb_dir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("outcomes") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    files = {"objects/paring_knife.yaml": PARING_KNIFE, "objects/slug.yaml": SLUG,
             "objects/toy_block.yaml": TOY,
             "receivers/toddler.yaml": TODDLER, "receivers/sitter.yaml": SITTER,
             "etiquette/careful.yaml": CAREFUL, "etiquette/careful_place.yaml": CAREFUL_PLACE,
             "etiquette/mixed.yaml": MIXED,
             "etiquette/weights.yaml": WEIGHTS, "scenes/far_table.yaml": FAR_TABLE}
    for name, text in files.items():
        (root / name).write_text(text, encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def planner(kb_dir) -> Planner:
    return Planner(kb_dir, db=False)


@pytest.fixture(scope="module")
def placed(planner):
    return planner.plan("paring_knife", receiver="toddler", culture="careful_place")


def _corners(boxes: dict, pose: np.ndarray) -> dict[str, np.ndarray]:
    """Each box's 8 corners (world, m) with the object at ``pose`` (4, 4)."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    out = {}
    for name, (centre, ext) in boxes.items():
        local = np.asarray(centre) + 0.5 * signs * np.asarray(ext)
        out[name] = local @ pose[:3, :3].T + pose[:3, 3]
    return out


def _centre_of_mass(boxes: dict, pose: np.ndarray) -> np.ndarray:
    """World centre of mass of uniform boxes."""
    vol = np.array([np.prod(ext) for _, ext in boxes.values()])
    centres = np.array([c for c, _ in boxes.values()])
    local = (vol[:, None] * centres).sum(axis=0) / vol.sum()
    return pose[:3, :3] @ local + pose[:3, 3]


def _scene(kb_dir: Path) -> dict:
    return yaml.safe_load((kb_dir / "scenes" / "table.yaml").read_text())


def _shoulder_and_reach(stature: float, scene: dict, posture: str = "standing"):
    """The right shoulder (world) and arm reach (m) of a right-handed receiver standing where
    the scene puts them, from the segment proportions of Drillis & Contini (Winter 2009):
    shoulder at 0.818 H, shoulder width 0.259 H (joint one upper-arm radius, 0.025 H, in),
    upper arm 0.186 H, forearm 0.146 H, grip at 40 % of the hand's 0.108 H."""
    pos = np.asarray(scene["receiver"]["position"], dtype=float)
    facing = np.asarray(scene["receiver"]["facing"], dtype=float)
    right = np.cross(facing, [0.0, 0.0, 1.0])
    height = 0.818 * stature - (0.530 - 0.285) * stature * (posture == "seated")
    shoulder = pos + (0.259 / 2 - 0.025) * stature * right + np.array([0.0, 0.0, height])
    return shoulder, (0.186 + 0.146 + 0.4 * 0.108) * stature


def _angle(u, v) -> float:
    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    return float(np.degrees(np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v),
                                              -1.0, 1.0))))


def _cli(capsys, kb_dir, *args) -> tuple[int, str]:
    code = main(["--kb", str(kb_dir), "plan", *args, "--no-db"])
    out, err = capsys.readouterr()
    assert code in (0, 4), err
    return code, out


# ---------------------------------------------------------------- refuse


def test_a_refuse_rule_refuses_with_the_rule_and_its_why(planner):
    plan = planner.plan("paring_knife", receiver="toddler", culture="careful")
    assert plan.outcome == "refuse" and not plan.feasible and plan.mode is None
    assert "no_edges_under_eight" in plan.reason
    assert "A child under 8 is not handed an edged tool." in plan.reason
    data = plan.to_dict()
    assert [r["rule"] for r in data["refused"]] == ["no_edges_under_eight"] == [
        r["rule"] for r in plan.refused]
    assert data["refused"][0]["source"].startswith("etiquette/careful.yaml:")
    assert data["robot_grasps"] == [] and data["object_pose"] is None
    # no mode was tried, and each says why
    assert data["modes_tried"] and all(
        "not tried" in m["reason"] and "no_edges_under_eight" in m["reason"]
        for m in data["modes_tried"])
    assert [e["status"] for e in data["trace"] if e["rule"] == "no_edges_under_eight"] == ["fail"]


def test_the_cli_exits_4_on_a_refusal_and_says_refused(capsys, kb_dir):
    code, out = _cli(capsys, kb_dir, "paring_knife", "-r", "toddler", "-c", "careful", "--json")
    data = json.loads(out)
    assert code == 4 and data["outcome"] == "refuse"
    assert "no_edges_under_eight" in data["reason"]
    code, out = _cli(capsys, kb_dir, "paring_knife", "-r", "toddler", "-c", "careful")
    text = " ".join(out.split())
    assert code == 4
    assert "REFUSED: rule no_edges_under_eight" in text
    assert "A child under 8 is not handed an edged tool." in text


def test_a_refusal_without_fallback_wins_over_one_with(planner):
    """Two rules refuse; only one would let the robot set it down: refused, both named."""
    plan = planner.plan("paring_knife", receiver="toddler", culture="mixed")
    assert plan.outcome == "refuse"
    assert "no_edges_under_eight" in plan.reason and "no_edges_under_five" in plan.reason
    assert {r["rule"] for r in plan.to_dict()["refused"]} == {"no_edges_under_eight",
                                                             "no_edges_under_five"}


# ---------------------------------------------------------------- place


def test_with_fallback_place_the_knife_is_set_down_and_the_cli_exits_0(capsys, kb_dir, placed):
    assert placed.outcome == "place" and placed.feasible and placed.mode is None
    assert "no_edges_under_eight" in placed.reason
    code, out = _cli(capsys, kb_dir, "paring_knife", "-r", "toddler", "-c", "careful_place",
                     "--json")
    assert code == 0 and out == placed.to_json()
    code, out = _cli(capsys, kb_dir, "paring_knife", "-r", "toddler", "-c", "careful_place")
    assert code == 0 and "PLACE: set down on the table" in " ".join(out.split())


def test_the_placed_knife_rests_on_the_table_top(kb_dir, placed):
    """Lowest point on the table's top (its height from the scene YAML) within 2 mm; nothing
    below it or beyond the table's edges; the object's pose is the placement's."""
    scene = _scene(kb_dir)
    top = scene["support"]["position"][2]
    cx, cy = scene["support"]["position"][:2]
    sx, sy = scene["support"]["size"]
    pose = np.asarray(placed.placement["object_pose"])
    np.testing.assert_allclose(pose, placed.object_pose, atol=1e-6)
    pts = np.concatenate(list(_corners(KNIFE_BOXES, pose).values()))
    assert abs(pts[:, 2].min() - top) <= 0.002
    assert (pts[:, 2] >= top - 1e-6).all()
    assert (np.abs(pts[:, 0] - cx) <= sx / 2).all() and (np.abs(pts[:, 1] - cy) <= sy / 2).all()


def test_the_placed_knife_is_stable(placed):
    """Its centre of mass lies over its support: the convex hull of its points on the
    table."""
    import shapely

    pose = placed.object_pose
    pts = np.concatenate(list(_corners(KNIFE_BOXES, pose).values()))
    low = pts[pts[:, 2] <= pts[:, 2].min() + 0.002]
    support = shapely.MultiPoint(low[:, :2]).convex_hull
    com = _centre_of_mass(KNIFE_BOXES, pose)
    assert support.geom_type == "Polygon"
    assert support.contains(shapely.Point(com[:2]))


def test_the_placed_knife_is_within_the_receiver_s_reach(kb_dir, placed):
    scene = _scene(kb_dir)
    shoulder, reach = _shoulder_and_reach(0.95, scene)
    handle = _corners({"handle": KNIFE_BOXES["handle"]}, placed.object_pose)["handle"]
    assert np.linalg.norm(handle.mean(axis=0) - shoulder) <= reach


def test_the_placed_knife_has_its_handle_towards_the_receiver_and_its_tip_away(kb_dir, placed):
    scene = _scene(kb_dir)
    pose = placed.object_pose
    to_receiver = np.asarray(scene["receiver"]["position"], dtype=float) - pose[:3, 3]
    to_receiver[2] = 0.0
    tip = pose[:3, :3] @ np.array([1.0, 0.0, 0.0])
    assert _angle(tip, to_receiver) >= 100.0
    assert _angle(-tip, to_receiver) <= 60.0  # the handle axis is -x
    # the robot holds the handle, never the edge, and the result carries its grasp
    data = placed.to_dict()
    grasp = data["placement"]["robot_grasp"]
    assert grasp["parts"] == ["handle", "handle"] and grasp["stage"] == "place"
    assert data["robot_grasps"] == [grasp]
    np.testing.assert_allclose(np.asarray(grasp["pose_world"]),
                               pose @ np.asarray(grasp["pose"]), atol=1e-6)


def test_an_adult_still_gets_the_knife_handed_over_with_the_warning(planner):
    plan = planner.plan("paring_knife", receiver="adult", culture="careful_place")
    assert plan.outcome == "handover" and plan.mode is not None
    said = [w for w in plan.warnings if "Mind the edge when taking it." in w]
    assert len(said) == 1 and said[0].startswith("edge_tip_away")


def test_a_warn_text_appears_once_when_the_object_is_placed(placed):
    said = [w for w in placed.warnings if "Mind the edge when taking it." in w]
    assert len(said) == 1 and "edge_tip_away" in said[0]


def test_a_dense_slug_no_two_grippers_can_hold_is_set_down(kb_dir, planner):
    """A hard H2G1 rule with fallback: place on an object too small for two grippers: H2G1
    is tried and fails, the slug is set down upright-stable within the seated receiver's
    reach."""
    plan = planner.plan("slug", receiver="sitter", culture="weights")
    data = plan.to_dict()
    h2g1 = [m for m in data["modes_tried"] if m["mode"] == "H2G1"]
    assert h2g1 and not h2g1[0]["feasible"]
    assert plan.outcome == "place", plan.reason
    assert "dense_two_hands" in plan.reason
    scene = _scene(kb_dir)
    pts = _corners(SLUG_BOXES, plan.object_pose)["body"]
    assert abs(pts[:, 2].min() - scene["support"]["position"][2]) <= 0.002
    shoulder, reach = _shoulder_and_reach(1.7, scene, "seated")
    assert np.linalg.norm(pts.mean(axis=0) - shoulder) <= reach


def _leaning_reach(stature: float, scene: dict, point: np.ndarray) -> float:
    """The least distance (m) from ``point`` (world) to the right shoulder of a standing
    receiver bending their trunk forward about the hip joints (0.530 H) by 0 to 45 degrees
    (EN 1005-4 rates up to 60 degrees acceptable for an infrequent movement)."""
    shoulder, _ = _shoulder_and_reach(stature, scene)
    pos = np.asarray(scene["receiver"]["position"], dtype=float)
    facing = np.asarray(scene["receiver"]["facing"], dtype=float)
    pivot = pos + np.array([0.0, 0.0, 0.530 * stature])
    arm = shoulder - pivot  # the shoulder's offset from the hip axis, upright
    best = np.inf
    for deg in np.linspace(0.0, 45.0, 91):
        t = np.radians(deg)
        fwd, up = arm @ facing, arm[2]
        side = arm - fwd * facing - np.array([0.0, 0.0, up])
        moved = pivot + side + (fwd * np.cos(t) + up * np.sin(t)) * facing \
            + np.array([0.0, 0.0, up * np.cos(t) - fwd * np.sin(t)])
        best = min(best, float(np.linalg.norm(point - moved)))
    return best


def test_a_standing_adult_gets_the_slug_set_down_where_they_reach_leaning_forward(
        kb_dir, planner):
    """The table top is at a standing adult's hip, far below the shoulder: they lean forward
    to take the slug, and it lies where their arm reaches with a lean a person makes (at
    most 45 degrees), within 90 % of the arm's reach (within_receiver_reach)."""
    plan = planner.plan("slug", receiver="adult", culture="weights")
    assert plan.outcome == "place", plan.reason
    scene = _scene(kb_dir)
    pts = _corners(SLUG_BOXES, plan.object_pose)["body"]
    assert abs(pts[:, 2].min() - scene["support"]["position"][2]) <= 0.002
    _, reach = _shoulder_and_reach(1.7, scene)
    top = pts[pts[:, 2] > pts[:, 2].max() - 1e-6].mean(axis=0)
    assert _leaning_reach(1.7, scene, top) <= 0.9 * reach + 0.01
    # upright it is out of reach: the lean is what makes it work, and the plan says so
    shoulder, _ = _shoulder_and_reach(1.7, scene)
    assert np.linalg.norm(top - shoulder) > reach
    assert plan.placement["measured"]["receiver_lean_deg"] > 0
    assert "lean forward" in plan.placement["why"]


def test_when_the_fallback_cannot_be_placed_either_the_reason_says_both(planner):
    """A standing adult 1.6 m from the robot cannot reach the table top even leaning
    forward: the slug is neither handed over nor set down, and the reason says why each
    failed."""
    plan = planner.plan("slug", receiver="adult", culture="weights", scene="far_table")
    assert plan.outcome == "infeasible" and plan.placement is None
    assert "H2G1" in plan.reason and "dense_two_hands" in plan.reason
    assert "setting it down instead" in plan.reason and "reach" in plan.reason


def test_without_a_fallback_rule_nothing_is_placed(planner):
    """The same slug to the same receiver under the base culture is simply handed over; the
    placement is never a way round a rule that does not name it."""
    plan = planner.plan("slug", receiver="sitter")
    assert plan.outcome == "handover"


def test_the_same_query_gives_byte_identical_json(kb_dir, placed):
    again = Planner(kb_dir, db=False)
    assert again.plan("paring_knife", receiver="toddler",
                      culture="careful_place").to_json() == placed.to_json()
    first = again.plan("paring_knife", receiver="toddler", culture="careful").to_json()
    assert again.plan("paring_knife", receiver="toddler", culture="careful").to_json() == first


# ---------------------------------------------------------------- batch and recording


def test_batch_has_an_outcome_column(tmp_path, kb_dir):
    from handover.engine.tools.batch import read_rows

    out = tmp_path / "rows.parquet"
    code = main(["--kb", str(kb_dir), "batch", "--objects", "paring_knife", "--out", str(out),
                 "--cultures", "careful,careful_place", "--receivers", "toddler,adult",
                 "--workers", "1", "--no-db", "--no-progress"])
    assert code == 0
    got = {(r["culture"], r["receiver"]): r["outcome"] for r in read_rows(out)}
    assert got == {("careful", "toddler"): "refuse", ("careful", "adult"): "handover",
                   ("careful_place", "toddler"): "place", ("careful_place", "adult"): "handover"}


def test_the_recording_shows_a_placement_like_a_handover_and_a_refusal_as_text(
        tmp_path, planner, placed):
    from handover.engine.report.rerun.reader import read_recording

    path = placed.record(tmp_path / "placed.rrd")
    summary = read_recording(path)
    entities = {e["path"]: e for e in summary["entities"]}
    assert {"world/handover/object", "world/handover/grippers", "world/scene"} <= set(entities)
    assert 4 in entities["world/handover/grippers"]["stages"]
    chosen = [s for s in summary["stages"] if s["stage"] == 4][0]["outcomes"]
    assert chosen.get("chosen") == 1
    stage4 = " ".join(d["text"] for d in summary["documents"] if d["stage"] == 4)
    assert "Set down" in stage4 and "no_edges_under_eight" in stage4

    refused = planner.plan("paring_knife", receiver="toddler", culture="careful")
    summary = read_recording(refused.record(tmp_path / "refused.rrd"))
    paths = {e["path"] for e in summary["entities"]}
    assert "world/handover/grippers" not in paths
    errors = [t["text"] for t in summary["trace"] if t["level"] == "ERROR"]
    assert errors and errors[0].startswith("refused: rule no_edges_under_eight")
    assert any("Refused" in d["text"] for d in summary["documents"])


# ---------------------------------------------------------------- resting on a table


def test_a_box_rests_on_its_largest_face_first_and_a_ball_nowhere():
    """The stable rests of a brick: its two largest faces first (tipping over the long edge
    takes atan(half width / half height) = 63 deg), the end faces last; a ball rolls."""
    import trimesh

    from handover.geometry.rests import MIN_TIP_DEG, resting_rotations

    brick = trimesh.creation.box((0.10, 0.06, 0.03))
    rotations, tips = resting_rotations(brick.vertices, np.zeros(3))
    assert len(rotations) == 6
    vertical = np.abs(rotations[:2, 2, :])  # which object axis each rest puts vertical
    np.testing.assert_allclose(vertical, [[0, 0, 1], [0, 0, 1]], atol=1e-9)
    np.testing.assert_allclose(tips[:2], np.degrees(np.arctan2(0.03, 0.015)), atol=1e-6)
    assert (np.diff(tips) <= 1e-9).all() and (tips >= MIN_TIP_DEG).all()
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.03)
    assert len(resting_rotations(ball.vertices, np.zeros(3))[0]) == 0


def test_a_toddler_gets_a_toy_within_reach_set_down_or_handed_low(kb_dir, planner):
    """A 0.95 m toddler, whose shoulder (0.78 m) is hardly above the 0.75 m table: the toy
    is either set down where their arm reaches, or handed where their grasp site is within
    their arm's reach and below their chin (0.870 H), never at their face."""
    plan = planner.plan("toy_block", receiver="toddler")
    assert plan.outcome in ("handover", "place"), plan.reason
    scene = _scene(kb_dir)
    shoulder, reach = _shoulder_and_reach(0.95, scene)
    for hand in plan.to_dict()["human_grasps"]:
        site = np.asarray(hand["position_world"], dtype=float)
        assert np.linalg.norm(site - shoulder) <= reach
        assert site[2] < 0.870 * 0.95
    assert plan.to_dict()["human_grasps"]
