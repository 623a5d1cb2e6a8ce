"""Run the physics check of grasps and measure it: slip per phase, drops, the receiver.

:func:`check` builds the schedule of targets (:mod:`.protocol`) and the MuJoCo models
(:mod:`.model`): one per run of phases with the same hands taking part, so a hand that waits
away from the object, or has let go and backed off, costs nothing while it touches nothing
(a hand that comes in starts at rest on its target; the joints the models share carry
over). A phase is simulated by calls of MuJoCo's ``rollout`` (the palm targets, finger
targets and the support's force are its open-loop inputs, so no Python runs per step; the
solver's warm start is carried from call to call, so the steps are those of a single
rollout), and its holders are measured as it goes: a run whose slip has passed a threshold
when a phase ends fails whatever comes next, and stops there, and a drop stops it at once
(``stop_early``). Slip is the motion of the object in the
holding hand's frame (the palm body, not its target) since the hand's grip settled: the
displacement of the object's point that sat at the grasp origin (mm) and the angle it
turned (deg). :func:`ensemble` runs the same check with the friction, grip force and
torsion scaled (:data:`.params.DEFAULT_ENSEMBLE`) on copies of the same models and gives
the share that pass and the worst slip.

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
from handover.geometry.physics.hands import squeeze_target
from handover.geometry.physics.model import Built, HandIn, build
from handover.geometry.physics.params import (
    DEFAULT_ENSEMBLE,
    Perturbation,
    Protocol,
    Solver,
    Thresholds,
)
from handover.geometry.physics.protocol import HandPlan, Motion, Schedule, schedule
from handover.geometry.physics.results import (
    RECORD_HZ,
    CheckResult,
    EnsembleResult,
    Grasp,
    PhaseSlip,
    Trajectory,
)
from handover.geometry.physics.shapes import ObjectModel
from handover.geometry.physics.slip import slip_since

__all__ = ["check", "ensemble"]

_CLOSE_PAST = 0.01  # m: the closed target lies this far past the contact (force-limited)
_CHUNK_S = 0.2  # s: a phase is simulated in runs this long, a drop ends it (``stop_early``)

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
_STATE = mujoco.mjtState


@dataclass
class _Segment:
    """Consecutive phases simulated on one model, the hands that take part in them.

    phases : indices of the schedule's phases, steps ``[start, stop)``. hands : indices
    (into the check's names) of the hands in ``built``, in its order. control : (stop -
    start, ncontrol) the open-loop inputs per step (``_CONTROL``). data : an MjData of the
    model (the perturbed copies share it). qpos_from, qpos_to, dof_from, dof_to : where
    the joints this model shares with the previous segment's sit in that one's qpos and
    qvel, and in its own. entering : the hands that come in here (indices into names).
    """

    phases: list[int]
    start: int
    stop: int
    hands: list[int]
    built: Built
    control: np.ndarray
    data: mujoco.MjData
    qpos_from: np.ndarray
    qpos_to: np.ndarray
    dof_from: np.ndarray
    dof_to: np.ndarray
    entering: list[int]


@dataclass
class _Prepared:
    """What every run of a check shares: the schedule, the hands' names (grippers, then
    receivers), the segments with their models, the first model's start state (nstate,)
    and the hands' target orientations."""

    schedule: Schedule
    names: list[str]
    segments: list[_Segment]
    state0: np.ndarray
    quats: np.ndarray  # (H, N, 4) each hand's target orientation per step, w x y z


_CONTROL = (_STATE.mjSTATE_CTRL.value, _STATE.mjSTATE_XFRC_APPLIED.value,
            _STATE.mjSTATE_MOCAP_POS.value, _STATE.mjSTATE_MOCAP_QUAT.value)  # fmt: skip
_CONTROL_SPEC = sum(_CONTROL)


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


def _offsets(m: mujoco.MjModel, parts: tuple[int, ...]) -> dict[int, int]:
    """Where each state component starts in a state vector of these ``parts`` (bit order)."""
    out, at = {}, 0
    for bit in sorted(parts):
        out[bit] = at
        at += mujoco.mj_stateSize(m, bit)
    return out


def _control(built: Built, sched: Schedule, hands: list[int], quats: np.ndarray, start: int,
             stop: int) -> np.ndarray:  # fmt: skip
    """(stop - start, ncontrol) the model's inputs over steps ``[start, stop)``: finger
    targets, the support's force on the object, the palms' targets (``_CONTROL``)."""
    m = built.model
    ctrl, xfrc, mpos, mquat = _CONTROL
    at = _offsets(m, _CONTROL)
    control = np.zeros((stop - start, mujoco.mj_stateSize(m, _CONTROL_SPEC)))
    for k, h in enumerate(hands):
        for a in built.actuators[k]:
            control[:, at[ctrl] + a] = sched.finger_targets[h, start:stop]
        pos = at[mpos] + 3 * built.mocap[k]
        control[:, pos:pos + 3] = sched.hand_poses[h, start:stop, :3, 3]
        quat = at[mquat] + 4 * built.mocap[k]
        control[:, quat:quat + 4] = quats[h, start:stop]
    control[:, at[xfrc] + 6 * built.object_body + 2] = built.weight * (
        1.0 - sched.weight[start:stop])
    return control


