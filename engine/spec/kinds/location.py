"""``location``: where the object is offered. A measure of the chosen handover location
(the receiver's reach, the height between elbow and chest, the distance in front of them,
the side, the robot's reach, nothing hit there, the distance kept from obstacles) within
bounds (hard) or near a preferred value (soft). The location is chosen per presentation
before the grasps are judged (:mod:`handover.engine.plan.world`); each row reports its
presentation's location."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import model_validator

from handover.engine.spec.kbmodel import Finite, Positive
from handover.engine.spec.kinds.base import RuleBase, register

Measure = Literal["receiver_reach", "height", "front", "lateral", "robot_reach", "clear",
                  "clearance"]


LOCATION_MEASURES = {
    "receiver_reach": ("fraction", "distance from the receiving shoulder to the receiver's "
                       "grasp site over the arm's reach (1: a straight arm)"),
    "height": ("fraction", "height of the receiver's grasp site in the elbow (0) to chest (1) "
               "band"),
    "front": ("m", "distance of the receiver's grasp site in front of their torso"),
    "lateral": ("m", "offset of the receiver's grasp site from their midline toward the "
                "receiving hand"),
    "robot_reach": ("fraction", "horizontal distance of the receiver's grasp site from the "
                    "robot's base axis over the robot's reach"),
    "clear": ("", "1 when the object, the receiver's hands and their reaching arm at this "
              "location hit nothing (table, obstacles, bodies; the arm: the scene and the "
              "robot), else 0"),
    "clearance": ("m", "how far the object and the receiver's hands stay from the scene's "
                  "table and obstacles at this location, at least: the hard clearance rules' "
                  "largest min where a location clear by that much was found (the trace "
                  "gives the distance measured), 0 where none was"),
}
"""Measures a ``location`` rule may judge: name -> (unit, meaning)."""


@register
class LocationRule(RuleBase):
    """measure (see ``:data:`LOCATION_MEASURES```), min / max (bounds, in the
    measure's unit), prefer and tolerance (soft: the score is 1 at ``prefer`` and falls as a
    Gaussian of width ``tolerance``)."""

    kind: Literal["location"] = "location"
    measure: Measure
    min: Finite | None = None
    max: Finite | None = None
    prefer: Finite | None = None
    tolerance: Positive | None = None

    colour = (0, 90, 160)
    summary = "where the object is offered: reach, height, side, nothing hit there"
    example = {"measure": "receiver_reach", "max": 0.95}

    @model_validator(mode="after")
    def _bounds(self) -> LocationRule:
        if self.min is None and self.max is None and self.prefer is None:
            raise ValueError("a 'location' rule needs min, max or prefer")
        if (self.prefer is None) != (self.tolerance is None):
            raise ValueError("prefer and tolerance go together")
        if self.min is not None and self.max is not None and self.min > self.max:
            raise ValueError("min must not exceed max")
        return self

    def features(self) -> list[str]:
        return ["location"]

    def describe(self) -> str:
        unit = LOCATION_MEASURES[self.measure][0]
        said = []
        if self.min is not None:
            said.append(f"at least {self.min:g} {unit}".rstrip())
        if self.max is not None:
            said.append(f"at most {self.max:g} {unit}".rstrip())
        if self.prefer is not None:
            said.append(f"near {self.prefer:g} {unit}".rstrip())
        return f"handover location: {self.measure} {' and '.join(said)}"

    def judge(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(pass, score) of location measure ``values`` (any shape)."""
        ok = np.isfinite(values)
        if self.min is not None:
            ok &= values >= self.min - 1e-9
        if self.max is not None:
            ok &= values <= self.max + 1e-9
        if self.prefer is not None:
            score = np.exp(-0.5 * ((values - self.prefer) / self.tolerance) ** 2)
        else:
            score = ok.astype(float)
        return ok, np.where(np.isfinite(score), score, 0.0)

    def threshold(self) -> str:
        bits = []
        if self.min is not None:
            bits.append(f">= {self.min:g}")
        if self.max is not None:
            bits.append(f"<= {self.max:g}")
        if self.prefer is not None:
            bits.append(f"best {self.prefer:g} +- {self.tolerance:g}")
        return f"{self.measure} " + " and ".join(bits)

