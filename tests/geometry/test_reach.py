"""Reachability maps: a one-joint arm whose reachable poses are known in closed form, the
shipped arm's own FK poses found reachable, far poses not, and the .npz cache."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from handover.geometry.frames import frame_from_o_a, transform_from
from handover.geometry.kinematics import Kinematics
from handover.geometry.reach import ReachMap, fibonacci_sphere
from handover.geometry.urdf import RobotModelError, load_urdf

ROBOT = Path(__file__).resolve().parents[2] / "kb" / "robots" / "idro_arms.urdf"

# One revolute joint about z and a 0.5 m link; the tool's z axis points along the link, so
# the reachable tool poses are on the circle of radius 0.5 (z = 0), approach pointing outward.
SWEEP = """\
    <robot name="sweep">
      <link name="base"/><link name="arm"/><link name="tool"/>
      <joint name="turn" type="revolute"><parent link="base"/><child link="arm"/>
        <axis xyz="0 0 1"/><limit lower="-3.14159" upper="3.14159"/></joint>
      <joint name="end" type="fixed"><parent link="arm"/><child link="tool"/>
        <origin xyz="0.5 0 0" rpy="0 1.5707963267948966 0"/></joint>
    </robot>
    """


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    path = tmp_path_factory.mktemp("sweep") / "sweep.urdf"
    path.write_text(textwrap.dedent(SWEEP))
    return Kinematics(load_urdf(path).chain("base", "tool"))


@pytest.fixture(scope="module")
def left():
    return Kinematics(load_urdf(ROBOT).chain("base_link", "left_flange"))


def _poses(points, approach):
    points = np.asarray(points, dtype=float)
    approach = np.broadcast_to(np.asarray(approach, dtype=float), points.shape)
    closing = np.cross(approach, [0.0, 0.0, 1.0]) + np.cross(approach, [1.0, 0.0, 0.0])
    return transform_from(frame_from_o_a(closing, approach), points)


def test_fibonacci_directions_are_unit_and_spread():
    d = fibonacci_sphere(100)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    # Every point's nearest neighbour is within ~25 degrees (4 pi / 100 sr per point).
    cos = d @ d.T - 2 * np.eye(100)
    assert np.degrees(np.arccos(cos.max(axis=1))).max() < 25
    assert abs(d.mean(axis=0)).max() < 0.02


def test_one_joint_arm_reaches_its_circle_pointing_outward_only(sweep):
    reach = ReachMap.build(sweep, samples=20_000, voxel=0.05, voxel_tolerance=0,
                           direction_tolerance=0)  # fmt: skip
    angles = np.linspace(-3.0, 3.0, 13)
    radial = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
    assert reach.reachable(_poses(0.5 * radial, radial)).all()
    assert not reach.reachable(_poses(0.5 * radial, -radial)).any()  # pointing inward
    assert not reach.reachable(_poses(0.5 * radial, [0, 0, 1])).any()  # pointing up
    assert not reach.reachable(_poses(0.2 * radial, radial)).any()  # inside the circle
    assert not reach.reachable(_poses(0.5 * radial + [0, 0, 0.2], radial)).any()  # above it


def test_shipped_arm_reaches_its_own_fk_poses_and_not_far_ones(left):
    reach = ReachMap.build(left, samples=400_000, voxel_tolerance=1, direction_tolerance=4)
    fresh = left.fk(left.random_configurations(500, np.random.default_rng(99)))
    assert reach.reachable(fresh).mean() >= 0.95
    far = fresh.copy()
    far[:, :3, 3] += [3.0, 0.0, 0.0]
    assert not reach.reachable(far).any()


def test_build_is_deterministic_and_save_load_round_trips(sweep, tmp_path):
    a = ReachMap.build(sweep, samples=5_000, key="k1")
    b = ReachMap.build(sweep, samples=5_000, key="k1")
    assert_array_equal(a.bits, b.bits)
    path = a.save(tmp_path)
    assert path.name == "reach-k1.npz"
    loaded = ReachMap.load(path)
    assert_array_equal(loaded.bits, a.bits)
    np.testing.assert_allclose(loaded.lower, a.lower)
    assert loaded.key == "k1" and loaded.samples == 5_000


def _save_many(args: tuple) -> str:
    """Save ``reach`` into ``folder`` ``times`` times (a process of the test below): the
    error it met, or ''."""
    reach, folder, times = args
    try:
        for _ in range(times):
            reach.save(folder)
    except Exception as e:  # noqa: BLE001 - reported to the test
        return f"{type(e).__name__}: {e}"
    return ""


def test_processes_saving_the_same_map_at_once_all_succeed(sweep, tmp_path):
    # Batch workers and service workers with one database build the same arm's map at the
    # same time. Each writes its own temporary file: with one name for all, one process
    # renamed the file another was still writing (a torn map), or found it gone.
    import multiprocessing

    reach = ReachMap.build(sweep, samples=5_000, key="shared")
    with multiprocessing.get_context("fork").Pool(4) as pool:
        errors = pool.map(_save_many, [(reach, tmp_path, 30)] * 4)
    assert errors == [""] * 4
    assert_array_equal(ReachMap.load(tmp_path / "reach-shared.npz").bits, reach.bits)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reach-shared.npz"]  # no temporary
    umask = os.umask(0)
    os.umask(umask)
    assert (tmp_path / "reach-shared.npz").stat().st_mode & 0o777 == 0o666 & ~umask


def test_cached_builds_once_per_urdf_hash_then_loads(sweep, tmp_path, monkeypatch):
    first = ReachMap.cached(sweep, tmp_path, "hash-a", samples=5_000)
    assert len(list(tmp_path.glob("reach-*.npz"))) == 1

    def no_build(*args, **kwargs):
        raise AssertionError("the cached map should have been loaded")

    monkeypatch.setattr(ReachMap, "build", no_build)
    again = ReachMap.cached(sweep, tmp_path, "hash-a", samples=5_000)
    assert_array_equal(again.bits, first.bits)
    monkeypatch.undo()
    ReachMap.cached(sweep, tmp_path, "hash-b", samples=5_000)  # another URDF: another file
    assert len(list(tmp_path.glob("reach-*.npz"))) == 2


def test_damaged_map_file_is_our_error_and_cached_rebuilds_it(sweep, tmp_path):
    built = ReachMap.cached(sweep, tmp_path, "h", samples=5_000)
    path = next(tmp_path.glob("reach-*.npz"))
    path.write_bytes(b"not a zip")
    with pytest.raises(RobotModelError, match="cannot read"):
        ReachMap.load(path)
    rebuilt = ReachMap.cached(sweep, tmp_path, "h", samples=5_000)
    assert_array_equal(rebuilt.bits, built.bits)
    with pytest.raises(RobotModelError, match="unknown parameters"):
        ReachMap.cached(sweep, tmp_path, "h", sampels=5)
    with pytest.raises(RobotModelError, match=r"\(m, 4, 4\)"):
        built.reachable(np.eye(4))


def test_eroding_keeps_the_core_and_drops_the_rim(sweep):
    """A map eroded by one voxel holds a subset of the map's bits, and loses the one-voxel-thin
    circle of the one-joint arm entirely (it has no inside); the reach index counts the
    approach bins a voxel holds."""
    full = ReachMap.build(sweep, samples=20_000, voxel=0.05, direction_tolerance=0)
    core = ReachMap.build(sweep, samples=20_000, voxel=0.05, direction_tolerance=0, erode=1)
    assert not (core.bits & ~full.bits).any()
    assert full.bits.any() and not core.bits.any()
    angles = np.linspace(-3.0, 3.0, 13)
    radial = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
    index = full.reach_index(0.5 * radial)
    assert (index > 0).all() and (index <= 3 / len(full.directions)).all()  # a few bins
    assert (full.reach_index(0.2 * radial) == 0).all()
    poses = _poses(0.5 * radial, radial)
    assert_array_equal(full.lookup(poses[:, :3, 3], poses[:, :3, 2]), full.reachable(poses))


def test_a_block_s_core_is_its_inside(left):
    """On the shipped arm, the core keeps poses deep in the workspace and is a subset of the
    whole map; eroding never adds a bit."""
    full = ReachMap.build(left, samples=400_000, voxel_tolerance=1, direction_tolerance=4)
    core = ReachMap.build(left, samples=400_000, voxel_tolerance=1, direction_tolerance=4,
                          erode=1)  # fmt: skip
    assert not (core.bits & ~full.bits).any() and core.bits.sum() < full.bits.sum()
    fresh = left.fk(left.random_configurations(500, np.random.default_rng(7)))
    assert core.reachable(fresh).mean() >= 0.8
