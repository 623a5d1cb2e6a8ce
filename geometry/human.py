"""A person's body as capsules and boxes, sized from stature alone, with the landmarks a
handover planner needs (shoulders, elbow and chest heights, arm reach, the front plane).

Segment proportions (fractions of stature H) are those of Drillis & Contini (1966) as tabled
by Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed. (2009), fig. 4.1:

=====================  ======   =====================  ======
height of                  H    length / width of          H
=====================  ======   =====================  ======
top of head            1.000    shoulder width          0.259
chin                   0.870    chest width             0.174
shoulder               0.818    hip width               0.191
chest (nipple)         0.720    upper arm               0.186
elbow                  0.630    forearm                 0.146
hip (trochanter)       0.530    hand (wrist-fingertip)  0.108
knee                   0.285    thigh                   0.245
ankle                  0.039    leg (knee-ankle)        0.246
                                foot length / width     0.152 / 0.055
=====================  ======   =====================  ======

Model choices not in that table (also fractions of H, named in ``_MODEL``): segment radii
(upper arm 0.025, forearm 0.020, hand 0.015, thigh 0.040, leg 0.030, neck 0.030, head 0.050),
torso depth 0.13, the grip centre at 40 % of the hand's length from the wrist, and the chair.

Standing: the torso is a box from 0.04 H below the hip joints to the shoulders, chest width
wide and 0.13 H deep; neck and head are vertical capsules; each arm is an upper arm, a forearm
and a hand (capsules) from the shoulder joint, pitched forward by ``upper_arm_pitch`` and
``forearm_pitch`` (rad from straight down: a relaxed pose); the shoulder joints sit one
upper-arm radius inside ``shoulder_width / 2`` so the arms' outer surface spans the width; legs
are thigh and leg capsules from the hip joints (one thigh radius inside the hip width) to the
ankles; the feet are boxes.

Seated: the thighs are horizontal at knee height (0.285 H), resting on the seat, so the seat
is at ``0.285 H - thigh radius`` (0.245 H, the popliteal height); the legs hang vertically
from the knees to the ankles (0.246 H: the table's leg length, exactly); the upper body is the
standing one lowered by ``0.530 H - 0.285 H``. The chair is a seat board and a backrest
(boxes). This puts the seated shoulder 0.328 H and the top of the head 0.510 H above the seat.

Frames: the body is built with x forward, y to the person's left, z up, origin on the floor
under the midpoint of the hip joints, then placed at ``position`` facing ``facing`` in the
world. A person facing the robot (facing -x) has their left on the world's -y side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handover.geometry.bodies import Body, BodyError

__all__ = ["Landmarks", "human_body", "POSTURES", "reaching_elbows", "ELBOW_SWIVELS"]

POSTURES = ("standing", "seated")

# Drillis & Contini / Winter fractions of stature.
_TOP, _CHIN, _SHOULDER, _CHEST, _ELBOW, _HIP, _KNEE, _ANKLE = (
    1.000, 0.870, 0.818, 0.720, 0.630, 0.530, 0.285, 0.039)  # fmt: skip
_SHOULDER_W, _CHEST_W, _HIP_W = 0.259, 0.174, 0.191
_UPPER_ARM, _FOREARM, _HAND, _THIGH, _LEG = 0.186, 0.146, 0.108, 0.245, 0.246
_FOOT_L, _FOOT_W = 0.152, 0.055

# Model choices (fractions of stature unless said otherwise).
_MODEL = {
    "r_upper_arm": 0.025,
    "r_forearm": 0.020,
    "r_hand": 0.015,
    "r_thigh": 0.040,
    "r_leg": 0.030,
    "r_neck": 0.030,
    "r_head": 0.050,
    "torso_depth": 0.13,
    "torso_below_hip": 0.04,
    "grip_fraction": 0.4,  # of the hand's length, from the wrist
    "seat_thickness": 0.025,
    "seat_width": 0.25,
    "seat_behind": 0.085,  # seat's rear edge behind the hip joints
    "seat_front": 0.20,  # seat's front edge ahead of the hip joints (knee at 0.245)
    "back_height": 0.30,
    "back_thickness": 0.025,
}


@dataclass(frozen=True)
class Landmarks:
    """Where a person's body is, for the planner (world frame, m).

    stature : m. posture : "standing" | "seated". position : (3,) the floor point under the
    hip joints' midpoint. facing : (3,) horizontal unit vector, the way the person faces.
    left : (3,) horizontal unit vector to the person's left (``z x facing``).
    left_shoulder, right_shoulder : (3,) shoulder joint centres.
    elbow_height : m, height of the elbow of a hanging arm (shoulder - upper arm).
    chest_height : m. arm_reach : m, shoulder joint to grip centre with a straight arm.
    upper_arm, forearm, hand : m, segment lengths.
    front_point : (3,) a point of the torso's front plane (at chest height); the plane's
    normal is ``facing``. seat_height : m, the seat's top (seated), else None.
    """

    stature: float
    posture: str
    position: np.ndarray
    facing: np.ndarray
    left: np.ndarray
    left_shoulder: np.ndarray
    right_shoulder: np.ndarray
    elbow_height: float
    chest_height: float
    arm_reach: float
    upper_arm: float
    forearm: float
    hand: float
    front_point: np.ndarray
    seat_height: float | None

    def shoulder(self, hand: str) -> np.ndarray:
        """(3,) the shoulder joint of ``hand`` ("left" | "right")."""
        if hand == "left":
            return self.left_shoulder
        if hand == "right":
            return self.right_shoulder
        raise BodyError(f"hand must be 'left' or 'right', got {hand!r}")

    def leaning_shoulder(self, hand: str, lean: np.ndarray) -> np.ndarray:
        """(L, 3) the shoulder joint of ``hand`` when the trunk bends forward by each ``lean``
        (L,) rad about the hip joints (the pelvis and legs stay, the upper body turns as one
        piece toward ``facing``): what a person does to reach a table below their chest.
        A lean of 0 gives :meth:`shoulder`."""
        angle = np.atleast_1d(np.asarray(lean, dtype=float))
        if angle.ndim != 1 or not np.isfinite(angle).all() or (angle < 0).any() \
                or (angle > np.pi / 2).any():
            raise BodyError(f"lean must be angles in [0, pi/2] rad, got {lean!r}")
        hip_z = (_KNEE if self.posture == "seated" else _HIP) * self.stature
        pivot = self.position + np.array([0.0, 0.0, hip_z])
        v = self.shoulder(hand) - pivot
        a, b, c = float(v @ self.facing), float(v @ self.left), float(v[2])
        cos, sin = np.cos(angle), np.sin(angle)
        fwd = a * cos + c * sin
        up = c * cos - a * sin
        return (pivot + b * self.left + fwd[:, None] * self.facing[None, :]
                + up[:, None] * np.array([0.0, 0.0, 1.0]))

    def side(self, hand: str) -> np.ndarray:
        """(3,) horizontal unit vector from the body's midline toward ``hand``'s side."""
        self.shoulder(hand)
        return self.left if hand == "left" else -self.left


def _placement(position: np.ndarray, facing: np.ndarray) -> np.ndarray:
    pos = np.asarray(position, dtype=float)
    if pos.shape == (2,):
        pos = np.append(pos, 0.0)
    if pos.shape != (3,) or not np.isfinite(pos).all():
        raise BodyError(f"position must be a finite (3,) point, got {position!r}")
    f = np.asarray(facing, dtype=float)
    if f.shape != (3,) or not np.isfinite(f).all():
        raise BodyError(f"facing must be a finite (3,) vector, got {facing!r}")
    f = np.array([f[0], f[1], 0.0])
    norm = float(np.linalg.norm(f))
    if norm < 1e-9:
        raise BodyError(f"facing must have a horizontal component, got {facing!r}")
    f /= norm
    out = np.eye(4)
    out[:3, 0], out[:3, 1], out[:3, 3] = f, np.cross([0.0, 0.0, 1.0], f), pos
    return out


def human_body(
    stature: float,
    posture: str = "standing",
    position: np.ndarray = (1.0, 0.0, 0.0),
    facing: np.ndarray = (-1.0, 0.0, 0.0),
    shoulder_width: float | None = None,
    *,
    upper_arm_pitch: float = 0.1,
    forearm_pitch: float = 0.3,
    chair: bool = True,
) -> tuple[Body, Landmarks]:
    """A person's body and landmarks in the world frame (see the module docstring).

    stature : m, > 0 (a child of 1.0 m, an elder of 1.6 m: every size follows from it).
    posture : "standing" | "seated". position : (3,) or (2,) m, the floor point under the
    hip joints. facing : (3,) the direction the person faces (made horizontal). Defaults: the
    receiver 1 m in front of the robot, facing it.
    shoulder_width : m, across the shoulders' outer surface (default 0.259 H).
    upper_arm_pitch, forearm_pitch : rad, forward from straight down, in [0, pi/2].
    chair : seated only, whether the chair's seat and back are part of the body.

    Returns ``(body, landmarks)``. Primitive names: torso, neck, head, {left,right}_upper_arm,
    _forearm, _hand, _thigh, _leg, _foot; seated adds chair_seat and chair_back.
    """
    h = float(stature)
    if not (np.isfinite(h) and h > 0):
        raise BodyError(f"stature must be a positive length in metres, got {stature!r}")
    if posture not in POSTURES:
        raise BodyError(f"posture must be one of {POSTURES}, got {posture!r}")
    for what, angle in (("upper_arm_pitch", upper_arm_pitch), ("forearm_pitch", forearm_pitch)):
        if not (np.isfinite(angle) and 0.0 <= angle <= np.pi / 2):
            raise BodyError(f"{what} must be in [0, pi/2] rad, got {angle!r}")
    k = {name: v * h for name, v in _MODEL.items() if name != "grip_fraction"}
    width = _SHOULDER_W * h if shoulder_width is None else float(shoulder_width)
    if not (np.isfinite(width) and width > 4 * k["r_upper_arm"]):
        raise BodyError(
            f"shoulder_width must exceed twice the arms' thickness ({4 * k['r_upper_arm']:.3f} m)"
            f", got {shoulder_width!r}"
        )
    seated = posture == "seated"
    hip_z = _KNEE * h if seated else _HIP * h
    lift = hip_z - _HIP * h  # the upper body's shift from standing
    shoulder_z, chin_z, top_z = (_SHOULDER * h + lift, _CHIN * h + lift, _TOP * h + lift)
    depth = k["torso_depth"]

    caps: list[tuple[str, np.ndarray, np.ndarray, float]] = []
    boxes: list[tuple[str, np.ndarray, np.ndarray]] = []

    def box(name: str, lo: tuple[float, float, float], hi: tuple[float, float, float]) -> None:
        pose = np.eye(4)
        pose[:3, 3] = 0.5 * (np.add(lo, hi))
        boxes.append((name, np.subtract(hi, lo), pose))

    torso_lo = hip_z - k["torso_below_hip"]
    box("torso", (-depth / 2, -_CHEST_W * h / 2, torso_lo), (depth / 2, _CHEST_W * h / 2,
                                                              shoulder_z))  # fmt: skip
    caps.append(("neck", np.array([0.0, 0.0, shoulder_z]), np.array([0.0, 0.0, chin_z]),
                 k["r_neck"]))  # fmt: skip
    r_head = k["r_head"]
    caps.append(("head", np.array([0.0, 0.0, chin_z + r_head]), np.array([0.0, 0.0,
                 top_z - r_head]), r_head))  # fmt: skip

    joint_y = width / 2 - k["r_upper_arm"]
    up_dir = np.array([np.sin(upper_arm_pitch), 0.0, -np.cos(upper_arm_pitch)])
    fore_dir = np.array([np.sin(forearm_pitch), 0.0, -np.cos(forearm_pitch)])
    shoulders = {}
    for side, sign in (("left", 1.0), ("right", -1.0)):
        s = np.array([0.0, sign * joint_y, shoulder_z])
        e = s + _UPPER_ARM * h * up_dir
        w = e + _FOREARM * h * fore_dir
        tip = w + (_HAND * h - k["r_hand"]) * fore_dir
        shoulders[side] = s
        caps += [(f"{side}_upper_arm", s, e, k["r_upper_arm"]),
                 (f"{side}_forearm", e, w, k["r_forearm"]),
                 (f"{side}_hand", w, tip, k["r_hand"])]  # fmt: skip
        hip = np.array([0.0, sign * (_HIP_W * h / 2 - k["r_thigh"]), hip_z])
        knee = hip + (np.array([_THIGH * h, 0.0, 0.0]) if seated
                      else np.array([0.0, 0.0, (_KNEE - _HIP) * h]))  # fmt: skip
        ankle = np.array([knee[0], knee[1], _ANKLE * h])
        caps += [(f"{side}_thigh", hip, knee, k["r_thigh"]),
                 (f"{side}_leg", knee, ankle, k["r_leg"])]  # fmt: skip
        heel = knee[0] - 0.25 * _FOOT_L * h
        box(f"{side}_foot", (heel, knee[1] - _FOOT_W * h / 2, 0.0),
            (heel + _FOOT_L * h, knee[1] + _FOOT_W * h / 2, _ANKLE * h))  # fmt: skip

    seat_height = None
    if seated:
        seat_height = hip_z - k["r_thigh"]
        if chair:
            half_w = k["seat_width"] / 2
            box("chair_seat", (-k["seat_behind"], -half_w, seat_height - k["seat_thickness"]),
                (k["seat_front"], half_w, seat_height))  # fmt: skip
            back_x = -k["seat_behind"]
            box("chair_back", (back_x - k["back_thickness"], -half_w, seat_height),
                (back_x, half_w, seat_height + k["back_height"]))  # fmt: skip

    place = _placement(position, facing)
    body = Body.from_primitives(caps, boxes).moved(place)
    rot, pos = place[:3, :3], place[:3, 3]
    chest_z = _CHEST * h + lift
    landmarks = Landmarks(
        stature=h,
        posture=posture,
        position=pos.copy(),
        facing=rot[:, 0].copy(),
        left=rot[:, 1].copy(),
        left_shoulder=rot @ shoulders["left"] + pos,
        right_shoulder=rot @ shoulders["right"] + pos,
        elbow_height=float(shoulder_z - _UPPER_ARM * h + pos[2]),
        chest_height=float(chest_z + pos[2]),
        arm_reach=float((_UPPER_ARM + _FOREARM + _MODEL["grip_fraction"] * _HAND) * h),
        upper_arm=_UPPER_ARM * h,
        forearm=_FOREARM * h,
        hand=_HAND * h,
        front_point=rot @ np.array([depth / 2, 0.0, chest_z]) + pos,
        seat_height=None if seat_height is None else float(seat_height + pos[2]),
    )
    return body, landmarks


ELBOW_SWIVELS = (0.0, np.pi / 4, np.pi / 2)
"""rad: the elbow's turns about the shoulder-to-wrist line tried for a reaching arm, from
hanging below the line (0) outward to level with it (a person lifts the elbow over a rail)."""


def reaching_elbows(shoulder: np.ndarray, wrist: np.ndarray, upper_arm: float, forearm: float,
                    outward: np.ndarray, swivels: tuple[float, ...] = ELBOW_SWIVELS
                    ) -> np.ndarray:
    """(n, S, 3) m: where the elbow of an arm reaching from ``shoulder`` to ``wrist`` (n, 3)
    m (world, z up) can be, for each of ``swivels`` (rad): the elbow that closes the
    triangle of the ``upper_arm`` and ``forearm`` lengths (m), turned about the
    shoulder-to-wrist line from straight below it towards ``outward`` (3,) or (n, 3) (the
    side of the reaching hand). A wrist beyond the arm's reach is reached with a straight arm
    pointing at it; one nearer than the two lengths allow, with the elbow fully bent.
    Vectorised; inputs not checked beyond shape."""
    sh = np.asarray(shoulder, dtype=float).reshape(-1, 3)
    wr = np.asarray(wrist, dtype=float).reshape(-1, 3)
    out_dir = np.broadcast_to(np.asarray(outward, dtype=float), sh.shape)
    a, b = float(upper_arm), float(forearm)
    d = wr - sh
    length = np.maximum(np.linalg.norm(d, axis=1), 1e-9)
    u = d / length[:, None]
    down = np.array([0.0, 0.0, -1.0])
    w_down = down - (u @ down)[:, None] * u
    flat = np.linalg.norm(w_down, axis=1) < 1e-6  # reaching straight up or down
    w_down[flat] = out_dir[flat] - np.einsum("ij,ij->i", out_dir[flat], u[flat])[:, None] * u[flat]
    w_down /= np.maximum(np.linalg.norm(w_down, axis=1, keepdims=True), 1e-12)
    w_out = np.cross(u, w_down)
    w_out *= np.where(np.einsum("ij,ij->i", w_out, out_dir) < 0, -1.0, 1.0)[:, None]
    reach = np.clip(length, abs(a - b) + 1e-9, a + b)
    cos = np.clip((a * a + reach**2 - b * b) / (2 * a * reach), -1.0, 1.0)
    sin = np.sqrt(1.0 - cos**2)
    out = np.empty((len(sh), len(swivels), 3))
    for j, phi in enumerate(swivels):
        w = np.cos(phi) * w_down + np.sin(phi) * w_out
        out[:, j] = sh + a * (cos[:, None] * u + sin[:, None] * w)
    return out
