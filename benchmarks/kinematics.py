"""Arm kinematics on the shipped robot: FK throughput, IK time and success, the reachability
map (build time, size, lookups, precision and recall against IK), link collision.

Run: ``.venv/bin/python benchmarks/kinematics.py [--targets 2000] [--samples 20000000]``

IK targets are FK poses of configurations drawn uniformly within the limits (all reachable).
The map is measured against IK with 10 restarts on random tool poses in the region where
the robot works (x 0.2-0.9 m, y -0.6-0.6 m, z 0.7-1.3 m, world frame; approach directions
uniform): precision = map-true poses IK solves / map-true poses (a lower bound: IK misses a
few reachable poses), recall = IK-solved poses the map accepts / IK-solved poses.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from importlib.resources import files
from pathlib import Path

import numpy as np

from handover.geometry.armcollision import Targets, arms_hits, world_hits
from handover.geometry.frames import frame_from_o_a, transform_from
from handover.geometry.kinematics import Kinematics
from handover.geometry.reach import ReachMap
from handover.geometry.urdf import load_urdf

ROBOT = Path(str(files("handover.kb") / "robots" / "idro_arms.urdf"))
TCP = transform_from(None, [0.0, 0.0, 0.11])  # flange to between the finger pads, about


def best_of(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=2000)
    parser.add_argument("--samples", type=int, default=20_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    start = time.perf_counter()
    robot = load_urdf(ROBOT)
    print(f"load_urdf: {1e3 * (time.perf_counter() - start):.0f} ms (first call imports yourdfpy)")
    chain = robot.chain("base_link", "left_flange")
    kin = Kinematics(chain, TCP)
    rng = np.random.default_rng(0)

    print("\n== forward kinematics (7-DOF arm)")
    q = kin.random_configurations(200_000, rng)
    for dtype in (np.float64, np.float32):
        t = best_of(lambda dtype=dtype: kin.fk(q, dtype=dtype), args.repeat)
        print(f"  fk {dtype.__name__}: {len(q) / t / 1e6:.2f} M poses/s")
    t = best_of(lambda: kin.link_poses(q[:20_000]), args.repeat)
    print(f"  link_poses (13 links): {20_000 / t / 1e6:.2f} M configurations/s")
    t = best_of(lambda: kin.jacobian(q[:20_000]), args.repeat)
    print(f"  jacobian: {20_000 / t / 1e6:.2f} M configurations/s")

    print(f"\n== inverse kinematics, {args.targets} reachable targets (FK of random q)")
    targets = kin.fk(kin.random_configurations(args.targets, rng))
    for restarts in (0, 5, 20):
        t0 = time.perf_counter()
        result = kin.ik(targets, restarts=restarts)
        dt = time.perf_counter() - t0
        ok = result.success
        print(f"  restarts {restarts:2d}: {1e3 * dt / len(targets):.3f} ms/target, "
              f"success {ok.mean():.1%}, max error of successes "
              f"{1e3 * result.position_error[ok].max():.3f} mm / "
              f"{np.degrees(result.rotation_error[ok].max()):.3f} deg")  # fmt: skip

    print("\n== the planner's inverse kinematics (RobotArms.solve: from the nearest of 4,096 "
          "sampled poses, restarts batched)")
    from handover.engine.assets.robot import RobotArms
    from handover.engine.load.loader import load_kb
    from handover.engine.store.kb import builtin_kb_dir

    arms = RobotArms.load(load_kb(builtin_kb_dir()), "idro")
    world = arms.fk("left", arms.arm("left").kin.random_configurations(200, rng))
    arms.solve("left", world[:1])  # the start library, once
    t0 = time.perf_counter()
    ok = np.array([arms.solve("left", world[i : i + 1]).ok[0] for i in range(len(world))])
    dt = time.perf_counter() - t0
    print(f"  one target at a time (as a plan asks): {1e3 * dt / len(world):.2f} ms/target, "
          f"success {ok.mean():.1%}")
    t0 = time.perf_counter()
    ok = arms.solve("left", world).ok
    dt = time.perf_counter() - t0
    print(f"  {len(world)} targets at once: {1e3 * dt / len(world):.2f} ms/target, "
          f"success {ok.mean():.1%}")

    print(f"\n== reachability map ({args.samples:,} samples)")
    with tempfile.TemporaryDirectory() as folder:
        t0 = time.perf_counter()
        reach = ReachMap.cached(kin, folder, robot.content_hash, samples=args.samples)
        build = time.perf_counter() - t0
        size = sum(p.stat().st_size for p in Path(folder).glob("*.npz"))
        t0 = time.perf_counter()
        ReachMap.cached(kin, folder, robot.content_hash, samples=args.samples)
        load = time.perf_counter() - t0
    print(f"  build + save: {build:.1f} s; load from cache: {1e3 * load:.0f} ms")
    print(f"  grid {tuple(int(s) for s in reach.shape)} x {len(reach.directions)} bins of "
          f"{reach.voxel:.2f} m; {reach.nbytes / 1e6:.2f} MB packed, {size / 1e6:.2f} MB on disk; "
          f"{reach.raw_fraction:.1%} of cells sampled, {reach.bits.mean():.1%} after tolerance")
    m = 3000
    points = rng.uniform([0.2, -0.6, 0.7], [0.9, 0.6, 1.3], (m, 3))
    approach = rng.normal(size=(m, 3))
    poses = transform_from(frame_from_o_a(np.cross(approach, rng.normal(size=(m, 3))), approach),
                           points)  # fmt: skip
    many = np.repeat(poses, 1_000_000 // m + 1, axis=0)[:1_000_000]
    t = best_of(lambda: reach.reachable(many), args.repeat)
    print(f"  lookups: {len(many) / t / 1e6:.1f} M poses/s")
    t0 = time.perf_counter()
    truth = kin.ik(poses, restarts=10).success
    ik_time = time.perf_counter() - t0
    said = reach.reachable(poses)
    tp = (said & truth).sum()
    print(f"  against IK (10 restarts, {1e3 * ik_time / m:.2f} ms/pose) on {m} poses in the "
          f"work region: {truth.mean():.1%} reachable")  # fmt: skip
    print(f"  precision {tp / max(said.sum(), 1):.2f}, recall {tp / max(truth.sum(), 1):.2f}, "
          f"unreachable poses rejected {(~said & ~truth).sum() / max((~truth).sum(), 1):.2f}")
    for vt, dt_, erode in ((0, 0, 0), (1, 4, 0), (0, 2, 1)):
        other = ReachMap.build(kin, samples=args.samples, voxel_tolerance=vt,
                               direction_tolerance=dt_, erode=erode)  # fmt: skip
        said = other.reachable(poses)
        tp = (said & truth).sum()
        print(f"  (voxel_tolerance={vt}, direction_tolerance={dt_}, erode={erode}: precision "
              f"{tp / max(said.sum(), 1):.2f}, recall {tp / max(truth.sum(), 1):.2f})"
              + ("  <- the core plans screen with" if erode else ""))

    print("\n== link collision (2,000 random configurations per arm)")
    right = Kinematics(robot.chain("base_link", "right_flange"), TCP)
    sl, sr = robot.chain_shapes(kin.chain), robot.chain_shapes(right.chain)
    body = ("base_link", "torso", "head")
    targets_w = Targets.from_shapes(robot.shapes(body), [robot.fixed_pose(b) for b in body])
    targets_w = targets_w + Targets.from_boxes(
        [("table", [0.5, 1.0, 0.05], transform_from(None, [0.55, 0.0, 0.725]))]
    )
    n = 2000
    pl = kin.link_poses(kin.random_configurations(n, rng))
    pr = right.link_poses(right.random_configurations(n, rng))
    t = best_of(lambda: world_hits(sl, pl, targets_w), args.repeat)
    hits = world_hits(sl, pl, targets_w).any(axis=1)
    print(f"  arm vs torso, base, head, table: {1e6 * t / n:.1f} us/configuration "
          f"({len(sl)} link shapes x {len(targets_w)} targets); "
          f"{hits.any(axis=1).mean():.1%} of random configurations hit something")
    t = best_of(lambda: arms_hits(sl, pl, sr, pr), args.repeat)
    both = arms_hits(sl, pl, sr, pr).any(axis=(1, 2))
    print(f"  arm vs arm: {1e6 * t / n:.1f} us/configuration pair ({len(sl)} x {len(sr)} shapes); "
          f"{both.mean():.1%} of random pairs collide")


if __name__ == "__main__":
    main()
