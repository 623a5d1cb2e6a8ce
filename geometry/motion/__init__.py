"""Collision-free arm motion: one arm chain against a world of boxes, capsules and the other
arm, planned with OMPL, timed with ruckig.

- :mod:`~handover.geometry.motion.checker`: :class:`ArmModel` (a URDF chain in the world) and
  :class:`ValidityChecker` (its links and carried boxes against fixed targets, vectorised).
- :mod:`~handover.geometry.motion.planner`: :func:`plan_segment`, one stage's motion as a
  :class:`Segment` or a :class:`PlanningFailure`; :func:`ends_failure`, its check of the
  start and the goal alone.
- :mod:`~handover.geometry.motion.timing`: :func:`time_parameterise`, rest-to-rest motion
  along a polyline under velocity, acceleration and jerk limits.
"""

from handover.geometry.motion.checker import ArmModel, ValidityChecker, obstacles
from handover.geometry.motion.planner import (
    DEFAULT_RESOLUTION,
    PLANNERS,
    PlannerSettings,
    PlanningFailure,
    Segment,
    densify,
    ends_failure,
    plan_segment,
)
from handover.geometry.motion.timing import (
    DEFAULT_ACCELERATION,
    DEFAULT_JERK,
    DEFAULT_PERIOD,
    time_parameterise,
)

__all__ = [
    "ArmModel",
    "ValidityChecker",
    "obstacles",
    "DEFAULT_RESOLUTION",
    "PLANNERS",
    "PlannerSettings",
    "PlanningFailure",
    "Segment",
    "densify",
    "ends_failure",
    "plan_segment",
    "DEFAULT_ACCELERATION",
    "DEFAULT_JERK",
    "DEFAULT_PERIOD",
    "time_parameterise",
]
