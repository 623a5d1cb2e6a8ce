"""Candidate generation speed: facet pairs, antipodal sites, candidates, collision filter.

Run: ``.venv/bin/python benchmarks/candidates.py [--repeat 3] [--no-kb]``

For icospheres of 80 to 81,920 faces (radius 20 mm, so that some grasps clear the palm), a
box, a composite hammer (handle cylinder + head box, unioned) and the built-in KB objects it
prints:

- faces, large planar facets, antiparallel facet pairs within the opening, sites (facet +
  antipodal), candidates before and after the collision filter;
- ``gen ms``: ``generate_with_stats`` without a collider on a freshly built mesh (cold
  caches: trimesh's facets and adjacency, the embree scene), best of ``--repeat``;
- ``coll/s``: collision checks per second of ``ObjectCollider.gripper_collides`` on those
  candidates (best of ``--repeat``; the collider's BVH is built once, not timed);
- ``fcl/s``: a bare python-fcl loop over the same poses
  (``geometry.collision.bare_fcl_loop_seconds``: one gripper BVH, one Transform and one
  collide per pose, no containment test: the floor) and ``ratio`` = our time / floor time
  (below 1: faster than the floor, thanks to the broad phase and the palm-first early exit).

Then antipodal sites on the curved objects (sampled over the whole surface, with no facet
step first) with rays along the normals only and with the oblique rays inside the friction
cone added (the count must not drop).

Then, for icospheres up to ``--naive-max-faces`` (default 20,480), the naive baseline: every
face pair screened at once (normals antiparallel within the gripper's tolerance, distance along
the normal below the opening; numpy, in row blocks), against our whole generation (``gen ms``
plus the collision filter on its candidates).

Targets (2 cores, one process): 5,120-face icosphere under 0.1 s, 81,920 faces under 3 s
(testing all face pairs there takes ~70 s, FIELD-NOTES.md); collision within 1.5x the floor;
a whole generation at 20,480 faces in at most half the time of the naive screening alone.
Numbers vary +-30-50 % from run to run on a shared machine.
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections.abc import Callable

import numpy as np

from handover.geometry import mesh as gm
from handover.geometry.collision import ObjectCollider, bare_fcl_loop_seconds
from handover.geometry.frames import rotation_about_axis, transform_from
from handover.geometry.generate import generate_with_stats
from handover.geometry.gripper import Gripper


def hammer() -> gm.PartMesh:
    """A hammer: handle cylinder (r 12 mm, 0.28 m along x, 32 sides) through a head box."""
    turn = rotation_about_axis([0, 1, 0], np.pi / 2)
    handle = gm.cylinder(0.012, 0.28, 32, transform_from(turn, [0.14, 0, 0]))
    head = gm.box((0.03, 0.11, 0.025), transform_from(None, [0.27, 0.0, 0.0]))
    return gm.compose([("handle", handle), ("head", head)])


def torus() -> gm.PartMesh:
    """A torus: ring radius 30 mm, tube radius 12 mm, 64 x 32 sections (4,096 faces)."""
    import trimesh

    t = trimesh.creation.torus(0.03, 0.012, major_sections=64, minor_sections=32)
    mesh, _ = gm.validate_mesh(t.vertices, t.faces)
    return gm.PartMesh.single(mesh)


def mug() -> gm.PartMesh:
    """A mug of 4 mm walls: a cup (r 40 mm, 100 mm tall) with a box handle."""
    from handover.geometry import hollow

    handle = gm.box((0.012, 0.02, 0.07), transform_from(None, [0.05, 0.0, 0.0]))
    return gm.compose([("body", hollow.cup(0.04, 0.1, 0.004)), ("handle", handle)])


def oblique_table(gripper: Gripper, cases: list[tuple[str, Callable[[], gm.PartMesh]]]) -> None:
    """Antipodal sites with rays along normals only against normals plus oblique rays."""
    from handover.geometry.antipodal import antipodal_sites

    print("\nantipodal sites: normal rays only vs normal + oblique rays in the friction cone")
    print(f"{'object':<16} {'faces':>6} {'normal':>7} {'+oblique':>9} {'ms normal':>10} "
          f"{'ms both':>8}")  # fmt: skip
    for name, make in cases:
        mesh = make().mesh
        kw = dict(spacing=gripper.finger_width / 2.0, min_opening=gripper.min_opening,
                  max_opening=gripper.max_opening, friction=gripper.friction)  # fmt: skip
        mesh.ray.intersects_first(mesh.vertices[:1], -mesh.vertex_normals[:1])  # warm scene
        start = time.perf_counter()
        normal = antipodal_sites(mesh, oblique_rays=0, **kw)
        t_normal = time.perf_counter() - start
        start = time.perf_counter()
        both = antipodal_sites(mesh, **kw)
        t_both = time.perf_counter() - start
        print(f"{name:<16} {len(mesh.faces):>6} {len(normal.sites):>7} {len(both.sites):>9} "
              f"{1000 * t_normal:>10.1f} {1000 * t_both:>8.1f}")  # fmt: skip


def builtin_objects() -> list[tuple[str, Callable[[], gm.PartMesh]]]:
    """The built-in KB's objects, or nothing (with a note) if the KB does not load."""
    try:
        from handover.engine.assets.objects import object_part_mesh
        from handover.engine.load.loader import load_kb

        kb = load_kb(None)
    except Exception as e:  # noqa: BLE001 - a benchmark reports and goes on
        print(f"(built-in KB not loaded: {type(e).__name__}: {str(e).splitlines()[0]})")
        return []
    return [
        (f"kb:{oid}", lambda obj=obj: object_part_mesh(kb, obj))
        for oid, obj in sorted(kb.objects.items())
    ]


