"""Mesh loading, validation, primitives and part composition (geometry.mesh)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose

from handover.geometry import mesh as gm
from handover.geometry.frames import rotation_about_axis, transform_from
from handover.geometry.mesh import MeshError, MeshWarning


def _polygon_area(n: int, r: float) -> float:
    """Area of the regular n-gon inscribed in a circle of radius r."""
    return n / 2 * r * r * np.sin(2 * np.pi / n)


def _polygon_perimeter(n: int, r: float) -> float:
    return n * 2 * r * np.sin(np.pi / n)


# ---------------------------------------------------------------- loading


@pytest.mark.parametrize("suffix", [".stl", ".obj", ".ply", ".glb"])
def test_load_round_trip_of_a_box(tmp_path, suffix):
    path = tmp_path / f"box{suffix}"
    trimesh.creation.box(extents=(0.1, 0.06, 0.03)).export(path)
    m = gm.load_mesh(path)
    assert len(m.faces) == 12
    assert m.is_watertight
    assert_allclose(sorted(m.extents), [0.03, 0.06, 0.1], atol=1e-7)
    assert m.volume == pytest.approx(0.1 * 0.06 * 0.03, rel=1e-6)


def test_load_applies_scale(tmp_path):
    path = tmp_path / "mm.stl"
    trimesh.creation.box(extents=(100, 60, 30)).export(path)
    m = gm.load_mesh(path, scale=0.001)
    assert_allclose(sorted(m.extents), [0.03, 0.06, 0.1], atol=1e-7)


def test_load_flattens_a_scene(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(extents=(1, 1, 1)))
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    scene.add_geometry(sphere, transform=transform_from(None, [5, 0, 0]))
    path = tmp_path / "scene.glb"
    scene.export(path)
    m = gm.load_mesh(path)
    assert len(m.faces) == 12 + 320
    assert m.bounds[1, 0] == pytest.approx(6.0)  # the sphere was moved by its scene transform


def test_inward_winding_is_turned_outward(tmp_path):
    box = trimesh.creation.box(extents=(1, 1, 1))
    path = tmp_path / "inside_out.obj"
    trimesh.Trimesh(box.vertices, box.faces[:, ::-1]).export(path)
    m = gm.load_mesh(path)
    assert m.volume > 0


def test_missing_file(tmp_path):
    with pytest.raises(MeshError, match="not found"):
        gm.load_mesh(tmp_path / "nothing.stl")


def test_unsupported_format(tmp_path):
    path = tmp_path / "a.xyz"
    path.write_text("1 2 3\n")
    with pytest.raises(MeshError, match="unsupported mesh format"):
        gm.load_mesh(path)


def test_garbage_file_is_an_empty_mesh(tmp_path):
    path = tmp_path / "garbage.stl"
    path.write_text("this is not a mesh")
    with pytest.raises(MeshError, match="empty|cannot read"):
        gm.load_mesh(path)


def test_point_cloud_is_not_a_mesh(tmp_path):
    path = tmp_path / "cloud.ply"
    trimesh.PointCloud(np.random.default_rng(0).random((10, 3))).export(path)
    with pytest.raises(MeshError, match="not a mesh"):
        gm.load_mesh(path)


def test_non_finite_vertex_is_named():
    box = trimesh.creation.box()
    v = np.array(box.vertices)
    v[3, 1] = np.nan
    with pytest.raises(MeshError, match="vertex 3 is not finite"):
        gm.validate_mesh(v, box.faces)


def test_non_finite_vertex_in_a_file(tmp_path):
    path = tmp_path / "nan.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    with pytest.raises(MeshError, match="not finite"):
        gm.load_mesh(path)


def test_all_degenerate_faces_means_no_area():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], dtype=float)  # collinear
    with pytest.raises(MeshError, match="no area"):
        gm.validate_mesh(v, [[0, 1, 2], [1, 2, 3]])


def test_degenerate_faces_are_removed_and_reported_by_index():
    box = trimesh.creation.box()
    v = np.vstack([box.vertices, [[5, 5, 5], [6, 5, 5], [7, 5, 5]]])
    f = np.vstack([box.faces[:6], [[8, 9, 10]], box.faces[6:]])  # a sliver in the middle
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # still a closed box: no warning
        m, kept = gm.validate_mesh(v, f)
    assert len(m.faces) == 12
    assert_allclose(kept, np.r_[0:6, 7:13])
    assert m.is_watertight


def test_too_many_faces(monkeypatch):
    monkeypatch.setattr(gm, "MAX_FACES", 10)
    box = trimesh.creation.box()
    with pytest.raises(MeshError, match="more than the limit of 10"):
        gm.validate_mesh(box.vertices, box.faces)


def test_empty_arrays():
    with pytest.raises(MeshError, match="empty"):
        gm.validate_mesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=int))


def test_bad_indices():
    with pytest.raises(MeshError, match="out of range"):
        gm.validate_mesh(np.eye(3), [[0, 1, 3]])


def test_open_mesh_warns_and_still_loads(tmp_path):
    box = trimesh.creation.box(extents=(1, 1, 1))
    path = tmp_path / "open.stl"
    trimesh.Trimesh(box.vertices, box.faces[:-2]).export(path)
    with pytest.warns(MeshWarning, match="not watertight"):
        m = gm.load_mesh(path)
    assert len(m.faces) == 10


def test_bad_scale(tmp_path):
    with pytest.raises(MeshError, match="scale"):
        gm.load_mesh(tmp_path / "x.stl", scale=0.0)


# ---------------------------------------------------------------- primitives


def test_box_primitive_with_transform():
    t = transform_from(rotation_about_axis([0, 0, 1], np.pi / 2), [1.0, 2.0, 3.0])
    m = gm.box((0.1, 0.06, 0.03), t)
    assert_allclose(m.extents, [0.06, 0.1, 0.03], atol=1e-12)  # x and y swapped by the turn
    assert_allclose(m.bounds.mean(axis=0), [1.0, 2.0, 3.0], atol=1e-12)


def test_cylinder_is_a_regular_prism():
    m = gm.cylinder(0.02, 0.1, sections=16)
    assert m.volume == pytest.approx(_polygon_area(16, 0.02) * 0.1, rel=1e-9)
    assert_allclose(m.bounds[:, 2], [-0.05, 0.05])


def test_icosphere_faces_and_radius():
    m = gm.icosphere(0.03, 2)
    assert len(m.faces) == 20 * 4**2
    assert_allclose(np.linalg.norm(m.vertices, axis=1), 0.03)


def test_capsule_height_excludes_caps():
    m = gm.capsule(0.01, 0.05)
    assert m.extents[2] == pytest.approx(0.05 + 2 * 0.01)
    assert m.is_watertight


@pytest.mark.parametrize(
    "make",
    [
        lambda: gm.box((0.1, 0.0, 0.1)),
        lambda: gm.cylinder(-1.0, 0.1),
        lambda: gm.cylinder(0.1, 0.1, sections=2),
        lambda: gm.icosphere(float("nan")),
        lambda: gm.capsule(0.1, 0.0),
    ],
)
def test_bad_primitive_dimensions(make):
    with pytest.raises(MeshError):
        make()


# ---------------------------------------------------------------- parts


def _hammer(sections: int = 16):
    """Head: box 0.1 x 0.04 x 0.04 at the origin; handle: cylinder r=0.01 along x from
    x=0 to x=0.2 (its first 0.05 m inside the head)."""
    head = gm.box((0.1, 0.04, 0.04))
    turn = rotation_about_axis([0, 1, 0], np.pi / 2)  # cylinder z -> x
    handle = gm.cylinder(0.01, 0.2, sections, transform_from(turn, [0.1, 0, 0]))
    return gm.compose([("head", head), ("handle", handle)])


def test_compose_unions_overlapping_parts_with_exact_part_areas():
    n, r = 16, 0.01
    pm = _hammer(n)
    assert pm.part_names == ["head", "handle"]
    assert pm.mesh.is_watertight
    cap = _polygon_area(n, r)
    box_area = 4 * (0.1 * 0.04) + 2 * (0.04 * 0.04)  # four long sides, two square ends
    areas = pm.part_areas()
    # the head loses the hole where the handle leaves it; the handle keeps the 0.15 m outside
    assert areas["head"] == pytest.approx(box_area - cap, rel=1e-9)
    assert areas["handle"] == pytest.approx(_polygon_perimeter(n, r) * 0.15 + cap, rel=1e-9)
    # no interior faces: the union's volume is the head plus the handle outside it
    assert pm.mesh.volume == pytest.approx(0.1 * 0.04 * 0.04 + cap * 0.15, rel=1e-9)


def test_compose_tags_faces_by_the_solid_they_came_from():
    pm = _hammer()
    c = pm.mesh.triangles_center
    handle = pm.face_part == pm.part_names.index("handle")
    assert (c[handle, 0] >= 0.05 - 1e-9).all()  # the handle's faces lie outside the head
    assert (np.abs(c[~handle]) <= [0.05 + 1e-9, 0.02 + 1e-9, 0.02 + 1e-9]).all()


def test_compose_shares_a_part_name_across_solids():
    a = gm.box((0.02, 0.02, 0.02))
    b = gm.box((0.02, 0.02, 0.02), transform_from(None, [0.01, 0, 0]))
    pm = gm.compose([("body", a), ("body", b)])
    assert pm.part_names == ["body"]
    assert pm.mesh.volume == pytest.approx(0.03 * 0.02 * 0.02, rel=1e-9)


def test_compose_falls_back_to_concatenation_for_open_parts():
    box = gm.box((0.02, 0.02, 0.02))
    open_part = trimesh.Trimesh(box.vertices + [0.1, 0, 0], box.faces[:-1])
    with pytest.warns(MeshWarning) as record:
        pm = gm.compose([("a", box), ("b", open_part)])
    messages = " | ".join(str(w.message) for w in record)
    assert "concatenated" in messages and "not watertight" in messages
    assert len(pm.mesh.faces) == 12 + 11
    assert (pm.face_part == np.r_[np.zeros(12), np.ones(11)]).all()


def test_mass_centre_volume_and_area():
    off = transform_from(None, [0.3, -0.2, 0.1])
    assert_allclose(gm.PartMesh.single(gm.box((0.1, 0.2, 0.3), off)).mass_centre,
                    [0.3, -0.2, 0.1], atol=1e-12)  # fmt: skip
    # an open box without its top: the area centroid sits below the middle
    box = gm.box((1.0, 1.0, 1.0))
    top = box.triangles_center[:, 2] > 0.49
    with pytest.warns(MeshWarning):
        open_box, _ = gm.validate_mesh(box.vertices, box.faces[~top])
    # five unit faces: four sides at z=0, the bottom at z=-0.5 -> mean z = -0.1
    assert_allclose(gm.mass_centre(open_box), [0, 0, -0.1], atol=1e-12)


def test_part_mesh_from_regions_first_region_wins():
    m = gm.box((0.2, 0.1, 0.1))
    pm = gm.part_mesh_from_regions(
        m,
        "body",
        [("grip", [0.1, 0, 0], [0.1, 1, 1]), ("tip", [0.075, 0, 0], [0.1, 1, 1])],
    )
    assert pm.part_names == ["body", "grip", "tip"]
    c = m.triangles_center
    expected = np.where(c[:, 0] >= 0.05, 1, np.where(c[:, 0] >= 0.025, 2, 0))
    assert (pm.face_part == expected).all()


def test_part_mesh_regions_need_positive_extents():
    with pytest.raises(MeshError, match="positive extents"):
        gm.part_mesh_from_regions(gm.box((1, 1, 1)), "body", [("x", [0, 0, 0], [1, 0, 1])])


def test_distance_to_faces_by_hand():
    m, _ = gm.validate_mesh(
        np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float),
        [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    )
    points = np.array([[0.2, 0.2, 0.5], [2.0, 0.0, 0.0], [0.25, 0.25, 0.0]])
    faces = np.array([0, 0, 0])  # the triangle in z = 0
    assert_allclose(gm.distance_to_faces(m, points, faces), [0.5, 1.0, 0.0], atol=1e-15)


def test_the_part_under_a_point_is_the_part_of_the_nearest_surface():
    """A handle (a thin bar) joined to a body (a block): a point on the bar's axis, inside
    it, is under the handle; one deep inside the block is under the body, whatever their
    order; on the surface it is the contact's own label."""
    body = trimesh.creation.box((0.08, 0.08, 0.08))
    handle = trimesh.creation.box((0.10, 0.01, 0.01), transform=transform_from(
        np.eye(3), [0.09, 0.0, 0.0]))
    pm = gm.compose([("body", body), ("handle", handle)])
    points = np.array([[0.10, 0.0, 0.0],    # on the bar's axis, 5 mm below its faces
                       [-0.01, 0.0, 0.0],   # in the block, 3 cm from its nearest face
                       [0.0, 0.0, 0.04],    # on the block's top face
                       [0.13, 0.0, 0.005]])  # on the bar's top face
    names = [pm.part_names[i] for i in pm.part_under(points)]
    assert names == ["handle", "body", "body", "handle"]
    assert pm.part_under(np.zeros((0, 3))).shape == (0,)
    with pytest.raises(ValueError, match="finite"):
        pm.part_under([[np.nan, 0.0, 0.0]])
