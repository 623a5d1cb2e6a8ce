"""Hollow primitives and the interior of an opening, checked against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from handover.geometry import hollow
from handover.geometry import mesh as gm
from handover.geometry.collision import ObjectCollider
from handover.geometry.frames import transform_from
from handover.geometry.generate import generate_candidates
from handover.geometry.gripper import Gripper
from handover.geometry.interior import Interior, mesh_interior

S = 32
POLY = S * math.sin(2 * math.pi / S) / 2  # area of the 32-gon inscribed in the unit circle


def test_cup_is_a_closed_wall_with_the_volume_of_its_profile():
    r, h, t, b = 0.04, 0.1, 0.004, 0.006
    cup = hollow.cup(r, h, t, b, sections=S)
    assert cup.is_watertight and cup.volume > 0
    expected = POLY * (r * r * h - (r - t) ** 2 * (h - b))
    assert_allclose(cup.volume, expected, rtol=1e-9)
    assert_allclose(cup.bounds, [[-r, -r, -h / 2], [r, r, h / 2]], atol=1e-12)
    cavity = hollow.cup_cavity(r, h, t, b, sections=S)
    assert cavity.is_convex
    assert_allclose(cavity.volume, POLY * (r - t) ** 2 * (h - b), rtol=1e-9)


def test_tube_is_open_at_both_ends():
    r, h, t = 0.02, 0.05, 0.003
    tube = hollow.tube(r, h, t, sections=S)
    assert tube.is_watertight
    assert_allclose(tube.volume, POLY * (r * r - (r - t) ** 2) * h, rtol=1e-9)
    # a ray along the axis passes through without touching the wall
    hit, _ = gm.ray_first_hits(tube, np.array([[0, 0, -1.0]]), np.array([[0, 0, 1.0]]))
    assert hit[0] == -1


def test_hemispherical_bowl_volume_tends_to_the_shell():
    r, t = 0.08, 0.005
    bowl = hollow.bowl(r, r, t, sections=128)
    shell = 2 / 3 * math.pi * (r**3 - (r - t) ** 3)
    assert bowl.is_watertight
    assert bowl.volume == pytest.approx(shell, rel=0.01)
    assert_allclose(bowl.bounds[:, 2], [-r / 2, r / 2], atol=1e-12)


def test_conical_bowl_wall_is_as_thick_as_asked():
    # a frustum: the inner wall is parallel to the outer one, thickness apart
    bowl = hollow.bowl(0.05, 0.08, 0.005, "conical", 0.03, sections=S)
    cavity = hollow.bowl_cavity(0.05, 0.08, 0.005, "conical", 0.03, sections=S)
    assert bowl.is_watertight and cavity.is_convex
    # along +x at mid-height the wall is crossed between the outer and inner surfaces
    origins = np.array([[0.2, 0.0, 0.0]])
    hit, d = gm.ray_first_hits(bowl, origins, np.array([[-1.0, 0.0, 0.0]]))
    hit2, d2 = gm.ray_first_hits(bowl, origins - [d[0] + 1e-6, 0, 0], [[-1.0, 0, 0]])
    slope = math.hypot(1.0, 0.02 / 0.08)
    assert d2[0] + 1e-6 == pytest.approx(0.005 * slope, rel=1e-6)


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: hollow.cup(0.02, 0.1, 0.02), "below its radius"),
        (lambda: hollow.cup(0.02, 0.1, 0.002, 0.1), "below its height"),
        (lambda: hollow.tube(0.02, 0.1, 0.03), "below its radius"),
        (lambda: hollow.bowl(0.08, 0.01, 0.02), "no opening"),
        (lambda: hollow.bowl(0.02, 0.08, 0.02, "conical"), "no opening"),
        (lambda: hollow.bowl(0.02, 0.08, 0.002, "round"), "profile"),
    ],
)
def test_impossible_walls_are_mesh_errors(build, message):
    with pytest.raises(gm.MeshError, match=message):
        build()


def test_cup_of_water_interior_by_hand_computed_points():
    # a glass 8 cm wide, 12 cm tall, 3 mm walls, 5 mm bottom, standing on z = 0
    r, h, t, b = 0.04, 0.12, 0.003, 0.005
    place = transform_from(None, [0.0, 0.0, h / 2])
    inside = Interior([hollow.cup_cavity(r, h, t, b, sections=64, transform=place)])
    points = np.array(
        [
            [0.0, 0.0, 0.06],  # the middle of the water
            [0.0, 0.0, 0.119],  # just below the rim plane
            [0.0, 0.0, 0.121],  # just above it: the air over the glass
            [0.030, 0.0, 0.01],  # near the wall, inside
            [0.0, 0.0385, 0.05],  # in the wall (inner radius 37 mm)
            [0.045, 0.0, 0.05],  # outside the glass
            [0.0, 0.0, 0.004],  # in the bottom (5 mm thick)
            [0.0, 0.0, 0.006],  # just above the bottom
        ]
    )
    assert inside.contains(points).tolist() == [
        True, True, False, True, False, False, False, True
    ]  # fmt: skip
    # boxes: a fingertip dipping 5 mm into the glass enters, a palm on the rim does not
    eye = np.stack([np.eye(3)] * 3)
    centres = np.array([[0.0, 0.0, 0.125], [0.0, 0.0, 0.130], [0.06, 0.0, 0.06]])
    half = np.array([[0.005, 0.005, 0.010], [0.05, 0.05, 0.010], [0.01, 0.01, 0.05]])
    assert inside.boxes_enter(centres, eye, half).tolist() == [True, False, False]


def test_mesh_interior_of_a_hollow_mug_is_its_cavity_not_the_handle_gap():
    r, h, t = 0.04, 0.1, 0.004
    body = hollow.cup(r, h, t, sections=S)
    bar = gm.box((0.01, 0.02, 0.06), transform_from(None, [0.06, 0, 0]))
    top = gm.box((0.025, 0.02, 0.01), transform_from(None, [0.0505, 0, 0.025]))
    low = gm.box((0.025, 0.02, 0.01), transform_from(None, [0.0505, 0, -0.025]))
    mug = gm.compose([("body", body), ("handle", bar), ("handle", top), ("handle", low)])
    cavity_volume = POLY * (r - t) ** 2 * (h - t)
    opening = mesh_interior(mug.mesh, up=[0, 0, 1])
    assert len(opening) == 1
    # what it holds, in columns half a millimetre wide: the cavity within a few per cent
    assert opening.volume == pytest.approx(cavity_volume, rel=0.04)
    probe = np.array([[0, 0, 0.0], [0.046, 0, 0.0], [0.0, 0, 0.06], [0.03, 0, 0.049]])
    assert opening.contains(probe).tolist() == [True, False, False, True]
    assert len(mesh_interior(mug.mesh, up=None)) == 0  # no way up: no opening to tell


def test_mesh_interior_needs_no_closed_mesh_but_a_floor():
    r, h, t = 0.04, 0.1, 0.004
    cup = hollow.cup(r, h, t, sections=S)
    side = np.flatnonzero(np.abs(cup.face_normals[:, 2]) < 0.1)  # outer and inner walls
    outer = side[np.linalg.norm(cup.triangles_center[side, :2], axis=1) > r - t / 2][:6]
    holed = cup.copy()
    holed.update_faces(np.setdiff1d(np.arange(len(cup.faces)), outer))  # holes in its side
    assert not holed.is_watertight
    inside = mesh_interior(holed, up=[0, 0, 1])
    assert inside.contains(np.array([[0.0, 0.0, 0.0]])).all()
    # a hole right through the floor (its inner and outer faces at the middle) drains it
    through = np.flatnonzero((np.abs(cup.face_normals[:, 2]) > 0.9)
                             & (cup.triangles_center[:, 2] < 0))
    drained = cup.copy()
    drained.update_faces(np.setdiff1d(np.arange(len(cup.faces)), through))
    assert len(mesh_interior(drained, up=[0, 0, 1])) == 0


def test_a_mug_wall_is_pinched_one_finger_inside_one_outside():
    # 4 mm walls: the gripper finds grasps across the body's wall, contacts 4 mm apart
    r, h, t = 0.04, 0.1, 0.004
    pm = gm.compose([("body", hollow.cup(r, h, t, sections=S))])
    grip = Gripper.default()
    c = generate_candidates(pm, grip, collider=ObjectCollider(pm.mesh))
    radial = np.linalg.norm(c.contacts[..., :2], axis=-1)  # (N, 2)
    on_side = (np.abs(c.contacts[..., 2]) < h / 2 - 1e-4).all(axis=1)
    across = on_side & (c.width < 0.0045) & (np.abs(c.o[:, 2]) < 0.1)
    assert across.any()
    outer = radial[across].max(axis=1)
    inner = radial[across].min(axis=1)
    assert (outer > (r - t) + 0.9 * t * math.cos(math.pi / S)).all()
    assert (inner < r - 0.9 * t).all()
    # the finger inside reaches down into the cup from the open top
    assert (c.a[across][:, 2] < -0.9).any()
