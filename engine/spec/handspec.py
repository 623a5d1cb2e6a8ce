"""A receiver's hand in the knowledge base (``hands/*.yaml``): its sizes and its repertoire
of grasps, each with its family (the geometry of :mod:`handover.geometry.grasps`), the room it
takes, the sections it holds, the load it bears and the parts it never holds."""

from __future__ import annotations

from typing import Literal

from pydantic import field_validator

from handover.engine.spec.kbmodel import Id, KBModel, NonNegative, Positive, Tag
from handover.geometry.grasps import FAMILIES

__all__ = ["GRASP_FAMILIES", "HandGraspSpec", "HumanHandSpec"]

GRASP_FAMILIES: tuple[str, ...] = tuple(FAMILIES)
"""The families of receiver grasps (their geometry: :mod:`handover.geometry.grasps`)."""


class HandGraspSpec(KBModel):
    """One grasp of a hand's repertoire: its family (the geometry of its boxes), the room it
    takes along the part (``width``, m), how far an edge grasp's fingertips reach in from the
    edge (``reach``, m; pinch and lateral), the sections it takes (``thickness``: [min, max]
    m across the part; a support from below ignores it), the weight it holds
    (``max_load_kg``) and the tags of parts (or objects) it never holds (``unsuited_tags``,
    e.g. a support from below under a hot pan). ``why`` says where it comes from."""

    name: Id
    family: Literal[GRASP_FAMILIES]  # type: ignore[valid-type]
    width: Positive
    reach: Positive = 0.025
    thickness: tuple[NonNegative, Positive] = (0.0, 1.0)
    max_load_kg: Positive
    unsuited_tags: list[Tag] = []
    why: str | None = None

    @field_validator("thickness")
    @classmethod
    def _range(cls, v: tuple[float, float]) -> tuple[float, float]:
        if v[0] > v[1]:
            raise ValueError(f"thickness [min, max] must have min <= max, got {list(v)}")
        return v


class HumanHandSpec(KBModel):
    """A human hand: a palm box and finger boxes, and the grasps it takes things with.

    palm : (breadth along the held part, length from wrist to knuckles, thickness), m.
    grip_width : m, the width a wrap takes along the part (when ``grasps`` is empty, the
    only grasp: a wrap of this width, as the hand was modelled before it had a repertoire).
    grasps : the repertoire, in the order the hand prefers them where rules say nothing
    (names unique).
    """

    id: Id
    name: str
    palm: tuple[Positive, Positive, Positive]
    finger_length: Positive
    finger_thickness: Positive
    grip_width: Positive
    grasps: list[HandGraspSpec] = []

    @field_validator("grasps")
    @classmethod
    def _unique(cls, v: list[HandGraspSpec]) -> list[HandGraspSpec]:
        names = [g.name for g in v]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"grasp names must be unique, {', '.join(twice)} given twice")
        return v

    def repertoire(self) -> list[HandGraspSpec]:
        """The hand's grasps: ``grasps``, else one wrap ``grip_width`` wide."""
        if self.grasps:
            return list(self.grasps)
        return [HandGraspSpec(name="wrap", family="wrap", width=self.grip_width,
                              thickness=(0.0, 2.0 * self.finger_length), max_load_kg=20.0,
                              source=self.source)]
