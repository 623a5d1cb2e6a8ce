"""What would change the answer (``--what-if``) and the reason of an infeasible plan, on
objects, grippers and cultures built here. Every change listed is checked by planning again
with it, independently of the code that found it."""

from __future__ import annotations

import json
import os
import shutil
import sys

import pytest
import yaml

from handover.engine.cli.app import main
from handover.engine.plan.whatif import WORKERS_ENV
from handover.engine.planner import Planner
from handover.engine.store.kb import builtin_kb_dir

# A chef's knife whose handle is 10 cm long: an adult's hand takes 9 cm of it, and the
# standard gripper's fingers (22 mm wide, 5 mm clearance each side) do not fit in the rest.
SHORT_KNIFE = """\
id: short_knife
name: A knife with a short handle
mass: 0.2
tags: [kitchen, tool, knife]
geometry:
  primitives:
    - {shape: box, part: handle, extents: [0.10, 0.026, 0.02], position: [-0.05, 0.004, 0]}
    - {shape: box, part: blade, extents: [0.2, 0.045, 0.002], position: [0.1, 0, 0]}
parts:
  handle: {tags: [handle, grip]}
  blade: {tags: [blade, sharp]}
axes:
  tip: [1, 0, 0]
  handle: [-1, 0, 0]
  up: [0, 1, 0]
tasks:
  cut:
    why: The receiver takes the handle, spine up.
    receiver_tags: [handle]
    present:
      - {axis: up, toward: up, max_deg: 45}
default_task: cut
"""

# Fingers 4 mm wide with 1 mm clearance: they fit beside the hand on that handle.
SMALL_JAW = """\
id: small_jaw
name: A small parallel-jaw gripper
max_opening: 0.05
min_opening: 0.0
finger_length: 0.04
finger_width: 0.004
finger_thickness: 0.006
palm: [0.03, 0.07, 0.04]
clearance: 0.001
friction: 0.5
parallel_tol_deg: 10
roll_step_deg: 15
"""

# A culture that keeps the gripper farther from the receiver's hand than a mug allows.
PICKY = """\
id: picky
name: Keeps its distance
extends: common
rules:
  - id: far_from_the_hand
    kind: clearance
    min_m: {q}
    why: The gripper stays this far from the receiver's hand.
"""

SAFETY = {"receiver_avoids_sharp", "giver_avoids_sharp", "sharp_tip_away", "collision_free",
          "clear_at_handover", "out_of_the_opening"}


@pytest.fixture(scope="module")
def kb_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("whatif") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    (root / "objects" / "short_knife.yaml").write_text(SHORT_KNIFE)
    (root / "grippers" / "small_jaw.yaml").write_text(SMALL_JAW)
    (root / "etiquette" / "picky.yaml").write_text(PICKY.format(q=0.5))
    # a receiver who takes everything with the whole hand: no room on the short handle
    (root / "receivers" / "whole_hand.yaml").write_text(
        "id: whole_hand\nname: Takes everything with the whole hand\ngrasps: [wrap]\n")
    return root


@pytest.fixture(scope="module")
def planner(kb_dir, tmp_path_factory):
    return Planner(kb=kb_dir, db=tmp_path_factory.mktemp("db"))


def test_a_handle_too_short_for_gripper_and_hand_names_the_geometry_first(planner, kb_dir):
    knife = yaml.safe_load(SHORT_KNIFE)
    handle = knife["geometry"]["primitives"][0]["extents"][0]
    hand = yaml.safe_load((kb_dir / "hands" / "adult_hand.yaml").read_text())
    jaw = yaml.safe_load((kb_dir / "grippers" / "parallel_jaw.yaml").read_text())
    small = yaml.safe_load(SMALL_JAW)
    # the premise, from the KB files: hand and standard fingers need more than the handle
    assert hand["grip_width"] + jaw["finger_width"] + 2 * jaw["clearance"] > handle
    assert hand["grip_width"] + small["finger_width"] + 2 * small["clearance"] < handle

    # with a fingertip grasp of the repertoire the adult takes it beside the gripper ...
    assert planner.plan("short_knife").feasible
    # ... one who only wraps cannot
    plan = planner.plan("short_knife", receiver="whole_hand", what_if=True)
    assert not plan.feasible
    reason = plan.reason
    cause = reason.index("the cause:")
    assert "receiver_hand" in reason[cause:] and "handle" in reason[cause:]
    # no safety knowledge rule is named before the geometric cause and its set
    geometry = reason.index("[geometry")
    for rule in SAFETY - {"collision_free"}:
        if rule in reason:
            assert reason.index(rule) > geometry, rule
            assert f"[safety: {rule}" in reason

    changes = plan.to_dict()["what_if"]
    assert changes and not changes[0]["safety"]
    safety = [c["safety"] for c in changes]
    assert safety == sorted(safety)  # every non-safety change before any safety one
    for c in changes:
        assert set(c) >= {"kind", "rule", "safety", "detail"}
        if c["kind"] == "relax_rule":
            assert c["safety"] == any(r in SAFETY for r in c["rules"])
    grippers = [c for c in changes if c["kind"] == "gripper"]
    assert [c["detail"].split()[1].rstrip(":") for c in grippers] == ["small_jaw"]
    # checked again here: the smaller gripper really plans it
    assert planner.plan("short_knife", receiver="whole_hand", gripper="small_jaw").feasible
    for c in changes:
        if c["kind"] in ("receiver", "scene"):
            name = c["detail"].split()[1].rstrip(":")
            query = {"receiver": "whole_hand"} | {c["kind"]: name}
            assert planner.plan("short_knife", **query).feasible, c


