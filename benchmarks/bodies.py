"""Throughput of the body queries at realistic sizes (geometry.bodies, .human, .locations).

Run: ``.venv/bin/python benchmarks/bodies.py [--repeat 3]``

The scene: the default receiver (standing, 1.75 m, 1 m in front of the robot facing it,
15 primitives) and the same receiver seated (17, with the chair). Queries sit where the
planner asks them: around the handover locations the receiver would take the object at, so
a realistic share of them touch the hands and forearms. Times are the best of ``--repeat``.

Tables:
1. building: a body from stature, the handover location grid.
2. points, oriented boxes (20,000 boxes, as 6,667 grippers' three parts), capsules.
3. an object mesh (a 30 cm handle of 512 and of 4,608 faces; a 1.2 m shaft of 4,608 faces and,
   as a worst case for fcl's BVH, of 5,000 sliver faces running its whole length) at 2,000
   poses against the body:
   ``Body.mesh_hits`` (numpy broad phase, fcl per surviving pair, containment), and for
   reference a bare fcl loop over every (pose, primitive) pair with no broad phase.
4. the clearance of one pose to every primitive (fcl distance), for the trace.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from handover.geometry.body_mesh import (
    _fcl_primitives,
    mesh_clearances,
    mesh_hits,
)
from handover.geometry.collision import ObjectCollider, _bvh_object
from handover.geometry.frames import transform_from
from handover.geometry.gripper import Gripper
from handover.geometry.human import human_body
from handover.geometry.locations import handover_locations

ROBOT_SHOULDER = np.array([0.0, -0.2, 1.1])


def best(fn, repeat: int) -> tuple[float, object]:
    out, times = None, []
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return min(times), out


def near_locations(landmarks, n: int, seed: int, jitter: float = 0.12) -> np.ndarray:
    """(n, 4, 4) poses: handover locations jittered by up to ``jitter`` m, random rotations."""
    loc = handover_locations(landmarks, ROBOT_SHOULDER, 0.9, "right")
    rng = np.random.default_rng(seed)
    centres = loc.points[rng.integers(len(loc), size=n)] + rng.uniform(-jitter, jitter, (n, 3))
    return transform_from(Rotation.random(n, random_state=seed).as_matrix(), centres)


def around_body(n: int, seed: int) -> np.ndarray:
    """(n, 4, 4) poses with centres anywhere in a box holding the default receiver's upper
    body and the space in front of it (x 0.45-1.15, |y| < 0.45, z 0.6-1.5 m): many touch."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform([0.45, -0.45, 0.6], [1.15, 0.45, 1.5], (n, 3))
    return transform_from(Rotation.random(n, random_state=seed).as_matrix(), centres)


def body_placements(body) -> np.ndarray:
    """(P, 4, 4) each primitive's fcl placement in the body's frame."""
    _, rot, shift = _fcl_primitives(body, 0.0)
    return transform_from(rot, shift)


def bare_fcl_all_pairs(body, mesh, poses) -> float:
    import fcl

    obj = _bvh_object(mesh.vertices, mesh.faces)
    prims, _, _ = _fcl_primitives(body, 0.0)
    for prim, place in zip(prims, body_placements(body), strict=True):
        prim.setTransform(fcl.Transform(place[:3, :3], place[:3, 3]))
    request = fcl.CollisionRequest()
    start = time.perf_counter()
    for pose in poses:
        obj.setTransform(fcl.Transform(pose[:3, :3], pose[:3, 3]))
        for prim in prims:
            fcl.collide(prim, obj, request)
    return time.perf_counter() - start


