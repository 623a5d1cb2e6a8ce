"""Run the physics check of grasps and measure it: slip per phase, drops, the receiver.

:func:`check` builds the MuJoCo model (:mod:`.model`), the schedule of targets
(:mod:`.protocol`) and runs it in one call of MuJoCo's ``rollout`` (the palm targets, finger
targets and the support's force are its open-loop inputs, so no Python runs per step).
Slip is the motion of the object in the holding hand's frame (the palm body, not its
target) since the hand's grip settled: the displacement of the object's point that sat at
the grasp origin (mm) and the angle it turned (deg). :func:`ensemble` runs the same check
with the friction, grip force and torsion scaled (:data:`.params.DEFAULT_ENSEMBLE`) in one
batched rollout and gives the share that pass and the worst slip.

Same inputs give identical numbers (MuJoCo is deterministic on one thread; nothing is
sampled).
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, replace

import mujoco
import numpy as np
from mujoco import rollout
from scipy.spatial.transform import Rotation

from handover.geometry.frames import transform_from
from handover.geometry.gripper import check_poses
from handover.geometry.physics.hands import Hand, squeeze_target
from handover.geometry.physics.model import Built, HandIn, build
from handover.geometry.physics.params import (
    DEFAULT_ENSEMBLE,
    Perturbation,
    Protocol,
    Solver,
    Thresholds,
)
from handover.geometry.physics.protocol import HandPlan, Motion, Schedule, schedule
from handover.geometry.physics.shapes import ObjectModel

__all__ = [
    "GRASP_KINDS",
    "Grasp",
    "PhaseSlip",
    "Trajectory",
    "RECORD_HZ",
    "CheckResult",
    "EnsembleResult",
    "check",
    "ensemble",
]

GRASP_KINDS = ("pinch", "squeeze")
"""``pinch``: the jaws close on the object across ``width``. ``squeeze``: the jaws stay
closed and the fingertips press a face along the approach axis (two arms squeezing an object
no single gripper spans)."""

_CLOSE_PAST = 0.01  # m: the closed target lies this far past the contact (force-limited)

RECORD_HZ = 50.0
"""Hz, how often a recorded :class:`Trajectory` samples the simulation."""


@dataclass(frozen=True)
class Grasp:
    """One hand's grasp on the object.

    hand : the :class:`~.hands.Hand` (a gripper, or the receiver's pads).
    pose : (4, 4) the grasp frame in the object frame: for a pinch, origin midway between
        the pads' contacts, ``o`` closing, ``a`` approach; for a squeeze, origin on the face
        pressed, ``a`` into the object.
    width : m, the object's width between the pads (pinch; ignored for a squeeze).
    kind : ``"pinch"`` or ``"squeeze"``.
    """

    hand: Hand
    pose: np.ndarray
    width: float = 0.0
    kind: str = "pinch"

    def __post_init__(self) -> None:
        if self.kind not in GRASP_KINDS:
            raise ValueError(f"unknown grasp kind {self.kind!r}: expected one of {GRASP_KINDS}")
        object.__setattr__(self, "pose", check_poses(self.pose, 0.0)[0][0])
        if not (np.isfinite(self.width) and self.width >= 0):
            raise ValueError(f"a grasp's width must be a non-negative length, got {self.width}")
        if self.kind == "pinch" and self.width > self.hand.max_opening:
            raise ValueError(
                f"the grasp is {self.width * 1000:.0f} mm across, more than the hand opens "
                f"({self.hand.max_opening * 1000:.0f} mm)"
            )


@dataclass(frozen=True)
class PhaseSlip:
    """The slip of the object in one holder's frame during one phase: the largest over the
    phase of the displacement (mm) and turn (deg) since the holder's grip settled; dropped
    if the displacement passed the drop threshold in this phase."""

    phase: str
    holder: str
    translation_mm: float
    rotation_deg: float
    dropped: bool

    def to_dict(self) -> dict:
        """JSON-ready, floats rounded to 0.01."""
        return {"phase": self.phase, "holder": self.holder,
                "translation_mm": round(self.translation_mm, 2),
                "rotation_deg": round(self.rotation_deg, 2), "dropped": self.dropped}  # fmt: skip


@dataclass(frozen=True)
class Trajectory:
    """The simulated motion for drawing (a recording), sampled at :data:`RECORD_HZ`.

    times : (T,) s from the start. object_poses : (T, 4, 4) the object's frame, world.
    hands : the hands' names; hand_poses : (H, T, 4, 4) each hand body (its grasp frame;
    for a squeeze, set back from the face), world; travel : (H, T) m, how far each hand's
    fingers (or a squeeze's press) have moved from open towards the object.
    phases : (name, start s) of each phase in order.
    """

    times: np.ndarray
    object_poses: np.ndarray
    hands: tuple[str, ...]
    hand_poses: np.ndarray
    travel: np.ndarray
    phases: tuple[tuple[str, float], ...]


@dataclass(frozen=True)
class CheckResult:
    """One check's outcome.

    mode : H1G1, H2G2 or H2G1. passed : no drop and every slip within the thresholds (the
    receiver's included). dropped : some holder dropped the object; dropped_in : the first
    phase it did, or None. receiver_held : the receiver holds it after the hand-over
    (None without a receiver). phases : every (phase, holder) measured, in order.
    max_translation_mm, max_rotation_deg : the largest slip of any phase. seconds : wall
    time of the check (build, run, measure); simulated_seconds : the protocol's length.
    trajectory : the motion, when the check was asked to record it (not in ``to_dict``).
    """

    mode: str
    passed: bool
    dropped: bool
    dropped_in: str | None
    receiver_held: bool | None
    phases: tuple[PhaseSlip, ...]
    max_translation_mm: float
    max_rotation_deg: float
    seconds: float
    simulated_seconds: float
    trajectory: Trajectory | None = None

    def slip(self, phase: str, holder: str | None = None) -> PhaseSlip:
        """The :class:`PhaseSlip` of ``phase`` (and ``holder``, if several hold in it)."""
        for p in self.phases:
            if p.phase == phase and (holder is None or p.holder == holder):
                return p
        raise KeyError(f"no measured phase {phase!r} for holder {holder!r}")

    def to_dict(self) -> dict:
        """JSON-ready, floats rounded (mm and deg to 0.01, seconds to 0.001)."""
        return {
            "mode": self.mode, "passed": self.passed, "dropped": self.dropped,
            "dropped_in": self.dropped_in, "receiver_held": self.receiver_held,
            "phases": [p.to_dict() for p in self.phases],
            "max_translation_mm": round(self.max_translation_mm, 2),
            "max_rotation_deg": round(self.max_rotation_deg, 2),
            "seconds": round(self.seconds, 3),
            "simulated_seconds": round(self.simulated_seconds, 3),
        }  # fmt: skip


@dataclass(frozen=True)
class EnsembleResult:
    """The nominal check and its perturbed runs.

    margin : the share of the perturbed runs that pass (0-1). robust : the margin reaches
    ``Thresholds.ensemble_fraction`` and the nominal passes. worst_translation_mm,
    worst_rotation_deg : the largest slip over all runs (the nominal's included).
    seconds : wall time of the nominal and the ensemble together (each run's own
    ``seconds`` is its share of it: they run in one batch).
    """

    nominal: CheckResult
    runs: tuple[tuple[Perturbation, CheckResult], ...]
    margin: float
    robust: bool
    worst_translation_mm: float
    worst_rotation_deg: float
    seconds: float

    def to_dict(self) -> dict:
        """JSON-ready: the nominal, each run's label, pass and slips, the margin."""
        return {
            "nominal": self.nominal.to_dict(),
            "runs": [{"label": p.label, "friction": p.friction, "force": p.force,
                      "torsion": p.torsion, "passed": r.passed, "dropped": r.dropped,
                      "max_translation_mm": round(r.max_translation_mm, 2),
                      "max_rotation_deg": round(r.max_rotation_deg, 2)}
                     for p, r in self.runs],
            "margin": round(self.margin, 3), "robust": self.robust,
            "worst_translation_mm": round(self.worst_translation_mm, 2),
            "worst_rotation_deg": round(self.worst_rotation_deg, 2),
            "seconds": round(self.seconds, 3),
        }  # fmt: skip


@dataclass
class _Prepared:
    built: Built
    schedule: Schedule
    names: list[str]
    control: np.ndarray
    control_spec: int
    state0: np.ndarray
    data: mujoco.MjData


def _hand_frame(grasp: Grasp) -> np.ndarray:
    """(4, 4) the hand body in the object frame while it holds."""
    if grasp.kind == "pinch":
        return grasp.pose
    back = grasp.hand.finger_length / 2.0 + grasp.hand.clearance
    return grasp.pose @ transform_from(translation=[0.0, 0.0, -back])


def _plan(grasp: Grasp, name: str) -> HandPlan:
    hand = grasp.hand
    if grasp.kind == "pinch":
        target = hand.opening(grasp.width) / 2.0 + _CLOSE_PAST
        contact = (hand.opening(grasp.width) - grasp.width) / 2.0
    else:
        target, contact = squeeze_target(hand), hand.clearance
    return HandPlan(name, _hand_frame(grasp), target, hand.speed, contact,
                    axis=1 if grasp.kind == "pinch" else 2)


def _offsets(m: mujoco.MjModel, parts: list[int]) -> dict[int, int]:
    """Where each state component starts in a state vector of these ``parts`` (bit order)."""
    out, at = {}, 0
    for bit in sorted(parts):
        out[bit] = at
        at += mujoco.mj_stateSize(m, bit)
    return out


def _prepare(obj: ObjectModel, grasps: list[Grasp], motion: Motion, mode: str,
             receiver: Grasp | list[Grasp] | None, protocol: Protocol,
             solver: Solver) -> _Prepared:  # fmt: skip
    names = [f"gripper{k}" for k in range(len(grasps))]
    plans = [_plan(g, n) for g, n in zip(grasps, names, strict=True)]
    takers = [] if receiver is None else [receiver] if isinstance(receiver, Grasp) else list(
        receiver
    )
    taker_names = ["receiver"] if len(takers) == 1 else [f"receiver{k}" for k in
                                                          range(len(takers))]  # fmt: skip
    everyone = list(grasps) + takers
    names += taker_names
    rplans = [_plan(g, n) for g, n in zip(takers, taker_names, strict=True)]
    sched = schedule(mode, plans, motion, protocol, solver.timestep, rplans)
    hands = []
    for h, (n, g) in enumerate(zip(names, everyone, strict=True)):
        opening = g.hand.opening(g.width) if g.kind == "pinch" else 0.0
        hands.append(HandIn(n, g.hand, g.kind, opening, sched.hand_poses[h, 0]))
    built = build(obj, motion.pickup, hands, solver)
    m = built.model
    st = mujoco.mjtState
    parts = [st.mjSTATE_CTRL.value, st.mjSTATE_XFRC_APPLIED.value, st.mjSTATE_MOCAP_POS.value,
             st.mjSTATE_MOCAP_QUAT.value]  # fmt: skip
    at = _offsets(m, parts)
    n = sched.steps
    control = np.zeros((n, sum(mujoco.mj_stateSize(m, p) for p in parts)))
    for h, acts in enumerate(built.actuators):
        for a in acts:
            control[:, at[parts[0]] + a] = sched.finger_targets[h]
    lift = built.weight * (1.0 - sched.weight)
    control[:, at[parts[1]] + 6 * built.object_body + 2] = lift
    quats = Rotation.from_matrix(sched.hand_poses[..., :3, :3].reshape(-1, 3, 3)).as_quat(
        scalar_first=True
    ).reshape(len(hands), n, 4)
    for h, mocap in enumerate(built.mocap):
        pos = at[parts[2]] + 3 * mocap
        control[:, pos:pos + 3] = sched.hand_poses[h, :, :3, 3]
        quat = at[parts[3]] + 4 * mocap
        control[:, quat:quat + 4] = quats[h]
    data = mujoco.MjData(m)
    data.xfrc_applied[built.object_body, 2] = built.weight
    mujoco.mj_forward(m, data)
    _check_start(built, data, names)
    state0 = np.empty(mujoco.mj_stateSize(m, st.mjSTATE_FULLPHYSICS.value))
    mujoco.mj_getState(m, data, state0, st.mjSTATE_FULLPHYSICS.value)
    spec = sum(parts)
    return _Prepared(built, sched, names, control, spec, state0, data)


def _check_start(built: Built, data: mujoco.MjData, names: list[str]) -> None:
    """Raise ``ValueError`` if a hand starts inside the object (deeper than 1 mm): its
    grasp does not fit the object, and the fingers would push it out or hold it from
    within."""
    m = built.model
    for c in data.contact[: data.ncon]:
        if c.dist >= -0.001:
            continue
        bodies = {int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])}
        if built.object_body not in bodies:
            continue
        other = (bodies - {built.object_body}).pop()
        root = int(m.body_rootid[other])
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, root)
        raise ValueError(
            f"{name if name in names else 'a hand'} starts {-c.dist * 1000:.1f} mm inside the "
            "object: the grasp's width or pose does not fit it"
        )


