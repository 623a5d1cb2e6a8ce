"""How people really take things (issue 25): everyday objects written here, each handed to an
adult with a grasp a person would use, the receiver's hand boxes outside the object and clear
of the robot's gripper, the receiver's arm clear of a bed's rail, nothing offered closer to an
obstacle than the clearance rule allows, and the KB errors of a bad repertoire.

Everything is checked from the result's JSON and from geometry computed here: the hand boxes'
depth in the object's mesh by a lattice of points and the object's own surface samples (with
trimesh), the gripper's boxes built from the result's gripper sizes as geometry/gripper.py
documents them, box overlap by a separating-axis test, the arm against the rail by sampling
its segments.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import trimesh

from handover.engine.errors import KBError
from handover.engine.load.loader import load_kb
from handover.engine.planner import Planner
from handover.engine.store.kb import builtin_kb_dir

GIVE = 0.005  # m: the hand_fit rule's max_depth_m in the built-in common culture
CLEARANCE = 0.025  # m: common's clear_of_obstacles

OBJECTS = {
    # a porcelain dinner plate, 26 cm across and 2 cm thick
    "plate": """\
id: plate
name: Porcelain dinner plate
mass: 0.6
tags: [kitchen]
geometry:
  primitives:
    - {shape: cylinder, part: plate, radius: 0.13, height: 0.02, position: [0, 0, 0.01]}
parts:
  plate: {tags: [fragile, flat]}
axes:
  up: [0, 0, 1]
""",
    # a glass of water: a 3 mm wall round the water, tagged only `liquid`
    "water_glass": """\
id: water_glass
name: A glass of water
mass: 0.35
tags: [liquid]
geometry:
  primitives:
    - {shape: cup, part: glass, radius: 0.032, height: 0.14, thickness: 0.003,
       bottom_thickness: 0.006, position: [0, 0, 0.07]}
parts:
  glass: {tags: [body]}
axes:
  up: [0, 0, 1]
""",
    # a paring knife: a 10 cm handle, no room for a whole hand and a gripper on it
    "paring_knife": """\
id: paring_knife
name: Paring knife
mass: 0.06
tags: [kitchen]
geometry:
  primitives:
    - {shape: box, part: handle, extents: [0.10, 0.02, 0.015], position: [-0.05, 0, 0]}
    - {shape: box, part: blade, extents: [0.08, 0.018, 0.0015], position: [0.04, 0, 0]}
parts:
  handle: {tags: [handle]}
  blade: {tags: [blade, sharp]}
axes:
  tip: [1, 0, 0]
  handle: [-1, 0, 0]
""",
    # a 1.2 m shelf board, light enough for one robot hand, a kilogram and more
    "board": """\
id: board
name: Shelf board
mass: 1.3
tags: [tool]
geometry:
  primitives:
    - {shape: box, part: board, extents: [0.2, 1.2, 0.012], position: [0, 0, 0.006]}
parts:
  board: {tags: [flat, edge]}
axes:
  up: [0, 0, 1]
""",
    # a business card, 0.4 mm thick
    "card": """\
id: card
name: Business card
mass: 0.002
tags: [paper]
geometry:
  primitives:
    - {shape: box, part: card, extents: [0.09, 0.055, 0.0004], position: [0, 0, 0.0002]}
parts:
  card: {tags: [flat]}
axes:
  up: [0, 0, 1]
""",
    "laptop": """\
id: laptop
name: Laptop, closed
mass: 1.4
tags: [office]
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.23, 0.33, 0.02], position: [0, 0, 0.01]}
parts:
  body: {tags: [flat]}
axes:
  up: [0, 0, 1]
""",
    # a kettle of hot water: the body is hot, the handle a loop beside it
    "kettle": """\
id: kettle
name: Kettle of hot water
mass: 0.9
tags: [kitchen]
geometry:
  primitives:
    - {shape: cylinder, part: body, radius: 0.08, height: 0.2, position: [0, 0, 0.1]}
    - {shape: box, part: handle, extents: [0.02, 0.02, 0.12], position: [0.125, 0, 0.11]}
    - {shape: box, part: handle, extents: [0.045, 0.02, 0.02], position: [0.1, 0, 0.175]}
    - {shape: box, part: handle, extents: [0.045, 0.02, 0.02], position: [0.1, 0, 0.045]}
