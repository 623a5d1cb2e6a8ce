"""Everyday things with parts nobody holds, written by a user into a temporary KB: a lit
candle in a chamberstick (the robot never takes the flame) and a full teapot whose lid sits
loose (it is never lifted by the lid). Planned through the command line, as a user plans
them (the KB read through its cache)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from handover.engine.cli.app import main
from handover.engine.store.kb import builtin_kb_dir

CANDLE = """\
id: chamberstick
name: Lit candle in a chamberstick
mass: 0.22
geometry:
  primitives:
    - {shape: cylinder, part: dish, radius: 0.048, height: 0.014, position: [0, 0, 0.007]}
    - {shape: box, part: handle, extents: [0.04, 0.012, 0.006], position: [0.066, 0, 0.011]}
    - {shape: cylinder, part: candle, radius: 0.012, height: 0.09, position: [0, 0, 0.059]}
    - {shape: capsule, part: flame, radius: 0.006, height: 0.016, position: [0, 0, 0.118]}
parts:
  dish: {tags: [base]}
  handle: {tags: [handle, loop]}
  candle: {tags: [body]}
  flame: {tags: [flame]}
axes:
  up: [0, 0, 1]
  handle: [1, 0, 0]
"""

TEAPOT = """\
id: teapot
name: Teapot, full and hot
mass: 0.85
tags: [container]
geometry:
  primitives:
    - {shape: cylinder, part: body, radius: 0.068, height: 0.115, position: [0, 0, 0.0575]}
    - {shape: cylinder, part: lid, radius: 0.034, height: 0.02, position: [0, 0, 0.125]}
    - {shape: box, part: handle, extents: [0.012, 0.015, 0.075], position: [0.108, 0, 0.062]}
    - {shape: box, part: handle, extents: [0.04, 0.015, 0.012], position: [0.086, 0, 0.094]}
    - {shape: box, part: handle, extents: [0.04, 0.015, 0.012], position: [0.086, 0, 0.03]}
parts:
  body: {tags: [body, hot]}
  lid: {tags: [cap, hot]}
  handle: {tags: [handle, loop]}
axes:
  up: [0, 0, 1]
  handle: [1, 0, 0]
"""


@pytest.fixture(scope="module")
def kb(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("everyday") / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    (root / "objects" / "chamberstick.yaml").write_text(CANDLE)
    (root / "objects" / "teapot.yaml").write_text(TEAPOT)
    return root


def _plan(kb: Path, capsys, *args: str) -> dict:
    code = main(["--kb", str(kb), "plan", *args, "--no-motion", "--json"])
    out = capsys.readouterr().out
    assert code in (0, 4), out
    return json.loads(out)


@pytest.mark.parametrize("args", [["chamberstick"], ["chamberstick", "--mode", "h2g1"],
                                  ["chamberstick", "-r", "elder", "-c", "korean"]])
def test_the_robot_never_takes_the_flame(kb, capsys, args):
    r = _plan(kb, capsys, *args)
    assert r["outcome"] == "handover", r["reason"]
    held = {p for g in r["robot_grasps"] for p in g["parts"]}
    assert held and "flame" not in held, held
    assert "giver_avoids_flame" in json.dumps(r["trace"])  # judged, and said so
    # nor do the pads close near it: every contact at least 3 cm from the flame (the
    # capsule of the file above, measured here: its axis from z 0.110 to 0.126, radius 6 mm)
    for g in r["robot_grasps"]:
        for c in np.asarray(g["contacts"], dtype=float):
            axis = np.array([0.0, 0.0, np.clip(c[2], 0.110, 0.126)])
            assert np.linalg.norm(c - axis) - 0.006 >= 0.03 - 0.001, (g["hand"], c)


@pytest.mark.parametrize("args", [["teapot"], ["teapot", "-r", "elder"],
                                  ["teapot", "--mode", "h1g1"]])
def test_a_full_teapot_is_never_lifted_by_its_lid(kb, capsys, args):
    r = _plan(kb, capsys, *args)
    held = [p for g in r["robot_grasps"] for p in g["parts"]]
    assert "lid" not in held, held
    if r["outcome"] == "handover":
        taken = {h["part"] for h in r["human_grasps"]}
        assert taken == {"handle"}, taken  # the receiver keeps off the hot body and lid
    else:  # one hand only: say which rule kept it off the lid
        assert "giver_not_by_the_lid" in r["reason"], r["reason"]
