"""A culture's etiquette, resolved: its own rules on top of those of the cultures it extends.

Every culture but ``common`` extends ``common`` unless it says ``extends:`` otherwise. A rule
that lists ``overrides: [id, ...]`` takes the place of the first rule it overrides (the others
it overrides disappear), so the resolved order is the base culture's order with overridden
rules replaced in place, then the new rules in the order written. The result is the same for
the same KB, always.

Example::

    >>> rules = resolve_culture(kb, "japanese")
    >>> [(r.rule.id, r.culture) for r in rules][:2]
    [('receiver_avoids_sharp', 'common'), ('giver_avoids_sharp', 'common')]
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from handover.engine.errors import KBError, KBIssue
from handover.engine.spec.applies import Applies, Facts, check
from handover.engine.spec.schema import Culture, ObjectSpec, Primitive, RuleBase
from handover.geometry.frames import rotation_from_euler_deg

if TYPE_CHECKING:
    from handover.engine.store.hazards import TagFamilies
    from handover.engine.store.kb import KB

__all__ = [
    "ResolvedRule",
    "resolve_culture",
    "culture_parent",
    "culture_chain",
    "applies_to_object",
    "object_tags",
    "part_tags",
    "object_extents",
    "object_size",
    "object_facts",
]


@dataclass(frozen=True)
class ResolvedRule:
    """A rule in force in a culture.

    rule : the rule as written
    culture : id of the culture whose file holds ``rule``
    overrides : the rules it replaced, each with its own ``overrides`` (the whole chain)
    """

    rule: RuleBase
    culture: str
    overrides: tuple[ResolvedRule, ...] = ()

    def chain(self) -> list[ResolvedRule]:
        """Every rule this one replaced, directly or through the rules it replaced."""
        out: list[ResolvedRule] = []
        for old in self.overrides:
            out.append(old)
            out.extend(old.chain())
        return out


def culture_parent(culture: Culture) -> str | None:
    """The id of the culture ``culture`` extends: its ``extends``, else ``common`` (None for
    ``common`` itself)."""
    if culture.extends is not None:
        return culture.extends
    return None if culture.id == "common" else "common"


def _walk(kb: KB, culture_id: str) -> tuple[list[str], str | None, str | None]:
    """``(ids, stop, parent)``: the culture and its ancestors, nearest first; ``stop`` is
    None, ``"cycle"`` or ``"unknown"``, with the ``parent`` id that stopped the walk."""
    ids = [culture_id]
    current = kb.cultures[culture_id]
    while True:
        parent = culture_parent(current)
        if parent is None:
            return ids, None, None
        if parent in ids:
            return ids, "cycle", parent
        if parent not in kb.cultures:
            return ids, "unknown", parent
        ids.append(parent)
        current = kb.cultures[parent]


def culture_chain(kb: KB, culture_id: str) -> tuple[list[str], str | None]:
    """The culture and its ancestors, nearest first, and what stopped the walk.

    Returns ``(ids, problem)``: ``problem`` is None when the chain ends at a culture that
    extends nothing, else a sentence (unknown culture, or a cycle).
    """
    ids, stop, parent = _walk(kb, culture_id)
    if stop == "cycle":
        loop = " -> ".join([*ids[ids.index(parent) :], parent])
        return ids, f"'extends' forms a cycle: {loop}"
    if stop == "unknown":
        last = kb.cultures[ids[-1]]
        implicit = "" if last.extends is not None else " (implicitly: no 'extends' given)"
        return ids, f"culture '{last.id}' extends '{parent}'{implicit}, which does not exist"
    return ids, None


def resolve_culture(kb: KB, culture_id: str) -> list[ResolvedRule]:
    """The rules in force in ``culture_id``: base rules first, overridden ones replaced in
    place by their overrider, then the culture's new rules in file order.

    Raises UsageError for an unknown culture, KBError for a broken chain (cannot happen on a
    KB returned by :func:`engine.load.loader.load_kb`, which checked it).
    """
    kb.culture(culture_id)
    rules, problems = _resolve(kb, culture_id)
    errors = [p for p in problems if p.severity == "error"]
    if errors:
        raise KBError(errors)
    return rules


def _resolve(kb: KB, culture_id: str) -> tuple[list[ResolvedRule], list[KBIssue]]:
    """Resolution and every problem met on the way (for :mod:`engine.load.lint`)."""
    problems: list[KBIssue] = []
    ids, stop = culture_chain(kb, culture_id)
    _, kind, parent = _walk(kb, culture_id)
    # a cycle is reported by each culture on it, at its own `extends`; an unknown parent by
    # the culture that names it
    if kind == "cycle" and parent == culture_id or kind == "unknown":
        culture = kb.cultures[ids[-1] if kind == "unknown" else culture_id]
        sub = ("extends",) if culture.extends is not None else ("id",)
        problems.append(kb.issue(culture, stop or "", *sub))
    resolved: list[ResolvedRule] = []
    for cid in reversed(ids):
        resolved = _apply_culture(kb, kb.cultures[cid], resolved, stop is None, problems)
    return resolved, problems


def _apply_culture(
    kb: KB,
    culture: Culture,
    base: list[ResolvedRule],
    complete: bool,
    problems: list[KBIssue],
) -> list[ResolvedRule]:
    """``culture``'s rules applied on top of ``base`` (the extended cultures' rules)."""
    replacement: dict[int, ResolvedRule] = {}  # base position -> the rule taking it
    taken: dict[int, RuleBase] = {}  # base position -> the rule of this culture overriding it
    appended: list[ResolvedRule] = []
    own: dict[str, RuleBase] = {}  # ids written in this culture so far
    base_ids = {rr.rule.id for rr in base}
    for rule in culture.rules:
        hit = [i for i, rr in enumerate(base) if rr.rule.id in rule.overrides and i not in taken]
        for k, target in enumerate(rule.overrides):
            earlier = next((taken[i] for i in taken if base[i].rule.id == target), None)
            if earlier is not None:
                msg = f"rule '{target}' is already overridden by '{earlier.id}' ({earlier.source})"
            elif target not in base_ids and complete:
                msg = (
                    f"rule '{rule.id}' overrides '{target}', but no culture that "
                    f"'{culture.id}' extends has a rule '{target}'"
                )
            else:
                continue
            problems.append(kb.issue(rule, msg, "overrides", k))
        replaced = tuple(base[i] for i in hit)
        _check_safety(kb, rule, replaced, problems)
        first = own.get(rule.id)
        clash = next(
            (
                rr
                for i, rr in enumerate(base)
                if rr.rule.id == rule.id and i not in hit and i not in taken
            ),
            None,
        )
        if first is not None:
            problems.append(
                kb.issue(
                    rule,
                    f"rule id '{rule.id}' appears twice in culture '{culture.id}' "
                    f"(first at {first.source})",
                    "id",
                )
            )
        elif clash is not None:
            problems.append(
                kb.issue(
                    rule,
                    f"rule id '{rule.id}' repeats the rule '{rule.id}' of culture "
                    f"'{clash.culture}' ({clash.rule.source}); to replace it, say "
                    f"'overrides: [{rule.id}]'",
                    "id",
                )
            )
        own.setdefault(rule.id, rule)
        new = ResolvedRule(rule=rule, culture=culture.id, overrides=replaced)
        if hit:
            replacement[hit[0]] = new
            for i in hit:
                taken[i] = rule
        else:
            appended.append(new)
    kept = [
        replacement.get(i, rr) for i, rr in enumerate(base) if i not in taken or i in replacement
    ]
    return kept + appended


def _safety_in(old: ResolvedRule) -> ResolvedRule | None:
    """The safety rule ``old`` is or stands in for (a rule that replaced a safety rule keeps
    its safety: overriding it in turn needs ``override_safety`` too), else None."""
    return next((r for r in [old, *old.chain()] if r.rule.safety), None)


def _check_safety(
    kb: KB, rule: RuleBase, replaced: tuple[ResolvedRule, ...], problems: list[KBIssue]
) -> None:
    for old in replaced:
        safe = _safety_in(old)
        if safe is None:
            continue
        what = f"the safety rule '{safe.rule.id}' ({safe.rule.source})"
        if safe is not old:
            what = f"'{old.rule.id}' ({old.rule.source}), which stands in for " + what
        if rule.override_safety:
            problems.append(
                kb.issue(
                    rule,
                    f"safety rule '{safe.rule.id}' ({safe.rule.source}) overridden by "
                    f"'{rule.id}': {rule.override_safety}",
                    "override_safety",
                    severity="warning",
                )
            )
        else:
            problems.append(
                kb.issue(
                    rule,
                    f"rule '{rule.id}' overrides {what} without 'override_safety: <reason>'",
                    "overrides",
                )
            )
    if rule.override_safety and not any(_safety_in(o) for o in replaced):
        problems.append(
            kb.issue(
                rule,
                f"rule '{rule.id}' gives 'override_safety' but overrides no safety rule",
                "override_safety",
                severity="warning",
            )
        )


# ---------------------------------------------------------------- rules and objects


def object_tags(obj: ObjectSpec, families: TagFamilies | None = None) -> set[str]:
    """The object's own tags and the tags of all its parts, with every tag they imply in the
    KB's hazard vocabulary ``families`` (:func:`handover.engine.store.hazards.tag_families`)
    when given."""
    tags = set(obj.tags)
    for part in obj.parts.values():
        tags.update(part.tags)
    return set(families.expand(tags)) if families is not None else tags


def part_tags(obj: ObjectSpec, names: Iterable[str],
              families: TagFamilies | None = None, *, whole_object: bool = True
              ) -> list[set[str]]:
    """The tags each part of ``names`` carries: its own, the object's (a tag of the whole
    object is a tag of every part of it: a hot potato is hot all over; not with
    ``whole_object`` False), and every tag those imply in ``families`` (an unknown part
    name: the object's alone)."""
    whole = set(obj.tags) if whole_object else set()
    out = []
    for name in names:
        tags = whole | (set(obj.parts[name].tags) if name in obj.parts else set())
        out.append(set(families.expand(tags)) if families is not None else tags)
    return out


def _half_extents(p: Primitive) -> tuple[float, float, float]:
    """Half extents (m) of the axis-aligned box around the ideal solid of ``p``."""
    if any(p.rotation_deg):
        r = rotation_from_euler_deg(p.rotation_deg).tolist()
    else:  # the rotation of zero angles is exactly the identity: skip numpy's overhead
        r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    if p.shape == "box":
        hx, hy, hz = (e / 2 for e in p.extents or (0.0, 0.0, 0.0))
        return tuple(abs(r[i][0]) * hx + abs(r[i][1]) * hy + abs(r[i][2]) * hz for i in range(3))
    radius = p.radius or 0.0
    if p.shape == "sphere":
        return (radius, radius, radius)
    half_h = (p.height or 0.0) / 2
    out = []
    for i in range(3):
        d = abs(r[i][2])  # the primitive's axis (local z) along world axis i
        if p.shape == "cylinder":
            out.append(half_h * d + radius * math.sqrt(max(0.0, 1.0 - d * d)))
        else:  # capsule: the segment swept by a sphere
            out.append(half_h * d + radius)
    return tuple(out)


def object_extents(obj: ObjectSpec) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """``(lower, upper)`` corners (m, object frame) of the box around the object's primitives
    (their ideal solids), or None for a mesh (its size needs the geometry)."""
    if not obj.geometry.primitives:
        return None
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for p in obj.geometry.primitives:
        half = _half_extents(p)
        for i in range(3):
            lo[i] = min(lo[i], p.position[i] - half[i])
            hi[i] = max(hi[i], p.position[i] + half[i])
    return tuple(lo), tuple(hi)


def object_size(obj: ObjectSpec) -> float | None:
    """The largest extent (m) of the object's bounding box, or None for a mesh."""
    ext = object_extents(obj)
    if ext is None:
        return None
    return max(h - lo for lo, h in zip(*ext, strict=True))


OBJECT_CONDITIONS = ("object_tags_any", "object_tags_none", "min_mass", "min_size")
"""The ``applies`` fields the object alone decides."""


def object_facts(obj: ObjectSpec, families: TagFamilies | None = None) -> Facts:
    """What the object alone tells a rule's conditions (no query: the rest unknown); its
    tags with what they imply in ``families``. Hazards measured on the geometry
    (``swallowable``) need the geometry: a plan's facts have them, these do not."""
    return Facts(tags=frozenset(object_tags(obj, families)), mass=obj.mass,
                 size=object_size(obj))


def applies_to_object(rule: RuleBase, obj: ObjectSpec, families: TagFamilies | None = None,
                      *, facts: Facts | None = None) -> bool | None:
    """Whether the object-dependent conditions of ``rule`` (:data:`OBJECT_CONDITIONS`) hold
    for ``obj``, judged by :func:`handover.engine.spec.applies.check`. None when only the
    geometry of a mesh could tell (``min_size`` on a mesh object). The receiver, task, mode,
    payload and opening conditions depend on the query and are not judged here: a rule with
    them "can apply". facts : :func:`object_facts` of ``obj`` when the caller has them (a
    check of many rules against many objects computes each object's once)."""
    only = Applies(**{f: getattr(rule.applies, f) for f in OBJECT_CONDITIONS})
    return check(only, object_facts(obj, families) if facts is None else facts)[0]

