"""What a container holds standing up: the opening of a cup, a glass, a bowl, a pot or a
tray found from its surface alone.

The object is looked at from above, along its ``up`` axis, through a square grid of vertical
columns: a ray cast down each column (embreex) finds the first surface it meets (a cup's
floor through its opening, the top of its rim on the wall, nothing beside the object). The
levels water would stand at are then those of a depression-filling flood over that height
map (as on terrain, priority-flood, Barnes et al. 2014: each column fills to the lowest rim
it would spill over on its way out of the grid, four neighbours a step): the columns where
the level stands above the surface hold something, from the surface up to the level. That
is the volume no finger may enter, whatever the mesh: a handle reaching above the rim, a
wavy rim, a scanned surface with holes in its sides (rays need no closed mesh), a bowl, a
tray with walls. A floor with a hole drains it (nothing held), and a solid holds nothing.

:class:`Columns` holds the result and answers whether points lie inside (vectorised, exact
for the columns). The grid turns about ``up`` with the object's own shape (the principal
axis of its outline seen from above), so the same object written in another frame gives the
same columns.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.mesh import ray_first_hits

if TYPE_CHECKING:
    import trimesh

__all__ = ["Columns", "held_volume", "GRID_CELLS", "MIN_DEPTH", "MIN_CELL"]

GRID_CELLS = 200
"""Columns across the object's larger extent seen from above (a 10 cm mug: 0.5 mm cells)."""
MIN_CELL = 2.5e-4
"""m: the finest column (a small object is not looked at finer than this)."""
MIN_DEPTH = 1e-3
"""m: a column holds something only where the level stands this much above its surface
(less is tessellation, not a container)."""
MIN_COLUMNS = 4
"""A group of holding columns (four-connected) smaller than this is dropped (a dimple)."""
_TOL = 1e-9


@dataclass(frozen=True)
class Columns:
    """A volume made of square columns standing along an axis.

    frame : (3, 3) columns are the grid's axes ``e1, e2, up`` in the object frame.
    origin : (3,) m, object frame: the grid's corner (cell ``(0, 0)`` spans ``[0, cell)``
        along ``e1`` and ``e2`` from it; heights are along ``up`` from it).
    cell : m, the columns' side.
    floor, top : (I, J) float, m: each column holds ``floor < h < top`` along ``up``; NaN
        where a column holds nothing.
    """

    frame: np.ndarray
    origin: np.ndarray
    cell: float
    floor: np.ndarray
    top: np.ndarray

    @property
    def held(self) -> np.ndarray:
        """(I, J) bool: the columns that hold something."""
        return np.isfinite(self.top)

    def __len__(self) -> int:
        return int(self.held.sum())

    @property
    def volume(self) -> float:
        """m^3: what the columns hold."""
        depth = np.where(self.held, self.top - self.floor, 0.0)
        return float(depth.sum() * self.cell**2)

    def local(self, points: np.ndarray) -> np.ndarray:
        """(n, 3) the points (n, 3), m, object frame, in the grid's frame."""
        return (np.asarray(points, dtype=float).reshape(-1, 3) - self.origin) @ self.frame

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(n,) bool: which points (n, 3), m, object frame, lie inside a column (on its
        floor or at its level counts as outside: a palm resting on the rim plane does not
        enter)."""
        p = self.local(points)
        i = np.floor(p[:, 0] / self.cell).astype(np.int64)
        j = np.floor(p[:, 1] / self.cell).astype(np.int64)
        n, m = self.top.shape
        inside = (i >= 0) & (i < n) & (j >= 0) & (j < m)
        out = np.zeros(len(p), dtype=bool)
        k = np.flatnonzero(inside)
        floor, top = self.floor[i[k], j[k]], self.top[i[k], j[k]]
        out[k] = np.isfinite(top) & (p[k, 2] > floor + _TOL) & (p[k, 2] < top - _TOL)
        return out

    def corners(self) -> np.ndarray:
        """(V, 3) m, object frame: the vertices of the convex hull of the columns' corners
        (at their floors and levels), the points a box thinner than a lattice step may
        still hold (:meth:`handover.geometry.interior.Interior.boxes_enter`)."""
        from scipy.spatial import ConvexHull

        i, j = np.nonzero(self.held)
        if not len(i):
            return np.zeros((0, 3))
        pts = []
        for di in (0.0, 1.0):
            for dj in (0.0, 1.0):
                for h in (self.floor[i, j], self.top[i, j]):
                    pts.append(np.stack([(i + di) * self.cell, (j + dj) * self.cell, h], 1))
        local = np.concatenate(pts)
        try:
            local = local[ConvexHull(local).vertices]
        except Exception:  # flat or degenerate: every corner counts  # noqa: BLE001
            pass
        return local @ self.frame.T + self.origin

    def transformed(self, transform: np.ndarray) -> Columns:
        """The columns moved by a rigid ``transform`` (4, 4)."""
        t = np.asarray(transform, dtype=float)
        return Columns(t[:3, :3] @ self.frame, t[:3, :3] @ self.origin + t[:3, 3], self.cell,
                       self.floor, self.top)

    def mesh(self) -> trimesh.Trimesh | None:
        """The columns as boxes in one mesh (for display), or None when they hold nothing."""
        import trimesh

        i, j = np.nonzero(self.held)
        if not len(i):
            return None
        boxes = []
        for a, b in zip(i, j, strict=True):
            h0, h1 = float(self.floor[a, b]), float(self.top[a, b])
            centre = np.array([(a + 0.5) * self.cell, (b + 0.5) * self.cell, (h0 + h1) / 2])
            pose = np.eye(4)
            pose[:3, :3] = self.frame
            pose[:3, 3] = self.frame @ centre + self.origin
            boxes.append(trimesh.creation.box((self.cell, self.cell, h1 - h0), pose))
        return trimesh.util.concatenate(boxes)


def grid_frame(vertices: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(3, 3) columns ``e1, e2, up``: ``e1`` the principal axis of the vertices (n, 3) seen
    from above (signed towards their longer tail), so the grid turns with the object's shape,
    not with the frame it is written in; a round outline (no principal axis) takes a fixed
    perpendicular of ``up``."""
    from handover.geometry.frames import perpendicular

    u = np.asarray(up, dtype=float).reshape(3)
    u = u / np.linalg.norm(u)
    v = np.asarray(vertices, dtype=float)
    flat = v - v.mean(axis=0)
    flat = flat - np.outer(flat @ u, u)
    _, s, vt = np.linalg.svd(flat, full_matrices=False)
    e1 = vt[0] - (vt[0] @ u) * u
    if s[0] <= 1e-9 or s[1] >= 0.999 * s[0] or np.linalg.norm(e1) < 1e-9:
        e1 = perpendicular(u)
    e1 = e1 / np.linalg.norm(e1)
    skew = float(np.sum((flat @ e1) ** 3))
    if skew < 0:
        e1 = -e1
    return np.stack([e1, np.cross(u, e1), u], axis=1)


