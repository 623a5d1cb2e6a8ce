"""The robot offers an object with its hand out in front of it, not beside its own torso
(``giver_torso`` rules; the built-in ``hand_out_in_front``, soft at 0.3 m). A closed umbrella
is written here: its handle is the receiver's, so the robot holds its canopy, and without the
rule it holds the canopy's far end about 0.2 m from its own base axis. It lies across the
table: along it, from the default place, it would reach into the receiver. Where the robot's hand
is, is computed here: the middle of the handover grasp's contacts (the JSON, object frame)
put in the world by the offered object's pose, against the robot's base axis read from the
robot's YAML."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from handover import Planner
from handover.engine.store.kb import builtin_kb_dir

RULE = "hand_out_in_front"
MIN_M = 0.3
UMBRELLA = """\
id: umbrella
name: Closed umbrella
mass: 0.45
geometry:
  primitives:
    - {shape: cylinder, part: handle, radius: 0.016, height: 0.14, position: [0.07, 0, 0],
       rotation_deg: [0, 90, 0]}
    - {shape: cylinder, part: shaft, radius: 0.006, height: 0.12, position: [0.20, 0, 0],
       rotation_deg: [0, 90, 0]}
    - {shape: cylinder, part: canopy, radius: 0.03, height: 0.55, position: [0.535, 0, 0],
       rotation_deg: [0, 90, 0]}
    - {shape: cylinder, part: tip, radius: 0.005, height: 0.06, position: [0.84, 0, 0],
       rotation_deg: [0, 90, 0]}
parts:
  handle: {tags: [handle]}
  shaft: {tags: []}
  canopy: {tags: []}
  tip: {tags: [pointed]}
axes:
  tip: [1, 0, 0]
"""


# The default table with the umbrella lying across it, the tip to the robot's left: along
# the table from the default place, its 0.87 m would reach into the receiver standing at 1 m
# (which the planner reports: it cannot lie there).
SCENE = """\
id: umbrella_table
name: An umbrella lying across the table
support: {position: [0.55, 0.0, 0.75], size: [0.5, 1.0], thickness: 0.03}
receiver: {position: [1.0, 0.0, 0.0], facing: [-1.0, 0.0, 0.0]}
object: {position: [0.45, -0.4], rotation_deg: [0, 0, 90]}
"""


def _kb(root: Path, *, without_rule: bool = False) -> Path:
    shutil.copytree(builtin_kb_dir(), root)
    (root / "objects" / "umbrella.yaml").write_text(UMBRELLA, encoding="utf-8")
    (root / "scenes" / "umbrella_table.yaml").write_text(SCENE, encoding="utf-8")
    if without_rule:
        common = root / "etiquette" / "common.yaml"
        doc = yaml.safe_load(common.read_text())
        doc["rules"] = [r for r in doc["rules"] if r["id"] != RULE]
        common.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def kb_dirs(tmp_path_factory) -> tuple[Path, Path]:
    base = tmp_path_factory.mktemp("giver_torso")
    return _kb(base / "kb"), _kb(base / "kb_without", without_rule=True)


def _robot_axis(kb_dir: Path) -> np.ndarray:
    robot = yaml.safe_load((kb_dir / "robots" / "idro.yaml").read_text())
    return np.asarray(robot["base_pose"]["position"][:2], dtype=float)


def _offering_hands(result: dict) -> list[tuple[dict, float]]:
    """Each robot grasp that holds the object where it is offered, with the middle of its
    contacts in the world ((3,) m: the offered object's pose applied to the JSON's contacts,
    object frame)."""
    pose = np.asarray(result["object_pose"], dtype=float)
    out = []
    for g in result["robot_grasps"]:
        if g.get("stage") == "pick":  # H2G2's first hand passes it on before the handover
            continue
        middle = np.asarray(g["contacts"], dtype=float).mean(axis=0)
        world = pose[:3, :3] @ middle + pose[:3, 3]
        out.append((g, world))
    return out


@pytest.mark.parametrize("receiver", ["adult", "seated_adult"])
def test_a_long_object_is_offered_with_the_robot_s_hand_out_in_front(kb_dirs, receiver):
    """The soft rule moves the robot's hand out in front of its torso: for a standing adult
    to its 0.3 m; for a seated one, lower and nearer the table, at least 5 cm further out
    than without the rule (the rule's score traded against the others')."""
    kb_dir, without = kb_dirs
    axis = _robot_axis(kb_dir)
    result = Planner(kb_dir, db=False).plan("umbrella", receiver=receiver,
                                            scene="umbrella_table").to_dict()
    assert result["feasible"], result["reason"]
    assert [h["part"] for h in result["human_grasps"]] == ["handle"]  # theirs, as before
    hands = _offering_hands(result)
    assert hands
    out = []
    for g, world in hands:
        distance = float(np.linalg.norm(world[:2] - axis))
        traced = [t for t in result["trace"] if t["rule"] == RULE and t.get("grasp") == g["id"]]
        assert traced and traced[0]["status"] == "scored"
        assert traced[0]["measured"] == pytest.approx(distance, abs=1e-5)
        out.append(distance)
    if receiver == "adult":
        assert min(out) >= MIN_M - 1e-6
    # the rule is what moves it: without it, the canopy is held by its far end, beside the
    # robot's torso
    before = Planner(without, db=False).plan("umbrella", receiver=receiver,
                                             scene="umbrella_table").to_dict()
    assert before["feasible"]
    closest = min(float(np.linalg.norm(w[:2] - axis)) for _, w in _offering_hands(before))
    assert closest < MIN_M and min(out) >= closest + 0.05


def test_a_hard_giver_torso_rule_refuses_and_says_so(kb_dirs, tmp_path):
    # Nothing can be offered 2 m out from the robot's axis (its reach is less): a hard rule
    # that asks it leaves no candidate, and the reason names it.
    kb_dir, _ = kb_dirs
    root = tmp_path / "kb"
    shutil.copytree(kb_dir, root)
    common = root / "etiquette" / "common.yaml"
    doc = yaml.safe_load(common.read_text())
    for rule in doc["rules"]:
        if rule["id"] == RULE:
            rule.update(hard=True, min_m=2.0)
    common.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    planned = Planner(root, db=False).plan("knife", mode="h1g1")
    assert not planned.feasible
    assert RULE in planned.reason
