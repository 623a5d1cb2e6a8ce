"""What two parallel jaws hold, analytically (geometry/holding.py): the pads' contact
patches on simple solids, the torques and weight they resist at a grip force, and the share
of that a hanging weight uses. Expected values are worked out by hand from the pad's size,
the grip force and friction (F = 70 N, mu = 0.5, mu_t = 0.003 m, a 22 x 60 mm pad)."""

import numpy as np
import pytest
import trimesh

from handover.geometry.frames import transform_from
from handover.geometry.holding import (
    GRAVITY,
    PadGrip,
    contact_patches,
    holding_capacity,
    load_torques,
    utilisation,
)

GRIP = PadGrip(grip_force=70.0, friction=0.5, torsional_friction=0.003, finger_width=0.022,
               finger_length=0.06)  # fmt: skip


def pose(n, o, a, p) -> np.ndarray:
    return transform_from(np.column_stack([n, o, a]).astype(float), p)


def test_a_pad_flat_on_a_wide_face_touches_over_the_whole_pad():
    box = trimesh.creation.box(extents=[0.2, 0.04, 0.2])  # faces at y = +-0.02
    g = pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0])
    p = contact_patches(box, g[None], np.array([0.04]), GRIP)
    assert p.extent_n[0] == pytest.approx(0.022)
    assert p.extent_a[0] == pytest.approx(0.06)
    # a uniformly pressed 22 x 60 mm rectangle: mean distance from its centre ~ 17 mm
    assert 0.014 < p.radius[0] < 0.020


def test_a_pad_across_a_thin_rim_touches_only_the_rims_height():
    rim = trimesh.creation.box(extents=[0.3, 0.01, 0.012])  # 12 mm high along z
    g = pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0])
    p = contact_patches(rim, g[None], np.array([0.01]), GRIP)
    assert p.extent_n[0] == pytest.approx(0.022)
    assert p.extent_a[0] <= 0.012 + 1e-9


def test_a_pad_on_a_sphere_touches_at_a_point():
    ball = trimesh.creation.icosphere(subdivisions=4, radius=0.03)
    g = pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0])
    p = contact_patches(ball, g[None], np.array([0.06]), GRIP)
    assert p.extent_n[0] < 0.01 and p.extent_a[0] < 0.01
    assert p.radius[0] < 0.004


def test_what_the_pads_hold_on_a_face_and_at_a_point():
    box = trimesh.creation.box(extents=[0.2, 0.04, 0.2])
    g = pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0])
    face = contact_patches(box, g[None], np.array([0.04]), GRIP)
    cap = holding_capacity(GRIP, face, np.array([0.04]))[0]
    # twist: 2 F (mu rho + mu_t); tip about n: F x 60 mm + mu F w; about a: F x 22 mm + mu F w
    assert cap[1] == pytest.approx(2 * 70 * (0.5 * face.radius[0] + 0.003))
    assert cap[0] == pytest.approx(70 * 0.06 + 0.5 * 70 * 0.04)
    assert cap[2] == pytest.approx(70 * 0.022 + 0.5 * 70 * 0.04)
    assert cap[3] == pytest.approx(70.0)  # 2 mu F
    ball = trimesh.creation.icosphere(subdivisions=4, radius=0.03)
    point = contact_patches(ball, g[None], np.array([0.06]), GRIP)
    twist = holding_capacity(GRIP, point, np.array([0.06]))[0, 1]
    # a (tessellated) sphere's point: little beyond the torsional friction's 2 F mu_t,
    # 0.42 N m, well below the face's ~1.6 N m
    assert 0.42 <= twist < 0.5 * cap[1]


def test_a_weight_off_the_closing_axis_twists_and_off_the_pads_plane_tips():
    g = pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0])[None]
    down = np.array([[0.0, 0.0, -1.0]])  # gravity along -a
    w = 1.0 * GRAVITY
    # centre of mass 0.1 m along n: the weight (along -a) turns it about o
    twist = load_torques(g, np.array([0.1, 0.0, 0.0]), down, np.array([w]))[0]
    assert twist[:3] == pytest.approx([0.0, 0.1 * w, 0.0])
    assert twist[3] == pytest.approx(w)  # all of it along the pads
    # gravity along the closing axis with the centre of mass 0.1 m along n: a tip about a
    tip = load_torques(g, np.array([0.1, 0.0, 0.0]), np.array([[0.0, -1.0, 0.0]]),
                       np.array([w]))[0]
    assert tip[:3] == pytest.approx([0.0, 0.0, -0.1 * w])
    assert tip[3] == pytest.approx(0.0)


def test_a_hammer_like_bar_holds_near_its_centre_of_mass_and_not_at_its_end():
    bar = trimesh.creation.box(extents=[0.3, 0.024, 0.03])  # 0.6 kg, 30 cm
    poses = np.stack([pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [x, 0, 0]) for x in (0.0, 0.14)])
    widths = np.array([0.024, 0.024])
    cap = holding_capacity(GRIP, contact_patches(bar, poses, widths, GRIP), widths)
    down = np.repeat([[0.0, 0.0, -1.0]], 2, axis=0)
    use = utilisation(load_torques(poses, np.zeros(3), down, np.full(2, 0.6 * GRAVITY * 1.4)),
                      cap)
    assert use[0] < 0.2  # at the centre of mass only the weight, 8 N of 70
    assert use[1] > 1.0  # 14 cm off: 1.15 N m about the closing axis, more than ~1 N m


def test_a_zero_capacity_under_a_load_is_unbounded_and_bad_numbers_are_refused():
    loads = np.array([[0.0, 0.5, 0.0, 1.0]])
    assert utilisation(loads, np.array([[1.0, 0.0, 1.0, 10.0]]))[0] == np.inf
    assert utilisation(np.zeros((1, 4)), np.zeros((1, 4)))[0] == 0.0
    with pytest.raises(ValueError, match="grip_force"):
        PadGrip(0.0, 0.5, 0.003, 0.022, 0.06)
    with pytest.raises(ValueError, match="torsional_friction"):
        PadGrip(70.0, 0.5, -1.0, 0.022, 0.06)
    with pytest.raises(ValueError, match="widths"):
        contact_patches(trimesh.creation.box(), np.eye(4)[None], np.zeros(2), GRIP)
