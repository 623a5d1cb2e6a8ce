"""How many hands the receiver takes an object with when the robot hands it over with both
(H2G1): two for a large or heavy object only where the parts they take it by leave room for
two hands side by side, else one. A cast-iron skillet too heavy for one gripper is taken by
its handle in one hand, not two hands squeezed onto one point of a 16 cm handle (two hands
on a wide tray: tests/engine/test_world.py). The skillet is written here; the handle's length
and the hand's width are read from the YAML, not from the planner."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from handover.engine.cli.app import main
from handover.engine.store.kb import builtin_kb_dir

HANDLE_LENGTH = 0.16
SKILLET = f"""\
id: skillet
name: Cast-iron skillet
mass: 2.4
tags: [cookware]
geometry:
  primitives:
    - {{shape: bowl, part: pan, profile: conical, radius: 0.13, bottom_radius: 0.115,
       height: 0.05, thickness: 0.005, position: [0, 0, 0.025]}}
    - {{shape: box, part: handle, extents: [{HANDLE_LENGTH}, 0.03, 0.015],
       position: [0.21, 0, 0.045]}}
parts:
  pan: {{tags: [body]}}
  handle: {{tags: [handle]}}
axes:
  up: [0, 0, 1]
  handle: [1, 0, 0]
"""
@pytest.fixture(scope="module")
def kb_dir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("hands") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    (root / "objects" / "skillet.yaml").write_text(SKILLET, encoding="utf-8")
    return root


def _plan(kb_dir: Path, capsys, obj: str) -> dict:
    code = main(["--kb", str(kb_dir), "plan", obj, "--json", "--no-motion"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def _grip_width(kb_dir: Path) -> float:
    receiver = yaml.safe_load((kb_dir / "receivers" / "adult.yaml").read_text())
    hand = yaml.safe_load((kb_dir / "hands" / f"{receiver['hand']}.yaml").read_text())
    return float(hand["grip_width"])


def test_a_skillet_too_heavy_for_one_gripper_is_taken_by_its_handle_in_one_hand(kb_dir,
                                                                                 capsys):
    grip = _grip_width(kb_dir)
    assert HANDLE_LENGTH < 2 * grip  # the handle has room for one hand only
    r = _plan(kb_dir, capsys, "skillet")
    assert r["feasible"] and r["mode"] == "H2G1"  # 2.4 kg: both grippers
    (hand,) = r["human_grasps"]
    assert hand["part"] == "handle"
    why = r["candidates"]["receiver_hands_why"]
    assert "no room for two hands side by side" in why and "one hand" in why

