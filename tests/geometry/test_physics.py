"""The physics check of grasps (MuJoCo): which grasps hold, by what they mean.

Objects are built here from primitives with realistic masses; the gripper is the project's
(Robotiq 2F-85-like: 85 mm stroke, 60 mm x 22 mm fingers) at the Franka Hand's continuous
70 N. Poses follow the grasp frame convention: ``a`` approach, ``o`` closing, ``n = o x a``.
"""

import json

import numpy as np
import pytest

from handover.geometry.frames import rotation_about_axis, transform_from
from handover.geometry.gripper import Gripper
from handover.geometry.physics import (
    DEFAULT_ENSEMBLE,
    ConvexPart,
    Grasp,
    Hand,
    Motion,
    ObjectModel,
    Primitive,
    Protocol,
    Solver,
    Thresholds,
    check,
    ensemble,
    receiver_grip_force,
)
from handover.geometry.physics.decompose import convex_parts, object_from_mesh

G = 9.81
GRIPPER = Gripper(max_opening=0.085, min_opening=0.0, finger_length=0.06, finger_width=0.022,
                  finger_thickness=0.01, palm=(0.06, 0.13, 0.08), clearance=0.005,
                  friction=0.5)  # fmt: skip
HAND = Hand.from_gripper(GRIPPER, grip_force=70.0)

PICK = transform_from(None, [0.5, 0.0, 0.1])
END = transform_from(rotation_about_axis([0, 0, 1], np.pi / 2), [0.6, 0.3, 0.4])
MOTION = Motion(PICK, END[None])  # lift, then carry with a quarter turn about z


def frame(n, o, a, p):
    """A grasp pose from its axes (columns n, o, a) and origin."""
    return transform_from(np.column_stack([n, o, a]).astype(float), p)


ALONG_X = rotation_about_axis([0, 1, 0], np.pi / 2)  # a primitive's z along the object's x
FROM_ABOVE = ([-1, 0, 0], [0, 1, 0], [0, 0, -1])  # approach down, close along y


def hammer() -> ObjectModel:
    """33 cm claw hammer: a 0.2 kg handle (32 mm across) along x and a 0.45 kg head at the
    far end; its centre of mass 3.6 cm before the head."""
    handle = Primitive("cylinder", (0.016, 0.30), transform_from(ALONG_X, [0.15, 0, 0]), 0.2)
    head = Primitive("box", (0.03, 0.10, 0.025), transform_from(None, [0.315, 0, 0]), 0.45)
    return ObjectModel((handle, head), mass=0.65)


def hammer_com_x() -> float:
    return (0.2 * 0.15 + 0.45 * 0.315) / 0.65


def test_a_grasp_at_the_hammers_centre_of_mass_holds():
    grasp = Grasp(HAND, frame(*FROM_ABOVE, [hammer_com_x(), 0, 0]), width=0.032)
    result = check(hammer(), [grasp], MOTION)
    assert result.passed and not result.dropped
    assert [p.phase for p in result.phases] == ["lift", "carry", "hold", "shake"]
    assert result.max_translation_mm < 5.0 and result.max_rotation_deg < 1.0


def test_a_grasp_at_the_end_of_the_hammers_handle_drops():
    x = 0.03
    grasp = Grasp(HAND, frame(*FROM_ABOVE, [x, 0, 0]), width=0.032)
    # Independently: the weight's torque about the closing axis against the most a pair of
    # pads holds, each at mu F over its half width plus its torsion.
    weight_torque = 0.65 * G * (hammer_com_x() - x)
    pads = 2 * HAND.friction * HAND.grip_force * HAND.finger_width / 2
    pads += 2 * HAND.torsional_friction * HAND.grip_force
    assert weight_torque > pads
    result = check(hammer(), [grasp], MOTION)
    assert result.dropped and not result.passed
    assert result.dropped_in == "lift"  # it swings out as the weight comes on
    assert result.slip("lift").rotation_deg > Thresholds().drop_deg


def test_moving_the_centre_of_mass_under_the_grasp_makes_it_hold_without_a_shake():
    # With no weight torque left, the end-of-handle grasp holds through lift, carry and
    # hold (shaken, the hammer's inertia about the grasp still turns it).
    x = 0.03
    held = ObjectModel(hammer().shapes, mass=0.65, com=np.array([x, 0.0, 0.0]))
    still = Protocol(shake_amplitude=0.0, shake_angle=0.0)
    grasp = Grasp(HAND, frame(*FROM_ABOVE, [x, 0, 0]), width=0.032)
    result = check(held, [grasp], MOTION, protocol=still)
    assert result.passed and [p.phase for p in result.phases] == ["lift", "carry", "hold"]


