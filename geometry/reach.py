"""Reachability maps: which tool poses an arm can reach, as voxels x approach directions.

A :class:`ReachMap` covers the arm's workspace (a cube around its first joint, as wide as
the chain is long) with voxels of ``voxel`` metres; each voxel holds one bit per approach
direction bin (``directions`` points of a Fibonacci sphere). Building samples random
configurations within the joint limits (seeded), computes the tool poses by forward
kinematics and sets the bit of each pose's voxel and of its approach direction (the tool
frame's z column, the grasp frame's ``a``). It then grows the set by a tolerance: each set bit
also sets the neighbouring voxels (``voxel_tolerance`` voxels on every side) and the
``direction_tolerance`` nearest direction bins, so that a pose between samples is not missed.
A lookup is then one bit read per pose (:meth:`ReachMap.reachable`).

The map is a screen, not a proof: ``True`` means a sample came near (confirm with IK), ``False``
means no sample did. ``benchmarks/kinematics.py`` measures its precision and recall against IK.

Maps are saved as ``.npz`` files (bits packed) named by a key that hashes the URDF's content,
the chain, the tool transform and the build parameters (:func:`map_key`);
:meth:`ReachMap.cached` loads one from a directory or builds and saves it.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from handover.geometry.atomic import atomic_path
from handover.geometry.kinematics import Kinematics
from handover.geometry.urdf import RobotModelError

__all__ = ["ReachMap", "fibonacci_sphere", "map_key", "workspace"]

_FORMAT = 1
# Direction lookup table: equal-area cells (uniform in z, uniform in azimuth).
_LUT_Z = 64
_LUT_PHI = 128
_SAMPLE_CHUNK = 1 << 16


def fibonacci_sphere(n: int) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere (the Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _direction_lut(directions: np.ndarray) -> np.ndarray:
    """(_LUT_Z * _LUT_PHI,) int: the nearest direction bin of each lookup cell's centre."""
    z = -1.0 + (np.arange(_LUT_Z) + 0.5) * 2.0 / _LUT_Z
    phi = -np.pi + (np.arange(_LUT_PHI) + 0.5) * 2.0 * np.pi / _LUT_PHI
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    r = np.sqrt(1.0 - zz**2)
    centres = np.stack([r * np.cos(pp), r * np.sin(pp), zz], axis=-1).reshape(-1, 3)
    return np.argmax(centres @ directions.T, axis=1).astype(np.int32)


def _settled(x: np.ndarray) -> np.ndarray:
    """x rounded to 1e-9 with no negative zeros: the same pose computed in another frame
    (rounding noise of 1e-16) falls in the same voxel and direction bin, and an axis-aligned
    approach has one azimuth (``atan2`` of signed zeros has four)."""
    return np.round(np.asarray(x, dtype=float), 9) + 0.0


def _direction_bins(approach: np.ndarray, lut: np.ndarray) -> np.ndarray:
    """(m,) int bins of unit vectors approach (m, 3) through the lookup table."""
    approach = _settled(approach)
    iz = np.clip(((approach[:, 2] + 1.0) * (0.5 * _LUT_Z)).astype(np.int64), 0, _LUT_Z - 1)
    phi = np.arctan2(approach[:, 1], approach[:, 0])
    ip = ((phi + np.pi) * (_LUT_PHI / (2.0 * np.pi))).astype(np.int64) % _LUT_PHI
    return lut[iz * _LUT_PHI + ip]


def map_key(urdf_hash: str, kin: Kinematics, **params: float | int) -> str:
    """A hex key naming a map: the URDF's content hash, the chain's end links, the tool
    transform and the build parameters."""
    h = hashlib.sha256()
    h.update(urdf_hash.encode())
    h.update(f"{kin.chain.base_link}\0{kin.chain.tip_link}\0".encode())
    h.update(np.round(kin.tcp, 12).tobytes())
    h.update(json.dumps({"format": _FORMAT, **params}, sort_keys=True).encode())
    return h.hexdigest()[:24]


