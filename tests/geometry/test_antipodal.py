"""Antipodal grasp sites on curved surfaces (geometry.antipodal)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from handover.geometry import mesh as gm
from handover.geometry.antipodal import antipodal_sites, deduplicate, sample_surface
from handover.geometry.frames import transform_from
from handover.geometry.quality import ContactPairs, cone_angles

OPEN = dict(min_opening=0.0, max_opening=0.085, friction=0.5)


def test_sample_surface_is_seeded_area_weighted_and_on_the_surface():
    m = gm.icosphere(0.03, 3)
    p1, f1, spacing = sample_surface(m, 0.005, seed=3)
    p2, f2, _ = sample_surface(m, 0.005, seed=3)
    p3, _, _ = sample_surface(m, 0.005, seed=4)
    assert_allclose(p1, p2)
    assert (f1 == f2).all()
    assert not np.allclose(p1, p3)
    assert len(p1) == int(np.ceil(m.area / 0.005**2))
    assert spacing == 0.005
    assert gm.distance_to_faces(m, p1, f1).max() < 1e-12


def test_sample_surface_respects_the_mask_and_the_cap():
    m = gm.box((0.1, 0.1, 0.1))
    top = m.face_normals[:, 2] > 0.5
    points, faces, _ = sample_surface(m, 0.01, face_mask=top)
    assert top[faces].all()
    assert_allclose(points[:, 2], 0.05)
    assert len(points) == 100  # 0.01 m^2 / (0.01 m)^2
    _, _, widened = sample_surface(m, 0.001, max_samples=600)
    assert widened == pytest.approx(np.sqrt(m.area / 600))


@pytest.mark.parametrize("subdivisions", [0, 1, 2, 3])
def test_icosphere_pairs_are_antipodal_and_all_around(subdivisions):
    m = gm.icosphere(0.03, subdivisions)
    found = antipodal_sites(m, spacing=0.011, **OPEN)
    s = found.sites
    assert len(s) >= 6
    # both contacts on the surface, on the faces they name
    for k in (0, 1):
        assert gm.distance_to_faces(m, s.contacts[:, k], s.faces[:, k]).max() < 5e-4
    assert_allclose(s.normals, m.face_normals[s.faces])
    # within the friction cone, within the opening
    assert (cone_angles(s.normals, s.axis) <= np.arctan(0.5) + 1e-9).all()
    assert (s.width <= 0.085).all() and (s.width > 0).all()
    # the approach is perpendicular to the closing line
    assert_allclose(np.einsum("ij,ij->i", s.approach, s.axis), 0.0, atol=1e-12)
    # grasp sites all around the sphere: contacts in every octant
    octant = (s.contacts.reshape(-1, 3) > 0) @ [1, 2, 4]
    assert set(octant.tolist()) == set(range(8))


def test_a_large_sphere_has_no_pair_within_the_opening():
    found = antipodal_sites(gm.icosphere(0.06, 2), spacing=0.011, **OPEN)
    assert found.samples > 0 and found.pairs == 0 and len(found.sites) == 0


def test_deduplicate_keeps_the_best_of_near_identical_pairs():
    contacts = np.array(
        [
            [[0, 0, 0], [0, 0, 0.03]],
            [[0.001, 0, 0], [0.001, 0, 0.03]],  # 1 mm from the first: a duplicate
            [[0.05, 0, 0], [0.05, 0, 0.03]],  # far away: distinct
        ],
        dtype=float,
    )
    sites = ContactPairs(
        contacts=contacts,
        normals=np.zeros((3, 2, 3)),
        faces=np.zeros((3, 2), int),
        approach=np.zeros((3, 3)),
        overlap_area=np.zeros(3),
        source=np.ones(3, np.int8),
    )
    assert deduplicate(sites, np.array([0.5, 0.9, 0.1]), 0.0025).tolist() == [1, 2]
    assert deduplicate(sites, np.array([0.9, 0.9, 0.1]), 0.0025).tolist() == [0, 2]


def test_pairs_stay_inside_the_material_of_a_non_convex_object():
    # an L-shaped bracket: rays from the inner corner's faces leave through the arms
    a = gm.box((0.06, 0.02, 0.02))
    b = gm.box((0.02, 0.06, 0.02), transform_from(None, [-0.02, 0.03, 0.0]))
    pm = gm.compose([("a", a), ("b", b)])
    assert pm.mesh.is_watertight
    found = antipodal_sites(pm.mesh, spacing=0.004, **OPEN)
    mids = found.sites.centre
    assert len(mids) > 0
    assert pm.mesh.contains(mids).all()
