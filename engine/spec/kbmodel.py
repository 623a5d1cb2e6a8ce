"""The building blocks every knowledge-base model shares: the base model with its source
position, and the field types (ids, tags, finite numbers, receiver-frame directions).

Kept apart from :mod:`handover.engine.spec.schema` so the rule kinds
(:mod:`handover.engine.spec.kinds`) and the schema both build on it without importing each other.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field

__all__ = [
    "Source",
    "KBModel",
    "Id",
    "Tag",
    "Positive",
    "NonNegative",
    "Finite",
    "FiniteVec3",
    "Vec3",
    "Direction",
    "DIRECTIONS",
    "nonzero",
]

Vec3 = tuple[float, float, float]
Id = Annotated[str, Field(pattern=r"^[a-z][a-z0-9_\-]*$", max_length=64)]
Tag = Annotated[str, Field(pattern=r"^[a-z][a-z0-9_\-]*$", max_length=64)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]
FiniteVec3 = tuple[Finite, Finite, Finite]


class Source(BaseModel):
    """Where an item was written: ``file`` relative to the KB root, 1-based ``line``/``col``,
    and ``path``, the keys and list indices leading to the item inside its file (``("rules",
    3)`` for a culture's fourth rule)."""

    model_config = ConfigDict(frozen=True)
    file: str = "<memory>"
    line: int = 0
    col: int = 0
    path: tuple[str | int, ...] = ()

    def __str__(self) -> str:
        return f"{self.file}:{self.line}"


class KBModel(BaseModel):
    """Base of every KB model: unknown keys are errors; ``source`` is filled by the loader."""

    model_config = ConfigDict(extra="forbid", validate_default=True)
    source: Source = Field(default_factory=Source, exclude=True, repr=False)


def nonzero(v: tuple[float, float, float]) -> tuple[float, float, float]:
    if math.sqrt(sum(c * c for c in v)) < 1e-9:
        raise ValueError("an axis must not be the zero vector")
    return v




# Named directions of the receiver frame, used by axis rules and task presentations.
# toward_receiver: horizontal, from the robot to the receiver; away_from_receiver: its
# opposite; up/down: world z; receiver_left/right: the receiver's own left/right;
# receiver_dominant/nondominant: the side of the receiver's dominant hand or the other.
Direction = Literal[
    "toward_receiver",
    "away_from_receiver",
    "up",
    "down",
    "receiver_left",
    "receiver_right",
    "receiver_dominant",
    "receiver_nondominant",
]
DIRECTIONS: tuple[str, ...] = get_args(Direction)
