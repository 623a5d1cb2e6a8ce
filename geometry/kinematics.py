"""Forward kinematics, Jacobians and inverse kinematics of a serial chain, for many
configurations at once (numpy, one array operation per joint over all configurations).
Longer than 500 lines: one class, whose forward kinematics, Jacobian and inverse kinematics
share the folded joint frames and their constants (a split would pass them back and forth).

:class:`Kinematics` is built once per :class:`~handover.geometry.urdf.Chain` (and, optionally,
a tool transform ``tcp`` from the tip link to the frame the caller cares about, e.g. the
planner's grasp frame). Every joint is rewritten as a rotation (or translation) about its own
z axis by folding a constant rotation into the fixed transforms on either side of it, so one
step of forward kinematics is a product with a constant (4, 3) matrix, summed term by term
(a pose's values do not depend on the batch it is computed in), plus a planar rotation of
two columns.

Poses are in the chain's base-link frame, metres; joint values in radians (metres for
prismatic joints). :meth:`Kinematics.ik` is damped least squares over all targets at once,
with joint-limit clamping (a joint on a limit sits out the steps that would push it past it)
and seeded random restarts for the targets that did not converge.

>>> from handover.geometry.urdf import load_urdf
>>> chain = load_urdf("kb/robots/idro_arms.urdf").chain("base_link", "left_flange")
>>> kin = Kinematics(chain)
>>> poses = kin.fk(np.tile(chain.mid, (3, 1)))
>>> poses.shape
(3, 4, 4)
>>> result = kin.ik(poses)
>>> bool(result.success.all())
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handover.geometry.urdf import Chain, RobotModelError

__all__ = ["Kinematics", "IKResult", "rotation_angle"]

# Configurations per block in forward kinematics: a block's arrays stay in the CPU cache.
_CHUNK = 4096
# IK damping: full `damping` while the error (m, rad combined) exceeds _DAMPING_ERROR, then
# proportional to the error, down to _DAMPING_MIN x damping. A damped step's gain is at most
# 1 / (2 lambda), so while lambda is proportional to the error the step stays within
# _DAMPING_ERROR / (2 damping) (1 rad for the default 0.05) however ill-conditioned the
# Jacobian. The floor is reached only at an error of 1e-3, about the tolerances. With a floor
# of 0.1 (lambda 0.005), runs in nearly singular poses (smallest singular value 2e-4 to 1e-3)
# crawled the last 0.1-0.6 mm at a few % per iteration (one took 35 iterations from 1.5e-4
# to 1e-4 m).
_DAMPING_ERROR = 0.1
_DAMPING_MIN = 0.01
# A run whose step moves no joint by more than this (rad, or m for prismatic joints) is at a
# fixed point (its next iterations would repeat this one) and stops.
_STILL = 1e-9
# Runs from given starts (ik_from, shared restarts): a run more than 1 cm or 3 degrees off that
# gains less than 10 % in this many iterations is stuck (on a joint limit, stretched out) and
# stops, and so does one that at that pace would still be 10 cm or 1 rad off at the end.
_PATIENCE = 10
_EYE6 = np.eye(6)
_STUCK_POSITION = 0.01  # m
_STUCK_ROTATION = np.radians(3.0)  # rad


@dataclass(frozen=True, eq=False)
class IKResult:
    """Inverse kinematics for m targets.

    q : (m, dof) joint values within the limits (for failures: the closest attempt).
    success : (m,) bool, both errors within tolerance.
    position_error : (m,) m. rotation_error : (m,) rad (angle of the residual rotation).
    attempts : (m,) int, how many starts were tried (1 + restarts used).
    """

    q: np.ndarray
    success: np.ndarray
    position_error: np.ndarray
    rotation_error: np.ndarray
    attempts: np.ndarray


def rotation_angle(r_a: np.ndarray, r_b: np.ndarray) -> np.ndarray:
    """(...) rad: angle of the rotation taking frames ``r_a`` to ``r_b`` (both (..., 3, 3)).

    The trace is summed term by term in a fixed order, not by a reduction (whose order numpy
    may choose by the batch's shape): a frame's angle is the same to the bit in any batch,
    which matters near 0, where arccos turns one ulp of the trace into 1e-11 rad."""
    p = np.asarray(r_a) * np.asarray(r_b)
    trace = p[..., 0, 0]
    for i, j in ((0, 1), (0, 2), (1, 0), (1, 1), (1, 2), (2, 0), (2, 1), (2, 2)):
        trace = trace + p[..., i, j]
    return np.arccos(np.clip(0.5 * (trace - 1.0), -1.0, 1.0))


def _columns(rot: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """(3, 4, 1) the columns of the (4, 3) matrix ``[rot; pos]`` (rot (3, 3), pos (3,)), as
    :func:`_times` takes them."""
    return np.ascontiguousarray(np.vstack([rot, pos]).T[:, :, None])


def _times(cols: np.ndarray, flat: np.ndarray) -> np.ndarray:
    """(4, N) ``[rot; pos] @ flat`` for ``cols`` = :func:`_columns` (rot, pos) and ``flat``
    (3, N), term by term: each column's value is the same to the bit in any batch (a BLAS
    product's is not: its kernels round the columns of a block and of its edge differently),
    so a pose's kinematics do not depend on the poses computed with it."""
    return cols[0] * flat[0] + cols[1] * flat[1] + cols[2] * flat[2]


def _z_to(axis: np.ndarray) -> np.ndarray:
    """(3, 3) a rotation taking +z to the unit vector ``axis`` (identity if it is +z)."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(np.dot(z, axis))
    if c > 1.0 - 1e-15:
        return np.eye(3)
    if c < -1.0 + 1e-15:
        return np.diag([1.0, -1.0, -1.0])  # half turn about x
    v = np.cross(z, axis)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def _rot4(r: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = r
    return out


class Kinematics:
    """Batched kinematics of one chain.

    chain : the :class:`Chain`. tcp : optional (4, 4) transform from the tip link to a tool
        frame; then :meth:`fk`, :meth:`jacobian` and :meth:`ik` speak of the tool frame.
    """

    def __init__(self, chain: Chain, tcp: np.ndarray | None = None) -> None:
        self.chain = chain
        dof = chain.dof
        if dof == 0:
            raise RobotModelError(
                f"chain {chain.base_link!r} -> {chain.tip_link!r} has no moving joint",
                chain.source or None,
            )
        tcp = np.eye(4) if tcp is None else np.asarray(tcp, dtype=float)
        if tcp.shape != (4, 4) or not np.isfinite(tcp).all():
            raise RobotModelError(f"tcp must be a finite (4, 4) transform, got {tcp.shape}")
        self.tcp = tcp
        self.dof = dof
        self.prismatic = np.array([k == "prismatic" for k in chain.kinds], dtype=bool)
        self.continuous = chain.continuous
        self._any_continuous = bool(self.continuous.any())
        self.lower = chain.lower.copy()
        self.upper = chain.upper.copy()
        c = [_rot4(_z_to(a)) for a in chain.axes]
        # Folded transforms: F_i = F_{i-1} @ A_i @ Z_i(q) with F_i = J_i @ C_i.
        folded = []
        prev = np.eye(4)
        for i in range(dof):
            folded.append(prev.T @ chain.origins[i] @ c[i])
            prev = c[i]
        self._a_rot = np.array([f[:3, :3] for f in folded])  # (dof, 3, 3)
        self._a_t = np.array([f[:3, 3] for f in folded])  # (dof, 3)
        self._c_t = np.array(c)  # (dof, 4, 4): J_i = F_i @ C_i^T
        tip = c[-1].T @ chain.tip_offset @ tcp
        self._tip = tip
        # Links: pose = F_j @ (C_j^T @ offset), or the offset itself for j = -1.
        self._link_joint = chain.link_joint
        self._link_local = np.array(
            [
                off if j < 0 else c[j].T @ off
                for j, off in zip(chain.link_joint, chain.link_offsets, strict=True)
            ]
        ).reshape(-1, 4, 4)

    @property
    def folded(self) -> np.ndarray:
        """(dof, 4, 4) the folded ``A_i``: joint frames ``F_i = F_(i-1) A_i Z_i(q_i)``."""
        return np.concatenate([np.concatenate([self._a_rot, self._a_t[:, :, None]], axis=2),
                               np.tile([[[0.0, 0.0, 0.0, 1.0]]], (self.dof, 1, 1))], axis=1)

    @property
    def link_frames(self) -> tuple[np.ndarray, np.ndarray]:
        """(L,) the joint moving each link (-1: none), (L, 4, 4) the link in that frame."""
        return np.asarray(self._link_joint, dtype=np.int64), self._link_local.copy()

    # ------------------------------------------------------------------ forward kinematics

    def _check_q(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.dof:
            raise RobotModelError(
                f"joint values must have shape (n, {self.dof}), got {np.shape(q)}"
            )
        if not np.isfinite(q).all():
            raise RobotModelError("joint values must be finite")
        return q

    def _frames(self, q: np.ndarray, dtype) -> tuple[np.ndarray, np.ndarray]:
        """Folded joint frames, component-major: the rotations (dof, 3, 3, n) as ``[joint,
        column, row, sample]`` and the origins (dof, 3, n). Column-major storage makes the
        product with a joint's constant rotation and origin one :func:`_times` over (3, 3n)."""
        n = q.shape[0]
        a_rot_t, a_t, cols = self._constants(dtype)
        qt = np.ascontiguousarray(q.T, dtype=dtype)
        cos, sin = np.cos(qt), np.sin(qt)
        rots = np.empty((self.dof, 3, 3, n), dtype=dtype)
        origins = np.empty((self.dof, 3, n), dtype=dtype)
        rot = np.repeat(a_rot_t[0][:, :, None], n, axis=2)
        pos = np.repeat(a_t[0][:, None], n, axis=1)
        for i in range(self.dof):
            if i:
                both = _times(cols[i], rot.reshape(3, 3 * n))
                pos = pos + both[3].reshape(3, n)
                rot = both[:3].reshape(3, 3, n)
            out = rots[i]
            if self.prismatic[i]:
                pos = pos + rot[2] * qt[i]
                out[...] = rot
            else:
                c, s = cos[i], sin[i]
                x, y = rot[0], rot[1]
                out[0] = c * x + s * y
                out[1] = c * y - s * x
                out[2] = rot[2]
            origins[i] = pos
            rot = out
        return rots, origins

    def _constants(self, dtype) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The folded fixed transforms in ``dtype``: rotations transposed (dof, 3, 3),
        origins (dof, 3) and both as :func:`_columns` (dof, 3, 4, 1), converted once per
        dtype."""
        key = np.dtype(dtype).str
        cache = self.__dict__.setdefault("_by_dtype", {})
        if key not in cache:
            rot_t = np.ascontiguousarray(self._a_rot.transpose(0, 2, 1), dtype=dtype)
            a_t = np.ascontiguousarray(self._a_t, dtype=dtype)
            cache[key] = (rot_t, a_t, np.stack([_columns(r, t) for r, t in zip(rot_t, a_t,
                                                                               strict=True)]))
        return cache[key]

    def _apply(self, rot: np.ndarray, pos: np.ndarray, local: str | int, dtype) -> np.ndarray:
        """(n, 4, 4) poses ``[rot pos] @ local`` for component-major rot (3, 3, n), pos (3, n);
        ``local``: "tip" (the tip or tool frame) or a link's index in ``chain.links``."""
        n = rot.shape[2]
        both = _times(self._local_columns(local, dtype), rot.reshape(3, 3 * n))
        out = np.zeros((n, 4, 4), dtype=dtype)
        out[:, :3, :3] = both[:3].reshape(3, 3, n).transpose(2, 1, 0)
        out[:, :3, 3] = (pos + both[3].reshape(3, n)).T
        out[:, 3, 3] = 1.0
        return out

    def _local_columns(self, local: str | int, dtype) -> np.ndarray:
        """:func:`_columns` of a fixed local transform (see :meth:`_apply`), once per dtype."""
        cache = self.__dict__.setdefault("_local_by_dtype", {})
        key = (local, np.dtype(dtype).str)
        if key not in cache:
            m = self._tip if local == "tip" else self._link_local[local]
            cache[key] = _columns(m[:3, :3].T.astype(dtype), m[:3, 3].astype(dtype))
        return cache[key]

    def fk(self, q: np.ndarray, *, dtype: type = np.float64) -> np.ndarray:
        """(n, 4, 4) tip (or tool) poses for configurations q (n, dof) (or (dof,)).

        dtype : float64, or float32 for speed (about 2e-7 m error).
        """
        q = self._check_q(q)
        out = np.empty((q.shape[0], 4, 4), dtype=dtype)
        for s in range(0, q.shape[0], _CHUNK):  # blocks that stay in the CPU's cache
            rots, origins = self._frames(q[s : s + _CHUNK], dtype)
            out[s : s + _CHUNK] = self._apply(rots[-1], origins[-1], "tip", dtype)
        return out

    def link_poses(self, q: np.ndarray) -> np.ndarray:
        """(n, L, 4, 4) the pose of every link of ``chain.links`` for q (n, dof)."""
        q = self._check_q(q)
        n = q.shape[0]
        rots, origins = self._frames(q, np.float64)
        out = np.empty((n, len(self._link_local), 4, 4))
        for k, (j, local) in enumerate(zip(self._link_joint, self._link_local, strict=True)):
            if j < 0:
                out[:, k] = local
            else:
                out[:, k] = self._apply(rots[j], origins[j], k, np.float64)
        return out

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(n, 6, dof) geometric Jacobian of the tip (or tool) in the base frame: rows
        0-2 linear velocity (m/s), rows 3-5 angular velocity (rad/s) per unit joint rate."""
        return self._fk_jacobian(self._check_q(q))[1]

    def _fk_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rots, origins = self._frames(q, np.float64)
        tip = self._apply(rots[-1], origins[-1], "tip", np.float64)
        n = q.shape[0]
        jac = np.empty((self.dof, 6, n))  # component-major, transposed once at the end
        z = rots[:, 2]  # (dof, 3, n): the joint axes in the base frame
        d = tip[:, :3, 3].T - origins  # (dof, 3, n): from each joint to the tip
        jac[:, 0] = z[:, 1] * d[:, 2] - z[:, 2] * d[:, 1]
        jac[:, 1] = z[:, 2] * d[:, 0] - z[:, 0] * d[:, 2]
        jac[:, 2] = z[:, 0] * d[:, 1] - z[:, 1] * d[:, 0]
        jac[:, 3:] = z
        if self.prismatic.any():
            jac[self.prismatic, :3] = z[self.prismatic]
            jac[self.prismatic, 3:] = 0.0
        return tip, jac.transpose(2, 1, 0)

    # ------------------------------------------------------------------ inverse kinematics

    def clamp(self, q: np.ndarray) -> np.ndarray:
        """q (n, dof) clamped into the limits (continuous joints wrapped to [-pi, pi))."""
        out = np.minimum(np.maximum(q, self.lower), self.upper)
        if self._any_continuous:
            wrapped = (q + np.pi) % (2.0 * np.pi) - np.pi
            out = np.where(self.continuous, wrapped, out)
        return out

    def random_configurations(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, dof) configurations drawn uniformly within the limits from ``rng``."""
        return self.lower + rng.random((n, self.dof)) * (self.upper - self.lower)

    def ik(
        self,
        targets: np.ndarray,
        *,
        q0: np.ndarray | None = None,
        restarts: int = 5,
        rng_seed: int = 0,
        max_iterations: int = 100,
        position_tolerance: float = 1e-4,
        rotation_tolerance: float = 1e-3,
        damping: float = 0.05,
        max_step: float = 0.5,
        shared_restarts: bool = False,
    ) -> IKResult:
        """Joint values reaching each target pose, by damped least squares.

        targets : (m, 4, 4) tip (or tool) poses in the base frame, m.
        q0 : (dof,) or (m, dof) first guess (default: the middle of each joint's range).
        restarts : targets that fail from ``q0`` are retried up to this many times from
            configurations drawn uniformly within the limits by ``numpy.random
            .default_rng(rng_seed)`` (same input, same answer).
        max_iterations : per start. position_tolerance : m. rotation_tolerance : rad.
        damping : m, the damping factor lambda of ``dq = J^T (J J^T + lambda^2 I)^-1 e``.
        max_step : rad, the largest change of any joint in one iteration.
        shared_restarts : every target not reached from its first guess restarts from the same
            ``restarts`` configurations (drawn once), all in one batch: a target's answer
            does not depend on the other targets asked with it, and a few targets cost
            about two runs.
        """
        targets = np.asarray(targets, dtype=float)
        if targets.ndim == 2:
            targets = targets[None]
        if targets.ndim != 3 or targets.shape[1:] != (4, 4):
            raise RobotModelError(f"targets must have shape (m, 4, 4), got {targets.shape}")
        if not np.isfinite(targets).all():
            raise RobotModelError("targets must be finite")
        m = len(targets)
        if q0 is None:
            start = np.tile(self.chain.mid, (m, 1))
        else:
            start = np.broadcast_to(self._check_q(q0), (m, self.dof)).copy()
        if restarts < 0 or max_iterations < 1:
            raise RobotModelError("restarts must be >= 0 and max_iterations >= 1")
        rng = np.random.default_rng(rng_seed)
        shared = self.random_configurations(restarts, rng) if shared_restarts else None
        best_q = self.clamp(start)
        best_pos = np.full(m, np.inf)
        best_rot = np.full(m, np.inf)
        success = np.zeros(m, dtype=bool)
        attempts = np.zeros(m, dtype=np.int64)
        rows = np.arange(m)
        if shared is not None and restarts:  # the first guess, then every restart in one batch
            return self._ik_shared(targets, start, shared, max_iterations, position_tolerance,
                                   rotation_tolerance, damping, max_step)
        for attempt in range(restarts + 1):
            if attempt:
                rows = np.flatnonzero(~success)
                if len(rows) == 0:
                    break
                start = (self.random_configurations(len(rows), rng) if shared is None
                         else np.tile(shared[attempt - 1], (len(rows), 1)))
            q, pos_err, rot_err = self._solve(
                targets[rows], self.clamp(start), max_iterations,
                position_tolerance, rotation_tolerance, damping, max_step,
            )  # fmt: skip
            attempts[rows] += 1
            ok = (pos_err <= position_tolerance) & (rot_err <= rotation_tolerance)
            better = ok | (
                pos_err / position_tolerance + rot_err / rotation_tolerance
                < best_pos[rows] / position_tolerance + best_rot[rows] / rotation_tolerance
            )
            take = rows[better]
            best_q[take] = q[better]
            best_pos[take] = pos_err[better]
            best_rot[take] = rot_err[better]
            success[rows[ok]] = True
        return IKResult(best_q, success, best_pos, best_rot, attempts)

    def ik_from(
        self,
        targets: np.ndarray,
        starts: np.ndarray,
        *,
        first: int = 2,
        max_iterations: int = 100,
        position_tolerance: float = 1e-4,
        rotation_tolerance: float = 1e-3,
        damping: float = 0.05,
        max_step: float = 0.5,
    ) -> IKResult:
        """:meth:`ik` of targets (m, 4, 4) from given starts (m, r, dof) per target, e.g.
        the configurations whose poses lie nearest each target: the ``first`` starts of
        every target in one batch, then the others for the targets not reached, in one
        batch. A target's answer is its first start (in order) that reaches it, else the
        closest attempt; it depends on that target and its starts only."""
        targets = np.asarray(targets, dtype=float).reshape(-1, 4, 4)
        starts = np.asarray(starts, dtype=float)
        m, r = starts.shape[:2]
        if starts.shape != (len(targets), r, self.dof) or r < 1:
            raise RobotModelError(f"starts must have shape (m, r, {self.dof}), "
                                  f"got {starts.shape}")  # fmt: skip
        q = np.repeat(self.clamp(starts[:, 0]), 1, axis=0)
        pos_err = np.full(m, np.inf)
        rot_err = np.full(m, np.inf)
        ok = np.zeros(m, dtype=bool)
        attempts = np.zeros(m, dtype=np.int64)
        for lo, hi in ((0, min(first, r)), (min(first, r), r)):
            rows = np.flatnonzero(~ok)
            if hi <= lo or not len(rows):
                continue
            n = hi - lo
            flat = self.clamp(starts[rows, lo:hi].reshape(-1, self.dof))
            q2, p2, r2 = self._solve(np.repeat(targets[rows], n, axis=0), flat, max_iterations,
                                     position_tolerance, rotation_tolerance, damping, max_step,
                                     _PATIENCE, np.repeat(np.arange(len(rows)), n))
            _keep_best(q, pos_err, rot_err, ok, rows, (q2, p2, r2), n, position_tolerance,
                       rotation_tolerance)
            attempts[rows] += n
        return IKResult(q, ok, pos_err, rot_err, attempts)

    def _ik_shared(self, targets, start, shared, iterations, pos_tol, rot_tol, damping,
                   max_step) -> IKResult:
        """:meth:`ik` with ``shared_restarts``: every target from its first guess, then the
        targets not reached from each of the ``shared`` configurations (r, dof), all restarts in
        one batch (a few targets then cost about one run); a target's answer is the first
        guess's if it reaches it, else the first restart that does, else the closest attempt."""
        m, r = len(targets), len(shared)
        q, pos_err, rot_err = self._solve(targets, self.clamp(start), iterations, pos_tol,
                                          rot_tol, damping, max_step, _PATIENCE)
        ok = (pos_err <= pos_tol) & (rot_err <= rot_tol)
        attempts = np.ones(m, dtype=np.int64)
        rows = np.flatnonzero(~ok)
        if len(rows):
            starts = np.tile(self.clamp(shared), (len(rows), 1))  # row-major: (rows * r)
            q2, p2, r2 = self._solve(np.repeat(targets[rows], r, axis=0), starts, iterations,
                                     pos_tol, rot_tol, damping, max_step, _PATIENCE)
            _keep_best(q, pos_err, rot_err, ok, rows, (q2, p2, r2), r, pos_tol, rot_tol)
            attempts[rows] += r
        return IKResult(q, ok, pos_err, rot_err, attempts)

    def _solve(self, targets, q, iterations, pos_tol, rot_tol, damping, max_step,
               patience: int = 0, groups: np.ndarray | None = None):
        """One damped-least-squares run from q (k, dof) for each target; returns the final
        q (k, dof), position errors (k,) and rotation errors (k,). patience : when > 0, a
        run still more than 1 cm or 3 degrees off that gained less than 10 % in ``patience``
        iterations (stuck on a joint limit) stops there. groups : (k,) int, runs of the same target
        (different starts): once one of them reaches it, the others stop.

        Joints on a limit whose step would leave the range sit the step out: the step is solved
        again with their Jacobian columns zeroed. (Clamped afterwards, their share of the
        step was lost while the other joints moved as if it were not, so a run pressed
        against a limit converged linearly, keeping 0.65-0.9 of its error per iteration, or
        not at all.) A run whose step moves no joint by more than _STILL stops where it is:
        its next iterations would repeat this one. Every quantity is per run (row), so a
        run's values do not depend on the batch it is solved in."""
        k = len(q)
        q = q.copy()
        pos_err = np.full(k, np.inf)
        rot_err = np.full(k, np.inf)
        active = np.arange(k)
        solved = None if groups is None else np.zeros(int(groups.max()) + 1 if k else 0, bool)
        before = np.full(k, np.inf)  # with patience: each run's error when last compared
        t_pos = targets[:, :3, 3]
        t_rot = targets[:, :3, :3]
        for iteration in range(iterations + 1):
            qa = q[active]
            tip, jac = self._fk_jacobian(qa)
            e_pos = t_pos[active] - tip[:, :3, 3]
            r = tip[:, :3, :3]
            rt = t_rot[active]
            pe = np.sqrt(e_pos[:, 0] ** 2 + e_pos[:, 1] ** 2 + e_pos[:, 2] ** 2)  # not a reduction
            re = rotation_angle(r, rt)
            pos_err[active] = pe
            rot_err[active] = re
            done = (pe <= pos_tol) & (re <= rot_tol)
            if groups is not None:
                solved[groups[active[done]]] = True
                done = done | solved[groups[active]]
            if patience and iteration % patience == 0:
                cost = pe / pos_tol + re / rot_tol
                far = (pe > _STUCK_POSITION) | (re > _STUCK_ROTATION)
                # At its pace of the last `patience` iterations, would it still be 10 cm /
                # 1 rad off when the iterations run out? (A pessimistic projection: runs
                # speed up near the target, so only the hopeless are stopped.)
                pace = np.minimum(cost / before[active], 1.0)
                left = (iterations - iteration) / patience
                done |= far & ((pace > 0.9) | (cost * pace**left > 1000.0))
                before[active] = cost
            if iteration == iterations or done.all():
                break
            keep = ~done
            active, qa, jac = active[keep], qa[keep], jac[keep]
            e_pos, r, rt, pe = e_pos[keep], r[keep], rt[keep], pe[keep]
            # Orientation error: 0.5 * sum_i r_i x rt_i (axis * sin(angle) for small angles).
            # sum_i a_i x b_i = vee(B A^T - A B^T), one product instead of three crosses.
            m = rt @ np.swapaxes(r, 1, 2)
            e_rot = 0.5 * np.stack([m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0],
                                    m[:, 1, 0] - m[:, 0, 1]], axis=1)  # fmt: skip
            scale = np.minimum(1.0, 0.2 / np.maximum(pe, 1e-12))  # at most 0.2 m per step
            err = np.concatenate([e_pos * scale[:, None], e_rot], axis=1)
            # Damping shrinks with the error (Levenberg-Marquardt-like): strong far from the
            # target (stable through singularities), light near it (fast final convergence).
            # The norm is summed term by term (per row, the same in any batch).
            enorm = np.sqrt(err[:, 0] ** 2 + err[:, 1] ** 2 + err[:, 2] ** 2 + err[:, 3] ** 2
                            + err[:, 4] ** 2 + err[:, 5] ** 2)  # fmt: skip
            lam = damping * np.clip(enorm / _DAMPING_ERROR, _DAMPING_MIN, 1.0)
            dq = _damped_step(jac, err, lam)
            # Joints on a limit pushed outwards: solved again without them (see the docstring).
            outward = ((qa <= self.lower) & (dq < 0.0)) | ((qa >= self.upper) & (dq > 0.0))
            if self._any_continuous:
                outward &= ~self.continuous
            pressed = outward.any(axis=1)
            if pressed.any():
                dq[pressed] = _damped_step(jac[pressed] * ~outward[pressed][:, None, :],
                                           err[pressed], lam[pressed])  # fmt: skip
            big = np.abs(dq).max(axis=1)
            dq *= np.minimum(1.0, max_step / np.maximum(big, 1e-12))[:, None]
            q_new = self.clamp(qa + dq)
            # A run that does not move is at a fixed point: it stops, at the q its errors are of.
            moving = np.abs(q_new - qa).max(axis=1) > _STILL
            q[active[moving]] = q_new[moving]
            active = active[moving]
            if not len(active):
                break
        return q, pos_err, rot_err


