"""Time parameterisation of a joint-space polyline under velocity, acceleration and jerk
limits, with ruckig.

A collision-checked path is a polyline: straight pieces in joint space between waypoints.
Each piece is driven from rest to rest along its own straight line: the line is
parameterised by ``u`` in ``[0, 1]`` (``q = q_a + u (q_b - q_a)``), and ruckig plans the
time-optimal, jerk-limited motion of ``u`` from 0 to 1 under the tightest of the joints'
limits scaled to ``u`` (``v_u = min_j v_j / |q_b,j - q_a,j|``, likewise for acceleration and
jerk). Every joint then keeps within its own limits and the motion never leaves the checked
line (the same as ruckig's phase synchronisation of all joints, by construction). The arm
stops at every waypoint: the price of executing exactly the path that was checked (a blended
path would leave it near the corners). Ruckig's intermediate waypoints are not used (in the
community version they call a remote service).

Limits: velocities from the URDF (:meth:`Chain.velocity_limits
<handover.geometry.urdf.Chain.velocity_limits>`); accelerations and jerks default to
:data:`DEFAULT_ACCELERATION` and :data:`DEFAULT_JERK`, the one place these defaults are
given. Radians (metres for prismatic joints), seconds.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "DEFAULT_ACCELERATION",
    "DEFAULT_JERK",
    "DEFAULT_PERIOD",
    "time_parameterise",
]

DEFAULT_ACCELERATION = 3.0
"""rad/s^2 (m/s^2): every joint's acceleration limit unless given. URDF has no acceleration
limits; this is a fifth of the Panda's smallest published one (7.5 rad/s^2 for joint 2): a
calm motion near a person."""

DEFAULT_JERK = 30.0
"""rad/s^3 (m/s^3): every joint's jerk limit unless given (the Panda's published jerk limits
are 3750-7500 rad/s^3; a handover wants far smoother starts and stops)."""

DEFAULT_PERIOD = 0.01
"""s: the sampling period of the output trajectory, shortened where needed so that no joint
moves more than the path's resolution between two samples."""


def _limits(value: np.ndarray | float | None, default: float, dof: int, what: str) -> np.ndarray:
    out = np.full(dof, default) if value is None else np.asarray(value, dtype=float)
    out = np.broadcast_to(out, (dof,)).astype(float)
    if not (np.isfinite(out).all() and (out > 0).all()):
        raise ValueError(f"{what} limits must be positive numbers, one per joint, got {out}")
    return out


def time_parameterise(
    waypoints: np.ndarray,
    velocity: np.ndarray,
    acceleration: np.ndarray | float | None = None,
    jerk: np.ndarray | float | None = None,
    *,
    resolution: float,
    period: float = DEFAULT_PERIOD,
) -> tuple[np.ndarray, np.ndarray]:
    """Samples of the rest-to-rest motion along the polyline ``waypoints`` (see the module
    docstring).

    waypoints : (w, dof), w >= 1, rad. velocity : (dof,) rad/s, > 0. acceleration, jerk :
    (dof,) or scalar, > 0 (defaults :data:`DEFAULT_ACCELERATION`, :data:`DEFAULT_JERK`).
    resolution : rad, the largest joint step allowed between two samples. period : s, the
    longest time between two samples.
    Returns ``(positions (k, dof), times (k,))``: the first sample is the first waypoint at
    time 0, the last the last waypoint; every waypoint is a sample.
    """
    from ruckig import InputParameter, Result, Ruckig, Trajectory

    q = np.asarray(waypoints, dtype=float)
    if q.ndim != 2 or len(q) < 1 or not np.isfinite(q).all():
        raise ValueError(f"waypoints must be a finite (w, dof) array, w >= 1, got {q.shape}")
    dof = q.shape[1]
    v = _limits(velocity, 1.0, dof, "velocity")
    a = _limits(acceleration, DEFAULT_ACCELERATION, dof, "acceleration")
    j = _limits(jerk, DEFAULT_JERK, dof, "jerk")
    if not (np.isfinite(resolution) and resolution > 0 and np.isfinite(period) and period > 0):
        raise ValueError("resolution (rad) and period (s) must be positive numbers")
    # No joint moves more than `resolution` between samples: |dq_j| <= v_j dt.
    dt = min(float(period), float(resolution) / float(v.max()))
    positions = [q[:1]]
    times = [np.zeros(1)]
    clock = 0.0
    otg = Ruckig(1)
    for qa, qb in zip(q[:-1], q[1:], strict=True):
        delta = qb - qa
        span = np.abs(delta)
        moving = span > 0
        if not moving.any():
            continue
        inp = InputParameter(1)
        inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [0.0], [0.0]
        inp.target_position, inp.target_velocity, inp.target_acceleration = [1.0], [0.0], [0.0]
        inp.max_velocity = [float((v[moving] / span[moving]).min())]
        inp.max_acceleration = [float((a[moving] / span[moving]).min())]
        inp.max_jerk = [float((j[moving] / span[moving]).min())]
        trajectory = Trajectory(1)
        result = otg.calculate(inp, trajectory)
        if result not in (Result.Working, Result.Finished):
            raise ValueError(f"ruckig could not time the piece from {qa} to {qb}: {result}")
        duration = float(trajectory.duration)
        count = max(1, int(np.ceil(duration / dt - 1e-9)))
        t = np.linspace(0.0, duration, count + 1)[1:]
        u = np.array([trajectory.at_time(float(ti))[0][0] for ti in t[:-1]] + [1.0])
        positions.append(qa + np.clip(u, 0.0, 1.0)[:, None] * delta)
        times.append(clock + t)
        clock += duration
    return np.concatenate(positions), np.concatenate(times)
