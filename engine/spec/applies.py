"""When a rule applies: the ``applies`` conditions, read in one place.

A rule's conditions are structured fields (never expressions). :func:`check` is the one
interpretation of them: the compiler calls it with everything a query knows, ``kb show`` with
what the object alone tells (the rest unknown), so both always agree.

>>> from handover.engine.spec.applies import Applies, Facts, check
>>> check(Applies(receiver_roles=["child"]), Facts(tags=frozenset(), role="adult"))
(False, 'condition not met: receiver role in child (is adult)')
>>> check(Applies(receiver_roles=["child"]), Facts(tags=frozenset()))[0] is None
True
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from handover.engine.spec.kbmodel import Id, KBModel, NonNegative, Tag

__all__ = ["Applies", "Facts", "check", "describe", "MODE_NAMES", "ROLES"]

ROLES = ("adult", "elder", "child", "superior")
MODE_NAMES = ("H1G1", "H2G2", "H2G1")

Role = Literal["adult", "elder", "child", "superior"]
Mode = Literal["H1G1", "H2G2", "H2G1"]


class Applies(KBModel):
    """When a rule applies. Every field given must hold; an empty ``Applies`` always holds.

    object_tags_any: the object, or one of its parts, carries one of these tags.
    object_tags_none: neither the object nor any part carries any of these tags.
    receiver_roles: the receiver's role is one of these.
    receiver_age_below: the receiver is younger than this (years; the profile's ``age``, else
    its role's default).
    receiver_age_at_least: the receiver is this old or older (years).
    tasks: the query's task is one of these.
    modes: the handover mode under evaluation is one of these.
    min_mass: the object's mass is at least this (kg).
    min_size: the object's largest bounding-box extent is at least this (m).
    exceeds_payload: the object's mass exceeds one robot hand's payload.
    exceeds_opening: no single gripper can take the object: no grasp candidate within the
    gripper's opening has both contacts on parts the robot may hold (parts no active hard
    giver contact rule forbids). Decided from the candidates, not from a bounding box: a mug
    wider than the opening is still taken by its handle.
    """

    object_tags_any: list[Tag] = []
    object_tags_none: list[Tag] = []
    receiver_roles: list[Role] = []
    receiver_age_below: NonNegative | None = None
    receiver_age_at_least: NonNegative | None = None
    tasks: list[Id] = []
    modes: list[Mode] = []
    min_mass: NonNegative | None = None
    min_size: NonNegative | None = None
    exceeds_payload: bool | None = None
    exceeds_opening: bool | None = None

    def is_about_load(self) -> bool:
        """Whether the conditions are about the object's mass or size (the large-object
        case of a two-hand rule, as opposed to etiquette)."""
        return bool(self.exceeds_payload or self.exceeds_opening
                    or self.min_mass is not None or self.min_size is not None)


@dataclass(frozen=True)
class Facts:
    """What conditions are judged on. A field left None is unknown (``kb show`` knows the
    object but no query); ``task`` uses ``...`` for unknown since None means "no task".

    tags : the object's and its parts' tags. mass : kg. size : m, largest extent; min_width :
    m, smallest. payload : kg, one robot hand's. max_opening : m, the gripper's.
    single_grasps : how many single-gripper grasp candidates lie within the opening on parts
    the robot may hold (``exceeds_opening`` holds when there is none).
    """

    tags: frozenset[str]
    mass: float | None = None
    size: float | None = None
    min_width: float | None = None
    payload: float | None = None
    max_opening: float | None = None
    single_grasps: int | None = None
    role: str | None = None
    age: float | None = None
    task: object = ...
    mode: str | None = None


def _tri(known: bool, ok: bool) -> bool | None:
    return ok if known else None


def check(applies: Applies, facts: Facts) -> tuple[bool | None, str]:
    """Whether ``applies`` holds for ``facts``: True, False, or None when it depends on
    something unknown (and nothing known fails). The text says which conditions failed, or
    why they hold (for traces)."""
    a = applies
    checks: list[tuple[bool | None, str]] = []
    if a.object_tags_any:
        checks.append((bool(facts.tags.intersection(a.object_tags_any)),
                       f"object tagged {'/'.join(a.object_tags_any)}"))
    if a.object_tags_none:
        checks.append((not facts.tags.intersection(a.object_tags_none),
                       f"object not tagged {'/'.join(a.object_tags_none)}"))
    if a.receiver_roles:
        checks.append((_tri(facts.role is not None, facts.role in a.receiver_roles),
                       f"receiver role in {'/'.join(a.receiver_roles)} (is {facts.role})"))
    if a.receiver_age_below is not None:
        known = facts.age is not None
        checks.append((_tri(known, known and facts.age < a.receiver_age_below),
                       f"receiver younger than {a.receiver_age_below:g} years"
                       + (f" (is {facts.age:g})" if known else "")))
    if a.receiver_age_at_least is not None:
        known = facts.age is not None
        checks.append((_tri(known, known and facts.age >= a.receiver_age_at_least),
                       f"receiver aged {a.receiver_age_at_least:g} years or more"
                       + (f" (is {facts.age:g})" if known else "")))
    if a.tasks:
        checks.append((_tri(facts.task is not ..., facts.task in a.tasks),
                       f"task in {'/'.join(a.tasks)} (is {facts.task})"))
    if a.modes:
        checks.append((_tri(facts.mode is not None, facts.mode in a.modes),
                       f"mode in {'/'.join(a.modes)} (is {facts.mode})"))
    if a.min_mass is not None:
        known = facts.mass is not None
        checks.append((_tri(known, known and facts.mass >= a.min_mass),
                       f"mass >= {a.min_mass:g} kg (is {facts.mass:g})" if known
                       else f"mass >= {a.min_mass:g} kg"))
    if a.min_size is not None:
        known = facts.size is not None
        checks.append((_tri(known, known and facts.size >= a.min_size),
                       f"size >= {a.min_size:g} m (is {facts.size:.3f})" if known
                       else f"size >= {a.min_size:g} m"))
    if a.exceeds_payload is not None:
        known = facts.mass is not None and facts.payload is not None
        exceeds = known and facts.mass > facts.payload
        text = (f"mass {facts.mass:g} kg {'>' if exceeds else '<='} payload {facts.payload:g} kg"
                if known else "mass against one hand's payload")
        checks.append((_tri(known, exceeds == a.exceeds_payload), text))
    if a.exceeds_opening is not None:
        known = facts.single_grasps is not None
        exceeds = known and facts.single_grasps == 0
        opening = (f" within the {facts.max_opening:g} m opening"
                   if facts.max_opening is not None else "")
        text = ((f"no single-gripper grasp{opening} on the parts the robot may hold" if exceeds
                 else f"{facts.single_grasps} single-gripper grasps{opening} on the parts "
                 "the robot may hold") if known
                else "whether one gripper can take the parts the robot may hold")
        checks.append((_tri(known, exceeds == a.exceeds_opening), text))
    failed = [text for ok, text in checks if ok is False]
    if failed:
        return False, "condition not met: " + "; ".join(failed)
    if any(ok is None for ok, _ in checks):
        unknown = [text for ok, text in checks if ok is None]
        return None, "depends on the query: " + "; ".join(unknown)
    return True, "; ".join(text for _, text in checks) or "always"


def describe(applies: Applies) -> str:
    """When a rule applies, in words ("always" for no condition)."""
    a = applies
    said = []
    if a.object_tags_any:
        said.append(f"object tagged {'/'.join(a.object_tags_any)}")
    if a.object_tags_none:
        said.append(f"object not tagged {'/'.join(a.object_tags_none)}")
    if a.receiver_roles:
        said.append(f"receiver is {'/'.join(a.receiver_roles)}")
    if a.receiver_age_below is not None:
        said.append(f"receiver younger than {a.receiver_age_below:g} years")
    if a.receiver_age_at_least is not None:
        said.append(f"receiver aged {a.receiver_age_at_least:g} years or more")
    if a.tasks:
        said.append(f"task is {'/'.join(a.tasks)}")
    if a.modes:
        said.append(f"mode is {'/'.join(a.modes)}")
    if a.min_mass is not None:
        said.append(f"mass at least {a.min_mass:g} kg")
    if a.min_size is not None:
        said.append(f"size at least {a.min_size:g} m")
    if a.exceeds_payload is not None:
        said.append(
            ("mass exceeds" if a.exceeds_payload else "mass within") + " one hand's payload"
        )
    if a.exceeds_opening is not None:
        said.append(
            "no single gripper can take it"
            if a.exceeds_opening
            else "a single gripper can take it"
        )
    return "; ".join(said) or "always"
