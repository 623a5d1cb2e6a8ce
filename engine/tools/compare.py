"""The same handover across cultures, receivers, tasks and grippers, side by side, with a
rule-by-rule diff of each combination against the first (``handover compare``).

>>> from handover import Planner
>>> report = compare(Planner(), "mug", cultures=["common", "korean"],
...                  receivers=["adult", "elder"])
>>> [(c["culture"], c["receiver"], c["mode"]) for c in report["combinations"]]
[('common', 'adult', 'H1G1'), ('common', 'elder', 'H1G1'), ('korean', 'adult', 'H1G1'), \
('korean', 'elder', 'H2G1')]
>>> report["diffs"][-1]["decided"][0]["rule"]
'two_hands_for_elders'

A diff (combination B against the baseline A) lists the rules that became active or inactive
(a rule not in force in a culture counts as inactive, reason "not in culture X"), the rules
that decided the difference, and the thresholds that changed, each with its source
file:line. The rules that decided, in this order: the mode rules that chose a different mode
(named by ``mode_reason``), the rules that removed the last candidates of an infeasible
plan, hard rules that pass in one chosen grasp's trace and fail in the other, then the soft
rule whose weighted score (weight x score in the chosen grasp's trace) differs the most.
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING, Any

from handover.engine.plan.situation import receiver_directions
from handover.engine.tools.coverage import decided_rules
from handover.engine.tools.kbtest import angle_between

if TYPE_CHECKING:
    from handover.engine.planner import Planner

__all__ = ["compare", "presented_axes", "rule_diff"]

DIMENSIONS = ("culture", "receiver", "task", "gripper")


def presented_axes(result: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Each named axis of the presented object as its nearest receiver-frame direction:
    ``{axis: {"toward": direction, "deg": angle to it}}`` ({} when infeasible)."""
    axes = (result.get("presentation") or {}).get("axes_world") or {}
    r = result["receiver"]
    directions = receiver_directions(r["position"], r["facing"], r["dominant_hand"])
    out = {}
    for axis, vec in axes.items():
        # dominant/nondominant restate left/right: name the side, the receiver is known
        angles = {d: angle_between(vec, v) for d, v in directions.items()
                  if not d.startswith(("receiver_dominant", "receiver_nondominant"))}
        best = min(angles, key=lambda d: (round(angles[d], 6), d))
        out[axis] = {"toward": best, "deg": round(angles[best], 1)}
    return out


def _summary(combo: dict[str, Any], result: dict[str, Any]) -> dict[str, Any]:
    return {
        **combo,
        "outcome": result["outcome"],
        "mode": result["mode"],
        "reason": result.get("reason"),
        "mode_reason": result.get("mode_reason"),
        "robot_grasps": [{"hand": g["hand"], "parts": list(g["parts"]),
                          "stage": g.get("stage", "handover")}
                         for g in result["robot_grasps"]],
        "receiver_parts": [h["part"] for h in result["human_grasps"]],
        "axes": presented_axes(result),
    }


def _label(combo: dict[str, Any], dims: list[str]) -> str:
    return "/".join(str(combo[d]) for d in dims)


def _handover_trace(result: dict[str, Any]) -> dict[str, list[dict]]:
    """rule id -> its entries in the chosen grasps' traces at the handover."""
    out: dict[str, list[dict]] = {}
    for t in result["trace"]:
        if t.get("stage", "handover") == "handover":
            out.setdefault(t["rule"], []).append(t)
    return out


def _weighted(entries: list[dict]) -> float | None:
    """Mean weight x score of a soft rule over the chosen grasps (None: not scored)."""
    scored = [e["weight"] * e["score"] for e in entries
              if e["status"] == "scored" and e["score"] is not None and e["weight"]]
    return sum(scored) / len(scored) if scored else None


