"""A mode attempt as a value: what it decided.

The :class:`Attempt` a mode planner returns carries the phase
(:class:`~handover.engine.plan.phase.Phase`) of each chosen grasp, so the trace, the
recording and the checks that a plan is feasible read exactly what the planner judged.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from handover.engine.plan.phase import Phase

if TYPE_CHECKING:
    from handover.engine.plan.compiler import ConstraintGraph
    from handover.engine.plan.evaluate import Decision

__all__ = ["Chosen", "Attempt"]


@dataclass(frozen=True)
class Chosen:
    """One chosen robot grasp: which hand, candidate and presentation, the phase its rules
    were judged in, and its stage (``pick``: H2G2's first grasp, else ``handover``)."""

    hand: str
    grasp: int
    presentation: int
    phase: Phase
    stage: str = "handover"


@dataclass(frozen=True)
class Attempt:
    """One mode tried: its graph, the phase of its rows, decision table, and the chosen
    grasps (empty when infeasible). ``extra`` holds the mode's own numbers for the result."""

    mode: str
    feasible: bool
    reason: str | None
    graph: ConstraintGraph | None = None
    decision: Decision | None = None
    phase: Phase | None = None
    chosen: tuple[Chosen, ...] = ()
    score: float | None = None
    extra: dict = field(default_factory=dict)
    # How far the attempt got: (rows kept, most hard rules any row passed) for ranking
    # infeasible attempts.
    progress: tuple[int, int] = (0, 0)

    def rejected(self, reason: str) -> Attempt:
        """This attempt turned infeasible with ``reason`` (chosen grasps dropped)."""
        return replace(self, feasible=False, reason=reason, chosen=(), score=None)
