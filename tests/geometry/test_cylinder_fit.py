"""Whether an object fits a cylinder in some orientation (geometry.cylinder_fit): the
small-parts cylinder of 16 CFR 1501 (31.7 mm across, 57.1 mm deep) against shapes whose fit
is known by hand."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import trimesh

from handover.geometry.cylinder_fit import enclosing_circle, fits_in_cylinder
from handover.geometry.frames import rotation_from_euler_deg

D, L = 0.0317, 0.0571


@pytest.mark.parametrize(("name", "mesh", "fits"), [
    ("a CR2032 coin cell, 20 x 3.2 mm", trimesh.creation.cylinder(0.010, 0.0032, sections=64),
     True),
    ("a 30 mm disc magnet", trimesh.creation.cylinder(0.015, 0.005, sections=64), True),
    ("a 31 mm ball", trimesh.creation.icosphere(3, 0.0155), True),
    ("a 32 mm ball", trimesh.creation.icosphere(3, 0.016), False),
    ("a 20 mm die", trimesh.creation.box((0.02, 0.02, 0.02)), True),
    ("a 25 mm cube: its face's diagonal is 35 mm", trimesh.creation.box((0.025,) * 3), False),
    ("a rod 20 x 56 mm", trimesh.creation.cylinder(0.010, 0.056), True),
    ("a rod 20 x 60 mm", trimesh.creation.cylinder(0.010, 0.060), False),
    ("a pen", trimesh.creation.cylinder(0.0055, 0.14), False),
    ("a mug", trimesh.creation.cylinder(0.04, 0.1), False),
])
def test_what_fits_the_small_parts_cylinder(name, mesh, fits):
    fit = fits_in_cylinder(mesh.vertices, D, L)
    assert fit.fits is fits, name
    assert (fit.margin >= 0) is fits
    if fits:
        assert fit.length <= L + 1e-9 and fit.width <= D + 1e-9


@pytest.mark.parametrize("angles", [(0, 0, 0), (90, 0, 0), (33, -71, 140)])
def test_the_answer_does_not_depend_on_the_frame(angles):
    rot = rotation_from_euler_deg(np.array(angles, dtype=float))
    for mesh in (trimesh.creation.cylinder(0.010, 0.0032, sections=64),
                 trimesh.creation.box((0.025,) * 3), trimesh.creation.cylinder(0.010, 0.056)):
        plain = fits_in_cylinder(mesh.vertices, D, L)
        turned = fits_in_cylinder(mesh.vertices @ rot.T + 0.3, D, L)
        assert plain.fits == turned.fits
        assert turned.margin == pytest.approx(plain.margin, abs=0.01)


def test_a_triangle_needs_its_circumscribed_circle_not_its_diameter():
    # an equilateral prism of side s, 70 mm long: its outline along its axis is s across but
    # needs a circle 2 s / sqrt(3) wide, so a cylinder between the two does not take it
    side = 0.03
    prism = trimesh.creation.cylinder(side / math.sqrt(3), 0.07, sections=3)
    assert enclosing_circle(prism.vertices[:, :2])[1] == pytest.approx(side / math.sqrt(3))
    assert not fits_in_cylinder(prism.vertices, 0.033, 0.08).fits
    fit = fits_in_cylinder(prism.vertices, 0.035, 0.08)
    assert fit.fits and 2 * side / math.sqrt(3) - 1e-9 <= fit.width <= 0.035


def test_the_smallest_enclosing_circle_against_every_pair_and_triple():
    rng = np.random.default_rng(3)
    for _ in range(20):
        pts = rng.normal(size=(9, 2))
        centre, radius = enclosing_circle(pts)
        assert (np.linalg.norm(pts - centre, axis=1) <= radius + 1e-9).all()
        best = math.inf  # brute force: the smallest circle through 2 or 3 of them holding all
        for a, b in itertools.combinations(pts, 2):
            c, r = (a + b) / 2, np.linalg.norm(a - b) / 2
            if (np.linalg.norm(pts - c, axis=1) <= r + 1e-9).all():
                best = min(best, r)
        for a, b, c in itertools.combinations(pts, 3):
            m = np.array([b - a, c - a])
            if abs(np.linalg.det(m)) < 1e-12:
                continue
            rhs = 0.5 * np.array([b @ b - a @ a, c @ c - a @ a])
            centre3 = np.linalg.solve(m, rhs)
            r = np.linalg.norm(a - centre3)
            if (np.linalg.norm(pts - centre3, axis=1) <= r + 1e-9).all():
                best = min(best, r)
        assert radius == pytest.approx(best, rel=1e-9)


def test_bad_input_says_what_is_wrong():
    with pytest.raises(ValueError, match="positive diameter"):
        fits_in_cylinder(np.zeros((4, 3)), 0.0, 0.05)
    with pytest.raises(ValueError, match="finite points"):
        fits_in_cylinder(np.full((4, 3), np.nan), 0.03, 0.05)
