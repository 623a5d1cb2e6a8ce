"""What the hazard measurements cost: the opening a container holds standing up, and whether an
object fits the small-parts cylinder.

Run: ``.venv/bin/python benchmarks/hazards.py [--repeat 3]``

For mugs of a few tessellations (a cylinder minus a smaller one with a torus handle whose
top reaches above the rim, the case the convex hull's pieces got wrong), a spherical bowl and
a tray of boxes, it prints the faces, the grid's columns, the columns that hold something and
their volume against the cavity's, and ``held ms``: :func:`handover.geometry.held.
held_volume` (rays down the columns, the flood), best of ``--repeat``. Then, for a coin
cell, balls of 30 and 32 mm, a 25 mm cube, a pen and a mug, ``fit ms``:
:func:`handover.geometry.cylinder_fit.fits_in_cylinder` on the small-parts cylinder (31.7 x
57.1 mm), with the answer, best of ``--repeat``. Both run once per plan of an object (the
first only for an object a ``keep_out`` rule is about, the second when the KB measures
hazards). Numbers vary +-30-50 % from run to run on a shared machine.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import trimesh

from handover.geometry import hollow
from handover.geometry import mesh as gm
from handover.geometry.cylinder_fit import fits_in_cylinder
from handover.geometry.frames import transform_from
from handover.geometry.held import held_volume


def mug(sections: int) -> tuple[trimesh.Trimesh, float]:
    """A mug of ``sections`` sides (8 mm wall and floor, its handle above the rim) and its
    cavity's volume (m^3)."""
    outer = trimesh.creation.cylinder(radius=0.04, height=0.1, sections=sections)
    outer.apply_translation([0, 0, 0.05])
    inner = trimesh.creation.cylinder(radius=0.032, height=0.1, sections=sections)
    inner.apply_translation([0, 0, 0.058])
    body = trimesh.boolean.difference([outer, inner], engine="manifold")
    handle = trimesh.creation.torus(0.025, 0.006, major_sections=sections,
                                    minor_sections=max(8, sections // 4))
    handle.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    handle.apply_translation([0.064, 0, 0.075])
    polygon = sections * math.sin(2 * math.pi / sections) / 2
    return trimesh.boolean.union([body, handle], engine="manifold"), \
        polygon * 0.032**2 * 0.092


def tray() -> tuple[trimesh.Trimesh, float]:
    base = gm.box((0.5, 0.35, 0.008), transform_from(None, [0, 0, 0.004]))
    walls = [gm.box((0.5, 0.01, 0.04), transform_from(None, [0, y, 0.02])) for y in (-0.17, 0.17)]
    walls += [gm.box((0.01, 0.33, 0.04), transform_from(None, [x, 0, 0.02]))
              for x in (-0.245, 0.245)]
    return gm.compose([("tray", p) for p in [base, *walls]]).mesh, 0.48 * 0.33 * 0.032


def best_ms(fn, repeat: int) -> tuple[float, object]:
    best, out = math.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return 1e3 * best, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per case (best is shown)")
    args = parser.parse_args()

    print(f"{'container':<22}{'faces':>8}{'columns':>9}{'holding':>9}{'volume/cavity':>15}"
          f"{'held ms':>9}")
    bowl = hollow.bowl(0.08, 0.05, 0.004, "spherical", sections=96)
    cases = [(f"mug, {n} sides", *mug(n)) for n in (32, 64, 256)]
    cases += [("bowl, 96 sides", bowl, hollow.bowl_cavity(0.08, 0.05, 0.004, "spherical",
                                                          sections=96).volume),
              ("tray of boxes", *tray())]
    for name, m, cavity in cases:
        ms, held = best_ms(lambda m=m: held_volume(m, [0.0, 0.0, 1.0]), args.repeat)
        print(f"{name:<22}{len(m.faces):>8}{held.top.size:>9}{len(held):>9}"
              f"{held.volume / cavity:>15.3f}{ms:>9.1f}")

    print(f"\n{'object':<22}{'hull pts':>9}{'fits':>6}{'fit ms':>9}")
    shapes = [
        ("coin cell 20 x 3.2 mm", trimesh.creation.cylinder(0.010, 0.0032, sections=64)),
        ("ball 30 mm", trimesh.creation.icosphere(3, 0.015)),
        ("ball 32 mm", trimesh.creation.icosphere(3, 0.016)),
        ("cube 25 mm", trimesh.creation.box((0.025,) * 3)),
        ("pen", trimesh.creation.cylinder(0.0055, 0.14)),
        ("mug", trimesh.creation.cylinder(0.04, 0.1)),
    ]
    for name, m in shapes:
        ms, fit = best_ms(lambda m=m: fits_in_cylinder(m.vertices, 0.0317, 0.0571), args.repeat)
        hull = len(np.unique(m.convex_hull.vertices, axis=0))
        print(f"{name:<22}{hull:>9}{'yes' if fit.fits else 'no':>6}{ms:>9.1f}")


if __name__ == "__main__":
    main()