def knife() -> ObjectModel:
    """A chef's knife on its side: 0.12 kg handle along -x, a 2 mm blade along +x whose
    spine slopes down to the tip (the tip is a convex wedge), 0.22 kg in all."""
    handle = Primitive("box", (0.11, 0.022, 0.018), transform_from(None, [-0.055, 0, 0]), 0.12)
    blade = Primitive("box", (0.10, 0.002, 0.04), transform_from(None, [0.05, 0, -0.005]))
    outline = [(0.10, -0.025), (0.10, 0.015), (0.21, -0.025)]  # (x, z): edge, spine, tip
    tip = np.array([[x, y, z] for x, z in outline for y in (-0.001, 0.001)])
    faces = np.array([[0, 2, 4], [1, 5, 3], [0, 1, 3], [0, 3, 2], [2, 3, 5], [2, 5, 4],
                      [4, 5, 1], [4, 1, 0]])  # fmt: skip
    return ObjectModel((handle, blade, ConvexPart(tip, faces)), mass=0.22)


def test_a_knife_held_on_its_2mm_blade_edges_near_the_tip_slips():
    # Pinched across the blade's height at x = 0.17: the pads touch the 2 mm spine and the
    # edge; the spine slopes, so the upper pad meets it at one corner and only torsion
    # holds the weight's torque about the closing axis.
    grasp = Grasp(HAND, frame([1, 0, 0], [0, 0, 1], [0, -1, 0], [0.17, 0, -0.015]), 0.02)
    result = check(knife(), [grasp], MOTION)
    assert not result.passed
    assert result.max_rotation_deg > Thresholds().max_slip_deg
    # The same knife held on its handle holds.
    handle = Grasp(HAND, frame(*FROM_ABOVE, [-0.03, 0, 0]), width=0.022)
    assert check(knife(), [handle], MOTION).passed


def tray(mass: float) -> ObjectModel:
    """A 40 x 30 cm tray with a 3 cm rim, 4 mm walls (a loaded one weighs 1.5 kg)."""
    t = 0.004
    parts = [((0.40, 0.30, t), [0, 0, 0]), ((0.40, t, 0.03), [0, 0.148, 0.015]),
             ((0.40, t, 0.03), [0, -0.148, 0.015]), ((t, 0.30, 0.03), [0.198, 0, 0.015]),
             ((t, 0.30, 0.03), [-0.198, 0, 0.015])]  # fmt: skip
    return ObjectModel(tuple(Primitive("box", e, transform_from(None, p)) for e, p in parts),
                       mass=mass)  # fmt: skip


def test_a_loaded_tray_held_by_one_gripper_drops_and_two_hold_it():
    # Pinching the middle of a short rim from above (fingertips clear of the base).
    one = Grasp(HAND, frame([0, 1, 0], [1, 0, 0], [0, 0, -1], [0.198, 0, 0.034]), 0.004)
    result = check(tray(1.5), [one], MOTION)
    assert result.dropped and result.dropped_in == "lift"
    other = Grasp(HAND, frame([0, -1, 0], [-1, 0, 0], [0, 0, -1], [-0.198, 0, 0.034]), 0.004)
    both = check(tray(1.5), [one, other], MOTION, mode="H2G1")
    assert both.passed
    assert {p.holder for p in both.phases} == {"gripper0", "gripper1"}


def box(mass: float = 0.5) -> ObjectModel:
    return ObjectModel((Primitive("box", (0.06, 0.06, 0.12)),), mass=mass)


BOX_TOP = Grasp(HAND, frame(*FROM_ABOVE, [0, 0, 0.04]), width=0.06)


def test_a_box_held_across_its_faces_holds():
    result = check(box(), [BOX_TOP], MOTION)
    assert result.passed
    assert result.max_translation_mm < 1.0 and result.max_rotation_deg < 0.5


def test_the_same_check_twice_gives_identical_numbers():
    grasp = Grasp(HAND, frame(*FROM_ABOVE, [0.10, 0, 0]), width=0.032)  # a slipping one
    first, second = check(hammer(), [grasp], MOTION), check(hammer(), [grasp], MOTION)
    assert first.phases == second.phases  # exact floats
    assert first.max_rotation_deg > 0.0  # it moves, so equality says something


