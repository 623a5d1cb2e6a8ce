"""Where the object lies at pick-up (engine/plan/pickup.py), through the CLI: an object the
scene's place puts a few centimetres into the robot lies pushed clear of it, with a warning;
an object that cannot lie where the scene puts it (through a wall, through the robot) has
nothing planned, and the answer says what it passes through."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from handover.engine.cli.app import main

# A 1.2 m broom handle lying along the table, pointing at the robot: the default scene puts
# its centre 0.33 m in front of the robot, so it would reach 0.27 m behind the robot's axis.
BROOM = ("id: broom\nname: A long-handled broom\nmass: 0.4\ngeometry:\n  primitives:\n"
         "    - {shape: cylinder, part: handle, radius: 0.013, height: 1.2,\n"
         "       position: [0, 0, 0], rotation_deg: [0, 90, 0]}\n"
         "parts:\n  handle: {tags: [handle]}\naxes:\n  handle: [-1, 0, 0]\n")


# A 0.7 m wooden rod (30 mm), its frame at its middle.
ROD = ("id: rod\nname: A 0.7 m wooden rod\nmass: 0.3\ngeometry:\n  primitives:\n"
       "    - {shape: cylinder, part: rod, radius: 0.015, height: 0.7,\n"
       "       position: [0, 0, 0], rotation_deg: [0, 90, 0]}\n"
       "parts:\n  rod: {tags: [handle]}\n")


@pytest.fixture(scope="module")
def own_kb(tmp_path_factory) -> Path:
    from handover.engine.store.kb import builtin_kb_dir

    root = tmp_path_factory.mktemp("pickup") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    (root / "objects" / "broom.yaml").write_text(BROOM, encoding="utf-8")
    (root / "objects" / "rod.yaml").write_text(ROD, encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def builtin_dir() -> Path:
    from handover.engine.store.kb import builtin_kb_dir

    return Path(builtin_kb_dir())


def _plan(capsys, *argv: str) -> tuple[int, dict]:
    code = main(["plan", *argv, "--json", "--no-motion"])
    return code, json.loads(capsys.readouterr().out)


def _box_corners(extents, position) -> np.ndarray:
    """(8, 3) the corners of a box primitive, object frame (the KB's numbers, not the
    planner's mesh)."""
    half = np.asarray(extents, dtype=float) / 2
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return np.asarray(position, dtype=float) + signs * half


def _robot_box(data: dict, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) world corners of a robot body box of the result (axis-aligned there)."""
    box = next(b for b in data["bodies"]["robot"] if b["name"] == name)
    centre = np.asarray(box["pose"], dtype=float)[:3, 3]
    half = np.asarray(box["extents"], dtype=float) / 2
    return centre - half, centre + half


def test_a_tray_the_scene_puts_into_the_robot_lies_pushed_clear_of_it(capsys, builtin_dir):
    """The default scene centres objects 0.33 m in front of the robot, 3 cm in from the
    table's edge; the 0.5 m tray would reach 8 cm from the robot's axis, inside its 24 cm
    torso. It lies pushed straight away from the robot, just clear of the torso, still on the
    table, and the plan says so; it is still handed over."""
    code, data = _plan(capsys, "tray")
    assert code == 0 and data["outcome"] == "handover"
    spec = yaml.safe_load((builtin_dir / "objects" / "tray.yaml").read_text(encoding="utf-8"))
    corners = np.vstack([_box_corners(p["extents"], p.get("position", [0, 0, 0]))
                         for p in spec["geometry"]["primitives"]])
    pose = np.asarray(data["initial_pose"], dtype=float)
    world = corners @ pose[:3, :3].T + pose[:3, 3]
    lo, hi = _robot_box(data, "torso")
    assert world[:, 0].min() >= hi[0] - 1e-6  # in front of the torso: not through it
    assert world[:, 0].min() <= hi[0] + 0.005 + 1e-6  # pushed just clear, not further
    at_scene = corners @ pose[:3, :3].T + [0.33, 0.0, pose[2, 3]]  # where the scene put it
    assert at_scene[:, 0].min() < hi[0]  # which was through the torso
    moved = pose[0, 3] - 0.33  # straight away from the robot, along x here
    assert moved > 0 and pose[1, 3] == 0.0
    table = next(b for b in data["scene"]["boxes"] if b["id"] == "table")
    front = np.asarray(table["pose"])[0, 3] - table["extents"][0] / 2
    assert pose[0, 3] > front  # its centre over the table top: it does not tip off
    assert any("would pass through the robot's body (robot:torso)" in w
               and f"{moved:.3f} m further from the robot" in w for w in data["warnings"])


def test_an_object_clear_of_the_robot_lies_where_the_scene_puts_it(capsys):
    code, data = _plan(capsys, "knife")
    assert code == 0
    pose = np.asarray(data["initial_pose"], dtype=float)
    assert pose[:2, 3].tolist() == [0.33, 0.0]
    assert not any("pass through" in w for w in data["warnings"])


def test_a_broom_pointing_at_the_robot_cannot_lie_there_and_nothing_is_planned(capsys,
                                                                               own_kb):
    """A 1.2 m handle lying along the table from the scene's place would run 0.27 m behind
    the robot's axis, through its torso; pushed clear of it, it reaches the receiver
    standing 1 m from the robot. A careful person says the scene cannot be: nothing is
    planned (exit 4), every mode is reported not tried, the reason names the receiver and
    a warning where it was pushed to."""
    code, data = _plan(capsys, "--kb", str(own_kb), "broom")
    assert code == 4 and data["outcome"] == "infeasible"
    assert data["robot_grasps"] == [] and data["human_grasps"] == []
    assert "cannot lie where scene table puts it" in data["reason"]
    assert "body:receiver:" in data["reason"]
    assert any("would pass through the robot's body (robot:torso)" in w
               for w in data["warnings"])
    assert [t["mode"] for t in data["modes_tried"]] == ["H1G1", "H2G2", "H2G1"]
    assert all("not tried" in t["reason"] for t in data["modes_tried"])
    # independently: pushed just clear of the torso, its far end is at the receiver's legs
    pose = np.asarray(data["initial_pose"], dtype=float)
    near_end = (pose @ np.array([-0.6, 0.0, 0.0, 1.0]))[:3]
    far_end = (pose @ np.array([0.6, 0.0, 0.0, 1.0]))[:3]
    lo, hi = _robot_box(data, "torso")
    assert hi[0] - 1e-6 <= near_end[0] <= hi[0] + 0.005 + 1e-6  # just clear of the torso
    legs = [b for b in data["bodies"]["receiver"] if b["name"].endswith("thigh")]
    assert far_end[0] > min(b["p0"][0] - b["radius"] for b in legs)


def test_a_rod_pointing_at_the_robot_lies_pushed_clear_and_is_handed_over(capsys, own_kb):
    """A 0.7 m rod lying along the table from the scene's place would reach 2 cm behind the
    robot's axis; pushed 15 cm away from the robot it is clear of it, its centre still over
    the table, its far end short of the receiver: it is planned, and the plan says where
    it lies."""
    code, data = _plan(capsys, "--kb", str(own_kb), "rod")
    assert code == 0 and data["outcome"] == "handover"
    pose = np.asarray(data["initial_pose"], dtype=float)
    near_end = (pose @ np.array([-0.35, 0.0, 0.0, 1.0]))[:3]
    lo, hi = _robot_box(data, "torso")
    assert hi[0] - 1e-6 <= near_end[0] <= hi[0] + 0.005 + 1e-6  # just clear of the torso
    table = next(b for b in data["scene"]["boxes"] if b["id"] == "table")
    centre, half = np.asarray(table["pose"])[:2, 3], np.asarray(table["extents"][:2]) / 2
    assert np.all(np.abs(pose[:2, 3] - centre) <= half)
    assert any("would pass through the robot's body" in w for w in data["warnings"])


def test_a_knife_the_scene_puts_through_a_wall_is_not_planned_and_what_if_names_a_scene(
        capsys, builtin_dir):
    """The scene ``hammer_by_wall`` puts its object 0.62 m out, rotated half a turn, under a
    shelf and against a wall: written for the hammer. The knife there runs through the wall:
    nothing is planned, the reason names the wall, and ``--what-if`` finds the scenes where
    the knife lies clear and is handed over."""
    code, data = _plan(capsys, "knife", "--scene", "hammer_by_wall", "--what-if")
    assert code == 4 and data["outcome"] == "infeasible"
    assert "passes through scene:wall" in data["reason"]
    scene = yaml.safe_load((builtin_dir / "scenes" / "hammer_by_wall.yaml").read_text(
        encoding="utf-8"))
    wall = next(o for o in scene["obstacles"] if o["id"] == "wall")
    wall_x = (wall["position"][0] - wall["extents"][0] / 2,
              wall["position"][0] + wall["extents"][0] / 2)
    knife = yaml.safe_load((builtin_dir / "objects" / "knife.yaml").read_text(encoding="utf-8"))
    points = np.vstack([_box_corners(p["extents"], p.get("position", [0, 0, 0]))
                        for p in knife["geometry"]["primitives"] if p["shape"] == "box"])
    pose = np.asarray(data["initial_pose"], dtype=float)
    xs = (points @ pose[:3, :3].T + pose[:3, 3])[:, 0]
    assert xs.min() < wall_x[0] and xs.max() > wall_x[1]  # it spans the wall's thickness
    scenes = {c["detail"].split()[1].rstrip(":") for c in data["what_if"]
              if c["kind"] == "scene"}
    assert "table" in scenes and "hammer_by_wall" not in scenes


def test_the_hammer_under_its_shelf_lies_clear_and_is_planned(capsys):
    """The scene the wall and shelf were written for: the hammer's head 1.2 cm under the
    shelf, clear of everything; it is planned as before."""
    code, data = _plan(capsys, "hammer", "--scene", "hammer_by_wall")
    assert code == 0 and data["outcome"] == "handover"
    assert not any("pass through" in w for w in data["warnings"])