def _poses(qpos: np.ndarray, adr: int) -> tuple[np.ndarray, Rotation]:
    """Positions (N, 3) and rotations of a free joint's body over the run."""
    return qpos[:, adr:adr + 3], Rotation.from_quat(qpos[:, adr + 3:adr + 7], scalar_first=True)


def _pose_matrices(positions: np.ndarray, rotations: Rotation) -> np.ndarray:
    return transform_from(rotations.as_matrix(), positions)


def _trajectory(prep: _Prepared, states: np.ndarray) -> Trajectory:
    m, sched = prep.built.model, prep.schedule
    stride = max(1, int(round(1.0 / (RECORD_HZ * sched.dt))))
    rows = np.arange(stride - 1, sched.steps, stride)
    qpos = states[rows, 1:1 + m.nq]
    obj = _pose_matrices(*_poses(qpos, prep.built.object_qpos))
    hands = np.stack([_pose_matrices(*_poses(qpos, int(a))) for a in prep.built.hand_qpos])
    joints = [m.actuator_trnid[acts[0], 0] for acts in prep.built.actuators]
    travel = np.stack([qpos[:, m.jnt_qposadr[j]] for j in joints])
    phases = tuple((p.name, p.start * sched.dt) for p in sched.phases)
    return Trajectory((rows + 1) * sched.dt, obj, tuple(prep.names), hands, travel, phases)


