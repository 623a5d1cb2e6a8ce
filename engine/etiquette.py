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
from dataclasses import dataclass
from typing import TYPE_CHECKING

from handover.engine.errors import KBError, KBIssue
from handover.engine.schema import Culture, ObjectSpec, Primitive, Rule

if TYPE_CHECKING:
    from handover.engine.loader import KB

__all__ = [
    "ResolvedRule",
    "resolve_culture",
    "culture_parent",
    "culture_chain",
    "applies_to_object",
    "object_tags",
    "object_extents",
    "object_size",
    "describe_rule",
    "describe_applies",
]


@dataclass(frozen=True)
class ResolvedRule:
    """A rule in force in a culture.

    rule : the rule as written
    culture : id of the culture whose file holds ``rule``
    overrides : the rules it replaced, each with its own ``overrides`` (the whole chain)
    """

    rule: Rule
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
    KB returned by :func:`engine.loader.load_kb`, which checked it).
    """
    kb.culture(culture_id)
    rules, problems = _resolve(kb, culture_id)
    errors = [p for p in problems if p.severity == "error"]
    if errors:
        raise KBError(errors)
    return rules


def _resolve(kb: KB, culture_id: str) -> tuple[list[ResolvedRule], list[KBIssue]]:
    """Resolution and every problem met on the way (for :mod:`engine.lint`)."""
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
    taken: dict[int, Rule] = {}  # base position -> the rule of this culture overriding it
    appended: list[ResolvedRule] = []
    own: dict[str, Rule] = {}  # ids written in this culture so far
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
    kb: KB, rule: Rule, replaced: tuple[ResolvedRule, ...], problems: list[KBIssue]
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


def object_tags(obj: ObjectSpec) -> set[str]:
    """The object's own tags and the tags of all its parts."""
    tags = set(obj.tags)
    for part in obj.parts.values():
        tags.update(part.tags)
    return tags


def _rotation(deg: tuple[float, float, float]) -> list[list[float]]:
    """Rotation matrix of extrinsic x, y, z rotations (degrees): Rz @ Ry @ Rx."""
    ax, ay, az = (math.radians(d) for d in deg)
    cx, sx, cy, sy, cz, sz = (
        math.cos(ax),
        math.sin(ax),
        math.cos(ay),
        math.sin(ay),
        math.cos(az),
        math.sin(az),
    )
    return [
        [cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
        [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
        [-sy, cy * sx, cy * cx],
    ]


def _half_extents(p: Primitive) -> tuple[float, float, float]:
    """Half extents (m) of the axis-aligned box around the ideal solid of ``p``."""
    r = _rotation(p.rotation_deg)
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


def applies_to_object(rule: Rule, obj: ObjectSpec) -> bool | None:
    """Whether the object-dependent conditions of ``rule`` hold for ``obj``.

    Checks ``object_tags_any``, ``object_tags_none``, ``min_mass`` and ``min_size`` (the
    box around the primitives). Returns None when only the geometry of a mesh could tell
    (``min_size`` on a mesh object). The receiver, task, mode, payload and opening conditions
    are not evaluated here (they depend on the query): a rule with them "can apply".
    """
    a = rule.applies
    tags = object_tags(obj)
    if a.object_tags_any and not tags.intersection(a.object_tags_any):
        return False
    if a.object_tags_none and tags.intersection(a.object_tags_none):
        return False
    if a.min_mass is not None and obj.mass < a.min_mass:
        return False
    if a.min_size is not None:
        size = object_size(obj)
        if size is None:
            return None
        if size < a.min_size:
            return False
    return True


# ---------------------------------------------------------------- words


def _deg(x: float) -> str:
    return f"{x:g} deg"


def describe_rule(rule: Rule) -> str:
    """What ``rule`` asks, in a few words (for listings and traces)."""
    k = rule.kind
    if k == "contact":
        said = []
        if rule.forbid_tags:
            verb = "never holds" if rule.hard else "avoids holding"
            said.append(f"{rule.who} {verb} a part tagged {'/'.join(rule.forbid_tags)}")
        if rule.require_tags:
            verb = "holds" if rule.hard else "prefers to hold"
            said.append(f"{rule.who} {verb} a part tagged {'/'.join(rule.require_tags)}")
        return "; ".join(said)
    if k == "axis":
        bounds = []
        if rule.min_deg is not None:
            bounds.append(f"at least {_deg(rule.min_deg)}")
        if rule.max_deg is not None:
            bounds.append(f"at most {_deg(rule.max_deg)}")
        return f"axis '{rule.axis}' {' and '.join(bounds)} from {rule.toward}"
    if k == "task_present":
        cone = f" (default cone {_deg(rule.max_deg)})" if rule.max_deg is not None else ""
        return f"the task's axes point where it says and the receiver gets its part{cone}"
    if k == "clearance":
        return f"giver's grasp at least {rule.min_m:g} m from the receiver's hand"
    if k == "giver_side":
        return f"giver holds the object within the robot-side {rule.max_fraction:g} of its length"
    if k == "approach":
        return f"gripper approaches within {_deg(rule.max_deg or 0)} of robot-to-receiver"
    if k == "mode":
        return f"handover mode {rule.mode} {'required' if rule.hard else 'preferred'}"
    if k == "quality":
        return f"grasp quality at least {rule.min_quality:g}"
    if k == "torque":
        return f"torque of the object's weight about the grasp at most {rule.max_nm:g} N m"
    if k == "collision":
        return f"no collision with {', '.join(rule.against)}"
    return k


def describe_applies(applies) -> str:
    """When a rule applies, in words ("always" for no condition)."""
    a = applies
    said = []
    if a.object_tags_any:
        said.append(f"object tagged {'/'.join(a.object_tags_any)}")
    if a.object_tags_none:
        said.append(f"object not tagged {'/'.join(a.object_tags_none)}")
    if a.receiver_roles:
        said.append(f"receiver is {'/'.join(a.receiver_roles)}")
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
            "no single gripper opening spans it"
            if a.exceeds_opening
            else "a single gripper opening spans it"
        )
    return "; ".join(said) or "always"
