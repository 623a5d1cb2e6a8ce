"""What a container holds standing up (geometry.held), on meshes built here whose cavities
are known by construction: a mug whose handle reaches above its rim, the same mug written
in another frame, a bowl, a tray of boxes, a cup with a notch in its rim, solids."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from handover.geometry import hollow
from handover.geometry import mesh as gm
from handover.geometry.frames import rotation_from_euler_deg, transform_from
from handover.geometry.held import held_volume

R_OUT, R_IN, H, FLOOR = 0.04, 0.032, 0.1, 0.008  # an 8 mm wall, an 8 mm floor


def mug(handle_z: float = 0.075) -> trimesh.Trimesh:
    """A mug: a cylinder minus a smaller one, with a torus for a handle whose top (at
    ``handle_z`` + 31 mm) reaches above the rim at 0.1 m."""
    outer = trimesh.creation.cylinder(radius=R_OUT, height=H, sections=64)
    outer.apply_translation([0, 0, H / 2])
    inner = trimesh.creation.cylinder(radius=R_IN, height=H, sections=64)
    inner.apply_translation([0, 0, FLOOR + H / 2])
    body = trimesh.boolean.difference([outer, inner], engine="manifold")
    handle = trimesh.creation.torus(0.025, 0.006, major_sections=48, minor_sections=16)
    handle.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    handle.apply_translation([0.064, 0, handle_z])  # its inner side in the wall, not the cavity
    return trimesh.boolean.union([body, handle], engine="manifold")


def in_cavity(points: np.ndarray) -> np.ndarray:
    """The mug's cavity, from its dimensions: inside the inner wall, above the floor, below
    the rim."""
    r = np.linalg.norm(points[:, :2], axis=1)
    return (r < R_IN) & (points[:, 2] > FLOOR) & (points[:, 2] < H)


def probes() -> np.ndarray:
    """Points in and around the mug, none within 1.5 mm of the cavity's boundary."""
    rng = np.random.default_rng(7)
    pts = rng.uniform([-0.05, -0.05, -0.01], [0.09, 0.05, 0.13], size=(4000, 3))
    r = np.linalg.norm(pts[:, :2], axis=1)
    near = (np.abs(r - R_IN) < 0.0015) | (np.abs(pts[:, 2] - FLOOR) < 0.0015) \
        | (np.abs(pts[:, 2] - H) < 0.0015)
    return pts[~near]


def test_a_mug_whose_handle_reaches_above_its_rim_holds_its_cavity_not_the_handle_gap():
    m = mug()
    assert m.bounds[1][2] > H + 0.005  # the handle's top is above the rim
    held = held_volume(m, [0, 0, 1])
    pts = probes()
    np.testing.assert_array_equal(held.contains(pts), in_cavity(pts))
    assert held.volume == pytest.approx(math.pi * R_IN**2 * (H - FLOOR), rel=0.03)
    # the hole of the handle, above the rim, in the wall: not in it
    assert not held.contains(np.array([[0.064, 0, 0.075], [0, 0, H + 0.002],
                                       [0.036, 0, 0.05]])).any()


@pytest.mark.parametrize("turn", [(90, 0, 0), (0, 90, 30), (37, -61, 112)])
def test_the_same_mug_written_in_another_frame_holds_the_same(turn):
    rot = rotation_from_euler_deg(np.array(turn, dtype=float))
    turned = mug()
    turned.apply_transform(transform_from(rot, [0.2, -0.1, 0.05]))
    held = held_volume(turned, rot @ np.array([0.0, 0.0, 1.0]))
    pts = probes()
    inside = held.contains(pts @ rot.T + np.array([0.2, -0.1, 0.05]))
    np.testing.assert_array_equal(inside, in_cavity(pts))
    assert held.volume == pytest.approx(held_volume(mug(), [0, 0, 1]).volume, rel=0.01)


def test_a_bowl_holds_its_cavity():
    r, h, t = 0.08, 0.05, 0.004
    bowl = hollow.bowl(r, h, t, "spherical", sections=96)
    cavity = hollow.bowl_cavity(r, h, t, "spherical", sections=96)
    held = held_volume(bowl, [0, 0, 1])
    assert held.volume == pytest.approx(cavity.volume, rel=0.04)
    inside = trimesh.sample.volume_mesh(cavity, 2000)
    deep = np.abs(trimesh.proximity.signed_distance(cavity, inside)) > 0.0015
    assert held.contains(inside[deep]).all()


def test_a_tray_of_boxes_holds_up_to_its_rim_and_a_notch_lowers_the_level():
    base = gm.box((0.3, 0.2, 0.01), transform_from(None, [0, 0, 0.005]))
    walls = [gm.box((0.3, 0.01, 0.04), transform_from(None, [0, y, 0.02])) for y in (-0.095, 0.095)]
    walls += [gm.box((0.01, 0.18, 0.04), transform_from(None, [x, 0, 0.02]))
              for x in (-0.145, 0.145)]
    tray = gm.compose([("tray", p) for p in [base, *walls]]).mesh
    held = held_volume(tray, [0, 0, 1])
    assert held.contains(np.array([[0.0, 0.0, 0.02], [0.1, 0.05, 0.039]])).all()
    assert not held.contains(np.array([[0.0, 0.0, 0.041], [0.0, 0.0, 0.009]])).any()
    assert held.volume == pytest.approx(0.28 * 0.18 * 0.03, rel=0.03)
    # a notch 15 mm deep in one wall: the level stands at the notch's bottom, as water does
    notched = trimesh.boolean.difference(
        [tray, gm.box((0.03, 0.05, 0.03), transform_from(None, [0.0, 0.095, 0.04]))],
        engine="manifold")
    low = held_volume(notched, [0, 0, 1])
    assert low.contains(np.array([[0.0, 0.0, 0.024]])).all()
    assert not low.contains(np.array([[0.0, 0.0, 0.026]])).any()


@pytest.mark.parametrize("solid", [
    gm.box((0.05, 0.04, 0.03)),
    gm.cylinder(0.03, 0.1, 48, None),
    gm.icosphere(0.03, 3),
])
def test_a_solid_holds_nothing(solid):
    assert len(held_volume(solid, [0, 0, 1])) == 0
    assert len(held_volume(solid, [0.3, -0.2, 0.9])) == 0


def test_the_way_up_must_be_a_direction():
    with pytest.raises(ValueError, match="up direction"):
        held_volume(gm.box((0.05, 0.04, 0.03)), [0, 0, 0])
