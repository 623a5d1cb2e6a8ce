"""Squeeze sites (geometry/squeeze.py): where two grippers, jaws closed, press opposite sides
of an object no gripper spans. Objects are built here; what is expected is worked out from
their shape (a box's faces, a ball's centre)."""

import numpy as np
import pytest
import trimesh

from handover.geometry.gripper import Gripper
from handover.geometry.mesh import PartMesh
from handover.geometry.squeeze import (
    SOURCE_SQUEEZE,
    SQUEEZE_GAP,
    fibonacci_half_sphere,
    opposed,
    squeeze_sites,
)

GRIPPER = Gripper(max_opening=0.085, min_opening=0.0, finger_length=0.06, finger_width=0.022,
                  finger_thickness=0.01, palm=(0.06, 0.13, 0.08), clearance=0.005,
                  friction=0.5)  # fmt: skip


def part_mesh(mesh: trimesh.Trimesh) -> PartMesh:
    return PartMesh(mesh, np.zeros(len(mesh.faces), dtype=np.int64), ["body"],
                    np.asarray(mesh.center_mass, dtype=float))


def test_a_crate_is_squeezed_at_the_centres_of_its_opposite_faces():
    crate = trimesh.creation.box(extents=[0.3, 0.4, 0.2])
    sites = squeeze_sites(part_mesh(crate), GRIPPER, friction=0.5, directions=8, rolls=4)
    assert (sites.source == SOURCE_SQUEEZE).all() and (sites.width == 0).all()
    square = np.abs(sites.a).max(axis=1) > 1 - 1e-9  # pressing straight into a face
    centres = np.unique(np.round(sites.centre[square], 9), axis=0)
    expected = np.array([[s * 0.15, 0, 0] for s in (-1, 1)] + [[0, s * 0.2, 0] for s in (-1, 1)]
                        + [[0, 0, s * 0.1] for s in (-1, 1)])
    np.testing.assert_allclose(np.sort(centres, axis=0), np.sort(expected, axis=0), atol=1e-9)
    np.testing.assert_allclose(sites.quality[square], 1.0)
    np.testing.assert_allclose(sites.com_distance, 0.0, atol=1e-9)
    # each press point comes with its rolls, the fingertips a gap off the face
    assert len(sites) % 4 == 0
    tips = sites.poses()[:, :3, 3] + (GRIPPER.finger_length / 2) * sites.a
    np.testing.assert_allclose(np.linalg.norm(tips - sites.centre, axis=1), SQUEEZE_GAP)


def test_presses_hold_the_crate_only_against_each_other():
    crate = trimesh.creation.box(extents=[0.3, 0.4, 0.2])
    s = squeeze_sites(part_mesh(crate), GRIPPER, friction=0.5, directions=8, rolls=1)
    plus_y = np.flatnonzero(np.isclose(s.a[:, 1], -1.0))[0]  # presses on +y towards -y
    minus_y = np.flatnonzero(np.isclose(s.a[:, 1], 1.0))[0]
    plus_x = np.flatnonzero(np.isclose(s.a[:, 0], -1.0))[0]
    assert opposed(s.centre[plus_y], s.a[plus_y], s.centre[minus_y], s.a[minus_y])
    assert not opposed(s.centre[plus_y], s.a[plus_y], s.centre[plus_x], s.a[plus_x])
    # the same direction is no squeeze: both push the same way
    assert not opposed(s.centre[plus_y], s.a[plus_y], s.centre[minus_y], s.a[plus_y])


def test_a_ball_is_squeezed_through_its_centre_from_every_side():
    ball = trimesh.creation.icosphere(subdivisions=4, radius=0.11)
    sites = squeeze_sites(part_mesh(ball), GRIPPER, friction=0.5, directions=24, rolls=2)
    assert len(sites) >= 2 * 24 * 2
    np.testing.assert_allclose(np.linalg.norm(sites.centre, axis=1), 0.11, atol=0.002)
    # every press points at the centre
    toward = -sites.centre / np.linalg.norm(sites.centre, axis=1, keepdims=True)
    assert (np.einsum("ij,ij->i", toward, sites.a) > np.cos(np.radians(2))).all()


def test_directions_and_bad_input():
    d = fibonacci_half_sphere(50)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    assert (d[:, 2] >= 0).all()
    np.testing.assert_array_equal(d, fibonacci_half_sphere(50))  # deterministic
    crate = part_mesh(trimesh.creation.box(extents=[0.3, 0.4, 0.2]))
    with pytest.raises(ValueError, match="friction"):
        squeeze_sites(crate, GRIPPER, friction=0.0)
    with pytest.raises(ValueError, match="rolls"):
        squeeze_sites(crate, GRIPPER, friction=0.5, rolls=0)
    with pytest.raises(ValueError, match="count"):
        fibonacci_half_sphere(0)
