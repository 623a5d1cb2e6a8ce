"""What ``kb show`` computes (engine.kbshow): the same reading of rules as the compiler."""

from __future__ import annotations

import pytest

from handover.engine.compiler import compile
from handover.engine.errors import UsageError
from handover.engine.etiquette import resolve_culture
from handover.engine.kbshow import item_kind, not_applicable, object_view, show_item
from handover.engine.prepare import prepare
from handover.engine.query import Query


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
