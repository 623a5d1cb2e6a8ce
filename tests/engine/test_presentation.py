"""Presentations and the receiver's grasp site (the paper's 3.1: its A/C split), by hand."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from handover.engine.plan.presentation import (
    axis_goals,
    handover_poses,
    presentation_rotations,
    principal_axes,
    unique_rotations,
)
from handover.engine.plan.receiver_sites import (
    hand_axes,
    predict_receiver_sites,
    predict_two_hand_sites,
    receiver_region,
)
from handover.geometry.frames import rotation_from_euler_deg

TOWARD = np.array([1.0, 0.0, 0.0])


def test_24_distinct_proper_rotations():
    rots = presentation_rotations(TOWARD)
    assert rots.shape == (24, 3, 3)
    for r in rots:
        assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(r), 1.0)
    flat = {tuple(np.round(r, 6).ravel()) for r in rots}
    assert len(flat) == 24
    # The first one maps the object frame onto [toward, robot's left, up].
    assert_allclose(rots[0], np.eye(3), atol=1e-12)


def test_rotations_follow_the_receiver_direction():
    toward = np.array([0.0, 1.0, 0.0])  # receiver on the robot's left
    rots = presentation_rotations(toward)
    assert_allclose(rots[0] @ [1, 0, 0], toward, atol=1e-12)
    assert_allclose(rots[0] @ [0, 0, 1], [0, 0, 1], atol=1e-12)


def test_handover_pose_centres_the_bounding_box_on_the_handover_point():
    verts = np.array([[0, 0, 0], [0.2, 0.1, 0.05]], dtype=float)
    point = np.array([0.5, 0.0, 1.0])
    poses = handover_poses(verts, presentation_rotations(TOWARD), point)
    for pose in poses:
        world = verts @ pose[:3, :3].T + pose[:3, 3]
        assert_allclose(0.5 * (world.min(0) + world.max(0)), point, atol=1e-12)


def _handle_samples():
    """A 0.2 m handle along object x (x in [0, 0.2]) as rings of points around the x axis,
    radius 0.015, and a blade part beyond it (x in [0.2, 0.4])."""
    xs = np.linspace(0.0, 0.4, 81)
    angles = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    pts = np.array([[x, 0.015 * np.cos(t), 0.015 * np.sin(t)] for x in xs for t in angles])
    parts = (pts[:, 0] > 0.2).astype(np.int64)  # 0 handle, 1 blade
    return pts, parts


def test_receiver_site_is_on_the_handle_axis_in_the_receivers_half():
    pts, parts = _handle_samples()
    region = receiver_region(pts, parts, [{"handle"}, {"blade", "sharp"}], {"handle"}, {"sharp"})
    assert set(region.parts.tolist()) == {0}
    assert_allclose(np.abs(region.axis), [1, 0, 0], atol=1e-9)
    rots = presentation_rotations(TOWARD)
    # Presentation 0: object x (handle toward +x... the handle spans x 0..0.2) to the receiver.
    sites = predict_receiver_sites(region, rots[:1], TOWARD, grip_width=0.09)
    site = sites.site[0]
    # The handle spans s in [0, 0.2]: the middle of the receiver's half is s = 0.15.
    assert abs(site[0] - 0.15) < 0.01
    assert_allclose(site[1:], [0, 0], atol=1e-9)
    assert sites.part[0] == 0
    assert abs(sites.thickness[0] - 0.03) < 0.002


def test_far_end_site_sits_one_half_hand_from_the_end():
    pts, parts = _handle_samples()
    region = receiver_region(pts, parts, [{"handle"}, set()], {"handle"}, set())
    sites = predict_receiver_sites(region, presentation_rotations(TOWARD)[:1], TOWARD,
                                   grip_width=0.08, where="far_end")
    assert abs(sites.site[0][0] - (0.2 - 0.04)) < 0.01


def test_forbidden_parts_are_never_the_receivers():
    pts, parts = _handle_samples()
    region = receiver_region(pts, parts, [{"handle"}, {"sharp"}], set(), {"sharp"})
    assert region.parts.max() == 0
    nothing = receiver_region(pts, parts, [{"sharp"}, {"sharp"}], set(), {"sharp"})
    assert nothing.empty
    sites = predict_receiver_sites(nothing, presentation_rotations(TOWARD), TOWARD, 0.09)
    assert not sites.valid.any()


def test_two_hand_sites_are_on_the_receivers_edge_left_and_right():
    # A 0.5 (y) x 0.3 (x) tray top sampled on a grid, object frame = world in presentation 0.
    xs, ys = np.meshgrid(np.linspace(-0.15, 0.15, 31), np.linspace(-0.25, 0.25, 51))
    pts = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    region = receiver_region(pts, np.zeros(len(pts), dtype=np.int64), [set()], set(), set())
    right, left = predict_two_hand_sites(region, presentation_rotations(TOWARD)[:1], TOWARD,
                                         grip_width=0.08)
    # Receiver's edge: x near 0.15 - 0.04; receiver's right is the robot's left (+y).
    assert abs(right.site[0][0] - 0.11) < 0.02 and abs(left.site[0][0] - 0.11) < 0.02
    assert abs(right.site[0][1] - (0.25 - 0.08)) < 0.02
    assert abs(left.site[0][1] + (0.25 - 0.08)) < 0.02


def test_a_disc_has_no_long_axis_and_the_hand_takes_its_rim_tangent():
    # A disc of radius 12 cm in the object's xy plane, sampled on rings.
    r, a = np.meshgrid(np.linspace(0.01, 0.12, 12), np.linspace(0, 2 * np.pi, 72, endpoint=False))
    pts = np.stack([(r * np.cos(a)).ravel(), (r * np.sin(a)).ravel(), np.zeros(r.size)], axis=1)
    region = receiver_region(pts, np.zeros(len(pts), dtype=np.int64), [set()], set(), set())
    assert region.isotropic
    assert_allclose(np.abs(region.normal), [0, 0, 1], atol=1e-9)
    rots = presentation_rotations(TOWARD)
    axes = hand_axes(region, rots, TOWARD)
    world = np.einsum("kij,kj->ki", rots, axes)
    for k, rot in enumerate(rots):
        normal_w = rot @ region.normal
        if abs(normal_w[0]) > 0.9:  # facing the receiver: the hand's axis is horizontal
            assert abs(world[k][2]) < 1e-9
        else:  # the rim tangent at the point nearest the receiver: across robot->receiver
            assert abs(world[k][0]) < 1e-9
        assert abs(world[k] @ normal_w) < 1e-9  # in the disc's plane
    # A ruler is not isotropic: its hand axis is its length, in every presentation.
    ruler = receiver_region(pts * [1.0, 0.1, 1.0], np.zeros(len(pts), dtype=np.int64), [set()],
                            set(), set())  # fmt: skip
    assert not ruler.isotropic
    assert_allclose(np.abs(hand_axes(ruler, rots, TOWARD)), [[1, 0, 0]] * 24, atol=1e-9)


# ---------------------------------------------------------------- solved from the named axes


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


def _turn(axis, deg: float) -> np.ndarray:
    """Rotation by ``deg`` about ``axis`` (Rodrigues, written out here)."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    t = np.radians(deg)
    return np.eye(3) + np.sin(t) * kx + (1 - np.cos(t)) * kx @ kx