def _damped_step(jac: np.ndarray, err: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """(k, dof) damped-least-squares steps ``J^T (J J^T + lam^2 I)^-1 e`` for Jacobians jac
    (k, 6, dof), errors err (k, 6) and damping factors lam (k,), one small system per row."""
    jjt = jac @ np.swapaxes(jac, 1, 2) + (lam**2)[:, None, None] * _EYE6
    return np.einsum("kji,kj->ki", jac, np.linalg.solve(jjt, err[:, :, None])[:, :, 0])


def _keep_best(q: np.ndarray, pos_err: np.ndarray, rot_err: np.ndarray, ok: np.ndarray,
               rows: np.ndarray, runs: tuple[np.ndarray, np.ndarray, np.ndarray], n: int,
               pos_tol: float, rot_tol: float) -> None:
    """Update, in place, the answers of targets ``rows`` (k,) from their ``n`` restarts each:
    ``runs`` = (q (k*n, dof), position errors (k*n,), rotation errors (k*n,)), row-major by
    target. A target takes its first restart that reaches it, else its closest one if that is
    closer (errors weighed by their tolerances) than its current answer."""
    q2, p2, r2 = runs
    q2 = q2.reshape(len(rows), n, q.shape[1])
    p2, r2 = p2.reshape(len(rows), n), r2.reshape(len(rows), n)
    good = (p2 <= pos_tol) & (r2 <= rot_tol)
    cost = p2 / pos_tol + r2 / rot_tol
    pick = np.where(good.any(axis=1), np.argmax(good, axis=1), np.argmin(cost, axis=1))
    cols = np.arange(len(rows))
    closer = good.any(axis=1) | (cost[cols, pick] < pos_err[rows] / pos_tol
                                 + rot_err[rows] / rot_tol)  # fmt: skip
    take = rows[closer]
    q[take] = q2[cols, pick][closer]
    pos_err[take] = p2[cols, pick][closer]
    rot_err[take] = r2[cols, pick][closer]
    ok[take] = good.any(axis=1)[closer]
