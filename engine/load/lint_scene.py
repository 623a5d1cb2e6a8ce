"""Semantic checks of a scene (part of ``handover kb validate``, see
:mod:`handover.engine.load.lint`): people standing inside the furniture, an object that would
float beside the table.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import TYPE_CHECKING

from handover.geometry.frames import rotation_from_euler_deg

if TYPE_CHECKING:
    from handover.engine.errors import KBIssue
    from handover.engine.store.kb import KB

__all__ = ["lint_scene", "PERSON_HEIGHT", "DEFAULT_OBJECT_XY"]


PERSON_HEIGHT = 1.0
"""m: the part of a standing person (from the feet up) that must be free of furniture."""

DEFAULT_OBJECT_XY = (0.5, 0.0)
"""m, world: where the object is put when a scene gives no placement (engine.plan.context)."""


def _segment_hits_box(p0, p1, centre, extents, rotation_deg) -> bool:
    """Whether the segment p0-p1 (world, m) meets the box (centre, extents, rotation
    extrinsic x, y, z degrees); a segment that only touches a face does not."""
    r = rotation_from_euler_deg(rotation_deg).tolist()
    local = [
        [sum(r[i][j] * (p[i] - centre[i]) for i in range(3)) for j in range(3)] for p in (p0, p1)
    ]
    lo, hi = 0.0, 1.0  # Liang-Barsky clipping against the open slabs
    for a in range(3):
        half = extents[a] / 2.0
        start, delta = local[0][a], local[1][a] - local[0][a]
        if abs(delta) < 1e-12:
            if not -half < start < half:
                return False
            continue
        t0, t1 = sorted(((-half - start) / delta, (half - start) / delta))
        lo, hi = max(lo, t0), min(hi, t1)
        if lo >= hi:
            return False
    return True


def lint_scene(kb: KB, scene) -> Iterator[KBIssue]:
    """A scene whose people stand inside the furniture, or whose object would float.

    Errors: the receiver or the robot (standing at the origin) inside the table's footprint
    or an obstacle (from the feet up to :data:`PERSON_HEIGHT`); the object's placement (or
    the default one) off the table top.
    """
    support = scene.support
    boxes = []
    if support is not None:
        top = support.position
        extents = (support.size[0], support.size[1], top[2] + 1.0)  # down to the floor and below
        centre = (top[0], top[1], top[2] - extents[2] / 2.0)
        boxes.append(("the table", centre, extents, (0.0, 0.0, 0.0), ("support", "position")))
    for k, box in enumerate(scene.obstacles):
        boxes.append((f"obstacle '{box.id}'", box.position, box.extents, box.rotation_deg,
                      ("obstacles", k, "position")))  # fmt: skip
    people = [
        ("the receiver", tuple(scene.receiver.position), scene.receiver, ("position",)),
        ("the robot (at the origin)", (0.0, 0.0, 0.0), None, ()),
    ]
    rx, ry, _ = scene.receiver.position
    if math.hypot(rx, ry) < 1e-6:
        yield kb.issue(scene.receiver, f"scene '{scene.id}': the receiver stands on the robot "
                       "(at the origin): no direction to hand over in", "position")  # fmt: skip
    fx, fy, _ = scene.receiver.facing
    if math.hypot(fx, fy) < 1e-6:
        yield kb.issue(scene.receiver, f"scene '{scene.id}': the receiver faces straight up or "
                       "down; 'facing' needs a horizontal part", "facing")  # fmt: skip
    for who, feet, model, sub in people:
        head = (feet[0], feet[1], feet[2] + PERSON_HEIGHT)
        for name, centre, extents, rot, box_sub in boxes:
            if _segment_hits_box(feet, head, centre, extents, rot):
                where = ", ".join(f"{c:g}" for c in feet)
                yield kb.issue(
                    model if model is not None else scene,
                    f"scene '{scene.id}': {who} stands at ({where}), inside {name}; "
                    "people stand beside the furniture",
                    *(sub if model is not None else box_sub),
                )
    if support is not None:
        xy = scene.object.position if scene.object is not None else DEFAULT_OBJECT_XY
        half = (support.size[0] / 2.0, support.size[1] / 2.0)
        if any(abs(xy[a] - support.position[a]) > half[a] for a in range(2)):
            x0, y0 = support.position[0], support.position[1]
            yield kb.issue(
                scene.object if scene.object is not None else scene,
                f"scene '{scene.id}': the object is placed at ({xy[0]:g}, {xy[1]:g}), off the "
                f"table (x {x0 - half[0]:g}..{x0 + half[0]:g}, y {y0 - half[1]:g}.."
                f"{y0 + half[1]:g}): it would float at the table's height",
                *(("position",) if scene.object is not None else ("support",)),
            )