UP = np.array([0.0, 0.0, 1.0])
SKEWED = np.array([0.577, 0.577, 0.577])


@pytest.mark.parametrize("tilt", [SKEWED, "15 deg"])
def test_a_skewed_up_axis_is_put_exactly_upright_and_turned_about_it(tilt):
    up_obj = SKEWED if isinstance(tilt, np.ndarray) else _turn([1.0, 0.0, 0.0], 15.0) @ UP
    goals = axis_goals({"up": up_obj}, [("up", UP, None, 20.0)], TOWARD)
    rots = presentation_rotations(TOWARD, goals)
    angle = _angle_deg(rots @ (up_obj / np.linalg.norm(up_obj)), UP)
    upright = rots[angle < 1e-6]
    # four, a quarter turn apart about the vertical
    assert len(upright) == 4
    x_world = upright @ np.array([1.0, 0.0, 0.0])
    headings = np.sort(np.degrees(np.arctan2(x_world[:, 1], x_world[:, 0])) % 360.0)
    assert_allclose(np.diff(headings), [90.0, 90.0, 90.0], atol=1e-6)
    # no presentation is "nearly" upright: within the rule's 20 degrees means exactly (the
    # frame-aligned ones 15 degrees off are left out)
    assert not ((angle > 1e-6) & (angle <= 20.0)).any()
    for r in rots:
        assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(r), 1.0)