parts:
  body: {tags: [hot]}
  handle: {tags: [handle, loop]}
axes:
  up: [0, 0, 1]
  handle: [1, 0, 0]
""",
}

# The card lies with 3.5 cm over the table's edge, as one leaves a card to be picked up.
SCENES = {
    "card_at_the_edge": """\
id: card_at_the_edge
name: A card at the table's robot-side edge
support: {position: [0.55, 0.0, 0.75], size: [0.5, 1.0], thickness: 0.03}
receiver: {position: [1.0, 0.0, 0.0], facing: [-1.0, 0.0, 0.0]}
object: {position: [0.31, 0.0]}
""",
}

# A patient sitting up in bed facing along it, their right side to the robot; a bedside
# table on the robot's side, and (in bed_rail) the bed's rail between them, its top 17 cm
# below their shoulder; the robot cannot reach past it (the patient sits 1.15 m away).
RAIL_CENTRE = np.array([0.90, -0.25, 0.575])
RAIL_EXTENTS = np.array([0.03, 1.0, 0.45])
BED = """\
id: {id}
name: A patient sitting up in bed
support: {{position: [0.45, 0.0, 0.60], size: [0.3, 0.4], thickness: 0.03}}
{obstacles}receiver: {{position: [1.15, 0.0, 0.0], facing: [0.0, -1.0, 0.0]}}
object: {{position: [0.40, 0.0]}}
"""
RAIL = (f"obstacles:\n  - {{id: bed_rail, position: {RAIL_CENTRE.tolist()}, "
        f"extents: {RAIL_EXTENTS.tolist()}}}\n")
PATIENT = """\
id: patient
name: Patient sitting up in bed
posture: seated
stature: 1.70
"""

# A lamp's shade just under where a knife is offered to a standing adult.
LAMP_CENTRE = np.array([0.73, 0.12, 1.08])
LAMP_EXTENTS = np.array([0.22, 0.22, 0.10])
# A culture that lets things be offered touching an obstacle (the clearance rule at 0).
CARELESS = """\
id: careless
name: Offered wherever nothing is hit
rules:
  - id: touching_is_fine
    overrides: [clear_of_obstacles]
    override_safety: To see what the clearance rule changes.
    kind: location
    measure: clearance
    min: 0.0
    safety: true
    why: Nothing offered may hit an obstacle, but it may come as close as it likes.
"""
LAMP = f"""\
id: lamp
name: A lamp's shade over the handover
support: {{position: [0.55, 0.0, 0.75], size: [0.5, 1.0], thickness: 0.03}}
obstacles:
  - {{id: lamp, position: {LAMP_CENTRE.tolist()}, extents: {LAMP_EXTENTS.tolist()}}}
receiver: {{position: [1.0, 0.0, 0.0], facing: [-1.0, 0.0, 0.0]}}
object: {{position: [0.33, 0.0]}}
"""


def _write(root, arms: bool = True):
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    for name, text in OBJECTS.items():
        (root / "objects" / f"{name}.yaml").write_text(text)
    for name, text in SCENES.items():
        (root / "scenes" / f"{name}.yaml").write_text(text)
    (root / "scenes" / "bed_rail.yaml").write_text(BED.format(id="bed_rail", obstacles=RAIL))
    (root / "scenes" / "bed_no_rail.yaml").write_text(BED.format(id="bed_no_rail",
                                                                 obstacles=""))
    (root / "scenes" / "lamp.yaml").write_text(LAMP)
    (root / "receivers" / "patient.yaml").write_text(PATIENT)
    (root / "etiquette" / "careless.yaml").write_text(CARELESS)
    return root


@pytest.fixture(scope="module")
def planner(tmp_path_factory):
    return Planner(kb=_write(tmp_path_factory.mktemp("grasps") / "kb"))


@pytest.fixture(scope="module")
def armless_planner(tmp_path_factory, arms_off):
    """The same KB with the robot's arms off (a floating gripper per hand): the laptop's
    edge, 8 cm over the table's, is where IDRO's arms' wrists meet its own torso, which is no
    matter of the receiver's hand."""
    return Planner(kb=arms_off(_write(tmp_path_factory.mktemp("armless") / "kb")))


