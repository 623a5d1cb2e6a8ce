"""Collision checks per second: our pipeline against a bare python-fcl loop (the floor).

Run: ``.venv/bin/python benchmarks/collision.py [--sites 200] [--repeat 3]``

Poses are candidate-like: antipodal pairs found by casting a ray inward from seeded surface
samples, each site rolled about ``o`` in 15-degree steps (24 poses per site, one width per
site), as ``geometry.generate`` produces them. Times are the best of ``--repeat`` runs.

Tables:
1. gripper against object mesh: ``ObjectCollider.gripper_collides`` (broad phase, palm first,
   early exit, containment) against ``geometry.collision.bare_fcl_loop_seconds`` (one gripper
   BVH at one width, one Transform and one collide per pose; answers less). Ratio = ours /
   floor in time: below 1 is faster than the floor.
2. the alternatives measured while choosing: bare loops with a fresh CollisionResult, three
   BVH parts, three ``fcl.Box`` parts (no broad phase).
3. box against box: numpy separating-axis test against an ``fcl.Box`` loop on the same pairs;
   ``BoxWorld`` and ``grippers_collide`` throughput.
4. the gripper given as meshes (a 64-sided cylindrical palm of radius 4 cm, fingers of 192
   triangles) against the box model, on the same poses: what a real gripper's meshes cost.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from handover.geometry.collision import (
    BoxWorld,
    ObjectCollider,
    _bvh_object,
    bare_fcl_loop_seconds,
    boxes_overlap,
    grippers_collide,
)
from handover.geometry.gripper import Gripper
from handover.geometry.hand import HumanHand


def candidate_poses(
    mesh: trimesh.Trimesh, gripper: Gripper, sites: int, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4, 4) grasp poses and (N,) widths: antipodal ray pairs rolled about ``o``."""
    points, face = trimesh.sample.sample_surface(mesh, sites * 4, seed=seed)
    normals = mesh.face_normals[face]
    hits, ray, _ = mesh.ray.intersects_location(
        points - normals * 1e-6, -normals, multiple_hits=False
    )
    other = np.full(points.shape, np.nan)
    other[ray] = hits
    width = np.linalg.norm(other - points, axis=1)
    ok = np.flatnonzero(np.isfinite(width) & (width > 1e-3) & (width < gripper.max_opening))
    ok = ok[:sites]
    p0, p1, width = points[ok], other[ok], width[ok]
    o = (p1 - p0) / width[:, None]
    helper = np.where(np.abs(o[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    a0 = np.cross(o, helper)
    a0 /= np.linalg.norm(a0, axis=1, keepdims=True)
    b0 = np.cross(o, a0)
    roll = np.radians(np.arange(0.0, 360.0, gripper.roll_step_deg))
    a = np.cos(roll)[None, :, None] * a0[:, None] + np.sin(roll)[None, :, None] * b0[:, None]
    o = np.broadcast_to(o[:, None], a.shape)
    poses = np.zeros(a.shape[:2] + (4, 4))
    poses[..., :3, 0] = np.cross(o, a)
    poses[..., :3, 1] = o
    poses[..., :3, 2] = a
    poses[..., :3, 3] = ((p0 + p1) / 2)[:, None]
    poses[..., 3, 3] = 1.0
    return poses.reshape(-1, 4, 4), np.repeat(width, len(roll))


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def meshes() -> dict[str, trimesh.Trimesh]:
    return {
        "sphere r18mm": trimesh.creation.icosphere(subdivisions=4, radius=0.018),
        "capsule": trimesh.creation.capsule(height=0.15, radius=0.015, count=[64, 64]),
        "torus": trimesh.creation.torus(0.05, 0.012, major_sections=128, minor_sections=64),
        "box": trimesh.creation.box(extents=(0.05, 0.07, 0.2)),
        "sphere r40mm": trimesh.creation.icosphere(subdivisions=5, radius=0.04),
    }


def loop_parts(collider_mesh, gripper, poses, widths, kind: str) -> float:
    """Seconds of a plain loop over every pose and every part (no broad phase, no early
    exit, no containment): ``kind`` is "bvh" (three box meshes) or "box" (three fcl.Box)."""
    import fcl

    target = _bvh_object(collider_mesh.vertices, collider_mesh.faces)
    posed = gripper.posed_boxes(poses, widths)
    if kind == "bvh":
        parts = []
        for ext in posed.extents:
            box = trimesh.creation.box(extents=ext)
            parts.append(_bvh_object(box.vertices, box.faces))
    else:
        parts = [
            fcl.CollisionObject(fcl.Box(*map(float, e)), fcl.Transform()) for e in posed.extents
        ]
    request = fcl.CollisionRequest()
    start = time.perf_counter()
    for i in range(len(poses)):
        rot = posed.rotations[i]
        for k, part in enumerate(parts):
            part.setTransform(fcl.Transform(rot, posed.centres[i, k]))
            fcl.collide(part, target, request)
    return time.perf_counter() - start


def bare_fresh_result(mesh, gripper, poses, widths) -> float:
    """The floor loop, but with a new CollisionResult per call (as FIELD-NOTES suggest)."""
    import fcl

    target = _bvh_object(mesh.vertices, mesh.faces)
    tool_mesh = gripper.trimesh(float(np.median(widths)))
    tool = _bvh_object(tool_mesh.vertices, tool_mesh.faces)
    request = fcl.CollisionRequest()
    start = time.perf_counter()
    for pose in poses:
        tool.setTransform(fcl.Transform(pose[:3, :3], pose[:3, 3]))
        fcl.collide(tool, target, request, fcl.CollisionResult())
    return time.perf_counter() - start


def table_mesh(gripper: Gripper, sites: int, repeat: int) -> None:
    print("1. gripper vs object mesh (checks/s; ratio = our time / floor time)")
    head = f"{'mesh':14s} {'faces':>6s} {'poses':>6s} {'hit':>5s} {'floor/s':>9s} {'ours/s':>9s}"
    print(head + f" {'ratio':>6s} {'build ms':>9s}")
    ratios = []
    for name, mesh in meshes().items():
        poses, widths = candidate_poses(mesh, gripper, sites)
        start = time.perf_counter()
        collider = ObjectCollider(mesh)
        collider.mesh.contains(np.zeros((1, 3)))  # builds the ray scene (cached on the mesh)
        build = time.perf_counter() - start
        floor = min(bare_fcl_loop_seconds(mesh, gripper, poses, widths) for _ in range(repeat))
        hit = collider.gripper_collides(gripper, poses, widths)
        ours = best(lambda c=collider, p=poses, w=widths: c.gripper_collides(gripper, p, w), repeat)
        n = len(poses)
        ratios.append(ours / floor)
        print(
            f"{name:14s} {len(mesh.faces):6d} {n:6d} {hit.mean():5.2f} {n / floor:9.0f} "
            f"{n / ours:9.0f} {ours / floor:6.2f} {build * 1e3:9.1f}"
        )
    print(f"worst ratio {max(ratios):.2f}, geometric mean {np.exp(np.mean(np.log(ratios))):.2f}")


def table_choices(gripper: Gripper, sites: int, repeat: int) -> None:
    print("\n2. choices (checks/s over the same poses, every part of every pose)")
    print(f"{'mesh':14s} {'floor':>8s} {'floor+res':>10s} {'3 BVH':>8s} {'3 Box':>8s}")
    for name, mesh in meshes().items():
        poses, widths = candidate_poses(mesh, gripper, sites)
        n = len(poses)
        rates = [
            n / min(bare_fcl_loop_seconds(mesh, gripper, poses, widths) for _ in range(repeat)),
            n / min(bare_fresh_result(mesh, gripper, poses, widths) for _ in range(repeat)),
            n / min(loop_parts(mesh, gripper, poses, widths, "bvh") for _ in range(repeat)),
            n / min(loop_parts(mesh, gripper, poses, widths, "box") for _ in range(repeat)),
        ]
        print(
            f"{name:14s} "
            + " ".join(f"{r:{w}.0f}" for r, w in zip(rates, (8, 10, 8, 8), strict=True))
        )


def table_boxes(gripper: Gripper, repeat: int) -> None:
    import fcl

    print("\n3. box against box")
    rng = np.random.default_rng(0)
    count = 20000
    ca, cb = rng.normal(0, 0.3, (2, count, 3))
    ra = Rotation.random(count, random_state=1).as_matrix()
    rb = Rotation.random(count, random_state=2).as_matrix()
    ea, eb = rng.uniform(0.05, 0.5, (2, count, 3))
    ours = best(lambda: boxes_overlap(ca, ra, ea, cb, rb, eb), repeat)

    def fcl_loop() -> None:
        request = fcl.CollisionRequest()
        for i in range(count):
            a = fcl.CollisionObject(fcl.Box(*ea[i]), fcl.Transform(ra[i], ca[i]))
            b = fcl.CollisionObject(fcl.Box(*eb[i]), fcl.Transform(rb[i], cb[i]))
            fcl.collide(a, b, request)

    floor = best(fcl_loop, repeat)
    numpy_answer = boxes_overlap(ca, ra, ea, cb, rb, eb)
    print(f"boxes_overlap (numpy SAT)      {count / ours:12.0f} pairs/s")
    print(
        f"fcl.Box loop on the same pairs {count / floor:12.0f} pairs/s ({floor / ours:.0f}x slower)"
    )
    print(f"  overlapping pairs {numpy_answer.mean():.2f}")

    hand = HumanHand.default()
    world_boxes = [
        (
            "table",
            np.array([1.0, 1.2, 0.03]),
            trimesh.transformations.translation_matrix([0.5, 0, 0.685]),
        ),
        (
            "wall",
            np.array([0.02, 1.2, 1.0]),
            trimesh.transformations.translation_matrix([1.2, 0, 1.0]),
        ),
    ]
    world_boxes += hand.boxes(np.array([0.6, 0.0, 1.0]), [0, 1.0, 0], [-1.0, 0, 0], 0.03)
    world = BoxWorld(world_boxes)
    n = 20000
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.random(n, random_state=3).as_matrix()
    poses[:, :3, 3] = rng.uniform([0.3, -0.3, 0.7], [0.8, 0.3, 1.2], (n, 3))
    widths = rng.uniform(0, gripper.max_opening, n)
    t_world = best(lambda: world.gripper_hits(gripper, poses, widths), repeat)
    print(
        f"BoxWorld.gripper_hits ({len(world)} boxes)  {n / t_world:12.0f} poses/s "
        f"({n * 3 * len(world) / t_world:.0f} box pairs/s)"
    )
    t_paired = best(
        lambda: grippers_collide(gripper, poses, widths, poses[::-1], widths[::-1]), repeat
    )
    print(f"grippers_collide paired        {n / t_paired:12.0f} pose pairs/s")
    m = 2000
    t_all = best(
        lambda: grippers_collide(
            gripper, poses[:m], widths[:m], poses[m : 2 * m], widths[m : 2 * m], paired=False
        ),  # fmt: skip
        repeat,
    )
    print(f"grippers_collide all pairs     {m * m / t_all:12.0f} pose pairs/s ({m} x {m})")


def table_mesh_gripper(gripper: Gripper, sites: int, repeat: int) -> None:
    import dataclasses

    pa = gripper.palm[2]
    w, t, length = gripper.finger_width, gripper.finger_thickness, gripper.finger_length
    palm = trimesh.creation.cylinder(radius=0.04, height=pa, sections=64)
    palm.apply_translation([0.0, 0.0, -pa / 2.0])
    finger = trimesh.creation.box(bounds=[[-w / 2, 0, -length / 2], [w / 2, t, length / 2]])
    finger = finger.subdivide().subdivide()
    meshed = dataclasses.replace(gripper, palm_mesh=(palm.vertices, palm.faces),
                                 finger_mesh=(finger.vertices, finger.faces))  # fmt: skip
    print(f"\n4. gripper as meshes (palm {len(palm.faces)} triangles, finger "
          f"{len(finger.faces)}) vs boxes (checks/s)")  # fmt: skip
    print(f"{'mesh':14s} {'boxes':>9s} {'hit':>5s} {'meshes':>9s} {'hit':>5s} {'ratio':>6s}")
    for name, mesh in meshes().items():
        poses, widths = candidate_poses(mesh, gripper, sites)
        collider = ObjectCollider(mesh)
        collider.mesh.contains(np.zeros((1, 3)))
        row = []
        for model in (gripper, meshed):
            hit = collider.gripper_collides(model, poses, widths)
            t = best(lambda c=collider, m=model, p=poses, w=widths: c.gripper_collides(m, p, w),
                     repeat)
            row.append((len(poses) / t, hit.mean()))
        (box_rate, box_hit), (mesh_rate, mesh_hit) = row
        print(f"{name:14s} {box_rate:9.0f} {box_hit:5.2f} {mesh_rate:9.0f} {mesh_hit:5.2f} "
              f"{box_rate / mesh_rate:6.2f}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sites", type=int, default=200, help="grasp sites per mesh (x24 rolls)")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    gripper = Gripper.default()
    print(f"ray engine embree: {trimesh.ray.has_embree}")
    table_mesh(gripper, args.sites, args.repeat)
    table_choices(gripper, args.sites, args.repeat)
    table_boxes(gripper, args.repeat)
    table_mesh_gripper(gripper, args.sites, args.repeat)


if __name__ == "__main__":
    main()