def test_a_run_stops_at_the_end_of_the_phase_it_failed_in_or_at_a_drop():
    # The end of the hammer's handle drops in the lift: the run stops there, within the
    # lift. A knife held at its blade tip turns past 5 deg in the lift without dropping:
    # the lift is run to its end. Nothing after can make them pass.
    end = Grasp(HAND, frame(*FROM_ABOVE, [0.03, 0, 0]), width=0.032)
    tip = Grasp(HAND, frame([1, 0, 0], [0, 0, 1], [0, -1, 0], [0.17, 0, -0.015]), 0.02)
    for obj, grasp, dropped in ((hammer(), end, "lift"), (knife(), tip, None)):
        early = check(obj, [grasp], MOTION)
        full = check(obj, [grasp], MOTION, stop_early=False)
        assert not early.passed and not full.passed
        assert early.failed_in == full.failed_in == "lift"
        assert early.dropped_in == full.dropped_in == dropped
        assert [p.phase for p in early.phases] == ["lift"]
        assert full.simulated_seconds == pytest.approx(4.8)
        assert [p.phase for p in full.phases] == ["lift", "carry", "hold", "shake"]
        if dropped:  # stopped at the drop: what it measured up to there, no more
            assert 0.3 < early.simulated_seconds < 0.8  # within the lift
            assert early.phases[0].dropped
            assert early.phases[0].translation_mm <= full.phases[0].translation_mm
            assert early.phases[0].rotation_deg <= full.phases[0].rotation_deg
        else:
            assert early.phases == full.phases[:1]  # the phase measured in full, exact
            assert early.simulated_seconds == pytest.approx(0.8)  # close 0.3, lift 0.5 s
    # A receiver never reached does not hold it.
    stopped = check(hammer(), [end], MOTION, receiver=Grasp(
        Hand.receiver_pads(receiver_grip_force("adult")),
        frame([1, 0, 0], [0, 1, 0], [0, 0, 1], [0.15, 0, 0]), 0.032))  # fmt: skip
    assert stopped.failed_in == "lift" and stopped.receiver_held is False


def test_only_the_hands_taking_part_in_a_phase_are_simulated_in_it():
    from handover.geometry.physics.check import _plan
    from handover.geometry.physics.protocol import schedule

    midair = transform_from(None, [0.55, 0.1, 0.35])
    motion = Motion(PICK, midair[None], regrasp_carry=END[None])
    below = Grasp(HAND, frame([0, 1, 0], [-1, 0, 0], [0, 0, 1], [0, 0, -0.03]), width=0.06)
    pads = receiver_from_below("adult")
    plans = [_plan(g, n) for g, n in ((BOX_TOP, "g0"), (below, "g1"), (pads, "r"))]
    phases = schedule("H2G2", plans[:2], motion, Protocol(), 0.002, plans[2:]).phases
    present = {p.name: p.present for p in phases}
    assert present["shake"] == ("g0",)  # the second gripper and the receiver wait away
    assert present["regrasp_approach"] == present["regrasp_release"] == ("g0", "g1")
    assert present["regrasp_shake"] == ("g1",)  # the first has let go and backed off
    assert present["handover_close"] == ("g1", "r") and present["handover_hold"] == ("r",)
    # A check with hands coming and going measures each where it holds.
    result = check(box(), [BOX_TOP, below], motion, mode="H2G2", receiver=pads, record=True)
    assert result.passed and result.receiver_held
    traj = result.trajectory
    waiting = traj.times < 4.8  # the receiver waits away until the regrasp is done
    assert np.allclose(traj.travel[2, waiting], 0.0)


def test_a_crate_too_wide_for_one_gripper_is_held_by_two_squeezing_it():
    crate = ObjectModel((Primitive("box", (0.40, 0.30, 0.20)),), mass=1.2)
    with pytest.raises(ValueError, match="more than the hand opens"):
        Grasp(HAND, frame(*FROM_ABOVE, [0, 0, 0.1]), width=0.30)
    # Jaws closed, each arm presses a 30 x 20 cm face at its centre along its approach.
    left = Grasp(HAND, frame([0, 0, 1], [0, 1, 0], [-1, 0, 0], [0.20, 0, 0]), kind="squeeze")
    right = Grasp(HAND, frame([0, 0, -1], [0, 1, 0], [1, 0, 0], [-0.20, 0, 0]), kind="squeeze")
    assert 2 * HAND.friction * HAND.grip_force > 1.2 * G  # friction at the squeeze holds it
    result = check(crate, [left, right], MOTION, mode="H2G1")
    assert result.passed and not result.dropped
    alone = check(crate, [left], MOTION)  # one arm pushing a face holds nothing
    assert alone.dropped