# ---------------------------------------------------------------- geometry computed here


def _lattice(extents: np.ndarray, pose: np.ndarray, n: int = 9) -> np.ndarray:
    """(n**3, 3): points through a box (extents (3,), pose (4, 4))."""
    t = np.linspace(-0.5, 0.5, n)
    local = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3) * extents
    return local @ pose[:3, :3].T + pose[:3, 3]


def _object_mesh(plan) -> trimesh.Trimesh:
    """The object's mesh where it is offered (world)."""
    mesh = plan.context.part_mesh.mesh.copy()
    mesh.apply_transform(np.asarray(plan.to_dict()["object_pose"], dtype=float))
    return mesh


def _box_depth(mesh: trimesh.Trimesh, surface: np.ndarray, extents, pose) -> float:
    """m: how deep a box and the object overlap: the deepest of its lattice points inside
    the mesh (distance to the surface), and the deepest sample of the object's surface
    inside the box (distance to the box's faces: a thin card through a finger)."""
    pts = _lattice(np.asarray(extents, float), np.asarray(pose, float))
    inside = mesh.contains(pts)
    deepest = 0.0
    if inside.any():
        _, dist, _ = trimesh.proximity.closest_point(mesh, pts[inside])
        deepest = float(dist.max())
    local = (surface - pose[:3, 3]) @ np.asarray(pose)[:3, :3]
    room = np.asarray(extents) / 2.0 - np.abs(local)
    within = (room > 0).all(axis=1)
    if within.any():
        deepest = max(deepest, float(room[within].min(axis=1).max()))
    return deepest


def _surface(mesh: trimesh.Trimesh) -> np.ndarray:
    points, _ = trimesh.sample.sample_surface(mesh, 60_000, seed=7)
    return np.concatenate([points, mesh.vertices])


def _gripper_boxes(result: dict, grasp: dict) -> list[tuple[np.ndarray, np.ndarray]]:
    """The gripper's palm and fingers (world), built from the result's sizes as
    geometry/gripper.py documents them: fingers along a in [-L/2, L/2], their inner faces at
    o = +-opening/2, the palm behind the fingers' roots."""
    g = result["gripper"]
    length, width_n, thick = g["finger_length"], g["finger_width"], g["finger_thickness"]
    opening = float(np.clip(grasp["width"] + 2 * g["clearance"], g["min_width"], g["max_width"]))
    palm = np.asarray(g["palm"], dtype=float)
    pose = np.asarray(grasp["pose_world"], dtype=float)
    out = []
    for ext, centre in (
        (palm, [0.0, 0.0, -length / 2 - palm[2] / 2]),
        (np.array([width_n, thick, length]), [0.0, -(opening + thick) / 2, 0.0]),
        (np.array([width_n, thick, length]), [0.0, (opening + thick) / 2, 0.0]),
    ):
        tf = pose.copy()
        tf[:3, 3] = pose[:3, :3] @ np.asarray(centre) + pose[:3, 3]
        out.append((ext, tf))
    return out


def _overlap(a, b) -> bool:
    """Separating-axis test of two oriented boxes (extents (3,), pose (4, 4)); touching
    within 1e-6 m is not overlapping."""
    (ea, pa), (eb, pb) = a, b
    ra, rb = pa[:3, :3], pb[:3, :3]
    d = pb[:3, 3] - pa[:3, 3]
    axes = [ra[:, i] for i in range(3)] + [rb[:, i] for i in range(3)]
    axes += [np.cross(ra[:, i], rb[:, j]) for i in range(3) for j in range(3)]
    for ax in axes:
        norm = np.linalg.norm(ax)
        if norm < 1e-9:
            continue
        ax = ax / norm
        half_a = np.sum(np.abs(ra.T @ ax) * ea / 2)
        half_b = np.sum(np.abs(rb.T @ ax) * eb / 2)
        if abs(d @ ax) > half_a + half_b - 1e-6:
            return False
    return True


def _point_box_distance(points: np.ndarray, centre, extents) -> np.ndarray:
    """(n,) m from points to an axis-aligned box (0 inside)."""
    gap = np.maximum(np.abs(points - centre) - np.asarray(extents) / 2.0, 0.0)
    return np.linalg.norm(gap, axis=1)


