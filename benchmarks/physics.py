"""The physics check (MuJoCo): time per check and per ensemble, and the analytic rule
against the simulation on grasps of household objects.

Run: ``.venv/bin/python benchmarks/physics.py [--repeat 3] [--tiles 1] [--force 70] [--full]``

The gripper is the project's (Robotiq 2F-85-like: 85 mm stroke, 60 x 22 mm fingers, pad
friction 0.5, torsion 0.003 m) at ``--force`` N per jaw (the Franka Hand's 70 N
continuous by default); ``--tiles N`` splits each pad into N x N boxes (the uniformly
pressed pad; 1 is the default, edge-loaded bound). The default protocol: close, lift 10 cm,
carry 1.5 s with a quarter turn, hold 1.5 s, shake +-2 cm / +-15 deg at 2 Hz, and where a
receiver is named the hand-over (4.8 s simulated without, 6.6 s with, at 2 ms). A run that
fails stops at the end of the phase it failed in (``failed in``; ``sim s`` the seconds
simulated); ``--full`` runs every phase, as the check did before it stopped early.
Times are CPU seconds of this process (``time.process_time``), best of ``--repeat``.

Tables:
1. each grasp: the analytic rule (N m, N; see ``analytic``): the weight's torque about the
   axis through the contacts at its worst orientation (``mgd``) against the torsion the
   pads hold (``hold`` = 2 mu F r + 2 mu_t F), its torque about a perpendicular axis
   (``mgs``) against the pads' pressure couple (``Fw``), the weight (``mg``) against the
   pads' friction (``2muF``); then what the simulation says: pass, the largest slip, the
   phase it failed in (where the run stopped) and dropped in, the seconds simulated; and
   the time of one check (best of ``--repeat``, CPU, one core) and per simulated step.
   The rule is applied to the last holders: the receiver's pads where there is a
   receiver, the second gripper of a midair regrasp.
2. plans with the robustness ensemble (6 perturbed runs: friction and force +-30 %, torsion
   x0.5 and x2): margin, worst slip, CPU time of nominal plus ensemble (best of
   ``--repeat``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

# Run as a file, this folder comes first on sys.path, where benchmarks/geometry.py would
# shadow the geometry package. Drop it.
_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402

from handover.geometry.frames import rotation_about_axis, transform_from  # noqa: E402
from handover.geometry.gripper import Gripper  # noqa: E402
from handover.geometry.physics import (  # noqa: E402
    ConvexPart,
    Grasp,
    Hand,
    Motion,
    ObjectModel,
    Primitive,
    check,
    ensemble,
    receiver_grip_force,
)

G = 9.81
GRIPPER = Gripper(max_opening=0.085, min_opening=0.0, finger_length=0.06, finger_width=0.022,
                  finger_thickness=0.01, palm=(0.06, 0.13, 0.08), clearance=0.005,
                  friction=0.5)  # fmt: skip
PICK = transform_from(None, [0.5, 0.0, 0.1])
MIDAIR = transform_from(rotation_about_axis([0, 0, 1], np.pi / 4), [0.55, 0.1, 0.35])
END = transform_from(rotation_about_axis([0, 0, 1], np.pi / 2), [0.6, 0.3, 0.4])
MOTION = Motion(PICK, END[None])
REGRASP = Motion(PICK, MIDAIR[None], regrasp_carry=END[None])
ALONG_X = rotation_about_axis([0, 1, 0], np.pi / 2)
FROM_ABOVE = ([-1, 0, 0], [0, 1, 0], [0, 0, -1])


def frame(n, o, a, p):
    return transform_from(np.column_stack([n, o, a]).astype(float), p)


def box_at(extents, centre, mass=None):
    return Primitive("box", extents, transform_from(None, centre), mass)


def objects() -> dict[str, ObjectModel]:
    tip = np.array([[x, y, z] for x, z in [(0.10, -0.025), (0.10, 0.015), (0.21, -0.025)]
                    for y in (-0.001, 0.001)])  # fmt: skip
    tip_faces = np.array([[0, 2, 4], [1, 5, 3], [0, 1, 3], [0, 3, 2], [2, 3, 5], [2, 5, 4],
                          [4, 5, 1], [4, 1, 0]])  # fmt: skip
    wall = 0.004
    tray = (box_at((0.40, 0.30, wall), [0, 0, 0]), box_at((0.40, wall, 0.03), [0, 0.148, 0.015]),
            box_at((0.40, wall, 0.03), [0, -0.148, 0.015]),
            box_at((wall, 0.30, 0.03), [0.198, 0, 0.015]),
            box_at((wall, 0.30, 0.03), [-0.198, 0, 0.015]))  # fmt: skip
    return {
        "hammer": ObjectModel((
            Primitive("cylinder", (0.016, 0.30), transform_from(ALONG_X, [0.15, 0, 0]), 0.2),
            box_at((0.03, 0.10, 0.025), [0.315, 0, 0], 0.45)), mass=0.65),  # fmt: skip
        "knife": ObjectModel((
            box_at((0.11, 0.022, 0.018), [-0.055, 0, 0], 0.12),
            box_at((0.10, 0.002, 0.04), [0.05, 0, -0.005]),
            ConvexPart(tip, tip_faces)), mass=0.22),  # fmt: skip
        "screwdriver": ObjectModel((
            Primitive("cylinder", (0.016, 0.10), transform_from(ALONG_X, [-0.05, 0, 0]), 0.08),
            Primitive("cylinder", (0.003, 0.15), transform_from(ALONG_X, [0.075, 0, 0]), 0.03),
        ), mass=0.11),  # fmt: skip
        "tray 0.8 kg": ObjectModel(tray, mass=0.8),
        "tray 1.5 kg": ObjectModel(tray, mass=1.5),
        "box": ObjectModel((box_at((0.06, 0.06, 0.12), [0, 0, 0]),), mass=0.5),
        "mug": ObjectModel((
            Primitive("cylinder", (0.04, 0.10), transform_from(None, [0, 0, 0.05]), 0.28),
            box_at((0.012, 0.01, 0.07), [0.055, 0, 0.05], 0.05),
            box_at((0.02, 0.01, 0.01), [0.045, 0, 0.085], 0.01),
            box_at((0.02, 0.01, 0.01), [0.045, 0, 0.015], 0.01)), mass=0.35),  # fmt: skip
        "crate": ObjectModel((box_at((0.40, 0.30, 0.20), [0, 0, 0]),), mass=1.2),
        "ball 22 cm": ObjectModel((Primitive("sphere", (0.11,)),), mass=0.45),
    }


def cases(hand: Hand) -> list[tuple[str, str, list[Grasp], str, list[Grasp] | None, Motion]]:
    """(label, object, grasps, mode, receiver grasps, motion)."""
    adult = Hand.receiver_pads(receiver_grip_force("adult"))
    hammer_com = (0.2 * 0.15 + 0.45 * 0.315) / 0.65

    def top(x, width, y=0.0, z=0.0):
        return Grasp(hand, frame(*FROM_ABOVE, [x, y, z]), width)

    def squeeze(x):
        return [Grasp(hand, frame([0, 0, 1], [0, 1, 0], [-1, 0, 0], [x, 0, 0]), kind="squeeze"),
                Grasp(hand, frame([0, 0, -1], [0, 1, 0], [1, 0, 0], [-x, 0, 0]),
                      kind="squeeze")]  # fmt: skip

    rim = [Grasp(hand, frame([0, 1, 0], [1, 0, 0], [0, 0, -1], [0.198, 0, 0.034]), 0.004),
           Grasp(hand, frame([0, -1, 0], [-1, 0, 0], [0, 0, -1], [-0.198, 0, 0.034]), 0.004)]
    box_top = top(0, 0.06, z=0.04)
    box_below = Grasp(hand, frame([0, 1, 0], [-1, 0, 0], [0, 0, 1], [0, 0, -0.03]), 0.06)
    mug_side = Grasp(hand, frame([0, 0, -1], [0, 1, 0], [1, 0, 0], [-0.015, 0, 0.07]), 0.074)
    return [
        ("hammer handle at its centre of mass", "hammer", [top(hammer_com, 0.032)], "H1G1",
         None, MOTION),
        ("hammer head, across its 25 mm", "hammer",
         [Grasp(hand, frame([1, 0, 0], [0, 0, 1], [0, -1, 0], [0.315, 0.03, 0]), 0.025)],
         "H1G1", None, MOTION),
        ("hammer handle 9 cm from the c.o.m.", "hammer", [top(0.18, 0.032)], "H1G1", None,
         MOTION),
        ("hammer handle end (24 cm)", "hammer", [top(0.03, 0.032)], "H1G1", None, MOTION),
        ("knife handle", "knife", [top(-0.03, 0.022)], "H1G1", None, MOTION),
        ("knife blade edges near the tip", "knife",
         [Grasp(hand, frame([1, 0, 0], [0, 0, 1], [0, -1, 0], [0.17, 0, -0.015]), 0.02)],
         "H1G1", None, MOTION),
        ("knife blade faces (2 mm) at the tip", "knife", [top(0.19, 0.002)], "H1G1", None,
         MOTION),
        ("screwdriver handle", "screwdriver", [top(-0.03, 0.032)], "H1G1", None, MOTION),
        ("screwdriver 6 mm shaft, 12 cm out", "screwdriver", [top(0.10, 0.006)], "H1G1", None,
         MOTION),
        ("tray 0.8 kg, one gripper on a rim", "tray 0.8 kg", rim[:1], "H1G1", None, MOTION),
        ("tray 1.5 kg, one gripper on a rim", "tray 1.5 kg", rim[:1], "H1G1", None, MOTION),
        ("tray 1.5 kg, two grippers (H2G1)", "tray 1.5 kg", rim, "H2G1", None, MOTION),
        ("tray 1.5 kg to two fingertip pinches", "tray 1.5 kg", rim, "H2G1",
         [Grasp(adult, frame([0, s, 0], [s, 0, 0], [0, 0, -1], [s * 0.198, 0.1, 0.02]),
                0.004) for s in (1, -1)], MOTION),  # fmt: skip
        ("box across its faces", "box", [box_top], "H1G1", None, MOTION),
        ("box, midair regrasp (H2G2)", "box", [box_top, box_below], "H2G2", None, REGRASP),
        ("box to an adult's pinch", "box", [box_top], "H1G1",
         [Grasp(adult, frame([0, -1, 0], [1, 0, 0], [0, 0, 1], [0, 0, -0.03]), 0.06)], MOTION),
        ("mug body from the side", "mug", [mug_side], "H1G1", None, MOTION),
        ("mug handle, gripper pinch", "mug",
         [Grasp(hand, frame([0, 0, 1], [0, 1, 0], [-1, 0, 0], [0.072, 0, 0.05]), 0.01)],
         "H1G1", None, MOTION),
        ("mug handle to an adult's pinch", "mug", [mug_side], "H1G1",
         [Grasp(adult, frame([0, 0, 1], [0, 1, 0], [-1, 0, 0], [0.062, 0, 0.05]), 0.01)],
         MOTION),
        ("crate 40x30x20 cm squeezed (H2G1)", "crate", squeeze(0.20), "H2G1", None, MOTION),
        ("ball 22 cm squeezed (H2G1)", "ball 22 cm", squeeze(0.11), "H2G1", None, MOTION),
    ]


def analytic(obj: ObjectModel, grasps: list[Grasp]) -> dict[str, float]:
    """The analytic rule's numbers for the hands together (N m and N).

    The axis through the contacts is o for one pinch, a for a squeeze, and with two hands
    the line through their origins. ``torque``: the weight's torque about that axis at the
    worst orientation, ``m g d`` (d: the centre of mass's distance from the axis), against
    ``hold``: the torsion the pads hold, ``2 mu F r + 2 mu_t F`` per pinch (r: half the
    pad's width; a squeezing hand is one pad). ``tip``: the weight's torque about a
    perpendicular axis, ``m g s`` (s: the centre of mass's distance along the axis), against
    ``couple``: for one pinch ``F w`` (the pressure shifting to the pads' edges, w the pad's
    width), for two hands the friction at each times half their distance. ``weight`` against
    ``friction``: ``m g`` and ``2 mu F`` per pinch.
    """
    com = obj.centre_of_mass()
    weight = obj.mass * G
    origins = [g.pose[:3, 3] for g in grasps]
    if len(grasps) == 1:
        g = grasps[0]
        axis = g.pose[:3, 1 if g.kind == "pinch" else 2]
    else:
        axis = origins[1] - origins[0]
        axis = axis / np.linalg.norm(axis)
    r = com - origins[0] if len(grasps) == 1 else com - (origins[0] + origins[1]) / 2
    along = float(abs(r @ axis))
    d = float(np.linalg.norm(r - (r @ axis) * axis))
    hold = friction = 0.0
    for g in grasps:
        h = g.hand
        pads = 2 if g.kind == "pinch" else 1
        hold += pads * (h.friction * h.grip_force * h.finger_width / 2
                        + h.torsional_friction * h.grip_force)  # fmt: skip
        friction += pads * h.friction * h.grip_force
    if len(grasps) == 1:
        couple = grasps[0].hand.grip_force * grasps[0].hand.finger_width
    else:
        couple = friction * float(np.linalg.norm(origins[1] - origins[0])) / 2
    return {"torque": weight * d, "hold": hold, "tip": weight * along, "couple": couple,
            "weight": weight, "friction": friction}  # fmt: skip


def best(fn, repeat: int):
    """``fn()`` and its least CPU time (s) over ``repeat`` calls."""
    times, out = [], None
    for _ in range(repeat):
        start = time.process_time()
        out = fn()
        times.append(time.process_time() - start)
    return out, min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--tiles", type=int, default=1)
    parser.add_argument("--force", type=float, default=70.0)
    parser.add_argument("--full", action="store_true",
                        help="simulate every phase of a run that failed")
    args = parser.parse_args()
    early = not args.full
    hand = Hand.from_gripper(GRIPPER, grip_force=args.force, pad_tiles=(args.tiles, args.tiles))
    objs = objects()
    print(f"grip force {args.force:g} N per jaw, pads {args.tiles}x{args.tiles} tiles, "
          f"CPU time best of {args.repeat}{', every phase' if args.full else ''}\n")  # fmt: skip
    head = (f"{'grasp':38s} {'mgd':>5s} {'hold':>5s} {'mgs':>5s} {'Fw':>5s} {'mg':>5s}"
            f" {'2muF':>5s} {'rule':>5s} | {'sim':6s} {'mm':>6s} {'deg':>6s} {'failed in':17s}"
            f" {'dropped in':17s} {'sim s':>5s} {'s/chk':>6s} {'us/st':>5s}")  # fmt: skip
    print(head)
    print("-" * len(head))
    times = []
    for label, name, grasps, mode, receiver, motion in cases(hand):
        obj = objs[name]
        holders = receiver or ([grasps[-1]] if mode == "H2G2" else grasps)
        a = analytic(obj, holders)
        holds = a["torque"] <= a["hold"] and a["tip"] <= a["couple"]
        rule = "holds" if holds and a["weight"] <= a["friction"] else "fails"
        result, seconds = best(lambda obj=obj, grasps=grasps, mode=mode, receiver=receiver,
                               motion=motion: check(obj, grasps, motion, mode=mode,
                                                    receiver=receiver, stop_early=early),
                               args.repeat)  # fmt: skip
        times.append(seconds)
        steps = round(result.simulated_seconds / 0.002)
        sim = "pass" if result.passed else "FAIL"
        if receiver is not None:
            sim += " R" if result.receiver_held else " r"
        print(f"{label:38s} {a['torque']:5.2f} {a['hold']:5.2f} {a['tip']:5.2f} "
              f"{a['couple']:5.2f} {a['weight']:5.1f} {a['friction']:5.0f} {rule:>5s}"
              f" | {sim:6s} {min(result.max_translation_mm, 999.9):6.1f}"
              f" {min(result.max_rotation_deg, 999.9):6.1f} {result.failed_in or '-':17s}"
              f" {result.dropped_in or '-':17s} {result.simulated_seconds:5.1f}"
              f" {seconds:6.3f} {1e6 * seconds / steps:5.0f}")  # fmt: skip
    times = np.array(times)
    print(f"\none check: median {np.median(times):.3f} s, max {times.max():.3f} s "
          f"(target <= 0.3 s); R / r: the receiver holds / does not\n")  # fmt: skip

    print(f"{'plan with the ensemble (7 runs)':38s} {'margin':>6s} {'robust':>6s} "
          f"{'worst mm':>8s} {'worst deg':>9s} {'seconds':>7s}")  # fmt: skip
    plans = [c for c in cases(hand) if c[0] in (
        "hammer handle at its centre of mass", "hammer handle 9 cm from the c.o.m.",
        "box to an adult's pinch", "box, midair regrasp (H2G2)",
        "crate 40x30x20 cm squeezed (H2G1)")]  # fmt: skip
    for label, name, grasps, mode, receiver, motion in plans:
        obj = objs[name]
        result, seconds = best(lambda obj=obj, grasps=grasps, mode=mode, receiver=receiver,
                               motion=motion: ensemble(obj, grasps, motion, mode=mode,
                                                       receiver=receiver, stop_early=early),
                               args.repeat)  # fmt: skip
        print(f"{label:38s} {result.margin:6.3f} {str(result.robust):>6s} "
              f"{result.worst_translation_mm:8.1f} {result.worst_rotation_deg:9.1f} "
              f"{seconds:7.3f}")  # fmt: skip
    print("(target: a plan with the ensemble <= 1.5 s on one core)")


if __name__ == "__main__":
    main()