def test_a_ball_squeezed_by_two_arms_holds():
    ball = ObjectModel((Primitive("sphere", (0.11,)),), mass=0.45)  # 22 cm across
    left = Grasp(HAND, frame([0, 0, 1], [0, 1, 0], [-1, 0, 0], [0.11, 0, 0]), kind="squeeze")
    right = Grasp(HAND, frame([0, 0, -1], [0, 1, 0], [1, 0, 0], [-0.11, 0, 0]), kind="squeeze")
    assert check(ball, [left, right], MOTION, mode="H2G1").passed


def receiver_from_below(who: str) -> Grasp:
    """The receiver pinches the box's lower part across x, from below."""
    pads = Hand.receiver_pads(receiver_grip_force(who))
    return Grasp(pads, frame([0, -1, 0], [1, 0, 0], [0, 0, 1], [0, 0, -0.03]), 0.06)


def test_an_adult_takes_a_2kg_box_and_a_child_cannot_hold_it():
    heavy = box(2.0)
    adult, child = receiver_from_below("adult"), receiver_from_below("child")
    # Independently: the pads' friction against the weight.
    assert 2 * adult.hand.friction * adult.hand.grip_force > 2.0 * G
    assert 2 * child.hand.friction * child.hand.grip_force < 2.0 * G
    given = check(heavy, [BOX_TOP], MOTION, receiver=adult)
    assert given.passed and given.receiver_held
    assert given.phases[-1].phase == "handover_hold" and given.phases[-1].holder == "receiver"
    # The gripper held it until the receiver's grip settled, then let go.
    assert given.slip("handover_close", "gripper0").translation_mm < 1.0
    dropped = check(heavy, [BOX_TOP], MOTION, receiver=child)
    assert dropped.receiver_held is False and dropped.dropped_in == "handover_release"


def test_a_midair_regrasp_passes_the_box_from_one_gripper_to_the_other():
    midair = transform_from(None, [0.55, 0.1, 0.35])
    motion = Motion(PICK, midair[None], regrasp_carry=END[None])
    below = Grasp(HAND, frame([0, 1, 0], [-1, 0, 0], [0, 0, 1], [0, 0, -0.03]), width=0.06)
    result = check(box(), [BOX_TOP, below], motion, mode="H2G2")
    assert result.passed
    holders = {p.phase: p.holder for p in result.phases}
    assert holders["shake"] == "gripper0" and holders["regrasp_shake"] == "gripper1"
    assert holders["regrasp_close"] == "gripper0" and holders["regrasp_release"] == "gripper1"


def test_the_ensemble_gives_the_share_of_perturbed_runs_that_pass():
    held = ensemble(box(), [BOX_TOP], MOTION)
    assert held.margin == 1.0 and held.robust
    assert len(held.runs) == len(DEFAULT_ENSEMBLE)
    assert held.worst_translation_mm >= held.nominal.max_translation_mm
    # A knife at its tip holds only when everything is in its favour; the hammer gripped
    # where the weight's torque is near what the pads hold passes, but not robustly.
    tip = Grasp(HAND, frame([1, 0, 0], [0, 0, 1], [0, -1, 0], [0.17, 0, -0.015]), 0.02)
    knife_runs = ensemble(knife(), [tip], MOTION)
    assert not knife_runs.robust and knife_runs.margin <= 1 / 6
    near = Grasp(HAND, frame(*FROM_ABOVE, [0.18, 0, 0]), width=0.032)
    marginal = ensemble(hammer(), [near], MOTION)
    assert marginal.nominal.passed and not marginal.robust
    assert 0.0 < marginal.margin < 1.0
    passed = dict((p.label, r.passed) for p, r in marginal.runs)
    assert passed["friction +30%"] and passed["force +30%"]
    assert not passed["friction -30%"] and not passed["force -30%"]
    json.dumps(marginal.to_dict())


def test_results_serialise_with_rounded_numbers():
    out = check(box(), [BOX_TOP], MOTION).to_dict()
    text = json.dumps(out)
    assert out["passed"] is True and out["mode"] == "H1G1"
    assert all(round(p["translation_mm"], 2) == p["translation_mm"] for p in out["phases"])
    assert "handover" not in text  # no receiver, no hand-over phases


def l_shape():
    """A knife-like L (20 mm handle, 4 mm blade) as one mesh: twice its volume as a hull."""
    from handover.geometry.mesh import box as box_mesh
    from handover.geometry.mesh import compose

    handle = box_mesh([0.10, 0.02, 0.02], transform_from(None, [-0.05, 0, 0]))
    blade = box_mesh([0.15, 0.004, 0.05], transform_from(None, [0.075, 0, -0.015]))
    return compose([("handle", handle), ("blade", blade)]).mesh