def test_an_object_written_along_its_axes_keeps_the_24_frame_aligned_presentations():
    goals = axis_goals({"up": UP, "handle": [1, 0, 0]},
                       [("up", UP, None, 20.0), ("handle", TOWARD, None, 60.0)], TOWARD)
    assert_allclose(presentation_rotations(TOWARD, goals), presentation_rotations(TOWARD))


def test_a_rule_that_wants_an_axis_away_puts_it_opposite_and_a_band_on_its_cone():
    tip = np.array([0.0, 0.6, 0.8])
    goals = axis_goals({"tip": tip}, [("tip", TOWARD, 100.0, None)], TOWARD)
    assert len(goals) == 1
    assert_allclose(goals[0].target, -TOWARD)
    rots = presentation_rotations(TOWARD, goals)
    assert (_angle_deg(rots @ (tip / 1.0), TOWARD) > 179.999).sum() == 4
    band = axis_goals({"tip": tip}, [("tip", UP, 60.0, 80.0)], TOWARD)
    assert len(band) == 4
    assert_allclose([g.angle_deg for g in band], [70.0] * 4, atol=1e-9)
    rots = presentation_rotations(TOWARD, band)
    angle = _angle_deg(rots @ tip, UP)
    # every presentation within the band puts the tip on the band's middle
    assert_allclose(angle[(angle >= 60.0) & (angle <= 80.0)], 70.0, atol=1.0)


def test_the_solved_presentations_are_the_same_orientations_in_any_frame():
    """Two named axes (a cup's up and its handle, not quite perpendicular) and the shape's
    principal axes, written in a frame turned by Q: every presentation that meets the rules
    exactly is the same world orientation of the object."""
    up, handle = UP, np.array([1.0, 0.0, 0.15])
    wants = [("up", UP, None, 20.0), ("handle", np.array([0.0, -1.0, 0.0]), None, 60.0)]
    box = np.array([[[0.0, 0, 0], [0.09, 0, 0], [0, 0.05, 0]],
                    [[0.0, 0, 0], [0, 0, 0.12], [0.02, 0.05, 0]]])  # two triangles: a shape
    for q in (_turn([1, 0, 0], 30.0), _turn(SKEWED, 77.0), _turn([0.2, -0.9, 0.4], 200.0)):
        rots = []
        for frame in (np.eye(3), q):
            goals = axis_goals({"up": frame @ up, "handle": frame @ handle}, wants, TOWARD)
            shape = principal_axes(box @ frame.T)
            r = presentation_rotations(TOWARD, goals, shape) @ frame  # the same object's
            exact = (_angle_deg(r @ up, UP) < 1e-6) | (_angle_deg(r @ handle, wants[1][1]) < 1e-6)
            rots.append(r[exact])
        a, b = rots
        assert len(a) == len(b) > 0
        for r in b:
            assert np.min(np.linalg.norm(a - r, axis=(1, 2))) < 1e-9