def _segment_box_distance(p0, p1, centre, extents) -> float:
    """m: from the segment p0-p1 to an axis-aligned box, sampled every 0.5 mm."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    n = max(int(np.linalg.norm(p1 - p0) / 0.0005), 2)
    t = np.linspace(0.0, 1.0, n)[:, None]
    return float(_point_box_distance(p0 + t * (p1 - p0), centre, extents).min())


def _box_points(extents, pose, step: float = 0.002) -> np.ndarray:
    """Points over a box's surface every ``step`` m (world)."""
    extents = np.asarray(extents, float)
    pts = []
    for axis in range(3):
        for sign in (-0.5, 0.5):
            others = [i for i in range(3) if i != axis]
            u = np.linspace(-0.5, 0.5, max(int(extents[others[0]] / step), 2))
            v = np.linspace(-0.5, 0.5, max(int(extents[others[1]] / step), 2))
            grid = np.zeros((len(u) * len(v), 3))
            grid[:, others[0]] = np.repeat(u, len(v))
            grid[:, others[1]] = np.tile(v, len(u))
            grid[:, axis] = sign
            pts.append(grid * extents)
    local = np.concatenate(pts)
    return local @ np.asarray(pose)[:3, :3].T + np.asarray(pose)[:3, 3]


def _hands_fit_and_clear(plan) -> None:
    """Every hand box outside the object (within the give) and clear of every gripper."""
    result = plan.to_dict()
    mesh = _object_mesh(plan)
    surface = _surface(mesh)
    grippers = [b for g in result["robot_grasps"] if g.get("stage") not in ("pick", "support")
                for b in _gripper_boxes(result, g)]
    assert result["human_grasps"]
    for h in result["human_grasps"]:
        assert h["grasp"]["boxes"] == h["model"]
        for box in h["model"]:
            ext, pose = np.asarray(box["extents"]), np.asarray(box["pose"])
            depth = _box_depth(mesh, surface, ext, pose)
            assert depth <= GIVE + 0.001, f"{h['grasp']['name']} {box['name']}: {depth:.4f} m"
            for gbox in grippers:
                assert not _overlap((ext, pose), gbox), f"{box['name']} meets the gripper"


# ---------------------------------------------------------------- everyday objects


PERSON_LIKE = {
    "plate": {"pinch", "support"},  # by its rim between thumb and fingers, or on the palm
    "water_glass": {"wrap"},  # a hand round the glass
    "paring_knife": {"pinch", "lateral", "tripod"},  # the end of a short handle
    "board": {"pinch", "support"},  # two hands at its edge, or under it
    "card": {"pinch", "lateral"},
    "kettle": {"hook", "wrap"},  # by its handle
}
SCENE_OF = {"card": "card_at_the_edge"}


@pytest.mark.parametrize("obj", sorted(PERSON_LIKE))
def test_an_everyday_object_is_handed_to_an_adult_with_a_grasp_a_person_would_use(planner, obj):
    plan = planner.plan(obj, scene=SCENE_OF.get(obj, "table"))
    result = plan.to_dict()
    assert result["outcome"] == "handover", result["reason"]
    for h in result["human_grasps"]:
        assert h["grasp"]["name"] in PERSON_LIKE[obj], h["grasp"]
    _hands_fit_and_clear(plan)


def test_a_laptop_is_taken_in_two_hands_by_its_front_edge_or_from_below(armless_planner):
    plan = armless_planner.plan("laptop")
    result = plan.to_dict()
    assert result["outcome"] == "handover", result["reason"]
    assert result["mode"] == "H2G1"  # a kilogram and more: two robot hands
    assert {h["hand"] for h in result["human_grasps"]} == {"left", "right"}
    for h in result["human_grasps"]:
        assert h["grasp"]["name"] in {"pinch", "support"}
    _hands_fit_and_clear(plan)


