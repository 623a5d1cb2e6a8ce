"""Run KB test cases (``kb/tests/*.yaml``, :mod:`engine.spec.kbtestspec`) through the Python
facade and check each expectation against the plan's result.

>>> from handover.engine.load.loader import load_kb
>>> kb = load_kb()
>>> report = run_tests(kb, case_files(kb))
>>> report.failed
0

Each case is planned with one :class:`handover.Planner` for the KB (the result is what
``handover plan --json`` prints). A failed expectation gives ``{"expect", "expected",
"got", "message"}``; a failed case also carries the trace lines that decided it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.errors import KBError, UsageError
from handover.engine.plan.situation import receiver_directions
from handover.engine.spec.kbtestspec import KBTestCase, KBTestFile, parse_comparison

if TYPE_CHECKING:
    from handover.engine.planner import Plan, Planner
    from handover.engine.spec.schema import ObjectSpec
    from handover.engine.store.kb import KB

__all__ = ["CaseRun", "KBTestReport", "case_files", "run_tests", "check_case", "angle_between"]

_OPS = {
    ">=": np.greater_equal,
    "<=": np.less_equal,
    ">": np.greater,
    "<": np.less,
}


@dataclass
class CaseRun:
    """One case run: where it is written (``file`` relative to the KB root, or as given),
    whether it passed, each failed expectation, what the plan was (``got``: outcome, mode,
    parts), the trace lines that decided a failed case, and the plan itself (for coverage)."""

    file: str
    line: int
    name: str
    passed: bool
    failures: list[dict[str, Any]]
    got: dict[str, Any]
    decisive: list[str] = field(default_factory=list)
    plan: Plan | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {"file": self.file, "line": self.line, "name": self.name, "passed": self.passed,
                "failures": self.failures, "got": self.got, "decisive": self.decisive}


@dataclass
class KBTestReport:
    """Every case run, in file order then case order."""

    cases: list[CaseRun]

    @property
    def passed(self) -> int:
        return sum(c.passed for c in self.cases)

    @property
    def failed(self) -> int:
        return len(self.cases) - self.passed


def case_files(kb: KB, paths: list[Path] | None = None) -> list[KBTestFile]:
    """The test files to run: the KB's own (``tests/``, loaded and checked with the KB) when
    ``paths`` is empty, else the files (``.yaml``/``.yml``) at or below ``paths``.

    A file outside the KB is validated and checked against the KB like a KB file; its
    problems raise KBError (file:line:col). A path that does not exist is a UsageError.
    """
    if not paths:
        return list(kb.tests.values())
    from handover.engine.load.lint_tests import lint_tests
    from handover.engine.store.validate import validate_document
    from handover.engine.store.yamlpos import YAML_SUFFIXES, parse_yaml

    found: list[Path] = []
    for path in paths:
        if path.is_dir():
            found.extend(sorted(p for p in path.rglob("*") if p.suffix in YAML_SUFFIXES))
        elif path.is_file():
            found.append(path)
        else:
            raise UsageError(f"test file or folder '{path}' does not exist")
    loaded = {(kb.root / tf.source.file).resolve(): tf for tf in kb.tests.values()}
    files: list[KBTestFile] = []
    errors = []
    for path in found:
        if path.resolve() in loaded:
            files.append(loaded[path.resolve()])
            continue
        name = _display(path, kb.root)
        parsed = parse_yaml(path, name)
        if isinstance(parsed, list):
            errors.extend(parsed)
            continue
        data, marks = parsed
        model, issues = validate_document(data, marks, KBTestFile, name)
        errors.extend(issues)
        if model is not None:
            kb.marks[name] = marks
            issues = [i for i in lint_tests(kb, model) if i.severity == "error"]
            errors.extend(issues)
            if not issues:
                files.append(model)  # type: ignore[arg-type]
    if errors:
        raise KBError(errors)
    return files


def _display(path: Path, root: Path) -> str:
    """``path`` relative to the KB root when inside it, else as given."""
    try:
        return path.resolve().relative_to(root).as_posix()
    except ValueError:
        return os.fspath(path)


def run_tests(kb: KB, files: list[KBTestFile], planner: Planner | None = None,
              select: str | None = None) -> KBTestReport:
    """Plan every case of ``files`` (those whose name contains ``select``, when given) with
    one ``Planner`` for ``kb`` and check its expectations."""
    from handover.engine.planner import Planner

    planner = planner or Planner(kb)
    runs = []
    for tf in files:
        for case in tf.cases:
            if select is not None and select.lower() not in case.name.lower():
                continue
            q = case.query
            plan = planner.plan(q.object, task=q.task, receiver=q.receiver, culture=q.culture,
                                scene=q.scene, mode=q.mode, gripper=q.gripper, robot=q.robot)
            result = plan.to_dict()
            failures = check_case(case, result, kb.object(q.object))
            runs.append(CaseRun(
                file=case.source.file, line=case.source.line, name=case.name,
                passed=not failures, failures=failures, got=_got(result),
                decisive=_decisive(case, result) if failures else [], plan=plan,
            ))  # fmt: skip
    return KBTestReport(runs)


def _got(result: dict[str, Any]) -> dict[str, Any]:
    return {
        "outcome": result["outcome"],
        "mode": result["mode"],
        "robot_parts": [list(g["parts"]) for g in result["robot_grasps"]],
        "receiver_parts": [h["part"] for h in result["human_grasps"]],
    }


def angle_between(u: Any, v: Any) -> float:
    """Degrees (0-180) between two (3,) vectors."""
    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    c = float(np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v)))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _fail(expect: str, expected: Any, got: Any, message: str) -> dict[str, Any]:
    return {"expect": expect, "expected": expected, "got": got, "message": message}


def _matches(obj: ObjectSpec, part: str, names: list[str]) -> bool:
    """Whether ``part`` is one of ``names`` or carries one of them as a tag."""
    tags = set(obj.parts[part].tags) if part in obj.parts else set()
    return part in names or bool(tags & set(names))


def check_case(case: KBTestCase, result: dict[str, Any], obj: ObjectSpec) -> list[dict]:
    """Every expectation of ``case`` that ``result`` (``PlanResult.to_dict()``) does not meet,
    in the order the file writes them; [] when the case passes."""
    e = case.expect
    out: list[dict] = []
    if e.outcome is not None and result["outcome"] != e.outcome:
        why = f": {result['reason']}" if result.get("reason") else ""
        out.append(_fail("outcome", e.outcome, result["outcome"],
                         f"outcome {result['outcome']}, expected {e.outcome}{why}"))
    if e.feasible is not None and result["feasible"] != e.feasible:
        why = f": {result['reason']}" if result.get("reason") else ""
        out.append(_fail("feasible", e.feasible, result["feasible"],
                         f"feasible {result['feasible']}, expected {e.feasible}{why}"))
    if e.mode is not None and result["mode"] != e.mode:
        why = result.get("mode_reason") or result.get("reason") or ""
        out.append(_fail("mode", e.mode, result["mode"],
                         f"mode {result['mode']}, expected {e.mode}" + (f": {why}" if why else "")))
    if e.receiver_parts_any:
        parts = [h["part"] for h in result["human_grasps"]]
        if not parts or not all(_matches(obj, p, e.receiver_parts_any) for p in parts):
            out.append(_fail("receiver_parts_any", e.receiver_parts_any, parts,
                             f"the receiver holds {', '.join(parts) or 'nothing'}, expected a "
                             f"part named or tagged {' or '.join(e.receiver_parts_any)}"))
    if e.robot_parts_none:
        parts = sorted({p for g in result["robot_grasps"] for p in g["parts"]})
        bad = [p for p in parts if _matches(obj, p, e.robot_parts_none)]
        if bad:
            out.append(_fail("robot_parts_none", e.robot_parts_none, parts,
                             f"the robot touches {', '.join(bad)}, expected no part named or "
                             f"tagged {' or '.join(e.robot_parts_none)}"))
    out.extend(_check_axes(case, result))
    out.extend(_check_rules(case, result))
    warnings = result.get("warnings", [])
    for text in e.warnings_contain:
        if not any(text in w for w in warnings):
            out.append(_fail("warnings_contain", text, warnings,
                             f"no warning contains '{text}'"))
    reason = result.get("reason") or ""
    for text in e.reason_contains:
        if text not in reason:
            out.append(_fail("reason_contains", text, reason,
                             f"the reason does not contain '{text}'"))
    return out


def _check_axes(case: KBTestCase, result: dict[str, Any]) -> list[dict]:
    out = []
    axes_world = (result.get("presentation") or {}).get("axes_world") or {}
    receiver = result["receiver"]
    directions = receiver_directions(receiver["position"], receiver["facing"],
                                     receiver["dominant_hand"])
    for axis, wanted in case.expect.axes.items():
        for direction, text in wanted.items():
            op, bound = parse_comparison(text)
            name = f"axes.{axis}.{direction}"
            if axis not in axes_world:
                out.append(_fail(name, text, None,
                                 f"no presented axis '{axis}' (outcome {result['outcome']})"))
                continue
            angle = angle_between(axes_world[axis], directions[direction])
            if not _OPS[op](round(angle, 6), bound):
                out.append(_fail(name, text, round(angle, 3),
                                 f"angle({axis}, {direction}) = {angle:.1f} deg, expected "
                                 f"{op} {bound:g}"))
    return out


def _check_rules(case: KBTestCase, result: dict[str, Any]) -> list[dict]:
    out = []
    trace = [t for t in result["trace"] if t.get("stage", "handover") == "handover"]
    for rule_id, status in case.expect.rules.items():
        got = sorted({t["status"] for t in trace if t["rule"] == rule_id})
        if got != [status]:
            shown = ", ".join(got) if got else "absent (no chosen grasp)"
            out.append(_fail(f"rules.{rule_id}", status, got or None,
                             f"rule {rule_id} is {shown}, expected {status}"))
    return out


def _decisive(case: KBTestCase, result: dict[str, Any], limit: int = 8) -> list[str]:
    """The trace lines that decided the plan, for a failed case: the reason (infeasible) or
    why the mode was chosen, then the chosen grasps' failing rules and the rules the case's
    expectations name, each with its source."""
    lines = []
    if result.get("reason"):
        lines.append(f"reason: {result['reason']}")
    elif result.get("mode_reason"):
        lines.append(f"mode {result['mode']}: {result['mode_reason']}")
    axes = set(case.expect.axes)
    seen = set()
    for t in result["trace"]:
        named = t["rule"] in case.expect.rules
        about_axis = t["kind"] == "axis" and any(a in t["threshold"] for a in axes)
        if t["status"] not in ("fail", "unknown") and not named and not about_axis:
            continue
        key = (t["rule"], t["status"], t["hand"])
        if key in seen:
            continue
        seen.add(key)
        measured = "" if t["measured"] is None else f", measured {t['measured']:g} {t['unit']}"
        threshold = f" vs {t['threshold']}" if t["threshold"] else ""
        lines.append(f"{t['hand']} grasp {t['grasp']}: {t['rule']} {t['status']}{measured}"
                     f"{threshold} ({t['source']})")
    return lines[:limit]
