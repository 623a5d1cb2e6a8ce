"""Arm motion on the shipped robot: time per segment and per plan-like sequence of segments,
and the corridor checks over many grasp candidates.

Run: ``.venv/bin/python benchmarks/motion.py [--repeat 3]``

The scene: the table (top at z 0.75 m), a 5 x 5 x 10 cm box on it, a shelf board 22 cm above
the table, a post beside the box, the receiver standing 1 m in front (torso, head and a
forearm reaching out, capsules), the robot's torso, and the right arm waiting at its rest. The
left arm carries the default gripper open (closed on the box while it holds it, the box
then carried as an attached box). The sequence: rest -> pre-grasp (10 cm above the box) ->
grasp -> lift (10 cm) -> handover approach (10 cm before the handover pose, gripper towards
the receiver) -> handover -> retreat (10 cm back) -> rest: 7 segments. Each segment is planned
with the default settings (seeded: every run gives the same segments); times are the median
over ``--repeat`` runs (the first run also pays OMPL's and ruckig's imports, reported apart).
"""

from __future__ import annotations

import argparse
import statistics
import time
from importlib.resources import files

import numpy as np
from scipy.spatial.transform import Rotation

from handover.geometry.bodies import Body
from handover.geometry.collision import ObjectCollider
from handover.geometry.corridor import check_corridors
from handover.geometry.frames import frame_from_o_a, transform_from
from handover.geometry.gripper import Gripper
from handover.geometry.motion import (
    ArmModel,
    PlanningFailure,
    ValidityChecker,
    obstacles,
    plan_segment,
)
from handover.geometry.urdf import load_urdf

ROBOT = files("handover.kb") / "robots" / "idro_arms.urdf"  # the installed package's file
TCP = transform_from(None, [0.0, 0.0, 0.11])  # kb/robots/idro.yaml
REST_LEFT = np.array([1.8, 1.32, -0.13, -0.43, -0.64, 0.58, 0.04])
REST_RIGHT = np.array([-1.8, 1.32, 0.13, -0.43, 0.64, 0.58, -0.04])
G = Gripper.default()
WIDTH = 0.05