def _measure(prep: _Prepared, states: np.ndarray, thresholds: Thresholds, mode: str,
             seconds: float) -> CheckResult:  # fmt: skip
    m, sched = prep.built.model, prep.schedule
    qpos = states[:, 1:1 + m.nq]  # FULLPHYSICS: time, then qpos
    p_obj, r_obj = _poses(qpos, prep.built.object_qpos)
    slips = []
    for h in range(len(prep.names)):
        ref = int(sched.settled[h])
        if ref < 0:
            slips.append(None)
            continue
        p_hand, r_hand = _poses(qpos, int(prep.built.hand_qpos[h]))
        inv = r_hand.inv()
        rel_p = inv.apply(p_obj - p_hand)  # the object's origin in the hand frame
        rel_r = inv * r_obj
        turn = rel_r * rel_r[ref].inv()
        moved = rel_p - turn.apply(rel_p[ref])  # where the hand-origin point went
        slips.append((np.linalg.norm(moved, axis=1) * 1000.0, np.degrees(turn.magnitude())))
    phases: list[PhaseSlip] = []
    dropped_in = None
    for phase in sched.phases:
        for holder in phase.holders:
            h = prep.names.index(holder)
            t, r = slips[h]
            mm = float(t[phase.start:phase.stop].max())
            deg = float(r[phase.start:phase.stop].max())
            drop = mm > thresholds.drop_mm or deg > thresholds.drop_deg
            if drop and dropped_in is None:
                dropped_in = phase.name
            phases.append(PhaseSlip(phase.name, holder, mm, deg, drop))
    within = all(p.translation_mm <= thresholds.max_slip_mm and
                 p.rotation_deg <= thresholds.max_slip_deg for p in phases)  # fmt: skip
    receiver_held = None
    if any(n.startswith("receiver") for n in prep.names):
        mine = [p for p in phases if p.holder.startswith("receiver")]
        receiver_held = bool(mine) and all(
            not p.dropped and p.translation_mm <= thresholds.max_slip_mm
            and p.rotation_deg <= thresholds.max_slip_deg for p in mine
        )
    dropped = dropped_in is not None
    return CheckResult(
        mode=mode, passed=within and not dropped, dropped=dropped, dropped_in=dropped_in,
        receiver_held=receiver_held, phases=tuple(phases),
        max_translation_mm=max((p.translation_mm for p in phases), default=0.0),
        max_rotation_deg=max((p.rotation_deg for p in phases), default=0.0),
        seconds=seconds, simulated_seconds=sched.steps * sched.dt,
    )  # fmt: skip


