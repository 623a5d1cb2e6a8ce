"""What the mode planners share: their registry, the robot gripper nearer a grasp, and moving
the handover to the next best locations when the arms hold no grasp where it was."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.attempt import Attempt, Relocation

if TYPE_CHECKING:
    from handover.engine.plan.phase import Hands

__all__ = ["CATALOGUE", "PLANNERS", "HANDS_NEEDED", "RELOCATIONS", "RETRY_CHECKS",
           "H2G1_RELOCATIONS", "register", "gripper_at", "relocated"]

RELOCATIONS = 6
"""How many times the presentations whose grasps no arm (or pair of arms) holds move to their
next best handover location before a two-handed mode gives up."""
RETRY_CHECKS = 8
"""Exact (arm, grasp) checks H2G1 spends at each next location (a third of
:data:`~handover.engine.plan.arms.solve.CONFIRM_LIMIT`): where the best pairs fail at the preferred
place, the others are tried more briefly."""
H2G1_RELOCATIONS = 2
"""How many next locations H2G1 tries (each costs a search of pairs, about 0.1 s: a book whose
every pair puts a wrist in the table would cost 0.6 s with :data:`RELOCATIONS`)."""

Planner = Callable[..., "Attempt"]
"""``(kb, ctx, *, quick=False) -> Attempt``: ``quick`` leaves an infeasible attempt's reason
unexplained (only feasibility is asked)."""
CATALOGUE = ("H1G1", "H2G2", "H2G1")
"""The modes in the order auto mode tries them (after a preferred mode and what it bends to):
one hand, then the midair regrasp, then two hands (the paper's order of simplicity)."""
PLANNERS: dict[str, Planner] = {}
"""Mode name -> planner, in :data:`CATALOGUE` order whatever order they register in."""
HANDS_NEEDED: dict[str, int] = {}
"""Mode name -> how many robot hands it takes."""


def register(mode: str, hands: int = 1) -> Callable[[Planner], Planner]:
    """Decorator: register a mode planner under ``mode``, needing ``hands`` robot hands."""

    def add(fn: Planner) -> Planner:
        PLANNERS[mode] = fn
        HANDS_NEEDED[mode] = hands
        ranked = sorted(PLANNERS.items(), key=lambda kv: (
            CATALOGUE.index(kv[0]) if kv[0] in CATALOGUE else len(CATALOGUE)))
        PLANNERS.clear()
        PLANNERS.update(ranked)
        return fn

    return add


def gripper_at(pose: np.ndarray, centre: np.ndarray, hands=("left", "right")) -> str:
    """The robot hand nearer a grasp centre (object frame) with the object at ``pose``
    (4, 4): left if it lies on the robot's left (+y); a robot with one hand uses it."""
    if len(hands) == 1:
        return hands[0]
    world = pose[:3, :3] @ centre + pose[:3, 3]
    return "left" if world[1] > 1e-9 else "right"


def relocated(attempt: Attempt, hands_at: Callable[[tuple[int, ...]], Hands],
              plan_at: Callable[[Hands], Attempt], times: int | None = None) -> Attempt:
    """``attempt`` (planned at the locations the location rules prefer), or, when it failed
    because the arms hold none of its best grasps (``notes.arm_failures``), the first
    plan feasible with the presentations that had grasps offered at their next best
    locations (``hands_at(avoid)``: the receiver's hands with the candidate locations
    ``avoid`` tried last, every hard location rule still holding; ``plan_at(hands)``: the
    mode planned there), at most ``times`` (:data:`RELOCATIONS`) times. A relocated plan says
    so in ``notes.relocation`` (:class:`~handover.engine.plan.attempt.Relocation`); a failure
    adds what the next locations lacked to its reason."""
    if attempt.feasible or attempt.notes.arm_failures is None:
        return attempt
    first = attempt.phase.hands
    avoid: set[int] = set()
    tried = attempt
    missed: list[str] = []  # why each location tried found no plan, in a few words
    for _ in range(RELOCATIONS if times is None else times):
        if tried.decision is None or not len(tried.decision.ranking()):
            break
        ranked = tried.decision.pk[tried.decision.ranking()]
        used = tried.phase.hands.location[np.unique(ranked)]
        if set(int(v) for v in used) <= avoid:
            break
        avoid |= {int(v) for v in used}
        missed.append(_short(tried.reason))
        moved = hands_at(tuple(sorted(avoid)))
        if np.array_equal(moved.location, tried.phase.hands.location):
            break
        tried = plan_at(moved)
        if tried.feasible:
            k = [int(v) for v in np.flatnonzero(moved.location != first.location)]
            return tried.noted(relocation=Relocation(
                presentations=tuple(k), locations_tried=len(avoid),
                why="; ".join(dict.fromkeys(missed))))
    if tried is attempt:  # no other location was tried
        return attempt
    elsewhere = "; ".join(dict.fromkeys([*missed[1:], _short(tried.reason)]))
    return replace(attempt, reason=f"{attempt.reason}; nor at the next best locations "
                   f"({elsewhere})").noted(relocations_tried=len(avoid))


def _short(reason: str | None) -> str:
    """A mode's reason's first clause ("no pair of arms holds ... (arm_reaches)")."""
    parts = (reason or "no plan").split(": ")
    return parts[1] if len(parts) > 1 else parts[0]
