"""What a plan's recording shows, stage by stage: the layout the writer
(:mod:`~handover.engine.report.rerun.writer`) and the reader
(:mod:`~handover.engine.report.rerun.reader`) share, and the outcome of every candidate at each
stage (pure numpy, no rerun).

The timeline ``stage`` has one step per stage of the decision (:data:`STAGES`); each grasp
candidate has an outcome class id per stage (``CLASS_*``; ``CLASS_RULE_BASE + h`` for a
candidate rejected by hard rule ``h`` of the decision), coloured by outcome or by the kind
of the rule that rejected it; ``ENTITY_*`` are the entity paths the reader looks for.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.spec.kinds import KINDS

if TYPE_CHECKING:
    from handover.engine.plan.evaluate import Decision
    from handover.engine.report.result import PlanResult

__all__ = [
    "APPLICATION_ID",
    "TIMELINE",
    "STAGES",
    "STAGE_HELP",
    "CLASS_GENERATED",
    "CLASS_ALIVE",
    "CLASS_KEPT",
    "CLASS_CHOSEN",
    "CLASS_RULE_BASE",
    "OUTCOME_COLOURS",
    "OTHER_KIND_COLOUR",
    "ENTITY_CANDIDATES",
    "ENTITY_LOCATIONS",
    "ENTITY_CENTRES",
    "ENTITY_APPROACH",
    "ENTITY_LOG",
    "ENTITY_SUMMARY",
    "ENTITY_ARMS",
    "hex_colour",
    "kind_colour",
    "rows_in",
    "stage_classes",
    "class_table",
    "shown_presentation",
    "RowStats",
    "row_stats",
    "stages_to_record",
]

APPLICATION_ID = "handover-grasp"
TIMELINE = "stage"
STAGES: dict[int, str] = {
    0: "generated",
    1: "pre-filtered",
    2: "collision-checked",
    3: "scored",
    4: "chosen",
    5: "pick",
    6: "midair",
    7: "handover",
}
STAGE_HELP = {
    0: "every geometric grasp candidate",
    1: "the cheap hard rules (every kind but collision) remove candidates",
    2: "the collision rules run on the rows that passed the cheap rules",
    3: "the soft rules score the rows that passed every hard rule",
    4: "the best row is chosen",
    5: "the first hand picks the object at its initial pose",
    6: "both hands hold the object at the midair pose; the second hand takes it",
    7: "the second hand presents the object to the receiver",
}

CLASS_GENERATED = 0
CLASS_ALIVE = 1
CLASS_KEPT = 2
CLASS_CHOSEN = 3
CLASS_RULE_BASE = 100
"""Class id of a candidate rejected by hard rule ``h`` (index into ``Decision.hard``) is
``CLASS_RULE_BASE + h``."""

OUTCOME_COLOURS: dict[str, tuple[int, int, int]] = {
    "generated": (150, 150, 150),
    "alive": (90, 160, 255),
    "kept": (40, 180, 80),
    "chosen": (255, 200, 0),
}
"""RGB of the outcomes that are not rejections."""

OTHER_KIND_COLOUR = (255, 0, 255)

ENTITY_CANDIDATES = "world/handover/candidates"
ENTITY_LOCATIONS = "world/handover/locations"
ENTITY_CENTRES = "world/handover/candidates/centres"
ENTITY_APPROACH = "world/handover/candidates/approach"
ENTITY_LOG = "trace/log"
ENTITY_SUMMARY = "trace/summary"
ENTITY_ARMS = "world/robot/arms"
"""The robot's arms: ``{ENTITY_ARMS}/{pickup,midair,handover}/{capsules,boxes,chain}``."""


def hex_colour(rgb: tuple[int, int, int]) -> str:
    """``"#rrggbb"`` of an RGB triple (0-255)."""
    return "#{:02x}{:02x}{:02x}".format(*rgb)


def kind_colour(kind: str) -> tuple[int, int, int]:
    """RGB of a candidate rejected by a hard rule of ``kind`` (each kind declares its own
    in :mod:`handover.engine.spec.kinds`)."""
    cls = KINDS.get(kind)
    return cls.colour if cls is not None else OTHER_KIND_COLOUR


def rows_in(decision: Decision, n: int, k: int) -> np.ndarray:
    """(n,) int64: the decision row of each grasp in presentation ``k`` (-1 where none)."""
    row = np.full(n, -1, dtype=np.int64)
    sel = np.flatnonzero(decision.pk == k)
    gi = decision.gi[sel]
    ok = (gi >= 0) & (gi < n)
    row[gi[ok]] = sel[ok]
    return row


def _cheap_and_collision(decision: Decision) -> tuple[list[int], list[int]]:
    cheap = [h for h, c in enumerate(decision.hard) if c.rule.kind != "collision"]
    coll = [h for h, c in enumerate(decision.hard) if c.rule.kind == "collision"]
    return cheap, coll


def _first_fail(fails: np.ndarray, cols: list[int]) -> np.ndarray:
    """(R,) int: the first of ``cols`` (hard-rule indices) failed by each row, -1 if none."""
    if not cols or fails.shape[0] == 0:
        return np.full(fails.shape[0], -1, dtype=np.int64)
    sub = fails[:, cols]
    return np.where(sub.any(axis=1), np.asarray(cols)[sub.argmax(axis=1)], -1)


