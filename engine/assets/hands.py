"""From a KB hand and receiver to geometry: the receiver's hand model and their repertoire of
grasps (each a :class:`~handover.geometry.grasps.GraspShape`), in the hand's order of
preference, restricted and scaled by the receiver's profile."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from handover.geometry.grasps import GraspShape
from handover.geometry.hand import HumanHand

if TYPE_CHECKING:
    from handover.engine.spec.schema import HandGraspSpec, HumanHandSpec, ReceiverProfile

__all__ = ["Repertoire", "human_hand", "receiver_repertoire"]


@dataclass(frozen=True)
class Repertoire:
    """The grasps a receiver takes things with, in the order their hand prefers them.

    shapes : the geometry of each grasp (its loads scaled by the receiver's grip strength).
    unsuited : per grasp, the tags of parts (or objects) it never holds.
    specs : per grasp, its KB entry (``source`` for file:line, ``why``).
    """

    shapes: tuple[GraspShape, ...]
    unsuited: tuple[frozenset[str], ...]
    specs: tuple[HandGraspSpec, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.shapes)

    def __len__(self) -> int:
        return len(self.shapes)


def human_hand(spec: HumanHandSpec) -> HumanHand:
    """The hand's boxes model (palm, fingers): the wrap of :mod:`handover.geometry.hand`."""
    return HumanHand(palm=tuple(spec.palm), finger_length=spec.finger_length,
                     finger_thickness=spec.finger_thickness, grip_width=spec.grip_width)


def receiver_repertoire(spec: HumanHandSpec, receiver: ReceiverProfile | None = None
                        ) -> Repertoire:
    """The grasps of ``spec`` (:meth:`HumanHandSpec.repertoire`) that ``receiver`` uses (its
    ``grasps``; all when None), each grasp's load times the receiver's ``grip_strength``. A
    name the receiver gives that the hand lacks is a ValueError (``handover kb validate``
    reports it at its line)."""
    hand = human_hand(spec)
    grasps = spec.repertoire()
    strength = 1.0 if receiver is None else float(receiver.grip_strength)
    if receiver is not None and receiver.grasps is not None:
        known = {g.name for g in grasps}
        missing = [n for n in receiver.grasps if n not in known]
        if missing:
            raise ValueError(f"receiver '{receiver.id}' uses grasps {missing} that hand "
                             f"'{spec.id}' does not have ({', '.join(sorted(known))})")
        grasps = [g for g in grasps if g.name in set(receiver.grasps)]
    shapes = tuple(GraspShape(name=g.name, family=g.family, hand=hand, width=g.width,
                              reach=g.reach, min_thickness=g.thickness[0],
                              max_thickness=g.thickness[1], max_load=g.max_load_kg * strength)
                   for g in grasps)
    return Repertoire(shapes=shapes, unsuited=tuple(frozenset(g.unsuited_tags) for g in grasps),
                      specs=tuple(grasps))
