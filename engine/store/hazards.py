"""The hazard vocabulary of a KB, resolved: which tags each tag implies all the way down
(``battery`` -> ``swallowable``; ``corrosive`` -> ``chemical``), what each means, and the
hazards measured on an object's geometry; and the checks across ``hazards/`` documents.

Every tag an object or part carries brings the tags it implies, so rules written for a
family (``chemical``) apply to its members (``corrosive``, ``toxic``) without naming them.

Errors (each at its file:line): a tag declared in two hazards files; an implied tag no
hazards file declares, no culture's vocabulary documents and no object carries; a cycle of
implications (a tag that implies itself, through others or directly); a measured hazard whose
tag no hazards file declares.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from handover.engine.errors import KBIssue

if TYPE_CHECKING:
    from handover.engine.spec.hazards import HazardTag, MeasuredHazard
    from handover.engine.store.kb import KB

__all__ = ["TagFamilies", "tag_families", "hazard_issues"]


@dataclass(frozen=True)
class TagFamilies:
    """The hazard tags of a KB, resolved.

    implied : tag -> every tag it implies, through any chain (never itself). declared : tag
    -> its :class:`~handover.engine.spec.hazards.HazardTag`. sources : tag -> ``file:line``
    of its declaration. measured : the hazards read from the geometry, in KB order.
    """

    implied: dict[str, frozenset[str]] = field(default_factory=dict)
    declared: dict[str, HazardTag] = field(default_factory=dict)
    sources: dict[str, str] = field(default_factory=dict)
    measured: tuple[MeasuredHazard, ...] = ()

    def expand(self, tags: Iterable[str]) -> frozenset[str]:
        """``tags`` with every tag they imply."""
        out = set(tags)
        for tag in list(out):
            out |= self.implied.get(tag, frozenset())
        return frozenset(out)

    def implied_by(self, tags: Iterable[str]) -> dict[str, str]:
        """The tags ``tags`` bring that they do not name, each with the tag that brings it
        (the first in sorted order) and its declaration: ``{"chemical": "implied by
        corrosive (hazards/household.yaml:12)"}``."""
        given = set(tags)
        out: dict[str, str] = {}
        for tag in sorted(given):
            for other in sorted(self.implied.get(tag, frozenset()) - given):
                out.setdefault(other, f"implied by {tag} ({self.sources.get(tag, '?')})")
        return out


def tag_families(kb: KB) -> TagFamilies:
    """The hazard vocabulary of ``kb`` (every ``hazards/`` document; a tag declared twice
    keeps its first declaration, a cycle is cut where it closes: both are errors of
    :func:`hazard_issues`)."""
    declared: dict[str, HazardTag] = {}
    sources: dict[str, str] = {}
    measured: list[MeasuredHazard] = []
    for doc in kb.hazards.values():
        for tag, spec in doc.tags.items():
            if tag not in declared:
                declared[tag] = spec
                sources[tag] = str(spec.source)
        measured.extend(doc.measured)
    implied: dict[str, frozenset[str]] = {}
    for tag in declared:
        seen: set[str] = set()
        stack = list(declared[tag].implies)
        while stack:
            other = stack.pop()
            if other in seen or other == tag:
                continue
            seen.add(other)
            if other in declared:
                stack.extend(declared[other].implies)
        implied[tag] = frozenset(seen)
    return TagFamilies(implied, declared, sources, tuple(measured))


def hazard_issues(kb: KB, known: set[str]) -> list[KBIssue]:
    """The errors across the ``hazards/`` documents of ``kb`` (see the module docstring).
    ``known``: the tags documented elsewhere (the cultures' vocabularies, objects' tags),
    which an implication may name too."""
    issues: list[KBIssue] = []
    first: dict[str, str] = {}
    for doc in kb.hazards.values():
        for tag, spec in doc.tags.items():
            if tag in first:
                issues.append(_at_key(kb, doc, ("tags", tag), f"hazard tag '{tag}' is declared "
                                      f"twice (first at {first[tag]})"))
            first.setdefault(tag, str(spec.source))
    families = tag_families(kb)
    declared = set(families.declared)
    for doc in kb.hazards.values():
        for tag, spec in doc.tags.items():
            for k, other in enumerate(spec.implies):
                if other not in declared and other not in known:
                    issues.append(kb.issue(
                        doc, f"hazard tag '{tag}' implies '{other}', which no hazards file "
                        "declares, no culture's vocabulary documents and no object carries "
                        "(a misspelt family silently drops its rules)", "tags", tag,
                        "implies", k))
                elif other == tag or tag in families.implied.get(other, frozenset()):
                    loop = " -> ".join(_loop(families, tag, other))
                    issues.append(kb.issue(
                        doc, f"hazard tag '{tag}' implies '{other}', which implies '{tag}' "
                        f"back: a cycle of implications ({loop})", "tags", tag, "implies", k))
        for k, m in enumerate(doc.measured):
            if m.tag not in declared:
                issues.append(kb.issue(
                    doc, f"measured hazard '{m.tag}' is not a hazard tag: declare it under "
                    "'tags' with what it means", "measured", k, "tag"))
    return issues


def _at_key(kb: KB, doc, sub: tuple, message: str) -> KBIssue:
    """An error at the key ``sub`` of ``doc`` (the tag's name, not its mapping below)."""
    marks = kb.marks.get(doc.source.file)
    if marks is None:
        return kb.issue(doc, message, *sub)
    line, col = marks.key((*doc.source.path, *sub))
    return KBIssue(doc.source.file, line, col, message)


def _loop(families: TagFamilies, start: str, nxt: str) -> list[str]:
    """The tags of a cycle through ``start`` and then ``nxt``, back to ``start``."""
    path = [start, nxt]
    while path[-1] != start and len(path) < 64:
        spec = families.declared.get(path[-1])
        step = next((t for t in (spec.implies if spec else [])
                     if t == start or start in families.implied.get(t, frozenset())), None)
        if step is None:
            break
        path.append(step)
    return path