def test_principal_axes_follow_the_shape_and_leave_out_what_it_does_not_decide():
    import trimesh

    box = trimesh.creation.box(extents=[0.3, 0.2, 0.05])
    turn = _turn([0.3, 0.5, -0.2], 40.0)
    axes = principal_axes(box.triangles)
    turned = principal_axes(box.triangles @ turn.T)
    assert axes.shape == turned.shape == (3, 3)
    assert_allclose(np.abs(np.sum((axes @ turn.T) * turned, axis=1)), 1.0, atol=1e-9)
    assert_allclose(np.abs(axes[0]), [1, 0, 0], atol=1e-9)  # the longest first
    rod = trimesh.creation.cylinder(radius=0.01, height=0.2, sections=16)
    assert_allclose(np.abs(principal_axes(rod.triangles)), [[0, 0, 1]], atol=1e-9)
    cube = trimesh.creation.box(extents=[0.1, 0.1, 0.1])
    assert principal_axes(cube.triangles).shape == (0, 3)


def test_near_identical_presentations_are_kept_once_in_their_order():
    base = presentation_rotations(TOWARD)
    nudged = base[:3] @ _turn([0.0, 1.0, 0.0], 0.5)  # half a degree off
    far = base[:2] @ _turn([0.0, 1.0, 0.0], 5.0)
    out = unique_rotations(np.concatenate([base, nudged, far]))
    assert len(out) == 26
    assert_allclose(out[:24], base)
    assert_allclose(out[24:], far)


TILT_DEG = 30.0
GLASS = """\
id: {id}
name: A glass of water
mass: 0.3
tags: [open_container, liquid]
geometry:
  primitives:
    - {{shape: cup, part: body, radius: 0.033, height: 0.1, thickness: 0.003,
       bottom_thickness: 0.005, position: {body}, rotation_deg: [{tilt}, 0, 0]}}
    - {{shape: cylinder, part: base, radius: 0.033, height: 0.02, position: {base},
       rotation_deg: [{tilt}, 0, 0]}}
parts:
  body: {{tags: [body]}}
  base: {{tags: [base]}}
axes:
  up: {up}
"""


def _glass(name: str, tilt: float) -> str:
    """A tumbler (a cup on a solid 2 cm base), its base's centre at the frame's origin and
    its own up along the frame's z turned by ``tilt`` degrees about x."""
    turn = _turn([1.0, 0.0, 0.0], tilt)
    return GLASS.format(id=name, tilt=tilt, body=(turn @ [0, 0, 0.07]).round(12).tolist(),
                        base=(turn @ [0, 0, 0.01]).round(12).tolist(),
                        up=(turn @ UP).round(12).tolist())  # fmt: skip


