"""Rule coverage of a set of planned cases (``handover kb test --coverage``): for every rule
of every culture, in how many cases it applied, rejected candidates, and decided.

Counts, per rule (a rule of culture C counts only in cases planned in C or in a culture that
extends C without overriding the rule):

applied
    cases where the rule was active: in force in the case's culture and its conditions
    (``applies``, the object's axes, ...) held, so it judged the candidates (the result's
    ``rules[].active``).
rejected
    cases where it rejected at least one candidate (``candidates.rejected_by``: the first
    hard rule a candidate failed, in evaluation order).
decided
    cases where it made the difference:

    - a hard rule in an infeasible plan that is in one of the smallest sets of rules that
      removed the last candidates (``candidates.blocking_sets``), or a mode rule the reason
      names;
    - a ``mode`` rule that chose the mode of a feasible plan (``mode_reason`` names it);
    - a hard rule that alone rejected at least one candidate of the chosen mode: no other hard
      rule judged on that candidate failed, so without this rule the planner could have
      chosen it (reach and collision rules are judged only on candidates that passed every
      hard rule before them, so a candidate failing a cheaper rule counts with the rules
      judged on it);
    - the soft rule whose weighted score most favours the chosen candidate over the next best
      one (``alternatives[0]``), when the chosen one scores strictly higher.

Rules that never applied are listed, and so are the tags objects carry that no rule reads.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from handover.engine.store.kb import KB
    from handover.engine.tools.kbtest import CaseRun

__all__ = ["rule_coverage", "decided_rules"]


def _keys(kb: KB) -> dict[tuple[str, str], str]:
    """(culture, rule id) -> coverage key: the rule id, or ``culture.rule`` where one id is
    used in several cultures."""
    ids: dict[str, int] = {}
    for culture in kb.cultures.values():
        for rule in culture.rules:
            ids[rule.id] = ids.get(rule.id, 0) + 1
    return {(c.id, r.id): r.id if ids[r.id] == 1 else f"{c.id}.{r.id}"
            for c in kb.cultures.values() for r in c.rules}


def decided_rules(result: dict[str, Any], decision: Any = None) -> set[str]:
    """The ids of the rules that decided a plan (see the module docstring).

    result : ``PlanResult.to_dict()``. decision : the chosen mode's decision table
    (``engine.plan.evaluate.Decision``) or None (then the sole-rejecter and soft-rule tests are
    skipped).
    """
    active = {r["rule"]: r for r in result.get("rules", []) if r.get("active")}
    out: set[str] = set()
    texts = [result.get("mode_reason") or ""]
    if not result["feasible"]:
        texts.append(result.get("reason") or "")
        texts.extend(t.get("reason") or "" for t in result.get("modes_tried", []))
        for entry in result["candidates"].get("blocking_sets", []):
            out.update(entry["rules"])
    for rule_id, r in active.items():
        if r["kind"] == "mode" and any(f"rule {rule_id} " in t for t in texts):
            out.add(rule_id)
    if decision is None or not result["feasible"]:
        return out
    fails = np.asarray(decision.fails)
    if fails.size:
        sole = fails.sum(axis=1) == 1
        for h in np.unique(np.argmax(fails[sole], axis=1)):
            out.add(decision.hard[int(h)].id)
    out.update(_soft_decider(result, decision))
    return out


def _soft_decider(result: dict[str, Any], decision: Any) -> set[str]:
    chosen = [g for g in result["robot_grasps"] if g.get("stage", "handover") == "handover"]
    alternatives = result.get("alternatives") or []
    pres = (result.get("presentation") or {}).get("index")
    if not chosen or not alternatives or pres is None or not decision.soft:
        return set()
    gi, pk = np.asarray(decision.gi), np.asarray(decision.pk)

    def row(grasp: int, presentation: int) -> int | None:
        hit = np.flatnonzero((gi == grasp) & (pk == presentation))
        return int(hit[0]) if len(hit) else None

    a = row(int(chosen[0]["id"]), int(pres))
    b = row(int(alternatives[0]["grasp"]), int(alternatives[0]["presentation"]))
    if a is None or b is None or not decision.score[a] > decision.score[b]:
        return set()
    weights = np.array([c.rule.weight for c in decision.soft])
    gain = weights * (np.nan_to_num(decision.soft_scores[a]) - np.nan_to_num(
        decision.soft_scores[b]))
    best = int(np.argmax(gain))
    return {decision.soft[best].id} if gain[best] > 0 else set()


def rule_coverage(kb: KB, runs: list[CaseRun]) -> dict[str, Any]:
    """Coverage of ``runs`` (cases planned, each with its ``plan``).

    Returns ``{"rules": {key: {"culture", "source", "kind", "hard", "applied", "rejected",
    "decided"}}, "never_applied": [key], "unread_tags": [tag]}``, rules in culture then file
    order (``key``: the rule id, or ``culture.rule`` where an id repeats across cultures).
    """
    from handover.engine.load.lint import rule_tags
    from handover.engine.store.cultures import object_tags
    from handover.engine.store.hazards import tag_families

    keys = _keys(kb)
    rules: dict[str, dict[str, Any]] = {}
    for culture in kb.cultures.values():
        for rule in culture.rules:
            rules[keys[(culture.id, rule.id)]] = {
                "culture": culture.id, "source": str(rule.source), "kind": rule.kind,
                "hard": rule.hard, "applied": 0, "rejected": 0, "decided": 0,
            }  # fmt: skip
    for run in runs:
        if run.plan is None:
            continue
        result = run.plan.to_dict()
        rejected = result["candidates"].get("rejected_by", {})
        decided = decided_rules(result, getattr(run.plan.attempt, "decision", None))
        for r in result.get("rules", []):
            key = keys.get((r["culture"], r["rule"]))
            if key is None or not r.get("active"):
                continue
            rules[key]["applied"] += 1
            rules[key]["rejected"] += int(rejected.get(r["rule"], 0) > 0)
            rules[key]["decided"] += int(r["rule"] in decided)
    read = {tag for c in kb.cultures.values() for rule in c.rules for tag, _ in rule_tags(rule)}
    carried = set().union(set(), *(object_tags(o) for o in kb.objects.values()))
    families = tag_families(kb)  # a tag is read when a rule reads it or a tag it implies
    return {
        "rules": rules,
        "never_applied": [k for k, v in rules.items() if v["applied"] == 0],
        "unread_tags": sorted(t for t in carried if not families.expand([t]) & read),
    }