def row(label: str, count: int, seconds: float, extra: str = "") -> None:
    rate = count / seconds
    print(f"  {label:<52} {count:>7} {seconds * 1e3:>9.2f} ms {rate:>12,.0f} /s  {extra}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    r = args.repeat

    print("1. building")
    t, (body, lm) = best(lambda: human_body(1.75), r)
    row("human_body standing (15 primitives)", 1, t)
    t, (seated, slm) = best(lambda: human_body(1.75, "seated"), r)
    row("human_body seated (17 primitives)", 1, t)
    t, loc = best(lambda: handover_locations(lm, ROBOT_SHOULDER, 0.9, "right"), r)
    row("handover_locations, 5 cm grid", len(loc), t, f"(of {loc.comfortable} comfortable)")
    t, loc2 = best(lambda: handover_locations(lm, ROBOT_SHOULDER, 0.9, "right", spacing=0.02), r)
    row("handover_locations, 2 cm grid", len(loc2), t)

    print("2. points, boxes, capsules against the standing body")
    rng = np.random.default_rng(0)
    pts = loc.points[rng.integers(len(loc), size=100_000)] + rng.uniform(-0.2, 0.2, (100_000, 3))
    t, hits = best(lambda: body.points_hit(pts), r)
    row("points_hit", len(pts), t, f"{hits.any(axis=1).mean():.0%} hit")
    gripper = Gripper.default()
    for where, poses in (("at locations", near_locations(lm, 6667, 1)),
                         ("around body", around_body(6667, 1))):  # fmt: skip
        posed = gripper.posed_boxes(poses, 0.03)
        centres = posed.centres.reshape(-1, 3)
        rots = np.repeat(posed.rotations, 3, axis=0)
        exts = np.tile(posed.extents, (len(poses), 1))
        t, hits = best(lambda c=centres, ro=rots, e=exts: body.boxes_hit(c, ro, e), r)
        row(f"boxes_hit (gripper parts), {where}", len(centres), t,
            f"{hits.any(axis=1).mean():.0%} hit")  # fmt: skip
        t, hits = best(lambda p=posed: body.posed_hits(p), r)
        row(f"posed_hits (grippers), {where}", len(poses), t,
            f"{hits.any(axis=1).mean():.0%} hit")  # fmt: skip
        t, hits = best(lambda p=posed: seated.posed_hits(p), r)
        row(f"posed_hits, seated body, {where}", len(poses), t,
            f"{hits.any(axis=1).mean():.0%} hit")  # fmt: skip
    a0 = pts[:10_000]
    a1 = a0 + rng.normal(size=(10_000, 3)) * 0.15
    t, hits = best(lambda: body.capsules_hit(a0, a1, 0.04), r)
    row("capsules_hit (arm links, r 4 cm)", len(a0), t, f"{hits.any(axis=1).mean():.0%} hit")

    print("3. object mesh at 2,000 poses against the standing body")
    for where, poses in (("at locations", near_locations(lm, 2000, 2, jitter=0.15)),
                         ("around body", around_body(2000, 2))):  # fmt: skip
        for count in (16, 48):
            mesh = trimesh.creation.capsule(height=0.3, radius=0.02, count=[count, count])
            faces = len(mesh.faces)
            t, hits = best(lambda mesh=mesh, p=poses: mesh_hits(body, mesh, p), r)
            row(f"mesh_hits, {faces} faces, {where}", len(poses), t,
                f"{hits.any(axis=1).mean():.0%} hit")  # fmt: skip
            collider = ObjectCollider(mesh)
            t, hits = best(lambda c=collider, p=poses: mesh_hits(body, c, p), r)
            row("  same, ObjectCollider's BVH (built once)", len(poses), t)
        t = min(bare_fcl_all_pairs(body, mesh, poses) for _ in range(r))
        row(f"bare fcl, all {len(body)} pairs, {faces} faces, {where}", len(poses), t,
            "(reference)")  # fmt: skip
        long = trimesh.creation.capsule(height=1.2, radius=0.015, count=[48, 48])
        t, hits = best(lambda p=poses, m=long: mesh_hits(body, m, p), r)
        row(f"mesh_hits, 1.2 m shaft, {len(long.faces)} faces, {where}", len(poses), t,
            f"{hits.any(axis=1).mean():.0%} hit")  # fmt: skip
        sliver = trimesh.creation.cylinder(radius=0.015, height=1.2, sections=1250)
        t, hits = best(lambda p=poses, m=sliver: mesh_hits(body, m, p), r)
        row(f"  same, {len(sliver.faces)} sliver faces (worst case)", len(poses), t,
            f"{hits.any(axis=1).mean():.0%} hit")  # fmt: skip

    print("4. clearance of one pose")
    mesh = trimesh.creation.capsule(height=0.3, radius=0.02, count=[48, 48])
    collider = ObjectCollider(mesh)
    t, d = best(lambda: mesh_clearances(body, collider, around_body(1, 3)[0]), r)
    row(f"mesh_clearances, {len(mesh.faces)} faces", 1, t, f"min {d.min():.3f} m")


if __name__ == "__main__":
    main()