def _joint_map(before: mujoco.MjModel, after: mujoco.MjModel) -> tuple[np.ndarray, ...]:
    """(qpos in ``before``, qpos in ``after``, dofs in ``before``, dofs in ``after``) of
    the joints both models have (by name)."""
    qf, qt, df, dt = [], [], [], []
    width = {int(mujoco.mjtJoint.mjJNT_FREE): (7, 6), int(mujoco.mjtJoint.mjJNT_SLIDE): (1, 1)}
    for j in range(after.njnt):
        name = mujoco.mj_id2name(after, mujoco.mjtObj.mjOBJ_JOINT, j)
        i = mujoco.mj_name2id(before, mujoco.mjtObj.mjOBJ_JOINT, name)
        if i < 0:
            continue
        nq, nv = width[int(after.jnt_type[j])]
        qf += range(before.jnt_qposadr[i], before.jnt_qposadr[i] + nq)
        qt += range(after.jnt_qposadr[j], after.jnt_qposadr[j] + nq)
        df += range(before.jnt_dofadr[i], before.jnt_dofadr[i] + nv)
        dt += range(after.jnt_dofadr[j], after.jnt_dofadr[j] + nv)
    return tuple(np.array(v, dtype=np.int64) for v in (qf, qt, df, dt))


def _prepare(obj: ObjectModel, grasps: list[Grasp], motion: Motion, mode: str,
             receiver: Grasp | list[Grasp] | None, protocol: Protocol,
             solver: Solver) -> _Prepared:  # fmt: skip
    """The schedule and one model per run of phases with the same hands taking part
    (a hand waiting away from the object, or gone after letting go, is left out), each
    model checked for a hand starting inside the object (``ValueError``)."""
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
    n = sched.steps
    # the poses are products of rotations: valid, and converted exactly as when checked
    quats = Rotation.from_matrix(sched.hand_poses[..., :3, :3].reshape(-1, 3, 3),
                                 assume_valid=True).as_quat(scalar_first=True)  # fmt: skip
    quats = quats.reshape(len(names), n, 4)
    runs: list[tuple[list[int], list[int]]] = []  # (phases, hands)
    for k, phase in enumerate(sched.phases):
        hands = [names.index(h) for h in phase.present] or list(range(len(names)))
        if runs and runs[-1][1] == hands:
            runs[-1][0].append(k)
        else:
            runs.append(([k], hands))
    models: dict[tuple[int, ...], tuple[Built, mujoco.MjData]] = {}
    segments: list[_Segment] = []
    for phases, hands in runs:
        key = tuple(hands)
        if key not in models:
            ins = []
            for h in hands:
                g = everyone[h]
                opening = g.hand.opening(g.width) if g.kind == "pinch" else 0.0
                ins.append(HandIn(names[h], g.hand, g.kind, opening, sched.hand_poses[h, 0]))
            built = build(obj, motion.pickup, ins, solver)
            data = mujoco.MjData(built.model)
            data.xfrc_applied[built.object_body, 2] = built.weight
            mujoco.mj_forward(built.model, data)  # everyone at the start: none inside
            _check_start(built, data, names)
            models[key] = (built, data)
        built, data = models[key]
        first, last = sched.phases[phases[0]], sched.phases[phases[-1]]
        if segments:
            before = segments[-1]
            maps = _joint_map(before.built.model, built.model)
            entering = [h for h in hands if h not in before.hands]
        else:
            maps = tuple(np.zeros(0, dtype=np.int64) for _ in range(4))
            entering = []
        segments.append(_Segment(phases, first.start, last.stop, hands, built,
                                 _control(built, sched, hands, quats, first.start, last.stop),
                                 data, *maps, entering))  # fmt: skip
    first = segments[0]
    state0 = np.empty(mujoco.mj_stateSize(first.built.model, _FULL))
    mujoco.mj_getState(first.built.model, first.data, state0, _FULL)
    return _Prepared(sched, names, segments, state0, quats)


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


