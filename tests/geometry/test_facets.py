"""Grasp sites on parallel facet pairs (geometry.facets, the paper's section 3.1)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
import trimesh
from numpy.testing import assert_allclose

from handover.geometry import mesh as gm
from handover.geometry.facets import facet_sites, overlap_site_points, planar_facets
from handover.geometry.frames import transform_from

PAD = 0.022
PARAMS = dict(
    min_opening=0.0,
    max_opening=0.085,
    finger_width=PAD,
    min_area=PAD**2,
    friction=0.5,
    parallel_tol_rad=np.deg2rad(10.0),
)


def _sorted_rows(a: np.ndarray) -> np.ndarray:
    a = np.round(np.asarray(a), 9) + 0.0
    return a[np.lexsort(a.T[::-1])]


def test_box_gives_exactly_the_face_pairs_within_the_opening():
    # 0.1 (x, too wide for 0.085) x 0.06 (y) x 0.03 (z)
    found = facet_sites(gm.box((0.1, 0.06, 0.03)), **PARAMS)
    s = found.sites
    assert found.facets.area.size == 6
    assert found.candidate_pairs == 2 and found.overlapping_pairs == 2
    axes = np.abs(s.axis)
    across_y = axes[:, 1] > 0.99
    across_z = axes[:, 2] > 0.99
    assert (across_y | across_z).all()
    assert_allclose(s.width[across_y], 0.06)
    assert_allclose(s.width[across_z], 0.03)
    # projected overlaps: the 0.1 x 0.03 side and the 0.1 x 0.06 top
    assert_allclose(s.overlap_area[across_y], 0.1 * 0.03)
    assert_allclose(s.overlap_area[across_z], 0.1 * 0.06)
    # grid sites: 22 mm apart from the centroid along the long axis (x) over the overlap
    # shrunk by min(11 mm, short side / 4); across, only 0. Where the shrunk overlap is at
    # least 11 mm across, rim sites too: on each edge at least 22 mm long, its middle and
    # every 22 mm from it while 11 mm from its ends; grid points within 11 mm give way.
    # Across y: the 0.1 x 0.03 side shrunk by 7.5 mm is 0.085 x 0.015: rim rows at
    # z = +-7.5 mm replace the centre row.
    row = (-0.022, 0.0, 0.022)
    assert_allclose(_sorted_rows(s.centre[across_y]),
                    _sorted_rows([[x, 0, z] for x in row for z in (-0.0075, 0.0075)]),
                    atol=1e-12)  # fmt: skip
    # Across z: the 0.1 x 0.06 top shrunk by 11 mm is 0.078 x 0.038: the centre row (19 mm
    # from the long edges, 17 mm from the ends) plus the rim
    grid = [[x, 0, 0] for x in row]
    rim = [[-0.039, 0, 0], [0.039, 0, 0]] + [[x, y, 0] for x in row for y in (-0.019, 0.019)]
    assert_allclose(_sorted_rows(s.centre[across_z]), _sorted_rows(grid + rim), atol=1e-12)
    # the grid approaches along the long axis; the rim from outside, along the edge normal
    assert_allclose(s.approach[across_y], [[0, 0, -np.sign(z)] for z in s.centre[across_y, 2]])
    end_rim = across_z & (np.abs(s.centre[:, 0]) > 0.03)  # (+-0.039, 0, 0)
    side_rim = across_z & (np.abs(s.centre[:, 1]) > 0.018)  # (x, +-0.019, 0)
    centre_row = across_z & ~(end_rim | side_rim)
    assert_allclose(np.abs(s.approach[centre_row, 0]), 1.0)
    assert_allclose(s.approach[end_rim], [[-np.sign(x), 0, 0] for x in s.centre[end_rim, 0]])
    assert_allclose(s.approach[side_rim], [[0, -np.sign(y), 0] for y in s.centre[side_rim, 1]])
    # contacts on the faces, normals exactly along the closing line
    assert_allclose(np.abs(s.contacts[across_y][:, :, 1]), 0.03)
    assert_allclose(np.abs(s.contacts[across_z][:, :, 2]), 0.015)
    assert_allclose(np.einsum("ij,ij->i", s.normals[:, 0], s.axis), -1.0)
    assert_allclose(np.einsum("ij,ij->i", s.normals[:, 1], s.axis), 1.0)
    assert_allclose(np.einsum("ij,ij->i", s.approach, s.axis), 0.0, atol=1e-12)
    # the contact faces are faces of the two facets
    box = gm.box((0.1, 0.06, 0.03))
    assert_allclose(np.einsum("ij,ij->i", box.face_normals[s.faces[:, 0]], s.normals[:, 0]), 1.0)
    assert found.paired_faces.sum() == 8  # the four faces across y and z; not the x ends


def test_all_three_pairs_of_a_small_cube():
    found = facet_sites(gm.box((0.05, 0.05, 0.05)), **PARAMS)
    # the 0.05 square shrunk by 0.011 is 0.028 across: its centre (the one grid point) and
    # the middles of its four edges, 14 mm out
    assert len(found.sites) == 3 * 5
    assert_allclose(found.sites.width, 0.05)
    assert_allclose(np.abs(found.sites.axis).sum(axis=0), [5, 5, 5])
    radius = np.sort(np.linalg.norm(found.sites.centre, axis=1))
    assert_allclose(radius, [0] * 3 + [0.014] * 12, atol=1e-12)
    assert found.paired_faces.all()


def _slanted_octagonal_prism(radius: float, height: float, shift: float) -> trimesh.Trimesh:
    """The paper's Fig. 3: a regular octagon (flat sides facing +-x and +-y) at z=0, the
    same octagon moved by (shift, 0, height) at the top, joined by slanted sides."""
    theta = np.deg2rad(22.5 + 45.0 * np.arange(8))
    ring = np.stack([radius * np.cos(theta), radius * np.sin(theta), np.zeros(8)], axis=1)
    vertices = np.vstack([ring, ring + [shift, 0.0, height]])
    bottom = [[0, k + 1, k] for k in range(1, 7)]
    top = [[8, 8 + k, 8 + k + 1] for k in range(1, 7)]
    sides = []
    for k in range(8):
        a, b = k, (k + 1) % 8
        sides += [[a, b, 8 + b], [a, 8 + b, 8 + a]]
    mesh, _ = gm.validate_mesh(vertices, np.array(bottom + top + sides))
    return mesh


def test_slanted_octagonal_prism_overlap_by_hand():
    r, h, s = 0.06, 0.04, 0.02
    prism = _slanted_octagonal_prism(r, h, s)
    assert prism.is_watertight
    found = facet_sites(prism, **PARAMS)
    # only the caps are within 85 mm: the side pairs are 2 r cos 22.5 = 111 mm apart
    # (99 mm for the sides slanted by the shift)
    assert found.overlapping_pairs == 1
    sites = found.sites
    assert_allclose(sites.width, h)
    assert_allclose(np.abs(sites.axis[:, 2]), 1.0)
    # Overlap of the octagon with itself moved by s along x: the octagon minus a central
    # strip of width s through its flat middle (s <= the side length 2 r sin 22.5):
    # 2 sqrt(2) r^2 - 2 a s, a = r cos 22.5 the apothem; centred at (s / 2, 0).
    a = r * np.cos(np.deg2rad(22.5))
    assert s <= 2 * r * np.sin(np.deg2rad(22.5))
    area = 2 * np.sqrt(2) * r * r - 2 * a * s
    assert_allclose(sites.overlap_area, area, rtol=1e-9)
    # the overlap's centroid, midway between the caps, is the grid's anchor: a site
    centre = np.array([s / 2, 0.0, h / 2])
    assert np.min(np.linalg.norm(sites.centre - centre, axis=1)) < 1e-9
    # every site lies inside both caps' projections, midway between the planes
    assert_allclose(sites.centre[:, 2], h / 2)
    assert_allclose(np.sort(sites.contacts[:, :, 2], axis=1), np.tile([0.0, h], (len(sites), 1)),
                    atol=1e-12)  # fmt: skip


def test_overlap_sites_small_overlap_is_its_centroid():
    square = shapely.Polygon([(0, 0), (0.03, 0), (0.03, 0.025), (0, 0.025)])
    owner, xy, axis = overlap_site_points(np.array([square]), PAD)
    assert owner.tolist() == [0]
    assert_allclose(xy, [[0.015, 0.0125]])
    assert_allclose(np.abs(axis), [[1, 0]])


def test_overlap_sites_narrow_strip_gets_a_line_of_sites():
    # 3 mm x 100 mm: narrower than a finger, still a row of sites 22 mm apart
    strip = shapely.Polygon([(0, 0), (0.1, 0), (0.1, 0.003), (0, 0.003)])
    owner, xy, _ = overlap_site_points(np.array([strip]), PAD)
    assert_allclose(np.sort(xy[:, 0]), 0.05 + PAD * np.arange(-2, 3))
    assert_allclose(xy[:, 1], 0.0015)


def test_l_shaped_overlap_site_lies_inside():
    ell = shapely.Polygon([(0, 0), (0.03, 0), (0.03, 0.005), (0.005, 0.005), (0.005, 0.03),
                           (0, 0.03)])  # fmt: skip
    owner, xy, _ = overlap_site_points(np.array([ell]), PAD)
    assert len(xy) >= 1
    assert shapely.contains_xy(ell, xy[:, 0], xy[:, 1]).all()


def test_faces_too_small_for_a_pad_are_left_to_antipodal_sampling():
    # the 0.01 x 0.01 ends are below the 22 mm x 22 mm pad: not facets; the sides are
    stick = gm.box((0.01, 0.01, 0.2))
    facets = planar_facets(stick, PAD**2)
    assert len(facets) == 4
    assert_allclose(facets.area, 0.01 * 0.2)


def test_facets_with_a_hole_keep_it():
    # a head box with a handle through its +x face: that face's polygon has a hole
    head = gm.box((0.1, 0.04, 0.04))
    handle = gm.cylinder(0.01, 0.2, 16, transform_from(None, [0, 0, 0.1]))
    pm = gm.compose([("head", head), ("handle", handle)])
    facets = planar_facets(pm.mesh, PAD**2)
    top = np.argmax(facets.normal[:, 2] * (facets.origin[:, 2] > 0.019))
    assert len(facets.polygon[top].interiors) == 1
    hole = 16 / 2 * 0.01**2 * np.sin(2 * np.pi / 16)
    assert facets.area[top] == pytest.approx(0.1 * 0.04 - hole, rel=1e-9)


def test_no_grasp_across_a_gap_between_two_plates():
    # two 10 mm plates 5 mm apart: squeezing both outer faces (25 mm) would pinch air
    a = gm.box((0.05, 0.05, 0.01), transform_from(None, [0, 0, 0.005]))
    b = gm.box((0.05, 0.05, 0.01), transform_from(None, [0, 0, 0.02]))
    pm = gm.compose([("a", a), ("b", b)])
    found = facet_sites(pm.mesh, **PARAMS)
    widths = np.unique(np.round(found.sites.width, 9))
    assert_allclose(widths, [0.01, 0.05])


def test_extra_vertices_on_edges_do_not_move_sites():
    # what an overlay of two nearly identical squares returns: the ring starting mid-edge
    # and a vertex 40 um from a corner on a straight edge; the sites must be the square's
    square = shapely.Polygon([(0, 0), (0.05, 0), (0.05, 0.05), (0, 0.05)])
    noisy = shapely.Polygon(
        [(0, 0.02), (0, 0), (0.05, 0), (0.05, 0.05), (0.00004, 0.05), (0, 0.05)]
    )
    clean_owner, clean_xy, clean_a = overlap_site_points(np.array([square]), PAD)
    owner, xy, a = overlap_site_points(np.array([noisy]), PAD)
    assert len(xy) == len(clean_xy) == 5
    order, clean_order = np.lexsort(xy.T), np.lexsort(clean_xy.T)
    assert_allclose(xy[order], clean_xy[clean_order], atol=1e-12)
    rim = np.linalg.norm(xy[order] - 0.025, axis=1) > 0.01  # the four edge middles
    assert_allclose(a[order][rim], clean_a[clean_order][rim], atol=1e-12)