def test_a_glass_written_in_a_tilted_frame_is_offered_upright_like_the_untilted_one(tmp_path):
    import shutil

    from handover.engine.load.loader import load_kb
    from handover.engine.planner import Planner
    from handover.engine.store.kb import builtin_kb_dir

    root = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    (root / "objects" / "glass.yaml").write_text(_glass("glass", 0.0))
    (root / "objects" / "tilted_glass.yaml").write_text(_glass("tilted_glass", TILT_DEG))
    table = (root / "scenes" / "table.yaml").read_text()
    # the tilted file's glass stands on the table like the other: the scene turns it back
    (root / "scenes" / "table_turned.yaml").write_text(
        table.replace("id: table", "id: table_turned") + f"  rotation_deg: [{-TILT_DEG}, 0, 0]\n")
    kb = load_kb(root)
    rule = next(r for r in kb.cultures["common"].rules if r.id == "open_container_upright")
    planner = Planner(kb=root, db=False)
    plans = {}
    for name, scene, tilt in (("glass", "table", 0.0), ("tilted_glass", "table_turned", TILT_DEG)):
        planned = planner.plan(name, scene=scene)
        result = planned.to_dict()
        assert result["outcome"] == "handover", result["reason"]
        rotation = np.asarray(result["object_pose"])[:3, :3]
        up_world = rotation @ (_turn([1.0, 0.0, 0.0], tilt) @ UP)
        assert _angle_deg(up_world, UP) <= rule.max_deg
        # and no finger in the water: the gripper's boxes, sampled, stay out of the cavity
        # (inner radius 30 mm, from the 5 mm bottom at z = 25 mm up to the rim at 120 mm)
        untilt = _turn([1.0, 0.0, 0.0], -tilt)
        t = np.linspace(-0.5, 0.5, 7)
        lattice = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
        for grasp in result["robot_grasps"]:
            for _, ext, box in planned.context.gripper.boxes(grasp["width"]):
                local = np.asarray(grasp["pose"]) @ box
                pts = (lattice * ext) @ local[:3, :3].T + local[:3, 3]
                pts = pts @ untilt.T
                inside = ((np.linalg.norm(pts[:, :2], axis=1) < 0.030)
                          & (pts[:, 2] > 0.025) & (pts[:, 2] < 0.12))
                assert not inside.any()
        plans[name] = (result, up_world)
    (a, up_a), (b, up_b) = plans["glass"], plans["tilted_glass"]
    assert _angle_deg(up_a, up_b) < 2.0
    assert a["mode"] == b["mode"]
    assert [g["parts"] for g in a["robot_grasps"]] == [g["parts"] for g in b["robot_grasps"]]
    assert [h["part"] for h in a["human_grasps"]] == [h["part"] for h in b["human_grasps"]]
    # the frame-aligned presentations alone hold nothing upright: every one is 30 degrees off
    tilted_up = _turn([1.0, 0.0, 0.0], TILT_DEG) @ UP
    assert _angle_deg(presentation_rotations(TOWARD) @ tilted_up, UP).min() > rule.max_deg


def test_a_coarse_handle_is_held_on_it_at_its_far_end_round_its_true_section():
    """A 28 x 3 x 2.4 cm box handle written with 12 faces: the face centroids near its far
    end are only its end cap's, yet the far-end hand stays on the handle (its middle at least
    a quarter of a grip in from the end, at most half) and closes round the handle's whole
    3 x 2.4 cm section."""
    import trimesh

    from handover.geometry.hand import HumanHand

    handle = trimesh.creation.box(extents=[0.28, 0.03, 0.024])
    handle.apply_translation([0.15, 0.0, 0.0])  # x from 0.01 to 0.29
    centroids = np.asarray(handle.triangles_center)
    region = receiver_region(centroids, np.zeros(len(centroids), dtype=np.int64),
                             [{"handle"}], {"handle"}, set())  # fmt: skip
    rots = presentation_rotations(TOWARD)[:1]  # object x toward the receiver: the end there
    sites = predict_receiver_sites(region, rots, TOWARD, grip_width=0.085, where="far_end",
                                   hand=HumanHand.default(), mesh=handle)  # fmt: skip
    assert 0.29 - 0.085 / 2 - 1e-9 <= sites.site[0][0] <= 0.29 - 0.085 / 4 + 1e-9
    assert_allclose(sites.site[0][1:], [0.0, 0.0], atol=1e-9)
    assert_allclose(sorted([sites.thickness[0], sites.depth[0]]), [0.024, 0.03], atol=1e-9)


def test_the_aligned_presentations_turn_with_the_object_s_named_axes_not_its_file():
    from handover.engine.plan.presentation import own_frame

    axes = {"up": [0.0, 0.0, 1.0], "handle": [1.0, 0.0, 0.0]}
    assert_allclose(own_frame(axes), np.eye(3))  # named along its frame: the frame itself
    turn = rotation_from_euler_deg(np.array([30.0, -50.0, 120.0]))
    turned = {k: turn @ np.asarray(v) for k, v in axes.items()}
    assert_allclose(own_frame(turned), turn, atol=1e-12)  # z its up, x its handle
    toward = np.array([1.0, 0.0, 0.0])
    plain = presentation_rotations(toward)
    skewed = presentation_rotations(toward, frame=own_frame(turned))
    # the same physical orientations: each puts the turned file's axes where the plain puts
    # the plain file's
    assert_allclose(skewed @ turn, plain, atol=1e-12)