def _enter(prep: _Prepared, before: _Segment, state: np.ndarray, warm: np.ndarray,
           seg: _Segment, model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The state (nstate,) and warm start (1, nv) ``seg``'s ``model`` starts from, where the
    previous segment's ended in ``state`` and ``warm``: the joints both models have carry
    over, and a hand that comes in starts at rest on its target (it waited there, away
    from the object), fingers open."""
    mujoco.mj_setState(before.built.model, before.data, state, _FULL)
    d = seg.data
    mujoco.mj_resetData(model, d)  # qpos0: fingers open
    d.time = before.data.time
    d.qpos[seg.qpos_to] = before.data.qpos[seg.qpos_from]
    d.qvel[seg.dof_to] = before.data.qvel[seg.dof_from]
    row = seg.start - 1  # the targets of the last step simulated
    for h in seg.entering:
        adr = int(seg.built.hand_qpos[seg.hands.index(h)])
        d.qpos[adr:adr + 3] = prep.schedule.hand_poses[h, row, :3, 3]
        d.qpos[adr + 3:adr + 7] = prep.quats[h, row]
    out = np.empty(mujoco.mj_stateSize(model, _FULL))
    mujoco.mj_getState(model, d, out, _FULL)
    start_warm = np.zeros((1, model.nv))
    start_warm[0, seg.dof_to] = warm[0, seg.dof_from]
    return out, start_warm


@dataclass
class _Run:
    """One simulated run: ``poses`` (H + 1, N, 7) the object's and each hand's free joint
    per step (position, quaternion w x y z; NaN where a hand is not simulated or past
    ``steps``), ``travel`` (H, N) m each hand's finger (or press) joint, ``steps`` the
    steps simulated, ``phases`` the slips measured, ``seconds`` wall time."""

    poses: np.ndarray
    travel: np.ndarray
    steps: int
    phases: list[PhaseSlip]
    seconds: float


def _simulate(prep: _Prepared, models: list[mujoco.MjModel], thresholds: Thresholds,
              stop_early: bool) -> _Run:  # fmt: skip
    """Run the schedule on ``models`` (one per segment, the prepared ones or perturbed
    copies), one phase per MuJoCo ``rollout`` (the warm start carried over, so the steps
    are those of one rollout), measuring each phase's holders as it ends; with
    ``stop_early``, stop after the first phase whose slip passes a threshold, and within a
    phase as soon as a holder has dropped the object (measured every :data:`_CHUNK_S`)."""
    start = time.perf_counter()
    chunk = max(1, int(round(_CHUNK_S / prep.schedule.dt)))
    sched, names = prep.schedule, prep.names
    n, hands = sched.steps, len(names)
    runner = rollout.Rollout(nthread=0)  # on this thread
    poses = np.full((hands + 1, n, 7), np.nan)
    travel = np.zeros((hands, n))
    phases: list[PhaseSlip] = []
    state, warm = prep.state0, None
    before: _Segment | None = None
    for seg, m in zip(prep.segments, models, strict=True):
        if before is not None:
            state, warm = _enter(prep, before, state, warm, seg, m)
        built = seg.built
        out = np.empty((seg.stop - seg.start, mujoco.mj_stateSize(m, _FULL)))
        cols = [1 + built.object_qpos] + [1 + int(a) for a in built.hand_qpos]
        fingers = [1 + int(m.jnt_qposadr[m.actuator_trnid[a[0], 0]]) for a in built.actuators]
        for k in seg.phases:
            phase = sched.phases[k]
            a, b = phase.start - seg.start, phase.stop - seg.start
            worst = {h: (0.0, 0.0) for h in (names.index(x) for x in phase.holders)}
            d = b
            for c in range(a, b, chunk if stop_early else max(1, b - a)):
                d = min(c + chunk, b) if stop_early else b
                runner.rollout([m], [seg.data], state[None], seg.control[None, c:d],
                               control_spec=_CONTROL_SPEC, nstep=d - c,
                               initial_warmstart=warm, state=out[None, c:d],
                               skip_checks=True)  # fmt: skip
                warm = seg.data.qacc_warmstart.copy()[None]
                state = out[d - 1]
                rows = slice(seg.start + c, seg.start + d)
                for which, col in zip([0] + [h + 1 for h in seg.hands], cols, strict=True):
                    poses[which, rows] = out[c:d, col:col + 7]
                for h, col in zip(seg.hands, fingers, strict=True):
                    travel[h, rows] = out[c:d, col]
                for h, (mm, deg) in worst.items():
                    now = slip_since(poses[0], poses[h + 1], int(sched.settled[h]), rows)
                    worst[h] = (max(mm, now[0]), max(deg, now[1]))
                dropped = any(mm > thresholds.drop_mm or deg > thresholds.drop_deg
                              for mm, deg in worst.values())  # fmt: skip
                if dropped and d < b:
                    break  # a drop fails the phase whatever its rest does
            failed = False
            for h, (mm, deg) in worst.items():
                drop = mm > thresholds.drop_mm or deg > thresholds.drop_deg
                phases.append(PhaseSlip(phase.name, names[h], mm, deg, drop))
                failed |= phases[-1].slipped(thresholds)
            if failed and stop_early:
                return _Run(poses, travel, seg.start + d, phases,
                            time.perf_counter() - start)  # fmt: skip
        before = seg
    return _Run(poses, travel, n, phases, time.perf_counter() - start)


def _pose_matrices(poses: np.ndarray) -> np.ndarray:
    """(..., 4, 4) of free-joint poses (..., 7)."""
    flat = poses.reshape(-1, 7)
    rot = Rotation.from_quat(flat[:, 3:], scalar_first=True).as_matrix()
    return transform_from(rot, flat[:, :3]).reshape(*poses.shape[:-1], 4, 4)


def _trajectory(prep: _Prepared, run: _Run) -> Trajectory:
    """The simulated motion sampled at :data:`RECORD_HZ` (a hand not simulated in a phase
    is where its target is, fingers open)."""
    sched = prep.schedule
    stride = max(1, int(round(1.0 / (RECORD_HZ * sched.dt))))
    rows = np.arange(stride - 1, run.steps, stride)
    obj = _pose_matrices(run.poses[0, rows])
    hands = np.empty((len(prep.names), len(rows), 4, 4))
    for h in range(len(prep.names)):
        here = ~np.isnan(run.poses[h + 1, rows, 0])
        hands[h] = sched.hand_poses[h, rows]
        if here.any():
            hands[h, here] = _pose_matrices(run.poses[h + 1, rows[here]])
    phases = tuple((p.name, p.start * sched.dt) for p in sched.phases if p.start < run.steps)
    return Trajectory((rows + 1) * sched.dt, obj, tuple(prep.names), hands,
                      run.travel[:, rows], phases)  # fmt: skip


def _result(prep: _Prepared, run: _Run, thresholds: Thresholds, mode: str,
            seconds: float) -> CheckResult:  # fmt: skip
    phases = run.phases
    dropped_in = next((p.phase for p in phases if p.dropped), None)
    failed_in = next((p.phase for p in phases if p.slipped(thresholds)), None)
    receiver_held = None
    if any(n.startswith("receiver") for n in prep.names):
        mine = [p for p in phases if p.holder.startswith("receiver")]
        receiver_held = bool(mine) and not any(p.dropped or p.slipped(thresholds)
                                               for p in mine)
    dropped = dropped_in is not None
    return CheckResult(
        mode=mode, passed=failed_in is None and not dropped, dropped=dropped,
        dropped_in=dropped_in, receiver_held=receiver_held, phases=tuple(phases),
        max_translation_mm=max((p.translation_mm for p in phases), default=0.0),
        max_rotation_deg=max((p.rotation_deg for p in phases), default=0.0),
        seconds=seconds, simulated_seconds=run.steps * prep.schedule.dt, failed_in=failed_in,
    )  # fmt: skip


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
    stop_early: bool = True,
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
    stop_early : stop at the end of the first phase whose slip passes a threshold (the
        run fails whatever follows; ``CheckResult.failed_in``); False runs every phase.
    Raises ``ValueError`` on inconsistent input (mode against grasps and motion, a grasp
    wider than its hand opens, a hand starting inside the object).
    """
    start = time.perf_counter()
    protocol, solver = protocol or Protocol(), solver or Solver()
    thresholds = thresholds or Thresholds()
    prep = _prepare(obj, list(grasps), motion, mode, receiver, protocol, solver)
    run = _simulate(prep, [s.built.model for s in prep.segments], thresholds, stop_early)
    result = _result(prep, run, thresholds, mode, time.perf_counter() - start)
    if record:
        result = replace(result, trajectory=_trajectory(prep, run))
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
    stop_early: bool = True,
) -> EnsembleResult:
    """The nominal :func:`check` and one run per perturbation (friction, grip force and
    torsion of every hand scaled), one after the other on one thread, on the same models
    and schedule (built once). Arguments as for :func:`check`; raises ``ValueError`` for
    an empty ``perturbations``."""
    if not perturbations:
        raise ValueError("an ensemble needs at least one perturbation")
    start = time.perf_counter()
    protocol, solver = protocol or Protocol(), solver or Solver()
    thresholds = thresholds or Thresholds()
    prep = _prepare(obj, list(grasps), motion, mode, receiver, protocol, solver)
    sets = [[s.built.model for s in prep.segments]]
    sets += [[_perturbed(s.built, p) for s in prep.segments] for p in perturbations]
    share = (time.perf_counter() - start) / len(sets)
    results = []
    for models in sets:
        run = _simulate(prep, models, thresholds, stop_early)
        measured = time.perf_counter()
        result = _result(prep, run, thresholds, mode, 0.0)
        seconds = share + run.seconds + time.perf_counter() - measured
        results.append(replace(result, seconds=seconds))
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
