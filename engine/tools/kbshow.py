"""What the knowledge base says about its items, as JSON-ready data (``handover kb list`` and
``handover kb show`` render it).

For an object, the rules of a culture are split into those that can apply to it and those
that cannot, with the reason. Both readings are the engine's own: a rule's conditions are
judged by :func:`handover.engine.spec.applies.check` on what the object alone tells (through
:func:`handover.engine.store.cultures.applies_to_object`), then the rule's kind says whether it can
judge this object at all (``rule.not_applicable``, as the compiler asks it for a plan), for
some task of the object.

Example::

    >>> data = show_item(kb, "knife", culture="japanese")
    >>> data["kind"], [p["name"] for p in data["parts"]]
    ('object', ['handle', 'blade'])
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from handover.engine.errors import UsageError
from handover.engine.plan import judge
from handover.engine.spec.applies import describe as describe_applies
from handover.engine.store.cultures import (
    applies_to_object,
    culture_chain,
    culture_parent,
    object_size,
    object_tags,
    part_tags,
    resolve_culture,
)
from handover.engine.store.hazards import tag_families

if TYPE_CHECKING:
    from handover.engine.spec.schema import KBModel, ObjectSpec, RuleBase, Task
    from handover.engine.store.cultures import ResolvedRule
    from handover.engine.store.hazards import TagFamilies
    from handover.engine.store.kb import KB

__all__ = [
    "SHOW_KINDS",
    "ObjectOnly",
    "listing",
    "item_kind",
    "show_item",
    "object_view",
    "culture_view",
    "rule_view",
    "tag_rules",
    "not_applicable",
]

SHOW_KINDS: dict[str, str] = {
    "object": "objects",
    "culture": "cultures",
    "receiver": "receivers",
    "scene": "scenes",
    "gripper": "grippers",
    "hand": "hands",
    "robot": "robots",
}
"""Kind of item (as ``kb show --kind`` names it) -> attribute of the KB holding them."""


def _text(s: str) -> str:
    return " ".join(s.split())


def listing(kb: KB) -> dict[str, list[dict[str, Any]]]:
    """One row per item of each kind (``kb list``): {kind attribute: [row]}, rows in KB order."""
    return {
        "objects": [
            {"id": o.id, "name": o.name, "mass": o.mass, "tags": list(o.tags),
             "parts": list(o.parts), "tasks": list(o.tasks)}
            for o in kb.objects.values()
        ],
        "cultures": [
            {"id": c.id, "name": c.name, "extends": culture_parent(c), "rules": len(c.rules)}
            for c in kb.cultures.values()
        ],
        "receivers": [
            {"id": r.id, "name": r.name, "role": r.role, "dominant_hand": r.dominant_hand,
             "posture": r.posture, "stature": r.height, "hand": r.hand}
            for r in kb.receivers.values()
        ],
        "scenes": [
            {"id": s.id, "name": s.name, "obstacles": [b.id for b in s.obstacles],
             "support": s.support is not None}
            for s in kb.scenes.values()
        ],
        "grippers": [
            {"id": g.id, "name": g.name, "max_opening": g.max_opening,
             "finger_length": g.finger_length}
            for g in kb.grippers.values()
        ],
        "hands": [
            {"id": h.id, "name": h.name, "grip_width": h.grip_width} for h in kb.hands.values()
        ],
        "robots": [
            {"id": r.id, "name": r.name, "hands": list(r.hands),
             "payload_per_hand": r.payload_per_hand, "gripper": r.gripper}
            for r in kb.robots.values()
        ],
    }  # fmt: skip


def item_kind(kb: KB, item_id: str, kind: str | None = None) -> str:
    """The kind of item ``item_id`` names (a key of :data:`SHOW_KINDS`).

    Raises UsageError for an unknown ``kind``, an id no item of that kind (or of any kind)
    has, and an id that names items of several kinds when ``kind`` is None.
    """
    if kind is not None:
        if kind not in SHOW_KINDS:
            raise UsageError(f"unknown kind '{kind}' (kinds: {', '.join(SHOW_KINDS)})")
        getattr(kb, kind)(item_id)  # raises UsageError naming the known ids
        return kind
    kinds = [k for k, attr in SHOW_KINDS.items() if item_id in getattr(kb, attr)]
    if not kinds:
        known = {k: sorted(getattr(kb, SHOW_KINDS[k])) for k in ("object", "culture",
                                                                 "receiver", "scene")}
        listed = "; ".join(f"{k}s: {', '.join(v) or 'none'}" for k, v in known.items())
        raise UsageError(f"no object, culture, receiver, scene, gripper, hand or robot "
                         f"'{item_id}' in the KB ({listed})")
    if len(kinds) > 1:
        raise UsageError(f"'{item_id}' names a {' and a '.join(kinds)}; choose with --kind")
    return kinds[0]


def show_item(kb: KB, item_id: str, kind: str | None = None,
              culture: str = "common") -> dict[str, Any]:
    """Everything ``kb show`` says of one item: :func:`object_view` for an object (with the
    rules of ``culture``), :func:`culture_view` for a culture, the model's fields for the
    other kinds. Every view has ``kind``, ``id`` and ``source`` (file:line).

    Raises UsageError as :func:`item_kind` does, or for an unknown ``culture``.
    """
    which = item_kind(kb, item_id, kind)
    if which == "object":
        kb.culture(culture)
        return object_view(kb, kb.object(item_id), culture)
    if which == "culture":
        return culture_view(kb, item_id)
    model: KBModel = getattr(kb, which)(item_id)
    return {"kind": which, **model.model_dump(mode="json"), "source": str(model.source)}


def rule_view(rr: ResolvedRule, obj: ObjectSpec | None = None) -> dict[str, Any]:
    """A rule in force: what it says and when (in words), why, where it is written, and the
    rules it overrides. With ``obj``: whether the object meets the rule's object conditions
    (``"met"``) or only its geometry can tell (``"depend on the geometry"``)."""
    rule = rr.rule
    out: dict[str, Any] = {
        "id": rule.id,
        "culture": rr.culture,
        "kind": rule.kind,
        "hard": rule.hard,
        "weight": rule.weight,
        "safety": rule.safety,
        "says": rule.describe(),
        "when": describe_applies(rule.applies),
        "why": _text(rule.why),
        "source": str(rule.source),
        "overrides": [
            {"id": o.rule.id, "culture": o.culture, "source": str(o.rule.source)}
            for o in rr.chain()
        ],
    }
    if rule.override_safety:
        out["override_safety"] = _text(rule.override_safety)
    if rule.fallback:
        out["fallback"] = rule.fallback
    if rule.warn:
        out["warn"] = _text(rule.warn)
    if obj is not None:
        verdict = applies_to_object(rule, obj)
        out["object_conditions"] = "met" if verdict else "depend on the geometry"
    return out


def object_view(kb: KB, obj: ObjectSpec, culture: str) -> dict[str, Any]:
    """An object: parts, axes, tasks, size (m, None for a mesh), and the rules of
    ``culture`` that can apply to it (``rules``, see :func:`rule_view`) or cannot
    (``not_applicable``: id, source, reason)."""
    resolved = resolve_culture(kb, culture)
    families = tag_families(kb)
    rules, skipped = [], []
    for rr in resolved:
        reason = not_applicable(rr.rule, obj, families)
        if reason is None:
            rules.append(rule_view(rr, obj))
        else:
            skipped.append({"id": rr.rule.id, "source": str(rr.rule.source), "reason": reason})
    size = object_size(obj)
    return {
        "kind": "object",
        "id": obj.id,
        "name": obj.name,
        "mass": obj.mass,
        "size": None if size is None else round(size, 6),
        "tags": list(obj.tags),
        "source": str(obj.source),
        "geometry": "mesh" if obj.geometry.mesh is not None else "primitives",
        "parts": [
            {"name": name, "tags": list(p.tags), "why": _text(p.why)}
            for name, p in obj.parts.items()
        ],
        "axes": {name: list(v) for name, v in obj.axes.items()},
        "tasks": [
            {
                "id": tid,
                "receiver_tags": list(t.receiver_tags),
                "receiver_site": t.receiver_site,
                "present": [p.model_dump(mode="json") for p in t.present],
                "why": _text(t.why),
                "source": str(t.source),
            }
            for tid, t in obj.tasks.items()
        ],
        "default_task": obj.default_task,
        "tags_with_rules": tag_rules(kb, culture, only=object_tags(obj, families)),
        "culture": culture,
        "rules_in_culture": len(resolved),
        "rules": rules,
        "not_applicable": skipped,
    }


def culture_view(kb: KB, culture_id: str) -> dict[str, Any]:
    """A culture: the chain of cultures it extends, its resolved rules (base rules first),
    and the tags those rules name (:func:`tag_rules`)."""
    c = kb.culture(culture_id)
    chain, _ = culture_chain(kb, culture_id)
    return {
        "kind": "culture",
        "id": c.id,
        "name": c.name,
        "extends": culture_parent(c),
        "chain": chain,
        "why": _text(c.why),
        "source": str(c.source),
        "rules": [rule_view(rr) for rr in resolve_culture(kb, culture_id)],
        "tags": tag_rules(kb, culture_id),
    }


def tag_rules(kb: KB, culture_id: str, only: set[str] | None = None) -> list[dict[str, Any]]:
    """The tags the rules in force in ``culture_id`` name (in their ``applies`` or their
    kind's tag fields), each with its meaning (the vocabulary's, else None), the ids of those
    rules and whether one is a safety rule (``hazard``: the hazard vocabulary in force).
    Hazard tags first, each group in vocabulary order then alphabetical; ``only``: these
    tags alone (an object's)."""
    from handover.engine.load.lint import rule_tags, vocabulary

    words = vocabulary(kb)
    rules: dict[str, list[RuleBase]] = {}
    for rr in resolve_culture(kb, culture_id):
        for tag, _ in rule_tags(rr.rule):
            if only is None or tag in only:
                named = rules.setdefault(tag, [])
                if rr.rule not in named:
                    named.append(rr.rule)
    order = {tag: k for k, tag in enumerate(words)}
    rows = [{"tag": tag, "meaning": words.get(tag),
             "hazard": any(r.safety for r in named),
             "rules": [r.id for r in named]} for tag, named in rules.items()]
    rows.sort(key=lambda r: (not r["hazard"], order.get(r["tag"], len(order)), r["tag"]))
    return rows


@dataclass(frozen=True)
class _ObjectSituation:
    obj: ObjectSpec
    task: Task | None


@dataclass(frozen=True)
class ObjectOnly:
    """What a query knows of its object before any geometry is built: the object, one of its
    tasks, and the tags of its parts. It offers the fields of a plan context that a rule
    kind's ``not_applicable`` reads (``situation.obj``, ``situation.task``, ``part_tags``,
    ``own_part_tags``), so ``kb show`` asks the kind itself, as the compiler does."""

    situation: _ObjectSituation
    part_tags: list[set[str]]
    own_part_tags: list[set[str]]

    @classmethod
    def of(cls, obj: ObjectSpec, task_id: str | None,
           families: TagFamilies | None = None) -> ObjectOnly:
        """The object ``obj`` queried with its task ``task_id`` (None: no task); its parts'
        tags as a plan has them (the object's, and what they imply in ``families``)."""
        task = obj.tasks[task_id] if task_id is not None else None
        return cls(_ObjectSituation(obj, task), part_tags(obj, obj.parts, families),
                   part_tags(obj, obj.parts, families, whole_object=False))


def not_applicable(rule: RuleBase, obj: ObjectSpec,
                   families: TagFamilies | None = None) -> str | None:
    """Why ``rule`` cannot bear on ``obj`` whatever the query (None when it can): the object
    fails its conditions, or the rule's kind cannot judge this object with any of its tasks
    (the reason given is the one for the object's default task). ``families``: the KB's
    hazard vocabulary (what the object's tags imply)."""
    if applies_to_object(rule, obj, families) is False:
        return f"needs {describe_applies(rule.applies)}"
    tasks = [obj.default_task, *(t for t in obj.tasks if t != obj.default_task)]
    reasons = [judge.not_applicable(rule, ObjectOnly.of(obj, t, families))  # type: ignore[arg-type]
               for t in tasks]
    return None if None in reasons else reasons[0]
