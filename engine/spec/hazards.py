"""The hazard vocabulary: a KB document (``hazards/``) that declares hazard tags, what each
means, where the meaning comes from, and which tags it implies, so an author writes the one
word that fits (``corrosive``) and every rule about its family (``chemical``) applies; and
the hazards measured on an object's geometry rather than tagged (``swallowable``: whatever
fits the small-parts cylinder).

>>> from handover.engine.spec.hazards import HazardFile
>>> doc = HazardFile(id="home", name="Home", tags={
...     "chemical": {"means": "A household chemical."},
...     "corrosive": {"means": "Burns skin.", "implies": ["chemical"]}})
>>> doc.tags["corrosive"].implies
['chemical']

Which tags a tag implies, all the way down, and the checks across documents (an implied tag
nobody declares, a cycle of implications, a tag declared twice) are the store's
(:mod:`handover.engine.store.hazards`).
"""

from __future__ import annotations

from pydantic import Field

from handover.engine.spec.kbmodel import Id, KBModel, Positive, Tag

__all__ = ["HazardTag", "Cylinder", "MeasuredHazard", "HazardFile"]


class HazardTag(KBModel):
    """One hazard tag.

    means : what an object or part so tagged is, in a sentence (shown by ``kb show``).
    implies : the tags it brings with it (``corrosive`` -> ``chemical``): rules naming those
        apply to whatever carries this one.
    sources : where the meaning comes from (standards, guidance), each in a sentence.
    """

    means: str = Field(min_length=1)
    implies: list[Tag] = []
    sources: list[str] = []


class Cylinder(KBModel):
    """A test cylinder: ``diameter`` and ``length`` (m, inside)."""

    diameter: Positive
    length: Positive


class MeasuredHazard(KBModel):
    """A hazard read from the geometry, whatever the object's tags: an object that fits
    ``fits_cylinder`` in some orientation carries ``tag`` (and what it implies).

    tag : the hazard tag it gives (declared in a hazards file's ``tags``). why : why the size
    matters, in a sentence. sources : the standards that define the test.
    """

    tag: Tag
    fits_cylinder: Cylinder
    why: str = Field(min_length=1)
    sources: list[str] = []


class HazardFile(KBModel):
    """A ``hazards/`` document: hazard tags (``tags``: tag -> :class:`HazardTag`) and hazards
    measured on the geometry (``measured``: :class:`MeasuredHazard`)."""

    id: Id
    name: str
    why: str = ""
    tags: dict[Tag, HazardTag] = {}
    measured: list[MeasuredHazard] = []