def test_a_mesh_is_decomposed_into_convex_parts_once_and_then_read_from_the_cache(
    tmp_path, monkeypatch
):
    import coacd
    import trimesh

    mesh = l_shape()
    assert mesh.convex_hull.volume > 1.9 * mesh.volume
    parts = convex_parts(mesh.vertices, mesh.faces, tmp_path)
    assert len(parts) >= 2
    volume = sum(trimesh.Trimesh(v, f).convex_hull.volume for v, f in parts)
    assert volume == pytest.approx(mesh.volume, rel=0.03)
    assert len(list(tmp_path.glob("*.npz"))) == 1

    def no_run(*args, **kwargs):
        raise AssertionError("CoACD ran although the parts were cached")

    monkeypatch.setattr(coacd, "run_coacd", no_run)
    again = convex_parts(mesh.vertices, mesh.faces, tmp_path)
    assert all(np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
               for a, b in zip(parts, again, strict=True))  # fmt: skip


def test_the_decomposed_mesh_is_held_where_its_hull_would_put_the_fingers_inside(tmp_path):
    mesh = l_shape()
    obj = object_from_mesh(mesh.vertices, mesh.faces, mass=0.15, cache_dir=tmp_path)
    # Pinch the blade across its 4 mm from below, 2 cm from the handle, where the hull
    # (handle to blade tip) is 18 mm thick: open for 4 mm, the pads would start inside it.
    grasp = Grasp(HAND, frame([1, 0, 0], [0, 1, 0], [0, 0, 1], [0.02, 0, -0.02]), 0.004)
    assert check(obj, [grasp], MOTION).passed
    hull = mesh.convex_hull
    as_hull = ObjectModel((ConvexPart(hull.vertices, hull.faces),), mass=0.15)
    with pytest.raises(ValueError, match="inside the object"):
        check(as_hull, [grasp], MOTION)


def test_bad_input_is_refused_with_a_reason():
    with pytest.raises(ValueError, match="needs 2 gripper"):
        check(box(), [BOX_TOP], MOTION, mode="H2G1")
    with pytest.raises(ValueError, match="regrasp_carry is required"):
        check(box(), [BOX_TOP, BOX_TOP], MOTION, mode="H2G2")
    with pytest.raises(ValueError, match="unknown mode"):
        check(box(), [BOX_TOP], MOTION, mode="H3G1")
    with pytest.raises(ValueError, match="a cylinder needs 2 positive"):
        Primitive("cylinder", (0.01,))
    with pytest.raises(ValueError, match="do not add up"):
        ObjectModel((Primitive("sphere", (0.05,), mass=0.3),), mass=0.5)
    with pytest.raises(ValueError, match="inside the object"):
        check(box(), [Grasp(HAND, frame(*FROM_ABOVE, [0, 0, 0.04]), width=0.03)], MOTION)
    with pytest.raises(ValueError, match="unknown receiver"):
        receiver_grip_force("giant")
    with pytest.raises(ValueError, match="at least two steps"):
        Solver(timestep=0.004)  # the default contacts' 4 ms time constant is one step
    with pytest.raises(ValueError, match="weight_ramp_time must not exceed"):
        Protocol(lift_time=0.1)
    with pytest.raises(ValueError, match="must not be below the max slips"):
        Thresholds(drop_mm=2.0)


def test_the_hand_takes_the_planners_gripper_numbers():
    hand = Hand.from_gripper(Gripper.default(), grip_force=40.0, torsional_friction=0.002)
    g = Gripper.default()
    assert (hand.finger_length, hand.finger_width, hand.finger_thickness) == (
        g.finger_length, g.finger_width, g.finger_thickness)  # fmt: skip
    assert hand.palm == g.palm and hand.max_opening == g.max_opening
    assert hand.friction == g.friction and hand.clearance == g.clearance
    assert hand.grip_force == 40.0 and hand.torsional_friction == 0.002
    assert hand.opening(0.03) == pytest.approx(g.opening(0.03))


SLOW = Protocol(lift_time=2.0, carry_time=0.5, hold_time=1.0, shake_amplitude=0.0,
                shake_angle=0.0)  # fmt: skip
STAY = Motion(PICK, (PICK @ transform_from(None, [0, 0, 0.1]))[None])  # lift only