def kb_gripper() -> Gripper:
    try:
        from handover.engine.assets.objects import gripper_from_spec
        from handover.engine.load.loader import load_kb

        kb = load_kb(None)
        if "parallel_jaw" in kb.grippers:
            return gripper_from_spec(kb.grippers["parallel_jaw"])
    except Exception:  # noqa: BLE001
        pass
    return Gripper.default()


def measure(name: str, make: Callable[[], gm.PartMesh], gripper: Gripper, repeat: int) -> dict:
    best_gen = np.inf
    for _ in range(repeat):
        part_mesh = make()  # fresh mesh: no cached facets, adjacency or ray scene
        start = time.perf_counter()
        candidates, stats = generate_with_stats(part_mesh, gripper)
        best_gen = min(best_gen, time.perf_counter() - start)
    collider = ObjectCollider(part_mesh.mesh)
    poses, widths = candidates.poses(), candidates.width
    n = len(candidates)
    ours = floor = np.nan
    kept = 0
    if n:
        ours = np.inf
        for _ in range(repeat):
            start = time.perf_counter()
            hits = collider.gripper_collides(gripper, poses, widths)
            ours = min(ours, time.perf_counter() - start)
        kept = int((~hits).sum())
        floor = min(bare_fcl_loop_seconds(part_mesh.mesh, gripper, poses, widths)
                    for _ in range(repeat))  # fmt: skip
    return {
        "name": name,
        "faces": stats.faces,
        "facets": stats.facets,
        "pairs": stats.facet_pairs,
        "sites": f"{stats.facet_sites}+{stats.antipodal_sites}",
        "cands": n,
        "kept": kept,
        "gen_ms": 1000 * best_gen,
        "coll_s": n / ours if n else np.nan,
        "fcl_s": n / floor if n else np.nan,
        "ratio": ours / floor if n else np.nan,
    }


