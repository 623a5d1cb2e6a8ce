"""What the rules of one grasp are judged against: the roles of the people (which parts each
may hold), the receiver's hands in every presentation and where each is offered, and the
phase of an attempt (which mode, pick-up or not, the receiver present or not, the other
gripper's grasp, the arm).

Nothing that decides a rule's outcome lives in shared mutable state: a mode planner builds
a :class:`Phase` and passes it to every rule it evaluates and to the trace.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.plan.receiver_sites import ReceiverRegion, ReceiverSites
    from handover.engine.plan.world import Locations

__all__ = ["Roles", "Hands", "Phase"]


@dataclass(frozen=True)
class Roles:
    """Which parts the people may hold, read from the compiled rules of one mode.

    want : tags of the part the receiver should hold (the task's, else the active receiver
    contact rules' ``require_tags``). receiver_forbid / giver_forbid : tags the receiver /
    the robot never holds (active hard contact rules).
    """

    want: frozenset[str] = frozenset()
    receiver_forbid: frozenset[str] = frozenset()
    giver_forbid: frozenset[str] = frozenset()


@dataclass(frozen=True, eq=False)
class Hands:
    """Where the receiver's hands go on the object, and where the object is offered, per
    presentation, for one set of roles and location rules.

    key : hashable identity (roles, number of hands, location rules) for memoised features.
    region : the receiver's graspable region. sites : one :class:`ReceiverSites` per
    receiver hand (one, or two for a large object); receiving : the receiver's hands that
    take it. s_range : (K, 2) m, the giver's graspable
    region's extent along robot->receiver in each presentation (the ``giver_side`` rule).
    poses : (K, 4, 4) object -> world at the handover, each presentation at its location.
    location : (K,) int, the chosen location of each presentation (index into
    ``locations.points``); where no location passes every hard location rule, the one that
    came closest (and ``located[k]`` is False). measured : measure -> (K,) the chosen
    location's values (``clear`` 1/0). hits : per presentation, what the object or the
    receiver's hands hit at the chosen location (names; empty when clear). avoid : the
    candidate locations tried last (a mode moved the presentations off them).
    """

    key: tuple
    region: ReceiverRegion
    sites: tuple[ReceiverSites, ...]
    s_range: np.ndarray
    poses: np.ndarray
    location: np.ndarray
    located: np.ndarray
    measured: dict
    hits: tuple[tuple[str, ...], ...]
    receiving: tuple[str, ...] = ("right",)
    locations: Locations | None = None
    avoid: tuple[int, ...] = ()


@dataclass(frozen=True)
class Phase:
    """What the rules of one grasp are judged against.

    mode : "H1G1" | "H2G2" | "H2G1". pickup : this gripper takes the object off the table (the
    scene is an obstacle at the initial pose). receiver_present : the receiver's hands are
    there (not while the robot passes the object between its own hands). other_grasp : the
    candidate the robot's other gripper holds at the same time, an obstacle (or None).
    arm : the robot arm holding this grasp (``left`` | ``right``) once a mode has decided
    it, else None (the ``reach`` rule then screens every arm's reachability map; with an arm
    it judges by exact inverse kinematics, see :mod:`handover.engine.plan.arms.solve`).
    giver_forbid : the tags the robot may not hold in this mode (the hard giver contact
    rules whose conditions hold: :attr:`ConstraintGraph.giver_forbid
    <handover.engine.plan.compiler.ConstraintGraph.giver_forbid>`). midair_lift : m, how
    much higher than its default (the handover pose moved back toward the robot) H2G2's
    midair regrasp is (:func:`~handover.engine.plan.arms.stages.objects_at`).
    """

    mode: str
    hands: Hands
    pickup: bool = True
    receiver_present: bool = True
    other_grasp: int | None = None
    arm: str | None = None
    giver_forbid: frozenset[str] = frozenset()
    midair_lift: float = 0.0

    def but(self, **changes) -> Phase:
        """A copy with ``changes`` (phases are values)."""
        return replace(self, **changes)