def test_a_glass_of_water_is_held_round_below_the_robots_grasp(planner):
    """The robot closes round the glass above the receiver's hand: neither enters the water,
    and the hand is nearer the base."""
    plan = planner.plan("water_glass")
    result = plan.to_dict()
    (hand,) = result["human_grasps"]
    (grasp,) = result["robot_grasps"]
    assert hand["position_world"][2] < grasp["pose_world"][2][3]
    assert grasp["width"] > 0.06  # round the glass, not across its 3 mm wall


def test_the_knife_and_the_kettle_are_taken_by_their_handles_never_the_blade_or_the_body(planner):
    for obj, forbidden in (("paring_knife", "blade"), ("kettle", "body")):
        plan = planner.plan(obj)
        result = plan.to_dict()
        pm = plan.context.part_mesh
        pose = np.asarray(result["object_pose"])
        faces = np.flatnonzero(np.asarray(pm.face_part) == pm.part_names.index(forbidden))
        part = pm.mesh.submesh([faces], append=True)
        part.apply_transform(pose)
        points, _ = trimesh.sample.sample_surface(part, 20_000, seed=3)
        for h in result["human_grasps"]:
            assert h["part"] == "handle"
            for box in h["model"]:
                pose_b = np.asarray(box["pose"])
                local = (points - pose_b[:3, 3]) @ pose_b[:3, :3]
                inside = (np.abs(local) < np.asarray(box["extents"]) / 2 - 1e-4).all(axis=1)
                assert not inside.any(), f"{obj}: {box['name']} on the {forbidden}"


def test_the_result_says_which_grasp_and_why_the_others_were_not_taken(planner):
    result = planner.plan("plate").to_dict()
    (hand,) = result["human_grasps"]
    grasp = hand["grasp"]
    assert grasp["family"] == grasp["name"] in ("pinch", "support")
    assert grasp["source"].startswith("hands/adult_hand.yaml:")
    assert "Feix" in grasp["why"] or "Cutkosky" in grasp["why"] or "GRASP" in grasp["why"]
    # the whole hand cannot go round a 26 cm plate; a lateral pinch is not for porcelain
    assert "lateral" in grasp["not_taken"] and "fragile" in grasp["not_taken"]["lateral"]
    entry = next(e for e in result["trace"] if e["rule"] == "receiver_hand_fits")
    assert entry["receiver_hand"]["grasps"][0]["name"] == grasp["name"]


# ---------------------------------------------------------------- a weaker grip, fewer grasps


def test_a_weaker_grip_takes_a_plate_on_the_palm_and_a_receiver_uses_only_their_grasps(
        tmp_path):
    root = _write(tmp_path / "kb")
    (root / "receivers" / "weak.yaml").write_text(
        "id: weak\nname: A weak grip\nrole: elder\ngrip_strength: 0.35\n")
    (root / "receivers" / "whole_hand.yaml").write_text(
        "id: whole_hand\nname: Takes everything in the whole hand\ngrasps: [wrap]\n")
    p = Planner(kb=root)
    weak = p.plan("plate", receiver="weak").to_dict()
    assert weak["outcome"] == "handover", weak["reason"]
    # a pinch holds 35 % of its 1.5 kg: not a 0.6 kg plate; the palm under it does
    assert [h["grasp"]["name"] for h in weak["human_grasps"]] == ["support"]
    assert "0.6" in weak["human_grasps"][0]["grasp"]["not_taken"]["pinch"]
    # who takes everything in the whole hand holds the plate's rim in it, fingers under it
    whole = p.plan("plate", receiver="whole_hand").to_dict()
    assert whole["outcome"] == "handover", whole["reason"]
    assert [h["grasp"]["name"] for h in whole["human_grasps"]] == ["wrap"]
    assert set(whole["human_grasps"][0]["grasp"]["not_taken"]) == set()


# ---------------------------------------------------------------- the reaching arm


def _arm_distances(hand: dict) -> list[float]:
    a = hand["arm"]
    return [_segment_box_distance(a["shoulder"], a["elbow"], RAIL_CENTRE, RAIL_EXTENTS),
            _segment_box_distance(a["elbow"], a["wrist"], RAIL_CENTRE, RAIL_EXTENTS)]