@dataclass(eq=False)
class ReachMap:
    """Voxels x approach-direction bits over one arm's workspace (chain base frame, m).

    lower : (3,) the grid's lowest corner. voxel : edge length, m. shape : (3,) voxels per
    axis. directions : (D, 3) the bins' unit vectors. bits : (nx * ny * nz * D,) bool,
    index ``((ix * ny + iy) * nz + iz) * D + bin``. key : the name it is cached under.
    samples : configurations sampled. raw_fraction : fraction of bits set before the
    tolerance grew them.
    """

    lower: np.ndarray
    voxel: float
    shape: np.ndarray
    directions: np.ndarray
    bits: np.ndarray
    key: str = ""
    samples: int = 0
    raw_fraction: float = 0.0

    def __post_init__(self) -> None:
        self._lut = _direction_lut(self.directions)

    @property
    def nbytes(self) -> int:
        """Bytes of the packed bits (the size on disk, before compression)."""
        return (self.bits.size + 7) // 8

    @classmethod
    def build(
        cls,
        kin: Kinematics,
        *,
        samples: int = 20_000_000,
        voxel: float = 0.05,
        directions: int = 100,
        voxel_tolerance: int = 0,
        direction_tolerance: int = 2,
        erode: int = 0,
        seed: int = 0,
        key: str = "",
    ) -> ReachMap:
        """Fill a map by forward sampling ``samples`` configurations of ``kin``'s chain.

        voxel : m. directions : number of approach bins. voxel_tolerance : voxels added on
        every side of a reached voxel (0 or 1 is typical). direction_tolerance : nearest
        neighbouring bins also set for a reached bin. erode : then keep a bit only where
        the voxels on its six sides (``erode`` times over) hold it too: the map's rim, where
        a few samples came near but inverse kinematics mostly fails, is dropped (on the
        shipped arm, 1 raises precision against IK from 0.83 to 0.94 for a recall of 0.93;
        ``benchmarks/kinematics.py``). seed : the sampler's seed.
        """
        if samples < 1 or voxel <= 0 or directions < 1 or voxel_tolerance < 0 or erode < 0:
            raise RobotModelError("reach map: samples, voxel and directions must be positive")
        centre, radius = workspace(kin)
        n_vox = int(np.ceil(2.0 * radius / voxel))
        shape = np.array([n_vox] * 3, dtype=np.int64)
        lower = centre - 0.5 * n_vox * voxel
        dirs = fibonacci_sphere(directions)
        lut = _direction_lut(dirs)
        hit = np.zeros(int(np.prod(shape)) * directions, dtype=bool)
        rng = np.random.default_rng(seed)
        for start in range(0, samples, _SAMPLE_CHUNK):
            q = kin.random_configurations(min(_SAMPLE_CHUNK, samples - start), rng)
            poses = kin.fk(q, dtype=np.float32)
            idx = _cell_index(poses[:, :3, 3], lower, voxel, shape)
            flat = idx * directions + _direction_bins(poses[:, :3, 2], lut)
            hit[flat[idx >= 0]] = True
        raw = float(hit.mean())
        grid = hit.reshape(*shape, directions)
        if direction_tolerance > 0:
            near = np.argsort(-(dirs @ dirs.T), axis=1)[:, 1 : direction_tolerance + 1]
            grown = grid.copy()
            for k in range(near.shape[1]):
                grown |= grid[..., near[:, k]]
            grid = grown
        if voxel_tolerance > 0:
            from scipy.ndimage import binary_dilation

            size = 2 * voxel_tolerance + 1
            grid = binary_dilation(grid, structure=np.ones((size, size, size, 1), dtype=bool))
        if erode > 0:
            grid = _eroded(grid, erode)
        return cls(lower, float(voxel), shape, dirs, grid.reshape(-1), key, samples, raw)

    def eroded(self, erode: int = 1) -> ReachMap:
        """This map with its rim eroded ``erode`` voxels (see :meth:`build`'s ``erode``): the
        same as building with ``erode`` from the same samples, without sampling again."""
        grid = self.bits.reshape(*self.shape, len(self.directions))
        bits = _eroded(grid, erode).reshape(-1) if erode > 0 else self.bits.copy()
        return ReachMap(self.lower, self.voxel, self.shape, self.directions, bits,
                        f"{self.key}-eroded{erode}" if self.key else "", self.samples,
                        self.raw_fraction)

    def reachable(self, poses: np.ndarray) -> np.ndarray:
        """(m,) bool: whether a sample came near each tool pose (m, 4, 4), base frame, m.
        Poses outside the grid are unreachable."""
        poses = np.asarray(poses, dtype=float)
        if poses.ndim != 3 or poses.shape[1:] != (4, 4):
            raise RobotModelError(f"poses must have shape (m, 4, 4), got {poses.shape}")
        return self.lookup(poses[:, :3, 3], poses[:, :3, 2])

    def lookup(self, points: np.ndarray, approaches: np.ndarray) -> np.ndarray:
        """(m,) bool: whether a sample came near each tool position points (m, 3) with
        approach (tool z axis) approaches (m, 3, unit), base frame, m. Outside: False."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        approaches = np.asarray(approaches, dtype=float).reshape(-1, 3)
        idx = _cell_index(points, self.lower, self.voxel, self.shape)
        inside = idx >= 0
        flat = idx * len(self.directions) + _direction_bins(approaches, self._lut)
        return inside & self.bits[np.where(inside, flat, 0)]

    def reach_index(self, points: np.ndarray) -> np.ndarray:
        """(m,) float in [0, 1]: the fraction of approach-direction bins the map holds in the
        voxel of each position points (m, 3), base frame, m (0 outside the grid): how many
        ways the arm reaches there (the reuleaux "reachability index")."""
        if not hasattr(self, "_index"):
            d = len(self.directions)
            self._index = self.bits.reshape(-1, d).sum(axis=1, dtype=np.int32) / float(d)
        idx = _cell_index(np.asarray(points, dtype=float).reshape(-1, 3), self.lower,
                          self.voxel, self.shape)
        return np.where(idx >= 0, self._index[np.maximum(idx, 0)], 0.0)

    def save(self, directory: str | os.PathLike) -> Path:
        """Write ``reach-<key>.npz`` into ``directory`` (created if needed); returns its path."""
        path = Path(directory) / f"reach-{self.key or 'unnamed'}.npz"
        # Written whole or not at all, through a temporary file of this process's own:
        # processes sharing a database may save the same map at once.
        with atomic_path(path) as tmp, open(tmp, "wb") as out:
            np.savez_compressed(
                out,
                format=np.int64(_FORMAT),
                lower=self.lower,
                voxel=np.float64(self.voxel),
                shape=self.shape,
                directions=self.directions,
                packed=np.packbits(self.bits),
                key=np.str_(self.key),
                samples=np.int64(self.samples),
                raw_fraction=np.float64(self.raw_fraction),
            )
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> ReachMap:
        """Read a map written by :meth:`save`; a broken file raises ``RobotModelError``."""
        try:
            with np.load(path) as data:
                if int(data["format"]) != _FORMAT:
                    raise RobotModelError("reach map: unknown format", path)
                shape = data["shape"].astype(np.int64)
                dirs = data["directions"]
                size = int(np.prod(shape)) * len(dirs)
                bits = np.unpackbits(data["packed"], count=size).astype(bool)
                return cls(data["lower"], float(data["voxel"]), shape, dirs, bits,
                           str(data["key"]), int(data["samples"]),
                           float(data["raw_fraction"]))  # fmt: skip
        except RobotModelError:
            raise
        except Exception as exc:  # zip, key and value errors of a damaged file
            raise RobotModelError(f"reach map: cannot read ({exc})", path) from None

    @classmethod
    def cached(
        cls, kin: Kinematics, directory: str | os.PathLike, urdf_hash: str, **params
    ) -> ReachMap:
        """The map of ``kin`` with ``params`` (see :meth:`build`) from ``directory``, built and
        saved there first if absent or unreadable. ``urdf_hash`` : the URDF's content hash
        (``RobotModel.content_hash``)."""
        defaults = {"samples": 20_000_000, "voxel": 0.05, "directions": 100,
                    "voxel_tolerance": 0, "direction_tolerance": 2, "seed": 0}  # fmt: skip
        unknown = set(params) - set(defaults) - {"erode"}
        if unknown:
            raise RobotModelError(f"reach map: unknown parameters {sorted(unknown)}")
        full = {**defaults, **params}
        if not full.get("erode"):  # absent from the key when 0: maps saved before keep theirs
            full.pop("erode", None)
        key = map_key(urdf_hash, kin, **full)
        path = Path(directory) / f"reach-{key}.npz"
        if path.is_file():
            try:
                found = cls.load(path)
                if found.key == key:
                    return found
            except RobotModelError:
                pass  # rebuilt below
        built = cls.build(kin, key=key, **full)
        built.save(directory)
        return built


def _eroded(grid: np.ndarray, erode: int) -> np.ndarray:
    """(nx, ny, nz, D) bool: a bit kept where the six face-neighbour voxels hold it too,
    ``erode`` times over."""
    from scipy.ndimage import binary_erosion, generate_binary_structure

    sides = generate_binary_structure(3, 1)[..., None]  # the six face neighbours
    return binary_erosion(grid, structure=sides, iterations=erode, border_value=0)


def _cell_index(points: np.ndarray, lower: np.ndarray, voxel: float, shape: np.ndarray):
    """(m,) int64 flat voxel index of points (m, 3), -1 outside the grid."""
    ijk = np.floor(_settled((points - lower) / voxel)).astype(np.int64)
    # Viewed unsigned, a negative index is huge: one comparison per axis tests both ends.
    unsigned = ijk.view(np.uint64)
    nx, ny, nz = (int(v) for v in shape)
    inside = unsigned[:, 0] < nx
    inside &= unsigned[:, 1] < ny
    inside &= unsigned[:, 2] < nz
    flat = (ijk[:, 0] * ny + ijk[:, 1]) * nz + ijk[:, 2]
    return np.where(inside, flat, -1)


def workspace(kin: Kinematics) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius (m) of a sphere holding every reachable tool position: centred
    at the first joint, as wide as the sum of the chain's link lengths after it."""
    chain = kin.chain
    centre = chain.origins[0][:3, 3].copy()
    radius = float(np.linalg.norm(chain.origins[1:, :3, 3], axis=1).sum())
    radius += float(np.linalg.norm((chain.tip_offset @ kin.tcp)[:3, 3]))
    prismatic = kin.prismatic
    radius += float(np.maximum(np.abs(chain.lower), np.abs(chain.upper))[prismatic].sum())
    return centre, radius + 1e-6
