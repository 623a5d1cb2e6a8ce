"""What the mode planners share: their registry, and the robot hand nearer a grasp."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.attempt import Attempt
    from handover.engine.context import PlanContext
    from handover.engine.loader import KB

__all__ = ["PLANNERS", "HANDS_NEEDED", "register", "hand_at"]

Planner = Callable[["KB", "PlanContext"], "Attempt"]
PLANNERS: dict[str, Planner] = {}
"""Mode name -> planner, in the order auto mode tries them (H1G1, H2G2, H2G1)."""
HANDS_NEEDED: dict[str, int] = {}
"""Mode name -> how many robot hands it takes."""


def register(mode: str, hands: int = 1) -> Callable[[Planner], Planner]:
    """Decorator: register a mode planner under ``mode``, needing ``hands`` robot hands."""

    def add(fn: Planner) -> Planner:
        PLANNERS[mode] = fn
        HANDS_NEEDED[mode] = hands
        return fn

    return add


def hand_at(pose: np.ndarray, centre: np.ndarray, hands=("left", "right")) -> str:
    """The robot hand nearer a grasp centre (object frame) with the object at ``pose``
    (4, 4): left if it lies on the robot's left (+y); a robot with one hand uses it."""
    if len(hands) == 1:
        return hands[0]
    world = pose[:3, :3] @ centre + pose[:3, 3]
    return "left" if world[1] > 1e-9 else "right"
