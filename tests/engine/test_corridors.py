"""The approach, lift and retreat corridors of the chosen grasps (the ``corridor`` rule kind),
in scenes written here: a carton under a low shelf, under a wall cabinet; and the corridor
distances of the gripper's YAML.

The corridors are checked here with python-fcl, independently of the planner's swept-box
test: the gripper's three boxes are built from the gripper's YAML by the box model that
``handover.geometry.gripper`` documents (a palm behind two fingers standing open at
``width + 2 clearance``), placed at many poses along the corridor (every 2 mm) and tested
against the scene's boxes as the scene YAML gives them. The robot's arms are taken off (a
floating gripper per hand), so what decides is the gripper and its corridors alone.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import fcl
import numpy as np
import pytest
import yaml

from handover import Planner
from handover.engine.errors import KBError
from handover.engine.load.loader import load_kb
from handover.engine.spec.schema import CorridorSpec
from handover.engine.store.kb import builtin_kb_dir

CARTON = """\
id: carton
name: Juice carton
mass: 0.3
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.06, 0.06, 0.16], position: [0, 0, 0.08]}
parts:
  body: {tags: [body]}
axes:
  up: [0, 0, 1]
"""

# The carton stands 0.16 m tall on the table top (z 0.75 m) at x = 0.40 m. A gripper taking
# it from above reaches about 0.15 m above its grasp, near the carton's top: an obstacle whose
# bottom is 1.06 m high leaves room for the gripper at the grasp, not for its 8 cm approach.
SHELF = {"id": "shelf", "position": [0.40, 0.0, 1.07], "extents": [0.20, 0.30, 0.02]}
CABINET = {"id": "cabinet", "position": [0.40, 0.0, 1.26], "extents": [0.20, 0.30, 0.40]}


def scene(name: str, obstacles: list[dict]) -> str:
    return yaml.safe_dump({
        "id": name, "name": name, "why": "A carton on the table, something above it.",
        "support": {"position": [0.55, 0.0, 0.75], "size": [0.5, 1.0], "thickness": 0.03},
        "obstacles": obstacles,
        "receiver": {"position": [1.0, 0.0, 0.0], "facing": [-1.0, 0.0, 0.0]},
        "object": {"position": [0.40, 0.0]}})


@pytest.fixture(scope="module")
def kbs(tmp_path_factory, arms_off) -> dict[str, Path]:
    """The built-in KB with the carton and its scenes, armless; and the same without the
    corridor rule."""
    root = tmp_path_factory.mktemp("corridors") / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    arms_off(root)
    (root / "objects" / "carton.yaml").write_text(CARTON, encoding="utf-8")
    for name, obstacles in (("open", []), ("shelf", [SHELF]), ("cabinet", [CABINET])):
        (root / "scenes" / f"{name}.yaml").write_text(scene(name, obstacles), encoding="utf-8")
    bare = root.parent / "bare"
    shutil.copytree(root, bare)
    common = bare / "etiquette" / "common.yaml"
    text = common.read_text(encoding="utf-8")
    start = text.index("  - id: corridors_free")
    end = text.index("  - id:", start + 1)
    common.write_text(text[:start] + text[end:], encoding="utf-8")
    return {"rule": root, "bare": bare}


@pytest.fixture(scope="module")
def planners(kbs) -> dict[str, Planner]:
    return {name: Planner(kb=root) for name, root in kbs.items()}


def gripper_spec() -> dict:
    return yaml.safe_load((builtin_kb_dir() / "grippers" / "parallel_jaw.yaml").read_text())


def gripper_boxes(spec: dict, width: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """(extents (3,), centre (3,)) of the palm and the two fingers in the grasp frame, from
    the YAML by the documented box model."""
    length, w, t = spec["finger_length"], spec["finger_width"], spec["finger_thickness"]
    opening = float(np.clip(width + 2 * spec["clearance"], spec.get("min_opening", 0.0),
                            spec["max_opening"]))
    palm = np.array(spec["palm"], dtype=float)
    return [(palm, np.array([0.0, 0.0, -length / 2 - palm[2] / 2])),
            (np.array([w, t, length]), np.array([0.0, -(opening + t) / 2, 0.0])),
            (np.array([w, t, length]), np.array([0.0, (opening + t) / 2, 0.0]))]


def fcl_box(extents, rotation, centre) -> fcl.CollisionObject:
    return fcl.CollisionObject(fcl.Box(*map(float, extents)),
                               fcl.Transform(np.asarray(rotation, float),
                                             np.asarray(centre, float)))


def touches(a: fcl.CollisionObject, b: fcl.CollisionObject) -> bool:
    return fcl.collide(a, b, fcl.CollisionRequest(), fcl.CollisionResult()) > 0


def sweep_hits(grasp: dict, corridor: dict, box: dict, step: float = 0.002) -> list[float]:
    """The distances (m) from the grasp, along the corridor's poses, where the open gripper
    touches ``box`` (a scene obstacle as its YAML gives it)."""
    spec = gripper_spec()
    start, end = (np.asarray(p, dtype=float) for p in corridor["poses"])
    obstacle = fcl_box(box["extents"], np.eye(3), box["position"])
    length = float(np.linalg.norm(end[:3, 3] - start[:3, 3]))
    grasp_at = end if corridor is grasp.get("approach") else start
    hits = []
    for s in np.arange(0.0, length + 1e-9, step):
        pose = start.copy()
        pose[:3, 3] = start[:3, 3] + (end[:3, 3] - start[:3, 3]) * (s / length if length else 0)
        rot = pose[:3, :3]
        for extents, centre in gripper_boxes(spec, grasp["width"]):
            if touches(fcl_box(extents, rot, rot @ centre + pose[:3, 3]), obstacle):
                hits.append(float(np.linalg.norm(pose[:3, 3] - grasp_at[:3, 3])))
                break
    return hits


def test_the_corridor_distances_come_from_the_gripper_yaml(planners):
    result = json.loads(planners["rule"].plan("carton", scene="open").to_json())
    (grasp,) = result["robot_grasps"]
    spec = gripper_spec()["corridors"]
    assert grasp["approach"]["distance"] == pytest.approx(spec["approach"])
    assert grasp["approach"]["min_distance"] == pytest.approx(spec["approach_min"])
    assert grasp["retreat"]["distance"] == pytest.approx(spec["retreat"])
    pre, at = (np.asarray(p) for p in grasp["approach"]["poses"])
    a = at[:3, 2]
    # The pre-grasp pose lies back along the approach: the gripper moves along +a into it.
    np.testing.assert_allclose(at[:3, 3] - pre[:3, 3], spec["approach"] * a, atol=1e-5)
    np.testing.assert_allclose(grasp["approach"]["direction"], a, atol=1e-5)
    # It lets go at the handover pose and withdraws back along -a.
    release, away = (np.asarray(p) for p in grasp["retreat"]["poses"])
    np.testing.assert_allclose(release, np.asarray(grasp["pose_world"]), atol=1e-5)
    np.testing.assert_allclose(away[:3, 3] - release[:3, 3],
                               -spec["retreat"] * release[:3, 2], atol=1e-5)


def test_under_a_low_shelf_the_carton_is_taken_from_a_side_whose_approach_is_free(planners):
    result = json.loads(planners["rule"].plan("carton", scene="shelf").to_json())
    assert result["outcome"] == "handover"
    (grasp,) = result["robot_grasps"]
    assert sweep_hits(grasp, grasp["approach"], SHELF) == []
    # Without the rule the best grasp comes down nearly vertically, and its own approach
    # runs into the shelf within the least approach the gripper accepts.
    bare = json.loads(planners["bare"].plan("carton", scene="shelf").to_json())
    (steep,) = bare["robot_grasps"]
    hits = sweep_hits(steep, steep["approach"], SHELF)
    assert hits and min(hits) < gripper_spec()["corridors"]["approach_min"]
    assert steep["id"] != grasp["id"]
    # The steep one comes from nearer the vertical than the chosen one.
    down = np.array([0.0, 0.0, -1.0])
    assert np.dot(steep["approach"]["direction"], down) > np.dot(
        grasp["approach"]["direction"], down)


def test_a_wall_cabinet_above_forbids_grasps_from_above(planners):
    open_plan = json.loads(planners["rule"].plan("carton", scene="open").to_json())
    (top,) = open_plan["robot_grasps"]
    # With nothing above, the carton is taken from straight above.
    np.testing.assert_allclose(top["approach"]["direction"], [0.0, 0.0, -1.0], atol=1e-6)
    result = planners["rule"].plan("carton", scene="cabinet", why_not=(top["id"],)).to_dict()
    assert result["outcome"] == "handover"
    (grasp,) = result["robot_grasps"]
    assert grasp["approach"]["direction"][2] > -0.9  # not from above
    assert sweep_hits(grasp, grasp["approach"], CABINET) == []
    # The grasp from above is rejected by its approach corridor, and the trace says that its
    # approach runs into the cabinet.
    (why,) = result["why_not"]
    entry = next(e for e in why["trace"] if e["rule"] == "corridors_free")
    assert entry["status"] == "fail"
    said = {c["name"]: c for c in entry["corridors"]}
    assert said["approach"]["free"] is False
    assert "'cabinet'" in said["approach"]["reason"]


def test_a_corridor_distance_of_zero_or_less_is_a_kb_error_at_its_line(tmp_path):
    root = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    path = root / "grippers" / "parallel_jaw.yaml"
    text = path.read_text(encoding="utf-8")
    for bad in ("0", "-0.05"):
        path.write_text(text.replace("  retreat: 0.10", f"  retreat: {bad}"), encoding="utf-8")
        with pytest.raises(KBError) as info:
            load_kb(root)
        (issue,) = info.value.issues
        lines = path.read_text(encoding="utf-8").splitlines()
        assert issue.file == "grippers/parallel_jaw.yaml"
        assert lines[issue.line - 1].strip().startswith(f"retreat: {bad}")
        assert "greater than 0" in issue.message


def test_the_documented_corridors_are_the_built_in_gripper_s(docs):
    shown = yaml.safe_load(docs.example("gripper-corridors").text)["corridors"]
    assert CorridorSpec(**shown).model_dump() == gripper_spec()["corridors"]


def test_the_object_a_gripper_carries_is_its_parts_boxes_not_one_box_around_them():
    """What the lift corridors and the arm's motion carry: each part's box. The knife's
    blade is its 2 mm (the KB's primitive), not the handle's 2 cm: a blade carried 5 mm over
    a table does not touch it. Every point of the knife lies in one of the boxes."""
    from handover.engine.plan.corridors import held_box

    spec = yaml.safe_load((builtin_kb_dir() / "objects" / "knife.yaml").read_text())
    written = {p["part"]: np.asarray(p["extents"]) for p in spec["geometry"]["primitives"]}
    ctx = Planner().plan("knife", motion=False).context
    pose = np.eye(4)
    pose[:3, 3] = [0.5, 0.1, 0.8]
    boxes = {name: (ext, box) for name, ext, box in held_box(ctx, pose)}
    assert set(boxes) == {f"object's {part}" for part in written}
    for part, extents in written.items():
        np.testing.assert_allclose(np.sort(boxes[f"object's {part}"][0]), np.sort(extents),
                                   atol=1e-6)
    points = np.asarray(ctx.part_mesh.mesh.vertices) @ pose[:3, :3].T + pose[:3, 3]
    inside = np.zeros(len(points), dtype=bool)
    for ext, box in boxes.values():
        local = (points - box[:3, 3]) @ box[:3, :3]
        inside |= (np.abs(local) <= ext / 2 + 1e-9).all(axis=1)
    assert inside.all()