def naive_pair_screening(part_mesh: gm.PartMesh, gripper: Gripper, block: int = 512) -> int:
    """Face pairs (i < j) whose normals are antiparallel within ``gripper.parallel_tol_deg``
    and whose centroids are closer than the opening along the normal: all F^2 pairs tested,
    vectorised over blocks of rows. Returns the number of pairs found."""
    normals = np.asarray(part_mesh.mesh.face_normals)
    centres = np.asarray(part_mesh.mesh.triangles_center)
    cos_tol = np.cos(np.radians(gripper.parallel_tol_deg))
    found = 0
    for start in range(0, len(normals), block):
        n_i, c_i = normals[start : start + block], centres[start : start + block]
        anti = n_i @ normals.T <= -cos_tol  # (B, F)
        rows, cols = np.nonzero(anti)
        keep = cols > rows + start
        rows, cols = rows[keep], cols[keep]
        depth = np.einsum("mi,mi->m", centres[cols] - c_i[rows], -n_i[rows])
        found += int(((depth > 0) & (depth <= gripper.max_opening)).sum())
    return found


def naive_table(gripper: Gripper, max_faces: int, generation_ms: dict[int, float]) -> None:
    print("\nnaive all-face-pairs screening vs our whole generation (icospheres, r 20 mm)")
    print(f"{'faces':>7} {'face pairs':>12} {'naive s':>9} {'ours s':>8} {'ours/naive':>10}")
    for sub in range(1, 8):
        part_mesh = gm.PartMesh.single(gm.icosphere(0.02, sub))
        faces = len(part_mesh.mesh.faces)
        if faces > max_faces:
            break
        start = time.perf_counter()
        pairs = naive_pair_screening(part_mesh, gripper)
        naive = time.perf_counter() - start
        ours = generation_ms[faces] / 1000.0
        print(f"{faces:>7} {pairs:>12} {naive:>9.3f} {ours:>8.3f} {ours / naive:>10.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="best of N runs")
    parser.add_argument("--no-kb", action="store_true", help="skip the built-in KB objects")
    parser.add_argument("--naive-max-faces", type=int, default=20480,
                        help="screen all face pairs on icospheres up to this many faces")
    args = parser.parse_args()
    warnings.simplefilter("ignore", gm.MeshWarning)

    gripper = kb_gripper()
    cases: list[tuple[str, Callable[[], gm.PartMesh]]] = [
        (f"icosphere/{s}", lambda s=s: gm.PartMesh.single(gm.icosphere(0.02, s)))
        for s in range(1, 7)
    ]
    cases.append(("box 100x60x30", lambda: gm.PartMesh.single(gm.box((0.1, 0.06, 0.03)))))
    cases.append(("hammer", hammer))
    cases.append(("torus", torus))
    cases.append(("mug 4mm wall", mug))
    if not args.no_kb:
        cases += builtin_objects()

    header = (
        f"{'object':<16} {'faces':>6} {'facets':>6} {'pairs':>5} {'sites':>9} {'cands':>6} "
        f"{'kept':>5} {'gen ms':>8} {'coll/s':>9} {'fcl/s':>9} {'ratio':>6}"
    )
    print(f"gripper: opening {gripper.max_opening * 1000:.0f} mm, roll step "
          f"{gripper.roll_step_deg:g} deg; best of {args.repeat}")  # fmt: skip
    print(header)
    print("-" * len(header))
    generation_ms: dict[int, float] = {}
    for name, make in cases:
        r = measure(name, make, gripper, args.repeat)
        if name.startswith("icosphere/"):
            # the whole generation: sites and candidates, then the collision filter
            generation_ms[r["faces"]] = r["gen_ms"] + 1000.0 * r["cands"] / r["coll_s"]
        print(
            f"{r['name']:<16} {r['faces']:>6} {r['facets']:>6} {r['pairs']:>5} {r['sites']:>9} "
            f"{r['cands']:>6} {r['kept']:>5} {r['gen_ms']:>8.1f} {r['coll_s']:>9.0f} "
            f"{r['fcl_s']:>9.0f} {r['ratio']:>6.2f}"
        )
    curved = [c for c in cases if c[0].startswith(("icosphere/", "torus", "mug", "kb:"))]
    oblique_table(gripper, curved)
    naive_table(gripper, args.naive_max_faces, generation_ms)


if __name__ == "__main__":
    main()