@pytest.mark.parametrize("kind", ["pinch", "squeeze"])
def test_the_jaws_press_with_the_grip_force_friction_holds_up_to_2_mu_f(kind):
    # At 20 N per jaw and mu 0.5 the pads' friction carries 20 N: 2.04 kg (a slow lift adds
    # 1.5 % at most). Just below holds, just above slides out.
    hand = Hand.from_gripper(GRIPPER, grip_force=20.0)
    limit = 2 * hand.friction * hand.grip_force / G
    if kind == "pinch":
        grasps = [Grasp(hand, frame(*FROM_ABOVE, [0, 0, 0.04]), width=0.06)]
        mode = "H1G1"
    else:  # two arms, each one pad: the same 2 mu F
        grasps = [Grasp(hand, frame([0, 0, 1], [0, 1, 0], [-1, 0, 0], [0.03, 0, 0]),
                        kind="squeeze"),
                  Grasp(hand, frame([0, 0, -1], [0, 1, 0], [1, 0, 0], [-0.03, 0, 0]),
                        kind="squeeze")]  # fmt: skip
        mode = "H2G1"
    held = check(box(0.9 * limit), grasps, STAY, mode=mode, protocol=SLOW)
    slid = check(box(1.15 * limit), grasps, STAY, mode=mode, protocol=SLOW)
    assert held.passed
    assert slid.dropped


def test_two_pinches_of_a_receiver_take_the_object_together_and_are_measured_each():
    pads = Hand.receiver_pads(receiver_grip_force("child"))
    # One child's pinch carries 2 mu F = 14.7 N, two carry 29.4 N: a 2 kg box (19.6 N)
    # slides out of one and is held by both.
    assert 2 * pads.friction * pads.grip_force < 2.0 * G < 4 * pads.friction * pads.grip_force
    below = Grasp(pads, frame([0, -1, 0], [1, 0, 0], [0, 0, 1], [0, 0, -0.03]), 0.06)
    side = Grasp(pads, frame([0, 0, -1], [0, 1, 0], [1, 0, 0], [-0.015, 0, -0.05]), 0.06)
    assert not check(box(2.0), [BOX_TOP], MOTION, receiver=below).receiver_held
    result = check(box(2.0), [BOX_TOP], MOTION, receiver=[below, side])
    assert result.passed and result.receiver_held
    assert {p.holder for p in result.phases if p.phase == "handover_hold"} == {
        "receiver0", "receiver1"}  # fmt: skip


def test_the_centre_of_mass_is_where_mujoco_puts_it():
    import mujoco

    obj = hammer()
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body()
    body.add_freejoint()
    for s, m in zip(obj.shapes, obj.shape_masses(), strict=True):
        size = [s.size[0], s.size[1] / 2, 0] if s.kind == "cylinder" else [v / 2 for v in s.size]
        kind = mujoco.mjtGeom.mjGEOM_CYLINDER if s.kind == "cylinder" else mujoco.mjtGeom.mjGEOM_BOX
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, s.pose[:3, :3].ravel())
        body.add_geom(type=kind, size=size, pos=s.pose[:3, 3], quat=quat, mass=m)
    model = spec.compile()
    np.testing.assert_allclose(obj.centre_of_mass(), model.body_ipos[1], atol=1e-9)
    np.testing.assert_allclose(obj.centre_of_mass(), [hammer_com_x(), 0, 0], atol=1e-9)


@pytest.mark.parametrize("tiles, holds", [((1, 1), True), ((3, 3), False)])
def test_a_box_pad_holds_torque_as_if_loaded_at_its_corners_and_tiles_spread_it(tiles, holds):
    # A 2 mm plate pinched over 22 x 50 mm of each pad, its weight 10 cm off the closing
    # axis: 1.57 N m. Coulomb friction at 70 N, mu 0.5 holds 2 mu F r plus torsion: with
    # the force at the patch's corners (r = 27.3 mm) 1.9 + 0.4 N m, spread evenly over it
    # (mean r = 14.4 mm) 1.0 + 0.4 N m. One box per pad is the first, 3 x 3 tiles the second.
    hand = Hand.from_gripper(GRIPPER, grip_force=70.0, pad_tiles=tiles)
    plate = ObjectModel((Primitive("box", (0.2, 0.002, 0.05)),), mass=1.6,
                        com=np.array([0.1, 0.0, 0.0]))  # fmt: skip
    torque = 1.6 * G * 0.1
    corners = 2 * hand.friction * hand.grip_force * np.hypot(0.011, 0.025)
    spread = 2 * hand.friction * hand.grip_force * 0.0144
    torsion = 2 * hand.torsional_friction * hand.grip_force
    assert spread + torsion < torque < corners + torsion
    grasp = Grasp(hand, frame(*FROM_ABOVE, [0, 0, 0]), width=0.002)
    result = check(plate, [grasp], STAY, protocol=SLOW)
    assert result.passed == holds