def _run(prep: _Prepared, models: list[mujoco.MjModel]) -> np.ndarray:
    """States (len(models), N, nstate) of the schedule run on each model, one thread."""
    state, _ = rollout.rollout(models, prep.data, prep.state0[None],
                               prep.control[None], control_spec=prep.control_spec,
                               nstep=prep.schedule.steps)  # fmt: skip
    return state


def check(
    obj: ObjectModel,
    grasps: list[Grasp],
    motion: Motion,
    mode: str = "H1G1",
    receiver: Grasp | list[Grasp] | None = None,
    protocol: Protocol | None = None,
    solver: Solver | None = None,
    thresholds: Thresholds | None = None,
    record: bool = False,
) -> CheckResult:
    """Simulate the grasps through the protocol and measure how the object slips.

    obj : the object (shapes, mass, centre of mass), in its own frame.
    grasps : the grippers' grasps, object frame: one for H1G1, two for H2G1 (holding
        together from pick-up) and H2G2 (the first to the midair pose, the second from there
        to the handover). Their hands are named ``gripper0``, ``gripper1`` in the result.
    motion : the object's world poses (pick-up, carry, H2G2's second carry).
    receiver : the receiver's grasp (pads, object frame), or a list of them (one per hand,
        named ``receiver0``, ``receiver1``), closing at the handover, after which the
        grippers open and retreat; or None.
    protocol, solver, thresholds : the parameters (their defaults if None).
    record : also return the motion (``CheckResult.trajectory``) for drawing.
    Raises ``ValueError`` on inconsistent input (mode against grasps and motion, a grasp
    wider than its hand opens).
    """
    start = time.perf_counter()
    protocol, solver = protocol or Protocol(), solver or Solver()
    thresholds = thresholds or Thresholds()
    prep = _prepare(obj, list(grasps), motion, mode, receiver, protocol, solver)
    states = _run(prep, [prep.built.model])[0]
    result = _measure(prep, states, thresholds, mode, time.perf_counter() - start)
    if record:
        result = replace(result, trajectory=_trajectory(prep, states))
    return result


