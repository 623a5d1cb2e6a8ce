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


def test_pairs_of_a_non_convex_object_pinch_its_material_or_span_it_from_outside():
    # an L-shaped bracket: rays from the inner corner's faces leave through the arms, and a
    # line across the notch gives jaws on the outside of both arms
    from handover.geometry.mesh import ray_first_hits

    a = gm.box((0.06, 0.02, 0.02))
    b = gm.box((0.02, 0.06, 0.02), transform_from(None, [-0.02, 0.03, 0.0]))
    pm = gm.compose([("a", a), ("b", b)])
    assert pm.mesh.is_watertight
    found = antipodal_sites(pm.mesh, spacing=0.004, **OPEN)
    c, o = found.sites.contacts, found.sites.axis
    assert len(c) > 0
    inside = pm.mesh.contains(found.sites.centre)
    assert inside.any()
    # a pair whose midpoint is in the air spans the whole object: nothing of it lies beyond
    # either contact along the closing line (the jaws close on it from outside)
    span = ~inside
    step = 1e-6
    beyond_1, _ = ray_first_hits(pm.mesh, c[span, 1] + step * o[span], o[span])
    beyond_0, _ = ray_first_hits(pm.mesh, c[span, 0] - step * o[span], -o[span])
    assert (beyond_1 < 0).all() and (beyond_0 < 0).all()


# ---------------------------------------------------------------- oblique pairs


def torus():
    """The torus of benchmarks/candidates.py: ring radius 30 mm, tube radius 12 mm."""
    import trimesh

    t = trimesh.creation.torus(0.03, 0.012, major_sections=64, minor_sections=32)
    mesh, _ = gm.validate_mesh(t.vertices, t.faces)
    return mesh


CURVED = {
    "icosphere": lambda: gm.icosphere(0.02, 3),
    "torus": torus,
}


@pytest.mark.parametrize("name", sorted(CURVED))
def test_every_pair_is_on_the_surface_within_the_friction_cone(name):
    import trimesh

    m = CURVED[name]()
    s = antipodal_sites(m, spacing=0.011, **OPEN).sites
    assert len(s) > 0
    points = s.contacts.reshape(-1, 3)
    # independently: trimesh's brute-force closest point on the whole surface
    _, distance, _ = trimesh.proximity.closest_point_naive(m, points)
    assert distance.max() < 5e-4
    # the face each contact names holds it (trimesh's own point-triangle distance), and
    # that face's normal is within the friction cone of the line between the contacts
    on_face = trimesh.triangles.closest_point(m.triangles[s.faces.reshape(-1)], points)
    assert np.linalg.norm(on_face - points, axis=1).max() < 5e-4
    normal = m.face_normals[s.faces]  # (S, 2, 3)
    line = s.contacts[:, 1] - s.contacts[:, 0]
    line /= np.linalg.norm(line, axis=1, keepdims=True)
    half = np.degrees(np.arctan(OPEN["friction"]))
    push0 = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", -normal[:, 0], line), -1, 1)))
    push1 = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", normal[:, 1], line), -1, 1)))
    assert push0.max() <= half + 1e-6 and push1.max() <= half + 1e-6


@pytest.mark.parametrize("name", sorted(CURVED))
def test_oblique_rays_add_pairs_and_never_remove_one(name):
    m = CURVED[name]()
    normal_only = antipodal_sites(m, spacing=0.011, oblique_rays=0, **OPEN)
    both = antipodal_sites(m, spacing=0.011, **OPEN)
    assert both.pairs > normal_only.pairs  # oblique rays found valid pairs
    assert len(both.sites) >= len(normal_only.sites)
    assert both.normal_sites == len(normal_only.sites)
    # the normal pairs come first, unchanged
    assert_allclose(both.sites.contacts[: both.normal_sites], normal_only.sites.contacts)
    # the oblique ones really are oblique: off the normal at their first contact
    oblique = both.sites.take(np.arange(both.normal_sites, len(both.sites)))
    assert (cone_angles(oblique.normals, oblique.axis).max(axis=1) > np.radians(2)).all()


def test_oblique_pairs_grip_a_sphere_off_centre():
    # on a sphere every chord within the cone is antipodal: normal rays give only chords
    # through the centre, oblique ones fill in the off-centre chords between them
    m = gm.icosphere(0.02, 4)
    normal_only = antipodal_sites(m, spacing=0.011, oblique_rays=0, **OPEN).sites
    both = antipodal_sites(m, spacing=0.011, **OPEN).sites
    assert len(both) > len(normal_only)
    off_axis = lambda s: np.linalg.norm(np.cross(s.centre, s.axis), axis=1)  # noqa: E731
    assert off_axis(normal_only).max() < 1e-3
    assert off_axis(both).max() > 0.004


def test_oblique_pairs_are_seeded():
    m = torus()
    a = antipodal_sites(m, spacing=0.011, seed=5, **OPEN).sites
    b = antipodal_sites(m, spacing=0.011, seed=5, **OPEN).sites
    assert a.contacts.tobytes() == b.contacts.tobytes()


# ---------------------------------------------------------------- around a cavity


def test_a_hollow_cup_is_gripped_across_its_body_from_outside_as_well_as_across_its_wall():
    from handover.geometry import hollow

    r, h, t = 0.04, 0.1, 0.005
    cup = hollow.cup(r, h, t, sections=64)  # open at +z, centred half its height below the rim
    found = antipodal_sites(cup, spacing=0.004, **OPEN)
    c = found.sites.contacts  # (S, 2, 3)
    radius = np.linalg.norm(c[:, :, :2], axis=2)  # of each contact, about the cup's axis
    outer = np.abs(radius - r) < 1e-3  # on the outer surface (64 sections: within 0.2 mm)
    inner = np.abs(radius - (r - t)) < 1e-3
    across_body = outer.all(axis=1) & (found.sites.width > 2 * r - 0.002)
    across_wall = (outer[:, 0] & inner[:, 1]) | (inner[:, 0] & outer[:, 1])
    assert across_wall.any()  # the wall pinched, one finger in the cavity
    assert across_body.sum() > 20  # the jaws closing on the body from outside
    heights = c[across_body][:, :, 2].mean(axis=1)
    assert np.ptp(heights) > 0.6 * h  # all along the wall, not only across the solid floor
    # the line between its contacts crosses the cavity (its midpoint is in it)
    mid = found.sites.centre[across_body]
    assert (np.linalg.norm(mid[:, :2], axis=1) < r - t).all()


def test_a_solid_convex_object_gains_no_pair_from_the_envelope():
    # a convex solid's lines leave it once: the pairs are those of its first exits only
    box = gm.box((0.05, 0.04, 0.03))
    found = antipodal_sites(box, spacing=0.004, oblique_rays=0, **OPEN)
    assert found.pairs == len(sample_surface(box, 0.004)[0])  # one pair per sample, no more