def rule_diff(a: dict[str, Any], b: dict[str, Any]) -> dict[str, Any]:
    """How the rules of plan ``b`` differ from those of plan ``a`` (both
    ``PlanResult.to_dict()``): ``became_active``, ``became_inactive``, ``decided``,
    ``thresholds``, each a list of ``{"rule", "source", "culture", ...}``."""
    rules_a = {r["rule"]: r for r in a.get("rules", [])}
    rules_b = {r["rule"]: r for r in b.get("rules", [])}
    culture_a, culture_b = a["query"]["culture"], b["query"]["culture"]

    def state(rules: dict, rule_id: str, culture: str) -> str:
        r = rules.get(rule_id)
        if r is None:
            return f"not in culture {culture}"
        return "active" if r["active"] else f"inactive: {r['reason']}"

    def entry(rule_id: str, **extra: Any) -> dict[str, Any]:
        r = rules_b.get(rule_id) or rules_a[rule_id]
        return {"rule": rule_id, "source": r["source"], "culture": r["culture"], **extra}

    became_active, became_inactive = [], []
    for rule_id in list(rules_a) + [r for r in rules_b if r not in rules_a]:
        was, now = state(rules_a, rule_id, culture_a), state(rules_b, rule_id, culture_b)
        if (was == "active") != (now == "active"):
            target = became_active if now == "active" else became_inactive
            target.append(entry(rule_id, was=was, now=now))

    decided: list[dict[str, Any]] = []
    if a["mode"] != b["mode"] or a["outcome"] != b["outcome"]:
        for side, result in (("to", b), ("from", a)):
            for rule_id in sorted(decided_rules(result)):
                if rule_id in rules_b or rule_id in rules_a:
                    if not any(d["rule"] == rule_id for d in decided):
                        decided.append(entry(rule_id, how=_how(result, rule_id), side=side))
    trace_a, trace_b = _handover_trace(a), _handover_trace(b)
    thresholds = []
    best_soft: tuple[float, dict[str, Any]] | None = None
    for rule_id in [r for r in trace_b if r in trace_a]:
        ea, eb = trace_a[rule_id], trace_b[rule_id]
        sa, sb = {e["status"] for e in ea}, {e["status"] for e in eb}
        if ("fail" in sa) != ("fail" in sb) and ea[0]["hard"]:
            if not any(d["rule"] == rule_id for d in decided):
                decided.append(entry(rule_id, how=f"{'/'.join(sorted(sa))} -> "
                                                  f"{'/'.join(sorted(sb))}"))
        ta = {e["threshold"] for e in ea if e["threshold"]}
        tb = {e["threshold"] for e in eb if e["threshold"]}
        if ta and tb and ta != tb:
            thresholds.append(entry(rule_id, was=sorted(ta), now=sorted(tb)))
        wa, wb = _weighted(ea), _weighted(eb)
        if wa is not None and wb is not None and abs(wb - wa) > 1e-6:
            if best_soft is None or abs(wb - wa) > best_soft[0]:
                best_soft = (abs(wb - wa), entry(
                    rule_id, how=f"weighted score {wa:.3f} -> {wb:.3f}"))
    if best_soft is not None and not any(d["rule"] == best_soft[1]["rule"] for d in decided):
        decided.append(best_soft[1])
    return {"became_active": became_active, "became_inactive": became_inactive,
            "decided": decided, "thresholds": thresholds}


def _how(result: dict[str, Any], rule_id: str) -> str:
    if result["feasible"]:
        return f"chose {result['mode']}"
    return f"made {result['query']['object']} infeasible"


def compare(planner: Planner, obj: str, cultures: list[str | None] | None = None,
            receivers: list[str | None] | None = None, tasks: list[str | None] | None = None,
            grippers: list[str | None] | None = None, scene: str | None = None,
            mode: str = "auto") -> dict[str, Any]:
    """Plan ``obj`` for every combination of ``cultures`` x ``receivers`` x ``tasks`` x
    ``grippers`` (None or [] for one: the default) and diff each against the first.

    Returns ``{"object", "combinations": [summary], "diffs": [{"from", "to", "mode",
    "outcome", ...rule_diff}]}``; a summary holds the combination, outcome, mode, reason,
    the chosen grasps' parts, the receiver's parts and the presented axes."""
    dims = [cultures or [None], receivers or [None], tasks or [None], grippers or [None]]
    combos = [dict(zip(DIMENSIONS, values, strict=True)) for values in itertools.product(*dims)]
    results = []
    for combo in combos:
        plan = planner.plan(obj, culture=combo["culture"], receiver=combo["receiver"],
                            task=combo["task"], gripper=combo["gripper"], scene=scene,
                            mode=mode)
        result = plan.to_dict()
        q = result["query"]
        resolved = {d: q.get(d) for d in DIMENSIONS}
        results.append((resolved, result))
    summaries = [_summary(combo, result) for combo, result in results]
    diffs = []
    varying = [d for d in DIMENSIONS if len({str(c[d]) for c, _ in results}) > 1] \
        or ["culture", "receiver"]
    base_combo, base = results[0]
    for combo, result in results[1:]:
        diffs.append({
            "from": _label(base_combo, varying), "to": _label(combo, varying),
            "outcome": [base["outcome"], result["outcome"]],
            "mode": [base["mode"], result["mode"]],
            **rule_diff(base, result),
        })  # fmt: skip
    return {"object": obj, "combinations": summaries, "diffs": diffs}
