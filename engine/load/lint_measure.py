"""Objects whose tags ask for a measurement their geometry cannot give: warnings of ``kb
validate``, located at the object.

A rule that cannot measure what it is about says ``unknown`` in a plan and a hard one then
blocks the handover (:mod:`handover.engine.plan.judge`); here the KB's author hears of it
before planning. Checked, for every object a rule names by its tags:

- a ``keep_out`` rule (an open container's opening): the object's geometry must have one, the
  cavity of a cup, bowl or tube primitive on the tagged parts, or a surface that holds
  something standing along its ``up`` axis (:func:`handover.engine.assets.objects.
  object_interior`), and it needs the ``up`` axis to tell;
- an ``axis`` rule that applies to it by its tags (``applies.object_tags_any``): the object
  must name that axis (:func:`handover.engine.load.lint.lint_cultures` warns for it, with the
  same words).

Building an object's geometry costs a few milliseconds (a mesh file is read), so this runs
with the deep checks (``handover kb validate``, ``load_kb(urdf=True)``), not when a planner
loads the KB.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from handover.engine.errors import KBIssue
from handover.engine.spec.schema import ObjectSpec
from handover.engine.store.cultures import applies_to_object, object_tags

if TYPE_CHECKING:
    from handover.engine.store.kb import KB

__all__ = ["lint_measurements", "opening_missing"]


def opening_missing(kb: KB, obj: ObjectSpec, tags: set[str]) -> str | None:
    """Why ``obj`` has no opening a rule about ``tags`` could keep hands out of (None: it
    has one). A mesh file that does not load is left to the mesh checks."""
    from handover.engine.assets.objects import object_interior, object_part_mesh
    from handover.geometry.mesh import MeshError

    if "up" not in obj.axes:
        return "it has no 'up' axis to find its opening along"
    whole = bool(set(obj.tags) & tags)
    parts = None if whole else {n for n, p in obj.parts.items() if set(p.tags) & tags}
    try:
        interior = object_interior(kb, obj, object_part_mesh(kb, obj), parts=parts)
    except MeshError:
        return None
    if len(interior):
        return None
    if obj.geometry.primitives:
        return ("its geometry has no opening: no cup, bowl or tube primitive on the parts so "
                "tagged, and its surface holds nothing standing along 'up'")
    return "no cavity that holds anything standing along its 'up' axis was found in its mesh"


def lint_measurements(kb: KB) -> Iterator[KBIssue]:
    """Warnings for the objects whose tags bring a ``keep_out`` rule their geometry cannot
    judge (see the module docstring)."""
    rules = [r for c in kb.cultures.values() for r in c.rules if r.kind == "keep_out"]
    for obj in kb.objects.values():
        carried = object_tags(obj)
        asked: dict[str, list[str]] = {}
        for rule in rules:
            tags = set(rule.tags) & carried
            if tags and applies_to_object(rule, obj) is not False:
                asked.setdefault("/".join(sorted(tags)), []).append(rule.id)
        for tags, ids in asked.items():
            why = opening_missing(kb, obj, set(tags.split("/")))
            if why is not None:
                yield kb.issue(obj, f"object '{obj.id}' is tagged {tags}, but {why}: "
                               f"{', '.join(sorted(set(ids)))} cannot measure it and a plan "
                               "will not hand it over (model the container with a cup, bowl "
                               "or tube primitive, or give it a mesh with its cavity and an "
                               "'up' axis; a closed container, a kettle with its lid on or a "
                               f"capped bottle, is tagged container, not {tags})",
                               severity="warning")
