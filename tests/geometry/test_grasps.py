"""The receiver's grasp repertoire as geometry: each family's boxes round the section they hold,
the surface-sample depth test, the cross-section's pieces, the reaching arm's elbow and the
grasps that close round a hollow part. Parts and expectations are built here by hand."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose

from handover.geometry.antipodal import enclosing_sites
from handover.geometry.grasps import FAMILIES, GraspShape
from handover.geometry.hand import HumanHand
from handover.geometry.human import reaching_elbows
from handover.geometry.penetration import SurfaceSamples, box_depths
from handover.geometry.sections import section_pieces

HAND = HumanHand.default()


def shape(family: str, **kw) -> GraspShape:
    args = {"width": 0.03, "reach": 0.025, "min_thickness": 0.0, "max_thickness": 0.05,
            "max_load": 1.0}
    args.update(kw)
    return GraspShape(name=family, family=family, hand=HAND, **args)


def _inside(points: np.ndarray, extents, pose) -> np.ndarray:
    local = (points - pose[:3, 3]) @ pose[:3, :3]
    return (np.abs(local) < np.asarray(extents) / 2 - 1e-9).all(axis=1)


def _boxes(s: GraspShape, thickness: float, depth: float, approach=(0.0, 0.0, 1.0)):
    ext, poses, valid = s.boxes_many(np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0]]),
                                     np.array([approach]), np.array([thickness]),
                                     np.array([depth]))
    return [(n, ext[0, b], poses[0, b]) for b, n in enumerate(s.box_names) if valid[0, b]]


def _slab(thickness: float) -> np.ndarray:
    """Points filling an edge's part: x in [-0.1, 0.1], y within the thickness, z in
    [0, 0.1] (the edge's face at z = 0, the hand coming along +z)."""
    g = np.linspace(-0.5, 0.5, 21)
    x, y, z = np.meshgrid(g * 0.2, g * thickness * 0.999, (g + 0.5) * 0.1, indexing="ij")
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


@pytest.mark.parametrize("family", ["pinch", "lateral"])
def test_an_edge_grasp_holds_the_edge_between_its_pads_and_keeps_the_hand_beyond_it(family):
    t = 0.02
    s = shape(family)
    boxes = {n: (e, p) for n, e, p in _boxes(s, t, s.reach)}
    assert set(boxes) == set(FAMILIES[family])
    part = _slab(t)
    for name, (ext, pose) in boxes.items():
        assert not _inside(part, ext, pose).any(), name  # none of them through the part
    pads = [n for n in boxes if n in ("thumb", "fingertips", "index")]
    for name in pads:
        ext, pose = boxes[name]
        # on a face of the edge (|y| just beyond t/2), reaching `reach` into the part
        assert abs(abs(pose[1, 3]) - (t + ext[1]) / 2) < 1e-12
        assert pose[2, 3] + ext[2] / 2 == pytest.approx(s.reach)
    behind = boxes["hand" if family == "pinch" else "fist"]
    assert behind[1][2, 3] + behind[0][2] / 2 < 0  # wholly beyond the edge
    wrist = s.wrists(np.zeros((1, 3)), np.array([[1.0, 0, 0]]), np.array([[0, 0, 1.0]]),
                     np.array([t]), np.array([s.reach]))[0]
    assert (wrist[:, 2] < behind[1][2, 3]).all()  # the forearm meets the hand behind it


def test_a_support_from_below_lays_the_palm_under_the_site():
    s = shape("support", width=0.09)
    ((name, ext, pose),) = _boxes(s, 0.0, 0.0)
    assert name == "palm"
    assert pose[2, 3] + ext[2] / 2 == pytest.approx(0.0)  # its top face at the site
    assert ext[1] == pytest.approx(HAND.palm[1] + HAND.finger_length)
    # the palm's middle under the site, the fingers stretched out beyond it
    assert pose[1, 3] == pytest.approx(HAND.finger_length / 2)


def test_a_wrap_of_the_repertoire_is_the_hand_models_wrap():
    s = shape("wrap", width=HAND.grip_width, max_thickness=0.16)
    got = _boxes(s, 0.03, 0.03)
    want = HAND.boxes(np.zeros(3), [1, 0, 0], [0, 0, 1], 0.03, 0.03)
    assert [n for n, _, _ in got] == [n for n, _, _ in want]
    for (_, e1, p1), (_, e2, p2) in zip(got, want, strict=True):
        assert_allclose(e1, e2)
        assert_allclose(p1, p2, atol=1e-12)


@pytest.mark.parametrize("family", ["tripod", "hook"])
def test_tripod_and_hook_close_round_a_stem_without_entering_it(family):
    t, d = 0.012, 0.012
    s = shape(family, width=0.025)
    g = np.linspace(-0.5, 0.5, 11)
    x, y, z = np.meshgrid(g * 0.2, g * t * 0.999, g * d * 0.999, indexing="ij")
    stem = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    boxes = {n: (e, p) for n, e, p in _boxes(s, t, d)}
    for name, (ext, pose) in boxes.items():
        assert not _inside(stem, ext, pose).any(), name
    far_side = np.array([[0.0, 0.0, d / 2 + 0.005]])  # beyond the stem, seen from the palm
    closes = "middle" if family == "tripod" else "fingertips"
    assert _inside(far_side, *boxes[closes]).all()
    if family == "hook":  # no thumb on the other side: the -y side is free
        assert not any(_inside(np.array([[0.0, -t / 2 - 0.005, 0.0]]), e, p).any()
                       for e, p in boxes.values())


def test_a_grasp_with_a_bad_size_or_family_is_refused():
    with pytest.raises(ValueError, match="width must be a positive number"):
        shape("pinch", width=-0.01)
    with pytest.raises(ValueError, match="family must be one of"):
        shape("grab")
    with pytest.raises(ValueError, match="thickness"):
        shape("pinch", min_thickness=0.05, max_thickness=0.01)


# ---------------------------------------------------------------- how deep boxes press in


def test_surface_samples_measure_a_box_pressed_into_a_face_and_one_through_a_thin_wall():
    block = trimesh.creation.box([0.2, 0.1, 0.05])
    samples = SurfaceSamples.from_mesh(block)
    rot = np.eye(3)[None]
    half = np.array([[0.02, 0.02, 0.01]])
    for delta in (0.0, 0.002, 0.006):
        centre = np.array([[0.0, 0.0, 0.025 + 0.01 - delta]])  # its bottom delta into the top
        assert samples.box_depths(centre, rot, half)[0] == pytest.approx(delta, abs=1e-9)
    # a 2 mm sheet through the middle of a 2 cm finger: the lattice of box_depths steps over
    # it (5 points across 2 cm), the surface samples do not
    sheet = trimesh.creation.box([0.2, 0.1, 0.002])
    finger = np.array([[0.0, 0.0, 0.0]]), np.eye(3)[None], np.array([[0.01, 0.01, 0.0104]])
    assert SurfaceSamples.from_mesh(sheet).box_depths(*finger)[0] > 0.009
    assert box_depths(sheet, *finger)[0] < 0.0015


def test_surface_samples_are_the_same_every_time():
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    a, b = SurfaceSamples.from_mesh(mesh), SurfaceSamples.from_mesh(mesh)
    assert_allclose(a.points, b.points)
    with pytest.raises(ValueError, match="spacing"):
        SurfaceSamples.from_mesh(mesh, spacing=0.0)


# ---------------------------------------------------------------- the section's pieces


def _square(cx: float, cy: float, r: float) -> np.ndarray:
    c = np.array([[cx - r, cy - r], [cx + r, cy - r], [cx + r, cy + r], [cx - r, cy + r]])
    return np.stack([c, np.roll(c, -1, axis=0)], axis=1)


def test_a_hand_closes_round_the_piece_of_the_section_that_holds_its_part():
    handle = _square(0.125, 0.0, 0.01)  # a kettle's handle bar beside its body
    body = _square(0.0, 0.0, 0.08)
    segments = np.concatenate([handle, body])
    samples = np.array([[0.125, 0.0], [0.0, 0.0], [0.125, 0.009]])
    near, on = section_pieces(segments, samples, own=np.array([[0.125, 0.01]]))
    assert near.tolist() == [True, False, True]
    ends = segments.reshape(-1, 2)
    assert on.tolist() == (np.abs(ends[:, 0] - 0.125) < 0.02).tolist()
    # one piece alone: everything belongs
    near, on = section_pieces(body, samples, own=np.array([[0.0, 0.08]]))
    assert near.all() and on.all()


# ---------------------------------------------------------------- the reaching arm


def test_the_reaching_arm_closes_its_triangle_and_lifts_its_elbow_outward():
    shoulder = np.array([[0.0, 0.0, 1.4]])
    wrist = np.array([[0.4, 0.1, 1.2]])
    upper, fore = 0.32, 0.26
    out = np.array([0.0, -1.0, 0.0])  # the right arm's outside
    elbows = reaching_elbows(shoulder, wrist, upper, fore, out, (0.0, np.pi / 4, np.pi / 2))[0]
    assert_allclose(np.linalg.norm(elbows - shoulder, axis=1), upper, atol=1e-9)
    assert_allclose(np.linalg.norm(wrist - elbows, axis=1), fore, atol=1e-9)
    line = (wrist - shoulder)[0] / np.linalg.norm(wrist - shoulder)
    # hanging: the lowest elbow of all; turned a quarter: level with the line, to the outside
    assert elbows[0, 2] < elbows[1, 2] < elbows[2, 2]
    off = elbows[2] - shoulder[0]
    off -= (off @ line) * line  # the elbow's offset from the shoulder-wrist line
    down = np.array([0.0, 0.0, -1.0]) - line[2] * -1.0 * line
    assert abs(off @ down) < 1e-9  # level: no part of it below the line
    assert off @ out > 0
    # beyond reach: a straight arm pointing at the wrist
    far = reaching_elbows(shoulder, np.array([[1.0, 0.0, 1.4]]), upper, fore, out)[0, 0]
    assert_allclose(far, [upper, 0.0, 1.4], atol=1e-9)


# ---------------------------------------------------------------- closing round a hollow part


def test_a_glass_is_held_round_and_a_solid_bar_gives_no_enclosing_pair():
    from handover.geometry.hollow import cup

    glass = cup(0.032, 0.14, 0.003, 0.006, 48, np.eye(4))
    pairs = enclosing_sites(glass, spacing=0.01, min_opening=0.0, max_opening=0.085,
                            friction=0.5)
    assert len(pairs)
    width = np.linalg.norm(pairs.contacts[:, 0] - pairs.contacts[:, 1], axis=1)
    assert (width > 0.06).all() and (width < 0.065).all()  # across the whole glass
    radial = np.linalg.norm(pairs.contacts[..., :2], axis=2)
    assert_allclose(radial, 0.032, atol=1e-3)  # both on the outer wall
    bar = trimesh.creation.cylinder(radius=0.02, height=0.1, sections=48)
    assert not len(enclosing_sites(bar, spacing=0.01, min_opening=0.0, max_opening=0.085,
                                   friction=0.5))
