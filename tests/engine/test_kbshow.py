"""What ``kb show`` computes (engine.tools.kbshow): the same reading of rules as the compiler."""

from __future__ import annotations

import pytest

from handover.engine.errors import UsageError
from handover.engine.plan.compiler import compile
from handover.engine.plan.prepare import prepare
from handover.engine.spec.query import Query
from handover.engine.store.cultures import resolve_culture
from handover.engine.tools.kbshow import item_kind, not_applicable, object_view, show_item


def test_every_kind_judges_every_builtin_object(builtin_kb):
    # Each kind's not_applicable reads only what an object alone tells (no geometry built).
    for obj in builtin_kb.objects.values():
        for culture in builtin_kb.cultures:
            for rr in resolve_culture(builtin_kb, culture):
                reason = not_applicable(rr.rule, obj)
                assert reason is None or isinstance(reason, str)


@pytest.mark.parametrize(("obj", "task"), [("knife", None), ("mug", None), ("hammer", "pull_nail")])
def test_rules_that_cannot_apply_are_inactive_in_the_compiled_plan(builtin_kb, obj, task):
    view = object_view(builtin_kb, builtin_kb.object(obj), "common")
    skipped = {r["id"]: r["reason"] for r in view["not_applicable"]}
    ctx = prepare(builtin_kb, Query(object=obj, task=task))
    inactive = {c.id: c.reason for c in compile(builtin_kb, ctx, "H1G1").inactive}
    for rule_id, reason in skipped.items():
        assert rule_id in inactive, (rule_id, reason)
        if not reason.startswith("needs "):  # the kind's own reason, as the compiler gives it
            assert inactive[rule_id] == reason


def test_task_rule_applies_only_to_objects_with_a_presented_task(builtin_kb):
    def skipped(obj: str) -> set[str]:
        view = object_view(builtin_kb, builtin_kb.object(obj), "common")
        return {r["id"] for r in view["not_applicable"]}

    assert "task_presentation" not in skipped("hammer")
    assert "task_presentation" in skipped("mug")


def test_kind_of_an_id(builtin_kb):
    assert item_kind(builtin_kb, "knife") == "object"
    assert show_item(builtin_kb, "adult")["kind"] == "receiver"
    with pytest.raises(UsageError, match="unknown kind"):
        item_kind(builtin_kb, "knife", "tool")
    with pytest.raises(UsageError, match="knife"):
        item_kind(builtin_kb, "spoon")


def test_a_culture_lists_the_hazard_tags_that_have_rules(builtin_kb):
    tags = {t["tag"]: t for t in show_item(builtin_kb, "common")["tags"]}
    for hazard in ("sharp", "pointed", "needle", "hot", "liquid", "open_container", "fragile",
                   "nozzle", "heavy", "small"):
        assert tags[hazard]["hazard"], hazard
        assert tags[hazard]["meaning"]
    assert {"needle_tip_away", "receiver_avoids_needle", "giver_avoids_needle",
            "no_hazards_to_young_children"} <= set(tags["needle"]["rules"])
    assert not tags["handle"]["hazard"]
    # hazards first
    flags = [t["hazard"] for t in show_item(builtin_kb, "common")["tags"]]
    assert flags == sorted(flags, reverse=True)


def test_an_object_lists_its_tags_that_have_rules(make_kb):
    from handover.engine.load.loader import load_kb

    kb = load_kb(make_kb({"objects/stick.yaml": """\
        id: stick
        name: Stick
        mass: 0.1
        tags: [garden]
        geometry:
          primitives:
            - {shape: box, part: grip, extents: [0.1, 0.02, 0.02], position: [-0.05, 0, 0]}
            - {shape: box, part: point, extents: [0.1, 0.01, 0.01], position: [0.05, 0, 0]}
        parts:
          grip: {tags: [handle]}
          point: {tags: [sharp]}
        axes:
          tip: [1, 0, 0]
        """}))
    view = show_item(kb, "stick")
    rows = {t["tag"]: t for t in view["tags_with_rules"]}
    assert set(rows) == {"sharp"}  # handle and garden: no rule of the minimal KB names them
    assert rows["sharp"]["rules"] == ["no_sharp", "tip_away"] and rows["sharp"]["hazard"]


def test_kb_show_prints_the_hazard_tags_and_a_rule_s_fallback_and_warning(capsys):
    from handover.engine.cli.app import main

    assert main(["kb", "show", "common"]) == 0
    out = capsys.readouterr().out
    assert "hazard tags with rules (named by a safety rule):" in out
    assert "  nozzle: nozzle_not_at_receiver" in out
    assert "fallback: place" in out and "warns: A sharp object is handed to a child" in out
    assert main(["kb", "show", "knife"]) == 0
    out = capsys.readouterr().out
    assert "hazard tags of knife with rules in common" in out
    assert "  sharp: receiver_avoids_sharp" in out