def test_a_recorded_check_gives_the_motion_where_the_schedule_puts_it():
    result = check(box(), [BOX_TOP], MOTION, record=True)
    traj = result.trajectory
    assert traj is not None and traj.hands == ("gripper0",)
    assert traj.times[-1] == pytest.approx(result.simulated_seconds)
    # The box ends held at the handover pose, turned a quarter about z; the gripper's
    # jaws have closed 5 mm (its clearance) each.
    np.testing.assert_allclose(traj.object_poses[-1], END, atol=2e-3)
    np.testing.assert_allclose(traj.hand_poses[0, -1], END @ BOX_TOP.pose, atol=2e-3)
    assert traj.travel[0, -1] == pytest.approx(HAND.clearance, abs=5e-4)
    assert [name for name, _ in traj.phases] == ["close", "lift", "carry", "hold", "shake"]
    assert check(box(), [BOX_TOP], MOTION).trajectory is None


def paperback(parts: int) -> ObjectModel:
    """A 0.45 kg paperback 15 x 23 x 3 cm lying flat: one block, or (parts=2) its pages
    (14.4 cm) and its 6 mm spine as two boxes of the same paper, as the KB writes it."""
    if parts == 1:
        return ObjectModel((Primitive("box", (0.15, 0.23, 0.03)),), mass=0.45)
    pages = Primitive("box", (0.144, 0.23, 0.03), transform_from(None, [0.003, 0, 0]))
    spine = Primitive("box", (0.006, 0.23, 0.03), transform_from(None, [-0.072, 0, 0]))
    return ObjectModel((pages, spine), mass=0.45)


def test_a_book_written_as_pages_and_spine_is_held_as_the_one_block_it_is():
    # Pinched from above across its thickness, over the seam between pages and spine: the
    # pads press one flat face each, whatever parts the KB names on it.
    seam = Grasp(HAND, frame([0, 1, 0], [0, 0, 1], [1, 0, 0], [-0.07, 0.0, 0.0]), width=0.03)
    one, two = (check(paperback(k), [seam], MOTION) for k in (1, 2))
    assert one.passed and two.passed
    assert two.max_translation_mm == pytest.approx(one.max_translation_mm, abs=1e-6)
    assert two.max_rotation_deg == pytest.approx(one.max_rotation_deg, abs=1e-6)


def test_only_boxes_that_together_are_a_box_collide_as_one():
    from handover.geometry.physics.shapes import flush_boxes

    [(members, union)] = flush_boxes(paperback(2).shapes)
    assert members == (0, 1)
    np.testing.assert_allclose(union.size, (0.15, 0.23, 0.03), atol=1e-12)
    np.testing.assert_allclose(union.pose, np.eye(4), atol=1e-12)
    # Turned a quarter about z, its extents written the other way round: still flush.
    turned = Primitive("box", (0.23, 0.006, 0.03),
                       transform_from(rotation_about_axis([0, 0, 1], np.pi / 2), [-0.072, 0, 0]))
    [(_, union)] = flush_boxes((paperback(2).shapes[0], turned))
    np.testing.assert_allclose(union.size, (0.15, 0.23, 0.03), atol=1e-12)
    pages = paperback(2).shapes[0]
    apart = Primitive("box", (0.006, 0.23, 0.03), transform_from(None, [-0.08, 0, 0]))
    thicker = Primitive("box", (0.006, 0.23, 0.04), transform_from(None, [-0.072, 0, 0]))
    askew = Primitive("box", (0.006, 0.23, 0.03),
                      transform_from(rotation_about_axis([0, 0, 1], 0.1), [-0.072, 0, 0]))
    rod = Primitive("cylinder", (0.003, 0.23), transform_from(None, [-0.072, 0, 0]))
    for other in (apart, thicker, askew, rod):
        assert flush_boxes((pages, other)) == []