@pytest.mark.parametrize("obj", ["mug", "water_glass"])
def test_a_patients_arm_reaches_over_the_bed_rail_not_through_it(planner, obj):
    """Without the rail the patient would take the object where their forearm then passes
    through the rail's place; with the rail, the offer moves so that upper arm and forearm
    (capsules as thick as the body's) clear it, and the hand keeps the clearance from it."""
    free = planner.plan(obj, scene="bed_no_rail", receiver="patient").to_dict()
    assert free["outcome"] == "handover", free["reason"]
    (hand,) = free["human_grasps"]
    assert min(d - r for d, r in zip(_arm_distances(hand), hand["arm"]["radius"],
                                     strict=True)) < 0

    plan = planner.plan(obj, scene="bed_rail", receiver="patient")
    result = plan.to_dict()
    assert result["outcome"] == "handover", result["reason"]
    (hand,) = result["human_grasps"]
    for dist, radius in zip(_arm_distances(hand), hand["arm"]["radius"], strict=True):
        assert dist >= radius - 1e-6
    for box in hand["model"]:
        pts = _box_points(box["extents"], box["pose"])
        assert _point_box_distance(pts, RAIL_CENTRE, RAIL_EXTENTS).min() >= CLEARANCE - 0.002


def _nearest_obstacle(plan) -> dict[str, float]:
    """m, per scene box: how near the offered object and the receiver's hands come to it
    (points every 2 mm over the hand boxes and 60,000 over the object's surface: within
    2 mm of the exact distance). The table counts as solid down to the floor."""
    result = plan.to_dict()
    points = [_surface(_object_mesh(plan))]
    points += [_box_points(b["extents"], b["pose"]) for h in result["human_grasps"]
               for b in h["model"]]
    pts = np.concatenate(points)
    out = {}
    for box in result["scene"]["boxes"]:
        centre = np.asarray(box["pose"])[:3, 3]
        ext = np.asarray(box["extents"])
        if box["id"] == "table":
            top = centre[2] + ext[2] / 2
            centre, ext = np.array([centre[0], centre[1], top / 2]), np.array([*ext[:2], top])
        out[box["id"]] = float(_point_box_distance(pts, centre, ext).min())
    return out


def test_nothing_is_offered_closer_to_an_obstacle_than_the_clearance(planner):
    """A lamp's shade just under the handover: where merely not touching is asked, the
    receiver's fingers pass a few millimetres over it; common's clear_of_obstacles keeps
    the object and the hand 25 mm from it and from the table."""
    careless = planner.plan("knife", scene="lamp", culture="careless")
    assert careless.outcome == "handover", careless.reason
    assert _nearest_obstacle(careless)["lamp"] < CLEARANCE - 0.01
    plan = planner.plan("knife", scene="lamp")
    result = plan.to_dict()
    assert result["outcome"] == "handover", result["reason"]
    for name, dist in _nearest_obstacle(plan).items():
        assert dist >= CLEARANCE - 0.002, name
    entry = next(e for e in result["trace"] if e["rule"] == "clear_of_obstacles")
    assert entry["status"] == "pass" and entry["measured"] >= CLEARANCE - 1e-9


# ---------------------------------------------------------------- bad input


def test_a_hand_grasp_of_negative_size_is_a_kb_error_at_its_line(make_kb):
    root = make_kb({"hands/adult_hand.yaml": """\
        id: adult_hand
        name: Hand
        palm: [0.09, 0.1, 0.03]
        finger_length: 0.08
        finger_thickness: 0.02
        grip_width: 0.09
        grasps:
          - name: pinch
            family: pinch
            width: -0.03
            max_load_kg: 1.0
        """})
    with pytest.raises(KBError) as err:
        load_kb(root)
    assert "hands/adult_hand.yaml:10:" in str(err.value)
    assert "width" in str(err.value)


def test_a_rule_naming_a_grasp_no_hand_has_is_a_kb_error_at_its_line(make_kb):
    root = make_kb({"etiquette/common.yaml": """\
        id: common
        name: Common
        rules:
          - id: pinch_the_rim
            kind: receiver_grasp
            grasps: [pinch]
            require_tags: [handle]
            why: A grasp the minimal hand does not have.
        vocabulary:
          handle: The part made to be held.
        """})
    with pytest.raises(KBError) as err:
        load_kb(root)
    message = str(err.value)
    assert "etiquette/common.yaml:6:" in message and "grasp 'pinch'" in message