def _perturbed(built: Built, p: Perturbation) -> mujoco.MjModel:
    m = copy.copy(built.model)
    for geoms in built.pad_geoms:
        m.geom_friction[geoms, 0] *= p.friction
        m.geom_friction[geoms, 1] *= p.torsion
    for acts in built.actuators:
        m.actuator_forcerange[acts] *= p.force
        m.actuator_gainprm[acts, 0] *= p.force  # still saturating 2 mm past the contact
        m.actuator_biasprm[acts, 1] *= p.force
        m.actuator_biasprm[acts, 2] *= np.sqrt(p.force)
    return m


def ensemble(
    obj: ObjectModel,
    grasps: list[Grasp],
    motion: Motion,
    mode: str = "H1G1",
    receiver: Grasp | list[Grasp] | None = None,
    protocol: Protocol | None = None,
    solver: Solver | None = None,
    thresholds: Thresholds | None = None,
    perturbations: tuple[Perturbation, ...] = DEFAULT_ENSEMBLE,
) -> EnsembleResult:
    """The nominal :func:`check` and one run per perturbation (friction, grip force and
    torsion of every hand scaled), batched in one rollout on one thread. Arguments as for
    :func:`check`; raises ``ValueError`` for an empty ``perturbations``."""
    if not perturbations:
        raise ValueError("an ensemble needs at least one perturbation")
    start = time.perf_counter()
    protocol, solver = protocol or Protocol(), solver or Solver()
    thresholds = thresholds or Thresholds()
    prep = _prepare(obj, list(grasps), motion, mode, receiver, protocol, solver)
    models = [prep.built.model] + [_perturbed(prep.built, p) for p in perturbations]
    states = _run(prep, models)
    seconds = time.perf_counter() - start
    results = [_measure(prep, s, thresholds, mode, seconds / len(models)) for s in states]
    nominal, runs = results[0], results[1:]
    margin = sum(r.passed for r in runs) / len(runs)
    return EnsembleResult(
        nominal=nominal,
        runs=tuple(zip(perturbations, runs, strict=True)),
        margin=margin,
        robust=nominal.passed and margin >= thresholds.ensemble_fraction,
        worst_translation_mm=max(r.max_translation_mm for r in results),
        worst_rotation_deg=max(r.max_rotation_deg for r in results),
        seconds=time.perf_counter() - start,
    )
