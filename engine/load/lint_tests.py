"""Semantic checks of a KB test file (part of ``handover kb validate`` and ``handover kb
test``, see :mod:`handover.engine.load.lint`): every id a case's query names exists, and every
axis, part, tag and rule its expectation names exists for the case's object and culture.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import TYPE_CHECKING

from handover.engine.spec.query import DEFAULTS
from handover.engine.store.cultures import _resolve, object_tags

if TYPE_CHECKING:
    from handover.engine.errors import KBIssue
    from handover.engine.spec.schema import KBModel, KBTestFile
    from handover.engine.store.kb import KB

__all__ = ["lint_tests"]


_QUERY_KINDS = {"receiver": "receivers", "culture": "etiquette", "scene": "scenes",
                "gripper": "grippers", "robot": "robots"}


def lint_tests(kb: KB, test_file: KBTestFile, failed: Iterable[str] = ()) -> Iterator[KBIssue]:
    """A test file's cases against the KB: every id a query names exists, every axis, part,
    tag and rule an expectation names exists for the case's object and culture (a misspelt
    name would make ``robot_parts_none`` pass, or a case fail for the wrong reason)."""
    failed = set(failed)
    names: dict[str, KBModel] = {}
    for case in test_file.cases:
        if case.name in names:
            first = names[case.name].source.line
            yield kb.issue(case, f"two cases named '{case.name}' (the first at line {first})",
                           "name")
        names.setdefault(case.name, case)
        q, expect = case.query, case.expect
        for field, kind in _QUERY_KINDS.items():
            item = getattr(q, field)
            attr = kind if kind != "etiquette" else "cultures"
            if item is not None and kind not in failed and item not in getattr(kb, attr):
                known = ", ".join(sorted(getattr(kb, attr))) or "none"
                yield kb.issue(q, f"unknown {field} '{item}' (known: {known})", field)
        if "objects" in failed:
            continue
        obj = kb.objects.get(q.object)
        if obj is None:
            known = ", ".join(sorted(kb.objects)) or "none"
            yield kb.issue(q, f"unknown object '{q.object}' (known: {known})", "object")
            continue
        if q.task is not None and q.task not in obj.tasks:
            yield kb.issue(q, f"object '{obj.id}' has no task '{q.task}' (its tasks: "
                           f"{', '.join(sorted(obj.tasks)) or 'none'})", "task")
        for axis in expect.axes:
            if axis not in obj.axes:
                yield kb.issue(expect, f"object '{obj.id}' has no axis '{axis}' (its axes: "
                               f"{', '.join(sorted(obj.axes)) or 'none'})", "axes", axis)
        known_names = set(obj.parts) | object_tags(obj)
        for field in ("receiver_parts_any", "robot_parts_none"):
            for i, name in enumerate(getattr(expect, field)):
                if name not in known_names:
                    yield kb.issue(expect, f"object '{obj.id}' has no part or tag '{name}' "
                                   f"(parts: {', '.join(obj.parts)})", field, i)
        culture = q.culture or DEFAULTS["culture"]
        if expect.rules and "etiquette" not in failed and culture in kb.cultures:
            in_force = {r.rule.id for r in _resolve(kb, culture)[0]}
            for rule_id in expect.rules:
                if rule_id not in in_force:
                    yield kb.issue(expect, f"rule '{rule_id}' is not in force in culture "
                                   f"'{culture}'", "rules", rule_id)