def stage_classes(
    decision: Decision | None, n: int, k: int, chosen: list[int] | tuple[int, ...] = ()
) -> dict[int, np.ndarray]:
    """The outcome class of every grasp candidate at stages 0-4, in presentation ``k``.

    decision : the decision table (rows grasp x presentation), or None (only stage 0, and
        stage 4 when ``chosen`` is given, can be told).
    n : number of grasp candidates. chosen : grasp indices chosen (stage 4).
    Returns {stage: (n,) uint16 class ids}: ``CLASS_GENERATED`` at stage 0; then
    ``CLASS_RULE_BASE + h`` for the first failing cheap hard rule ``h`` (stage 1) or
    collision rule (stage 2), ``CLASS_ALIVE`` for rows still in, ``CLASS_KEPT`` at stage 3
    for rows that passed every hard rule, ``CLASS_CHOSEN`` at stage 4 for ``chosen``.
    Grasps with no row in presentation ``k`` stay ``CLASS_GENERATED``.
    """
    chosen_idx = np.asarray([c for c in chosen if 0 <= c < n], dtype=np.int64)
    out = {0: np.full(n, CLASS_GENERATED, dtype=np.uint16)}
    if decision is None:
        if len(chosen_idx):
            c4 = out[0].copy()
            c4[chosen_idx] = CLASS_CHOSEN
            out[4] = c4
        return out
    row = rows_in(decision, n, k)
    has = row >= 0
    r = row[has]
    cheap, coll = _cheap_and_collision(decision)
    fails = decision.fails[r]
    f1 = _first_fail(fails, cheap)
    f2 = _first_fail(fails, coll)
    c1 = out[0].copy()
    c1[has] = np.where(f1 >= 0, CLASS_RULE_BASE + f1, CLASS_ALIVE)
    c2 = c1.copy()
    c2[has] = np.where((f1 < 0) & (f2 >= 0), CLASS_RULE_BASE + f2, c1[has])
    c3 = c2.copy()
    c3[has] = np.where(decision.kept[r], CLASS_KEPT, c2[has])
    c4 = c3.copy()
    c4[chosen_idx] = CLASS_CHOSEN
    out.update({1: c1, 2: c2, 3: c3, 4: c4})
    return out


def class_table(decision: Decision | None) -> tuple[list[tuple[int, str, tuple]], np.ndarray]:
    """The annotation classes [(id, label, rgb)] and a lookup (max id + 1, 3) uint8 of
    colours by class id."""
    classes = [
        (CLASS_GENERATED, "generated", OUTCOME_COLOURS["generated"]),
        (CLASS_ALIVE, "alive", OUTCOME_COLOURS["alive"]),
        (CLASS_KEPT, "kept", OUTCOME_COLOURS["kept"]),
        (CLASS_CHOSEN, "chosen", OUTCOME_COLOURS["chosen"]),
    ]
    for h, c in enumerate(decision.hard if decision is not None else []):
        label = f"rejected by {c.id} ({c.rule.kind})"
        classes.append((CLASS_RULE_BASE + h, label, kind_colour(c.rule.kind)))
    lut = np.zeros((max(cid for cid, _, _ in classes) + 1, 3), dtype=np.uint8)
    for cid, _, rgb in classes:
        lut[cid] = rgb
    return classes, lut


def shown_presentation(result: PlanResult, decision: Decision | None, k_total: int) -> int:
    """The presentation drawn: the chosen one, else the one whose rows got furthest (most
    kept, then most past the cheap rules, then fewest failed rules; lowest index on ties)."""
    pres = result.presentation or {}
    if result.feasible and pres.get("index") is not None:
        return int(pres["index"])
    if decision is None:
        return 0
    return decision.furthest_presentation(k_total)


@dataclass
class RowStats:
    """Row-level counts (all presentations) for the stage documents."""

    rows: int = 0
    past_cheap: int = 0
    kept: int = 0
    removed_cheap: dict[str, int] = field(default_factory=dict)
    removed_collision: dict[str, int] = field(default_factory=dict)


def row_stats(decision: Decision | None) -> RowStats:
    """How many rows (all presentations) the cheap hard rules and the collision rules
    removed, each by rule id (a row counted for its first failing rule)."""
    if decision is None:
        return RowStats()
    cheap, coll = _cheap_and_collision(decision)
    f1 = _first_fail(decision.fails, cheap)
    f2 = _first_fail(decision.fails, coll)
    c1 = Counter(f1[f1 >= 0].tolist())
    c2 = Counter(f2[(f1 < 0) & (f2 >= 0)].tolist())
    return RowStats(
        rows=int(decision.n_rows),
        past_cheap=int((f1 < 0).sum()),
        kept=int(decision.kept.sum()),
        removed_cheap={decision.hard[h].id: c1[h] for h in cheap if c1[h]},
        removed_collision={decision.hard[h].id: c2[h] for h in coll if c2[h]},
    )


def stages_to_record(result: PlanResult, decision: Decision | None, stats: RowStats) -> list[int]:
    """Stages 0-4 up to the last one with candidates (all of them for a feasible plan), then
    5-7 for a feasible H2G2 plan."""
    stages = [0]
    if decision is not None and stats.rows > 0:
        stages.append(1)
        if stats.past_cheap > 0:
            stages.append(2)
        if stats.kept > 0:
            stages.append(3)
    if result.feasible and result.robot_grasps:
        stages.append(4)
        if result.mode == "H2G2" and result.regrasp:
            stages += [5, 6, 7]
    return stages

