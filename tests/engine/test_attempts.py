"""Mode attempts are values: what one mode decides never depends on which modes ran before,
and a plan is feasible only if every hard rule of every chosen grasp passes in its trace.

Cultures are written by the tests: a culture that prefers two hands, random cultures of hard
and soft mode rules, a contact rule meant for children only.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handover import Planner
from handover.engine.cli.app import main
from handover.engine.plan.modes import attempt_mode, choose
from handover.engine.plan.prepare import prepare
from handover.engine.spec.query import Query
from handover.engine.spec.schema import Culture
from handover.engine.store.kb import builtin_kb_dir

PREFERS_TWO_HANDS = """\
id: two_hands_please
name: Prefers two hands
rules:
  - id: two_hands_preferred
    kind: mode
    mode: H2G1
    hard: false
    weight: 1.0
    overrides: [prefer_one_hand]
    why: Both hands whenever it works.
"""

FORMAL = """\
id: formal
name: Formal household
extends: japanese
rules:
  - id: two_hands_always
    kind: mode
    mode: H2G1
    hard: false
    weight: 2.0
    why: In this household everything is offered with both hands when it can be.
"""

CHILD_ONLY = """\
id: careful
name: Careful with children
rules:
  - id: robot_keeps_off_the_handle_for_a_child
    kind: contact
    who: giver
    forbid_tags: [handle]
    applies: {receiver_roles: [child]}
    why: A child takes the handle; the robot leaves all of it free.
  - id: child_never_gets_the_grip
    kind: contact
    who: receiver
    forbid_tags: [handle]
    applies: {receiver_roles: [child]}
    why: (a rule for children only; an adult's plan must not notice it)
"""


@pytest.fixture(scope="module")
def kb_copy(tmp_path_factory) -> Path:
    """The built-in KB copied, with the test cultures added."""
    root = tmp_path_factory.mktemp("kb") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    for name, text in {"two_hands_please": PREFERS_TWO_HANDS, "formal": FORMAL,
                       "careful": CHILD_ONLY}.items():
        (root / "etiquette" / f"{name}.yaml").write_text(text, encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def planner(kb_copy) -> Planner:
    return Planner(kb=kb_copy)


def hard_failures(plan_dict: dict) -> list[str]:
    return [f"{e['rule']} ({e['hand']})" for e in plan_dict["trace"]
            if e["hard"] and e["status"] == "fail"]


@pytest.mark.parametrize("obj", ["knife", "pen", "bottle"])
def test_a_culture_preferring_two_hands_keeps_the_pick_up_checks(planner, obj):
    """H2G1 is tried first and fails for these; H1G1 then runs with every check it has when
    forced (before, it ran with the pick-up collision switched off and its own trace said
    collision_free: fail)."""
    auto = planner.plan(obj, culture="two_hands_please")
    forced = planner.plan(obj, culture="two_hands_please", mode="h1g1")
    assert auto.to_dict()["modes_tried"][0]["mode"] == "H2G1"
    if auto.feasible:
        assert hard_failures(auto.to_dict()) == []
    if auto.mode == "H1G1":
        assert [g.pose.tolist() for g in auto.robot_grasps] == \
            [g.pose.tolist() for g in forced.robot_grasps]
        # The same trace, but that auto says the preference for two hands was relaxed.
        relaxed = [e.pop("relaxed") for e in auto.to_dict()["trace"] if "relaxed" in e]
        trace = auto.to_dict()["trace"]
        for e in trace:
            if e.pop("relaxed", None) is not None:
                assert e["rule"] == "two_hands_preferred"
        assert relaxed and all(r["asked"] == "H2G1" for r in relaxed)
        assert trace == forced.to_dict()["trace"]


def _same_attempt(a, b) -> None:
    assert (a.mode, a.feasible) == (b.mode, b.feasible)
    # A mode a strict (hard) rule required says so before the mode's own reason.
    assert a.reason == b.reason or (
        "a hard rule that does not bend: " in a.reason and a.reason.endswith(f": {b.reason}"))
    assert [(c.gripper, c.grasp, c.presentation, c.stage) for c in a.chosen] == \
        [(c.gripper, c.grasp, c.presentation, c.stage) for c in b.chosen]
    if a.decision is not None:
        np.testing.assert_array_equal(a.decision.kept, b.decision.kept)


mode_rules = st.lists(
    st.fixed_dictionaries({
        "mode": st.sampled_from(["H1G1", "H2G2", "H2G1"]),
        "hard": st.booleans(),
        "weight": st.sampled_from([0.25, 1.0, 3.0]),
        "roles": st.sampled_from([[], ["adult"], ["elder"]]),
    }),
    min_size=1, max_size=3,
)  # fmt: skip


@settings(max_examples=12, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rules=mode_rules, obj=st.sampled_from(["knife", "mug", "book", "pen", "bottle"]),
       receiver=st.sampled_from(["adult", "elder"]))
def test_each_auto_attempt_is_the_forced_mode_and_feasible_means_every_hard_rule_passes(
    planner, rules, obj, receiver
):
    kb = dataclasses.replace(planner.kb, cultures=dict(planner.kb.cultures))
    kb.cultures["random"] = Culture.model_validate({
        "id": "random", "name": "Random", "rules": [
            {"id": f"m{n}", "kind": "mode", "mode": r["mode"], "hard": r["hard"],
             "weight": r["weight"], "applies": {"receiver_roles": r["roles"]},
             "why": "random"}
            for n, r in enumerate(rules)
        ]})  # fmt: skip
    query = Query(object=obj, receiver=receiver, culture="random")
    chosen, tried, _ = choose(kb, prepare(kb, query, planner.db), "auto")
    for attempt in tried:
        if attempt.graph is None:  # ruled out by a required mode, never run
            continue
        forced = attempt_mode(kb, prepare(kb, query, planner.db), attempt.mode)
        _same_attempt(attempt, forced)
    if chosen.feasible:
        fails = [e["rule"] for e in chosen.trace
                 if e["hard"] and e["status"] == "fail"]
        assert fails == []
        assert chosen.chosen


def test_a_contact_rule_for_children_leaves_an_adult_s_plan_unchanged(planner):
    for obj in ("knife", "hammer", "mug"):
        base = planner.plan(obj).to_dict()
        careful = planner.plan(obj, culture="careful").to_dict()
        for key in ("feasible", "mode", "robot_grasps", "human_grasps", "object_pose"):
            assert careful[key] == base[key], (obj, key)
        inactive = {e["rule"]: e for e in careful["trace"] if e["status"] == "not_applicable"}
        assert "receiver role in child (is adult)" in \
            inactive["robot_keeps_off_the_handle_for_a_child"]["note"]
    child = planner.plan("hammer", culture="careful", receiver="child").to_dict()
    active = {e["rule"] for e in child["trace"] if e["status"] != "not_applicable"}
    if child["feasible"]:
        assert "robot_keeps_off_the_handle_for_a_child" in active
        assert all("handle" not in g["parts"] for g in child["robot_grasps"])


def _cli_plan(capsys, *args: str) -> tuple[int, dict]:
    code = main(["plan", *args, "--json"])
    out, err = capsys.readouterr()
    assert code in (0, 4), err
    return code, json.loads(out)


@pytest.mark.parametrize("obj", ["mug", "bottle"])
def test_the_readme_s_formal_culture_gives_two_hands(capsys, kb_copy, obj):
    code, r = _cli_plan(capsys, obj, "--culture", "formal", "--kb", str(kb_copy))
    assert code == 0 and r["mode"] == "H2G1", r["modes_tried"]
    assert "two_hands_always" in r["mode_reason"]
    assert hard_failures(r) == []
    assert {g["hand"] for g in r["robot_grasps"]} == {"left", "right"}


def test_the_heaviest_soft_mode_rule_wins_and_ties_go_to_kb_order(planner):
    kb = dataclasses.replace(planner.kb, cultures=dict(planner.kb.cultures))

    def culture(*rules):
        kb.cultures["w"] = Culture.model_validate({"id": "w", "name": "W", "rules": [
            {"id": rid, "kind": "mode", "mode": mode, "hard": False, "weight": w,
             "why": "w"} for rid, mode, w in rules]})  # fmt: skip
        from handover.engine.plan.modes import required_mode

        return required_mode(kb, prepare(kb, Query(object="book", culture="w"), planner.db))

    # common's prefer_one_hand (H1G1, weight 0.5) comes first in KB order.
    assert culture(("a", "H2G1", 0.5))[2] == "H1G1"  # a tie: KB order
    assert culture(("a", "H2G1", 0.6))[2] == "H2G1"
    assert culture(("a", "H2G2", 0.6), ("b", "H2G1", 0.7))[2] == "H2G1"
    assert culture(("a", "H2G2", 0.7), ("b", "H2G1", 0.7))[2] == "H2G2"


ONE_HANDED = """\
id: one_arm
name: One-armed robot
hands: [right]
payload_per_hand: 1.5
gripper: parallel_jaw
reach: 0.9
"""

FAR_RECEIVER = """\
id: far_receiver
name: The receiver stands 2.4 m away
support: {position: [0.55, 0.0, 0.75], size: [0.5, 1.0], thickness: 0.03}
receiver: {position: [2.4, 0.0, 0.0], facing: [-1.0, 0.0, 0.0]}
object: {position: [0.33, 0.0]}
"""


@pytest.fixture(scope="module")
def world_planner(kb_copy) -> Planner:
    (kb_copy / "robots" / "one_arm.yaml").write_text(ONE_HANDED, encoding="utf-8")
    (kb_copy / "scenes" / "far_receiver.yaml").write_text(FAR_RECEIVER, encoding="utf-8")
    return Planner(kb=kb_copy)


def test_a_one_handed_robot_plans_one_hand_only(world_planner):
    knife = world_planner.plan("knife", robot="one_arm")
    assert knife.mode == "H1G1" and [g.gripper for g in knife.robot_grasps] == ["right"]
    tray = world_planner.plan("tray", robot="one_arm").to_dict()  # needs two hands
    assert not tray["feasible"]
    tried = {m["mode"]: m["reason"] for m in tray["modes_tried"]}
    assert "has right only" in tried["H2G1"] or "not tried" in tried["H2G1"]
    forced = world_planner.plan("tray", robot="one_arm", mode="h2g1")
    assert not forced.feasible and "needs 2 robot hands" in forced.reason


def test_a_handover_point_beyond_the_robot_s_reach_is_refused_with_the_distance(world_planner):
    plan = world_planner.plan("knife", scene="far_receiver")
    assert not plan.feasible
    # The receiver stands 2.4 m away; the nearest place they reach (within_receiver_reach: 90 %
    # of their arm from the receiving shoulder) is that much nearer the robot than the
    # shoulder, horizontally, on a 6 cm grid.
    assert "beyond its reach of 0.9 m" in plan.reason and "within_robot_reach" in plan.reason
    distance = float(plan.reason.split("the best place the receiver can reach is ")[1].split()[0])
    lm = plan.context.world.receiver
    shoulder = np.hypot(*lm.right_shoulder[:2])
    assert distance == pytest.approx(shoulder - 0.9 * lm.arm_reach, abs=0.06)


@pytest.mark.parametrize("args", [("knife",), ("mug", "--receiver", "elder", "--culture",
                                                 "korean"), ("tray", "--mode", "h1g1")])
def test_the_facade_s_json_is_the_cli_s_byte_for_byte(capsys, args):
    code = main(["plan", *args, "--json"])
    out, err = capsys.readouterr()
    kwargs = dict(zip((a.lstrip("-") for a in args[1::2]), args[2::2], strict=True))
    plan = Planner().plan(args[0], motion=True, **kwargs)  # as the CLI, unless --no-motion
    assert out == plan.to_json()
    assert code == (0 if plan.feasible else 4)


def test_a_culture_with_no_hard_rule_plans(planner):
    """Every rule soft: nothing filters, the best-scored grasp is chosen (no crash on an empty
    set of hard rules)."""
    kb = dataclasses.replace(planner.kb, cultures=dict(planner.kb.cultures))
    kb.cultures["common"] = Culture.model_validate({  # the base culture itself, all soft
        "id": "common", "name": "Lenient", "rules": [
            {"id": "good_grip", "kind": "quality", "hard": False, "min_quality": 0.0,
             "why": "prefer good grasps"}]})  # fmt: skip
    chosen, _, _ = choose(kb, prepare(kb, Query(object="ball"), planner.db), "h1g1")
    assert chosen.feasible and chosen.decision.first_fail.max() == -1
