"""The words of a plan's recording: a markdown document per stage (what happened, which
rules removed how many candidates, the chosen grasps) and the text log lines of the rule
trace. Plain strings, no rerun; :mod:`engine.report.rerun.writer` logs them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.report.rerun.stages import (
    CLASS_RULE_BASE,
    ENTITY_CANDIDATES,
    STAGE_HELP,
    STAGES,
    RowStats,
    hex_colour,
    kind_colour,
)

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.evaluate import Decision
    from handover.engine.plan.records import RobotGrasp
    from handover.engine.report.result import PlanResult

__all__ = ["LEVELS", "stage_documents", "log_entries"]

LEVELS = {"pass": "INFO", "scored": "INFO", "fail": "WARN", "unknown": "WARN",
          "not_applicable": "DEBUG"}


def _fmt(value: Any, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}f}".rstrip("0").rstrip(".") or "0"
    return str(value)


def _trace_line(e: dict) -> str:
    """One rule decision of one chosen grasp, as a log line."""
    hard = "hard" if e.get("hard") else f"soft x{_fmt(e.get('weight'))}"
    head = f"grasp {e.get('grasp')} ({e.get('hand')} hand)"
    if e.get("stage") == "refuse":
        head = "refused"
    elif e.get("stage"):
        head += f" [{e['stage']}]"
    status = str(e.get("status"))
    body = f"{e.get('rule')} ({e.get('kind')}, {hard}): {status}"
    if status == "not_applicable":
        body += f" - {e.get('note') or ''}".rstrip(" -")
    elif status == "unknown":
        body += f" (not measured: {e.get('unknown_why') or ''})"
    else:
        measured = _fmt(e.get("measured"))
        unit = e.get("unit") or ""
        body += f", measured {measured} {unit}".rstrip() + f" vs {e.get('threshold') or '-'}"
        if not e.get("hard"):
            body += f", score {_fmt(e.get('score'))}"
    return f"{head}: {body}. {e.get('why') or ''} [{e.get('source') or ''}]".strip()


def _legend(classes: list[tuple[int, str, tuple]]) -> str:
    lines = ["| class | outcome | colour |", "|---|---|---|"]
    for cid, label, rgb in classes:
        lines.append(f"| {cid} | {label} | `{hex_colour(rgb)}` |")
    return "\n".join(lines)


def _removed_table(removed: dict[str, int], decision: Decision, shown: np.ndarray) -> str:
    """Markdown rows: rule, kind, colour, rows removed (all presentations), grasps removed in
    the shown presentation."""
    if not removed:
        return "_no candidate removed_"
    index = {c.id: h for h, c in enumerate(decision.hard)}
    lines = ["| rule | kind | colour | rows removed | shown grasps |", "|---|---|---|---|---|"]
    for rule_id, count in removed.items():
        h = index[rule_id]
        kind = decision.hard[h].rule.kind
        here = int((shown == CLASS_RULE_BASE + h).sum())
        colour = hex_colour(kind_colour(kind))
        lines.append(f"| {rule_id} | {kind} | `{colour}` | {count} | {here} |")
    return "\n".join(lines)


def _grasps_table(grasps: list[RobotGrasp]) -> str:
    """Markdown rows of the chosen grasps; with arms, the arm holding each and the stages its
    joint values are given for (drawn under ``world/robot/arms``)."""
    arms = any(g.arm for g in grasps)
    columns = ["hand", "grasp", "parts", "width m", "quality", "score"] + \
        (["arm (stages)"] if arms else [])
    lines = ["| " + " | ".join(columns) + " |", "|---" * len(columns) + "|"]
    for g in grasps:
        row = (f"| {g.gripper} | {g.id} | {'/'.join(g.parts)} | "
               f"{_fmt(g.width)} | {_fmt(g.quality)} | {_fmt(g.score)} |")
        if arms:
            row += f" {g.arm} ({', '.join(g.joints)}) |" if g.arm else " - |"
        lines.append(row)
    return "\n".join(lines)


def _refused_text(result: PlanResult) -> str:
    lines = ["## Refused", "", "Not handed to this receiver, by the rule"
             + ("s" if len(result.refused) > 1 else "") + ":", ""]
    lines += [f"- **{r['rule']}** ({r['source']}): {r['why']}" for r in result.refused]
    lines += ["", result.reason or ""]
    return "\n".join(lines)


def _placed_text(result: PlanResult) -> str:
    """Stage 4 of a placement: where and why, the grasp, the receiver's site, the axes."""
    p = result.placement or {}
    where = ", ".join(f"{v:.3f}" for v in np.asarray(p.get("position", []), dtype=float))
    text = (f"**Set down** on the table at ({where}), not handed over: "
            f"{(result.reason or '').removeprefix('not handed over: ')}\n\n"
            f"{p.get('why', '')}.\n\n")
    return text