def arc(start: np.ndarray, radius: float, duration: float, step: float = 0.0075):
    """An arm's timed carry sampled as a plan's trajectory is: the object swung a quarter
    turn round a vertical axis ``radius`` m from it (turning with it), at rest at both ends
    (a minimum-jerk angle over ``duration`` s), a pose every ``step`` s. Returns the poses
    (k, 4, 4), their times (k,) and the largest acceleration of the object's origin on the
    way, m/s^2, from the angle's derivatives (tangential r th'' and centripetal r th'^2)."""
    times = np.append(np.arange(0.0, duration, step), duration)
    tau = times / duration
    angle = 0.5 * np.pi * tau**3 * (10 - 15 * tau + 6 * tau**2)
    centre = start[:3, 3] - [radius, 0.0, 0.0]
    turns = rotation_about_axis([0, 0, 1], angle)
    poses = np.array([transform_from(r @ start[:3, :3], centre + r @ [radius, 0.0, 0.0])
                      for r in turns])
    fine = np.linspace(0.0, 1.0, 20001)
    rate = 0.5 * np.pi * 30 * fine**2 * (1 - fine) ** 2 / duration
    accel = 0.5 * np.pi * 60 * fine * (1 - fine) * (1 - 2 * fine) / duration**2
    return poses, times, float(np.hypot(radius * accel, radius * rate**2).max())


def test_a_timed_carry_moves_the_object_with_the_arm_s_own_accelerations():
    """Given an arm's carry as dense timed samples (a plan's trajectory through its forward
    kinematics), the check moves the object through them at their times: where they say at
    each sample's time, for as long as they last, and never accelerated harder than the arm
    does (no kink at a sample: straight pieces between 7.5 ms samples jerk the object at
    every one of them)."""
    from handover.geometry.physics.check import _plan
    from handover.geometry.physics.protocol import schedule

    lifted = PICK.copy()
    lifted[2, 3] += Protocol().lift_height
    poses, times, most = arc(lifted, 0.3, 2.0)
    motion = Motion(PICK, poses, carry_times=times)
    assert motion.carry_time == pytest.approx(2.0)
    dt = 0.002
    sched = schedule("H1G1", [_plan(BOX_TOP, "g0")], motion, Protocol(), dt)
    carry = next(p for p in sched.phases if p.name == "carry")
    assert (carry.stop - carry.start) * dt == pytest.approx(2.0, abs=dt)
    path = sched.object_poses[carry.start - 1:carry.stop]  # from the lift's end
    t = np.arange(len(path)) * dt
    for k in range(0, len(times), 20):  # at the samples' times, where they say
        np.testing.assert_allclose(path[int(round(times[k] / dt))], poses[k], atol=2e-4)
    np.testing.assert_allclose(path[-1], poses[-1], atol=1e-9)
    accel = np.diff(path[:, :3, 3], n=2, axis=0) / dt**2
    assert np.linalg.norm(accel, axis=1).max() <= 1.05 * most
    assert t[-1] == pytest.approx(2.0, abs=dt)
    # Untimed, the same samples as straight pieces jerk the object at their corners.
    untimed = Motion(PICK, poses, carry_time=2.0)
    sched = schedule("H1G1", [_plan(BOX_TOP, "g0")], untimed, Protocol(), dt)
    carry = next(p for p in sched.phases if p.name == "carry")
    jerked = np.diff(sched.object_poses[carry.start - 1:carry.stop, :3, 3], n=2, axis=0)
    assert np.linalg.norm(jerked, axis=1).max() / dt**2 > 3 * most


def test_a_timed_carry_starts_where_the_check_s_lift_ends_and_ends_where_the_arm_does():
    """The arm's leg starts 5 cm below where the check's own lift ends: the carry starts at
    the lifted pose (no jump), the offset fading on the way, and ends at the arm's last
    pose exactly; times that go back are refused."""
    from handover.geometry.physics.check import _plan
    from handover.geometry.physics.protocol import schedule

    low = PICK.copy()
    low[2, 3] += 0.05
    poses, times, _ = arc(low, 0.3, 2.0)
    sched = schedule("H1G1", [_plan(BOX_TOP, "g0")], Motion(PICK, poses, carry_times=times),
                     Protocol(), 0.002)
    carry = next(p for p in sched.phases if p.name == "carry")
    lifted = sched.object_poses[carry.start - 1]
    assert lifted[2, 3] == pytest.approx(PICK[2, 3] + Protocol().lift_height)
    step = np.linalg.norm(sched.object_poses[carry.start, :3, 3] - lifted[:3, 3])
    assert step < 1e-4
    np.testing.assert_allclose(sched.object_poses[carry.stop - 1], poses[-1], atol=1e-9)
    with pytest.raises(ValueError, match="increase"):
        Motion(PICK, poses, carry_times=times[::-1])
    with pytest.raises(ValueError, match="one time per pose"):
        Motion(PICK, poses, carry_times=times[:-1])