def _box(name, lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return (name, hi - lo, transform_from(None, (lo + hi) / 2))


def scene():
    model = load_urdf(str(ROBOT))
    left = ArmModel.from_urdf(model, "base_link", "left_flange", tcp=TCP)
    right = ArmModel.from_urdf(model, "base_link", "right_flange", tcp=TCP)
    table = _box("table", [0.35, -0.6, 0.0], [1.0, 0.6, 0.75])
    shelf = _box("shelf", [0.75, -0.6, 0.97], [1.0, 0.6, 0.99])
    post = _box("post", [0.45, 0.02, 0.75], [0.53, 0.1, 1.05])
    torso = _box("torso", [-0.12, -0.12, 0.3], [0.12, 0.12, 1.4])
    box = _box("box", [0.575, 0.225, 0.75], [0.625, 0.275, 0.85])
    receiver = Body.from_primitives([
        ("receiver torso", [1.25, 0, 0.95], [1.25, 0, 1.35], 0.17),
        ("receiver head", [1.25, 0, 1.6], [1.25, 0, 1.6], 0.11),
        ("receiver forearm", [1.0, -0.05, 1.1], [1.15, -0.1, 1.05], 0.04),
    ])  # fmt: skip
    other = right.targets(REST_RIGHT, "right:")
    scene_boxes = [table, shelf, post, torso]
    open_gripper = G.boxes(WIDTH)
    closed = G.boxes(WIDTH - 2 * G.clearance)  # the fingers on the box
    # The box in the grasp frame: its centre 3.5 cm along the approach (down).
    held = [("held box", np.array([0.05, 0.05, 0.1]), transform_from(None, [0, 0, 0.035]))]
    empty = ValidityChecker(left, obstacles([*scene_boxes, box], [receiver], [other]),
                            attached=open_gripper)  # fmt: skip
    holding = ValidityChecker(left, obstacles(scene_boxes, [receiver], [other]),
                              attached=[*closed, *held],
                              allowed=[("held box", "table")])  # lifted off it  # fmt: skip
    return left, empty, holding


def stages(left):
    down = frame_from_o_a([0, 1, 0], [0, 0, -1])
    forward = frame_from_o_a([0, 0, 1], [1, 0, 0])
    poses = {
        "pregrasp": transform_from(down, [0.6, 0.25, 0.92]),
        "grasp": transform_from(down, [0.6, 0.25, 0.835]),
        "lift": transform_from(down, [0.6, 0.25, 0.92]),
        "approach": transform_from(forward, [0.72, 0.0, 1.12]),
        "handover": transform_from(forward, [0.82, 0.0, 1.12]),
        "retreat": transform_from(forward, [0.72, 0.0, 1.12]),
    }
    names = list(poses)
    targets = np.linalg.inv(left.base) @ np.array([poses[k] for k in names])
    q, prev = {}, REST_LEFT
    for name, target in zip(names, targets, strict=True):  # each from the previous
        ik = left.kin.ik(target[None], q0=prev, restarts=20, rng_seed=0)
        if not ik.success[0]:
            raise SystemExit(f"inverse kinematics found no joints for {name}")
        q[name] = prev = ik.q[0]
    return [("rest->pregrasp", REST_LEFT, q["pregrasp"], "empty"),
            ("pregrasp->grasp", q["pregrasp"], q["grasp"], "empty"),
            ("grasp->lift", q["grasp"], q["lift"], "holding"),
            ("lift->approach", q["lift"], q["approach"], "holding"),
            ("approach->handover", q["approach"], q["handover"], "holding"),
            ("handover->retreat", q["handover"], q["retreat"], "empty"),
            ("retreat->rest", q["retreat"], REST_LEFT, "empty")]


def run(checkers, sequence):
    out = []
    for name, start, goal, which in sequence:
        t = time.perf_counter()
        seg = plan_segment(checkers[which], start, goal, name=name)
        out.append((name, time.perf_counter() - t, seg))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    left, empty, holding = scene()
    checkers = {"empty": empty, "holding": holding}
    sequence = stages(left)
    runs = [run(checkers, sequence) for _ in range(max(1, args.repeat) + 1)]
    first, rest = runs[0], runs[1:]
    print(f"{'segment':<22}{'planner':>12}{'checks':>8}{'waypoints':>10}{'samples':>9}"
          f"{'motion s':>10}{'plan ms':>10}")  # fmt: skip
    for i, (name, _, seg) in enumerate(first):
        ms = 1e3 * statistics.median(r[i][1] for r in rest)
        if isinstance(seg, PlanningFailure):
            print(f"{name:<22}{'FAILED':>12}  {seg.reason}  ({ms:.1f} ms)")
            continue
        same = all(np.array_equal(r[i][2].positions, seg.positions) for r in rest)
        print(f"{name:<22}{seg.planner:>12}{seg.checks:>8}{len(seg.waypoints):>10}"
              f"{len(seg.times):>9}{seg.duration:>10.2f}{ms:>10.1f}"
              f"{'' if same else '  (differs between runs!)'}")  # fmt: skip
    totals = [sum(t for _, t, _ in r) for r in rest]
    print(f"whole sequence ({len(sequence)} segments): median {1e3 * statistics.median(totals):.0f}"
          f" ms, min {1e3 * min(totals):.0f} ms, max {1e3 * max(totals):.0f} ms over "
          f"{len(rest)} runs; first run (with imports) {1e3 * sum(t for _, t, _ in first):.0f} ms")

    # Corridors: pre-grasp corridors (10 cm back along -a) of 2,000 random grasp poses around
    # the box, against the scene's boxes and the box's mesh.
    import trimesh

    rng = np.random.default_rng(0)
    rot = Rotation.random(2000, random_state=1).as_matrix()
    poses = transform_from(rot, np.array([0.6, 0.25, 0.8]) + rng.normal(0, 0.02, (2000, 3)))
    mesh = trimesh.creation.box(extents=[0.05, 0.05, 0.1],
                                transform=transform_from(None, [0.6, 0.25, 0.8]))
    world = [_box("table", [0.35, -0.6, 0.0], [1.0, 0.6, 0.75]),
             _box("shelf", [0.45, 0.0, 0.97], [1.0, 0.6, 0.99])]
    collider = ObjectCollider(mesh)
    for label, kwargs in (("boxes only", {}), ("boxes and the object mesh", {"obj": collider})):
        times = []
        for _ in range(max(1, args.repeat)):
            t = time.perf_counter()
            hits = check_corridors(G, poses, WIDTH, -poses[:, :3, 2], 0.10, world=world,
                                   **kwargs)  # fmt: skip
            times.append(time.perf_counter() - t)
        print(f"corridors, 2000 poses, {label}: {1e3 * statistics.median(times):.0f} ms "
              f"({hits.hit.mean():.0%} hit)")


if __name__ == "__main__":
    main()