def _infeasible_text(result: PlanResult) -> str:
    if result.outcome == "refuse":
        return _refused_text(result)
    lines = ["## No feasible handover", "", result.reason or "no reason given"]
    sets = (result.candidates or {}).get("blocking_sets") or []
    if sets:
        lines += ["", "Smallest sets of hard rules blocking the last candidates:", ""]
        lines += [f"- {' + '.join(s['rules'])}: {s['candidates']} rows" for s in sets]
    for tried in result.modes_tried:
        if not tried.get("feasible"):
            lines.append(f"- mode {tried.get('mode')}: {tried.get('reason') or 'infeasible'}")
    return "\n".join(lines)


def stage_documents(
    result: PlanResult,
    ctx: PlanContext,
    decision: Decision | None,
    stats: RowStats,
    classes: dict[int, np.ndarray],
    legend: list[tuple[int, str, tuple]],
    k: int,
    stages: list[int],
) -> dict[int, str]:
    """The markdown document of each recorded stage in ``stages``: {stage: text}.

    classes : {stage: (n,) class ids} of the grasps drawn (presentation ``k``);
    legend : the annotation classes [(id, label, rgb)]; stats : row counts of ``decision``.
    """
    q = result.query or {}
    n = len(classes[0])
    head = (
        f"**{result.object}** to the receiver ({(result.receiver or {}).get('role', '-')}), "
        f"culture {q.get('culture')}, scene {q.get('scene')}, task {q.get('task') or '-'}, "
        f"mode asked {q.get('mode')}"
    )
    placed = result.outcome == "place"
    where = "placed orientation" if placed else "presentation"
    which = "the chosen one" if result.feasible else "the one whose rows got furthest"
    shown = (f"Drawn: the {n} grasp candidates in {where} {k} ({which}), "
             f"on the object at its {'placed' if placed else 'handover'} pose.")  # fmt: skip
    docs: dict[int, str] = {}

    def title(s: int) -> str:
        return f"# Stage {s}: {STAGES[s]}\n\n_{STAGE_HELP[s]}._\n\n{head}\n"

    gen = ctx.generation or {}
    gen_text = ", ".join(f"{key} {_fmt(v) if isinstance(v, float) else v}"
                         for key, v in gen.items() if isinstance(v, (int, float, str)))  # fmt: skip
    rows_text = (f"{n} grasps x {ctx.k} presentations = {stats.rows} rows"
                 if decision is not None else f"{n} grasps")  # fmt: skip
    tried = "\n".join(
        f"- {t.get('mode')}: {'feasible' if t.get('feasible') else 'infeasible'}"
        + (f" ({t.get('reason')})" if t.get("reason") else "")
        for t in result.modes_tried
    )
    docs[0] = (
        title(0)
        + f"\n{rows_text}.\n\n{shown}\n\n"
        + (f"Generation: {gen_text}\n\n" if gen_text else "")
        + (f"Modes tried:\n\n{tried}\n\n" if tried else "")
        + f"Colours (class ids on `{ENTITY_CANDIDATES}`):\n\n"
        + _legend(legend)
    )
    if decision is not None and 1 in stages:
        docs[1] = (
            title(1) + f"\n{stats.past_cheap} of {stats.rows} rows pass every cheap "
            f"hard rule.\n\n" + _removed_table(stats.removed_cheap, decision, classes[1])
        )
    if decision is not None and 2 in stages:
        docs[2] = (
            title(2) + f"\n{stats.kept} of {stats.past_cheap} rows pass the collision "
            "rules.\n\n" + _removed_table(stats.removed_collision, decision, classes[2])
        )
    if decision is not None and 3 in stages:
        soft = "\n".join(f"- {c.id} ({c.rule.kind}) x{_fmt(float(c.rule.weight))}"
                         for c in decision.soft) or "- none"  # fmt: skip
        best = float(np.nanmax(decision.score)) if stats.kept else float("nan")
        alts = "\n".join(f"- grasp {a['grasp']} in presentation {a['presentation']}: "
                         f"{_fmt(a['score'])}" for a in result.alternatives)  # fmt: skip
        docs[3] = (title(3) + f"\n{stats.kept} rows kept; best score {_fmt(best)}. "
                   "Kept candidates are drawn larger the higher they score.\n\n"
                   f"Soft rules (weight):\n\n{soft}\n\n"
                   + (f"Next best rows:\n\n{alts}\n" if alts else ""))  # fmt: skip
    if 4 in stages:
        text = title(4) + (f"\n{_placed_text(result)}" if placed else
                           f"\nMode **{result.mode}**: {result.mode_reason}\n\n")
        text += _grasps_table(result.robot_grasps) + "\n\n"
        for h in result.human_grasps:
            pos = ", ".join(f"{v:.3f}" for v in np.asarray(h.position_world, dtype=float))
            how = f", a **{h.grasp.name}** ({h.grasp.how})" if h.grasp is not None else ""
            text += f"Receiver's {h.hand} hand on **{h.part}** at ({pos}){how}.\n\n"
        axes = (result.presentation or {}).get("axes_world") or {}
        if axes:
            text += ("Placed with " if placed else "Presented with ") + "; ".join(
                f"{name} -> ({', '.join(f'{v:+.2f}' for v in np.asarray(vec, dtype=float))})"
                for name, vec in axes.items()) + ".\n\n"  # fmt: skip
        for w in result.warnings:
            text += f"**warning**: {w}\n\n"
        text += "The rule trace of each chosen grasp is in the text log (`trace/log`)."
        docs[4] = text
    if 5 in stages:
        first, second = result.regrasp.first, result.regrasp.second
        docs[5] = (
            title(5) + f"\nThe {first.gripper} hand picks grasp {first.id} "
            f"({'/'.join(first.parts)}) at the initial pose."
        )
        docs[6] = (
            title(6) + f"\nThe {second.gripper} hand takes grasp {second.id} "
            f"({'/'.join(second.parts)}) while the {first.gripper} "
            "hand still holds the object; the grippers do not collide."
        )
        docs[7] = (
            title(7) + f"\nThe {second.gripper} hand presents the object "
            "(shown under `world/handover`)."
        )
    if not result.feasible:
        last = stages[-1]
        docs[last] = docs.get(last, title(last)) + "\n\n" + _infeasible_text(result)
    return docs


def log_entries(result: PlanResult, stages: list[int]) -> list[tuple[int, str, str]]:
    """(stage, level, text) of every log line, in order."""
    entries: list[tuple[int, str, str]] = []
    for w in result.warnings:
        entries.append((0, "WARN", w))
    pick_stage = 5 if 5 in stages else 4
    for e in result.trace:
        stage = {"pick": pick_stage, "refuse": stages[-1]}.get(e.get("stage"), 4)
        entries.append((stage, LEVELS.get(str(e.get("status")), "INFO"), _trace_line(e)))
    if result.outcome == "place":
        because = (result.reason or "").removeprefix("not handed over: ")
        entries.append((4, "WARN", f"set down, not handed over: {because}"))
    if not result.feasible:
        last = stages[-1]
        said = "refused" if result.outcome == "refuse" else "no feasible handover"
        entries.append((last, "ERROR", f"{said}: {result.reason}"))
        for s in (result.candidates or {}).get("blocking_sets") or []:
            entries.append((last, "WARN", f"blocked by {' + '.join(s['rules'])}: "
                                          f"{s['candidates']} rows"))  # fmt: skip
    entries.sort(key=lambda t: t[0])  # stable: keeps the trace's order within a stage
    return entries