def test_a_forced_mode_lists_the_modes_that_work(planner):
    tray = planner.plan("tray", mode="h1g1", what_if=True)
    assert not tray.feasible
    changes = tray.to_dict()["what_if"]
    modes = [c for c in changes if c["kind"] == "mode"]
    assert modes and changes[0]["kind"] in ("mode", "relax_rule")
    for c in modes:
        forced = c["detail"].split()[1].rstrip(":")
        assert planner.plan("tray", mode=forced).feasible


def test_a_threshold_is_loosened_to_what_the_nearest_candidate_needs(kb_dir, tmp_path):
    planner = Planner(kb=kb_dir, db=False)
    plan = planner.plan("mug", culture="picky", what_if=True)
    assert not plan.feasible and "far_from_the_hand" in plan.reason
    loosened = [c for c in plan.to_dict()["what_if"]
                if c["rule"] == "far_from_the_hand" and "->" in c["detail"]]
    assert loosened and not loosened[0]["safety"]
    new = float(loosened[0]["detail"].split("->")[1].split(":")[0])
    assert 0 < new < 0.5
    # the culture written again with that threshold plans, a little stricter does not
    root = tmp_path / "kb"
    shutil.copytree(kb_dir, root)
    (root / "etiquette" / "picky.yaml").write_text(PICKY.format(q=new))
    assert Planner(kb=root, db=False).plan("mug", culture="picky").feasible
    (root / "etiquette" / "picky.yaml").write_text(PICKY.format(q=round(new + 0.002, 3)))
    assert not Planner(kb=root, db=False).plan("mug", culture="picky").feasible


def test_a_feasible_plan_has_nothing_to_change(planner):
    plan = planner.plan("mug", what_if=True)
    assert plan.feasible and plan.to_dict()["what_if"] == []
    assert "what_if" not in planner.plan("mug").to_dict()


def test_the_cli_prints_the_changes_and_puts_them_in_the_json(kb_dir, tmp_path, capsys):
    db = str(tmp_path / "db")
    args = ["--kb", str(kb_dir), "plan", "short_knife", "--receiver", "whole_hand", "--what-if",
            "--db", db]
    rc = main(args)
    out = capsys.readouterr().out
    assert rc == 4 and "what if" in out and "--gripper small_jaw" in out
    rc = main([*args, "--json"])
    data = json.loads(capsys.readouterr().out)
    assert rc == 4 and any(c["kind"] == "gripper" for c in data["what_if"])


def test_the_changes_are_the_same_verified_in_one_process_or_in_several(kb_dir, planner,
                                                                         monkeypatch):
    """The changes are verified in forked processes where there are cores: each verification
    depends on its change alone, so the answer is the same bytes as verified one after the
    other in this process."""
    _skip_unless_forking()
    answers = []
    for workers in ("1", "2"):
        monkeypatch.setenv(WORKERS_ENV, workers)
        fresh = Planner(kb=kb_dir, db=planner.db.root)  # nothing memoised from the other run
        answers.append(fresh.plan("short_knife", receiver="whole_hand", what_if=True).to_json())
    assert answers[0] == answers[1]
    kinds = {c["kind"] for c in json.loads(answers[0])["what_if"]}
    assert {"relax_rule", "gripper"} <= kinds  # rules relaxed and another world, both verified


def test_a_process_running_other_threads_verifies_the_changes_itself(monkeypatch):
    """Forking a process that runs other threads could leave a lock they hold locked in the
    child: a what-if asked from a threaded program is verified in its own process."""
    import threading

    from handover.engine.plan import whatif

    monkeypatch.setenv(WORKERS_ENV, "2")
    _skip_unless_forking()
    assert whatif._workers(5) == 2
    seen = []
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        seen.append(whatif._workers(5))
        ran_in = whatif.verified([os.getpid, os.getpid])
    finally:
        stop.set()
        other.join()
    assert seen == [1]
    assert ran_in == [os.getpid(), os.getpid()]  # here, not in a forked process


def test_a_verifying_process_that_dies_leaves_the_changes_verified_here(monkeypatch):
    """A forked process killed on the way (out of memory, a signal) does not hang the
    what-if: the changes are verified in the planner's own process instead."""
    from handover.engine.plan import whatif

    monkeypatch.setenv(WORKERS_ENV, "2")
    _skip_unless_forking()
    parent = os.getpid()

    def dies_when_forked() -> str:
        if os.getpid() != parent:
            os._exit(1)
        return "verified here"

    assert whatif.verified([dies_when_forked, dies_when_forked]) == ["verified here"] * 2


def _skip_unless_forking() -> None:
    """Skip where the changes are always verified in this process: not Linux, or one core."""
    if not sys.platform.startswith("linux") or len(os.sched_getaffinity(0)) < 2:
        pytest.skip("not Linux, or one core: the changes are always verified in this process")


def test_how_many_processes_verify_the_changes(monkeypatch):
    """One per core by default, at most MAX_WORKERS (each forked process comes to hold its
    own pages); the variable sets another number, never beyond the cores or the changes."""
    from handover.engine.plan import whatif

    if not sys.platform.startswith("linux"):
        pytest.skip("not Linux: the changes are always verified in this process")
    monkeypatch.setattr(whatif.os, "sched_getaffinity", lambda pid: set(range(16)))
    monkeypatch.delenv(WORKERS_ENV, raising=False)
    assert whatif._workers(12) == whatif.MAX_WORKERS == 4
    assert whatif._workers(3) == 3 and whatif._workers(1) == 1
    for asked, got in (("8", 8), ("64", 12), ("1", 1), ("many", 4)):
        monkeypatch.setenv(WORKERS_ENV, asked)
        assert whatif._workers(12) == got, asked