def held_volume(mesh: trimesh.Trimesh, up: np.ndarray, *, cells: int = GRID_CELLS,
                min_depth: float = MIN_DEPTH) -> Columns:
    """What ``mesh`` holds standing along ``up`` (see the module docstring).

    mesh : object frame, m; need not be closed. up : (3,) the way it stands (its opening
    faces up). cells : columns across its larger extent seen from above. min_depth : m, the
    least depth a column must hold.
    Returns the :class:`Columns` (empty when it holds nothing). Deterministic.
    """
    u = np.asarray(up, dtype=float).reshape(3)
    if not np.all(np.isfinite(u)) or np.linalg.norm(u) < 1e-12:
        raise ValueError(f"the up direction must be a non-zero finite vector, got {u.tolist()}")
    vertices = np.asarray(mesh.vertices, dtype=float)
    frame = grid_frame(vertices, u)
    local = vertices @ frame
    lo, hi = local.min(axis=0), local.max(axis=0)
    cell = max(float(np.max(hi[:2] - lo[:2])) / int(cells), MIN_CELL)
    origin_local = np.array([lo[0] - 2.0 * cell, lo[1] - 2.0 * cell, lo[2]])
    n = int(np.ceil((hi[0] - origin_local[0]) / cell)) + 2
    m = int(np.ceil((hi[1] - origin_local[1]) / cell)) + 2
    origin = frame @ origin_local
    ii, jj = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    above = hi[2] - lo[2] + 0.1 * (hi[2] - lo[2] + cell)
    centres = np.stack([(ii + 0.5) * cell, (jj + 0.5) * cell, np.full(ii.shape, above)], -1)
    starts = centres.reshape(-1, 3) @ frame.T + origin
    down = np.broadcast_to(-frame[:, 2], starts.shape)
    hit, dist = ray_first_hits(mesh, starts, np.ascontiguousarray(down))
    surface = np.where(hit >= 0, above - dist, -np.inf).reshape(n, m)
    level = _flood(surface)
    with np.errstate(invalid="ignore"):  # -inf - -inf where nothing is: NaN, holds nothing
        depth = level - surface
    holds = np.isfinite(surface) & (depth > min_depth)
    holds = _drop_small(holds)
    floor = np.where(holds, surface, np.nan)
    top = np.where(holds, level, np.nan)
    return Columns(frame, origin, cell, floor, top)


def _flood(surface: np.ndarray) -> np.ndarray:
    """(I, J) the level water stands at over the height map ``surface`` (I, J) (``-inf``:
    no surface, where it drains): the least level from which a path of four-neighbour steps
    leaves the grid never climbing above it (the border drains). Computed by relaxation to
    the fixed point, vectorised."""
    level = np.full(surface.shape, np.inf)
    level[0, :], level[-1, :], level[:, 0], level[:, -1] = (
        surface[0, :], surface[-1, :], surface[:, 0], surface[:, -1])
    level = np.maximum(level, surface)
    while True:
        low = level.copy()
        low[1:, :] = np.minimum(low[1:, :], level[:-1, :])
        low[:-1, :] = np.minimum(low[:-1, :], level[1:, :])
        low[:, 1:] = np.minimum(low[:, 1:], level[:, :-1])
        low[:, :-1] = np.minimum(low[:, :-1], level[:, 1:])
        new = np.maximum(surface, low)
        if np.array_equal(new, level):
            return level
        level = new


def _drop_small(holds: np.ndarray) -> np.ndarray:
    """``holds`` without its four-connected groups of fewer than :data:`MIN_COLUMNS`."""
    from scipy.ndimage import label

    labels, count = label(holds)
    if not count:
        return holds
    sizes = np.bincount(labels.ravel())
    keep = sizes >= MIN_COLUMNS
    keep[0] = False
    return keep[labels]
