"""``handover grasps`` on mesh files with no KB entry and on KB objects."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose

import handover.engine.cli  # noqa: F401  (registers the commands)
from handover.engine.cli.app import main

GRIPPER = """\
id: parallel_jaw
name: Test gripper
max_opening: 0.085
finger_length: 0.04
finger_width: 0.022
finger_thickness: 0.01
palm: [0.06, 0.13, 0.08]
friction: 0.5
"""

MALLET = """\
id: mallet
name: A mallet
mass: 0.4
geometry:
  primitives:
    - {shape: cylinder, part: handle, radius: 0.01, height: 0.2, position: [0.1, 0, 0],
       rotation_deg: [0, 90, 0], sections: 16}
    - {shape: box, part: head, extents: [0.04, 0.04, 0.08]}
parts:
  handle: {tags: [handle]}
  head: {tags: []}
"""


@pytest.fixture
def kb(tmp_path: Path) -> Path:
    root = tmp_path / "kb"
    (root / "grippers").mkdir(parents=True)
    (root / "objects").mkdir()
    (root / "grippers" / "parallel_jaw.yaml").write_text(GRIPPER)
    (root / "objects" / "mallet.yaml").write_text(MALLET)
    return root


@pytest.fixture
def block(tmp_path: Path) -> Path:
    """A 30 x 40 x 120 mm block written by trimesh: not from any KB."""
    path = tmp_path / "block.stl"
    trimesh.creation.box(extents=(0.03, 0.04, 0.12)).export(path)
    return path


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_json_for_a_mesh_file(capsys, kb, block):
    code, out, _ = _run(capsys, "--kb", str(kb), "grasps", str(block), "--json")
    assert code == 0
    data = json.loads(out)
    assert data["mesh"]["file"] == str(block)
    assert data["mesh"]["faces"] == 12 and data["mesh"]["watertight"] is True
    assert_allclose(sorted(data["mesh"]["extents"]), [0.03, 0.04, 0.12], rtol=1e-6)
    assert data["gripper"]["id"] == "parallel_jaw" and data["gripper"]["source"] == "kb"
    grasps = data["grasps"]
    assert len(grasps) == data["count"] > 0
    quality = [g["quality"] for g in grasps]
    assert quality == sorted(quality, reverse=True)
    for g in grasps:
        pose = np.array(g["pose"])
        c0, c1 = np.array(g["contacts"])
        # numbers are rounded to 6 decimals
        assert_allclose(pose[:3, :3].T @ pose[:3, :3], np.eye(3), atol=1e-5)
        # the gripper at the contacts' midpoint, pulled back along -a by its offset
        assert_allclose(pose[:3, 3], (c0 + c1) / 2 - g["offset"] * pose[:3, 2], atol=2e-6)
        assert_allclose(pose[:3, 1], (c1 - c0) / np.linalg.norm(c1 - c0), atol=1e-5)
        assert g["width"] == pytest.approx(np.linalg.norm(c1 - c0), abs=2e-6)
        assert g["width"] <= data["gripper"]["max_width"]
        assert g["parts"] == ["body", "body"]
        assert g["source"] == "facet"
    # the block is 30 and 40 mm across two ways (120 mm is beyond the opening)
    assert {round(g["width"], 6) for g in grasps} <= {0.03, 0.04}


def test_limit_and_roll_step(capsys, kb, block):
    code, out, _ = _run(capsys, "--kb", str(kb), "grasps", str(block), "--json")
    everything = json.loads(out)["grasps"]
    code, out, _ = _run(
        capsys, "--kb", str(kb), "grasps", str(block), "--json", "--limit", "3",
        "--roll-step-deg", "90",
    )  # fmt: skip
    data = json.loads(out)
    assert code == 0 and len(data["grasps"]) == 3
    assert data["stats"]["rolls_per_site"] == 4
    assert {g["roll_deg"] for g in data["grasps"]} <= {0.0, 90.0, 180.0, 270.0}
    assert data["grasps"][0]["quality"] == everything[0]["quality"]


def test_obj_file_and_same_output_twice(capsys, kb, tmp_path):
    path = tmp_path / "ball.obj"
    trimesh.creation.icosphere(subdivisions=2, radius=0.015).export(path)
    first = _run(capsys, "--kb", str(kb), "grasps", str(path), "--json")
    second = _run(capsys, "--kb", str(kb), "grasps", str(path), "--json")
    assert first[0] == 0 and first[1] == second[1]
    grasps = json.loads(first[1])["grasps"]
    assert grasps and all(g["source"] == "antipodal" for g in grasps)


def test_table_for_a_kb_object(capsys, kb):
    code, out, _ = _run(capsys, "--kb", str(kb), "grasps", "mallet")
    assert code == 0
    assert "mallet" in out and "parts: handle, head" in out
    assert "candidates" in out


def test_kb_without_gripper_uses_the_default_and_says_so(capsys, tmp_path, block):
    root = tmp_path / "nogripper"
    (root / "objects").mkdir(parents=True)
    (root / "objects" / "mallet.yaml").write_text(MALLET)
    code, out, _ = _run(capsys, "--kb", str(root), "grasps", str(block), "--json")
    data = json.loads(out)
    assert code == 0 and data["gripper"]["source"] == "default"
    assert any("no gripper" in note for note in data["notes"])


def test_missing_mesh_file_exits_5(capsys, kb, tmp_path):
    code, _, err = _run(capsys, "--kb", str(kb), "grasps", str(tmp_path / "none.stl"))
    assert code == 5 and "not found" in err


def test_garbage_mesh_file_exits_5(capsys, kb, tmp_path):
    path = tmp_path / "junk.stl"
    path.write_text("solid nothing\nendsolid\n")
    code, _, err = _run(capsys, "--kb", str(kb), "grasps", str(path))
    assert code == 5 and "bad mesh" in err


def test_unknown_object_or_gripper_exits_2(capsys, kb, block):
    code, _, err = _run(capsys, "--kb", str(kb), "grasps", "no_such_thing")
    assert code == 2 and "unknown object" in err
    code, _, err = _run(capsys, "--kb", str(kb), "grasps", str(block), "--gripper", "nope")
    assert code == 2 and "unknown gripper" in err


def test_open_mesh_still_works_with_a_note(capsys, kb, tmp_path):
    box = trimesh.creation.box(extents=(0.03, 0.04, 0.12))
    path = tmp_path / "open.stl"
    trimesh.Trimesh(box.vertices, box.faces[:-1]).export(path)
    code, out, _ = _run(capsys, "--kb", str(kb), "grasps", str(path), "--json")
    data = json.loads(out)
    assert code == 0 and data["mesh"]["watertight"] is False
    assert any("not watertight" in note for note in data["notes"])
