"""Where the object goes while an arm carries it, from a plan's planned motion: the holding
arm's joint trajectory through the forward kinematics of the plan's robot, the object rigid
in the gripper (as the gripper took it at its first stage). What the physics check carries
(:func:`handover.engine.plan.physics.plan_motion`) when the plan has its motion: the arm's
joint-space path turns the object its own way between two stages, not along the shortest
turn between their orientations, and at its own pace: every sample of the trajectory, at its
time (the check's splines through them give the object the arm's accelerations).

:func:`plan_motion` gives the physics check the object's poses along a plan (its stage
poses, or the arms' paths); :func:`plan_pose` reads a pose of the plan's JSON.

A plan's JSON names each segment of a grasp's ``trajectory`` ``"<stage>-><stage>"``
(``grasp->lift``, ``lift->approach``, ``approach->handover``; an H2G2 first grasp's
``lift->midair``, its second's ``midair->approach``): a leg is the segments from the one that
leaves the stage the carry starts at to the one that reaches the stage it ends at.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.errors import UsageError

if TYPE_CHECKING:
    from handover.engine.store.kb import KB
    from handover.geometry.physics import Motion

__all__ = ["plan_pose", "plan_motion", "arm_carry", "leg_poses"]


def leg_poses(fk, grasp: dict, start: str, end: str, held_at_start: np.ndarray,
              ends_at: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The object along the segments of ``grasp``'s trajectory from the one leaving stage
    ``start`` (``lift`` for a grasp that picks the object up) to the one reaching stage
    ``end``: (k, 4, 4) world, at every sample of those segments (the last ``ends_at``
    (4, 4) exactly), and (k,) s, when (from the leg's start; each segment's times follow the
    one before it); None when the trajectory has no such segments. ``fk(q (n, dof)) ->
    (n, 4, 4)``: the arm's grasp frame in the world; ``held_at_start`` (4, 4): the object
    where the gripper holds it at the first stage of ``grasp["joints"]`` (its tool pose
    there gives the object in the tool frame)."""
    segments = grasp.get("trajectory") or []
    names = [str(s.get("segment", "")) for s in segments]
    first = next((i for i, n in enumerate(names) if n.startswith(f"{start}->")), None)
    last = next((i for i, n in enumerate(names) if n.endswith(f"->{end}")), None)
    if first is None or last is None or last < first:
        return None
    joints = grasp["joints"]
    stage = next(iter(joints))
    order = list(segments[first]["joint_names"])
    q0 = np.array([[joints[stage][n] for n in order]], dtype=float)
    in_tool = np.linalg.inv(fk(q0)[0]) @ held_at_start
    qs, ts, since = [], [], 0.0
    for i in range(first, last + 1):
        q = np.asarray(segments[i]["positions"], dtype=float)
        t = np.asarray(segments[i]["times"], dtype=float)
        if q.ndim != 2 or t.shape != (len(q),) or len(q) == 0:
            raise ValueError(f"segment {names[i]!r}: {len(t)} times for {len(q)} positions")
        keep = slice(1, None) if qs else slice(None)  # a segment starts where the last ended
        qs.append(q[keep])
        ts.append(since + t[keep] - t[0])
        since += float(t[-1] - t[0])
    q, times = np.concatenate(qs), np.concatenate(ts)
    out = fk(q) @ in_tool
    out[-1] = ends_at
    return out, times


def arm_carry(kb: KB, data: dict) -> Motion | None:
    """The object's motion along the carried legs of a plan's JSON ``data`` with its arms'
    motion: picked up at ``initial_pose``, its poses along each leg and how long each takes
    (:class:`~handover.geometry.physics.Motion`); None when the plan has no trajectory for a
    leg, or its robot has no arms in ``kb``."""
    from handover.engine.assets.robot import plan_arms
    from handover.geometry.physics import Motion

    grasps = [g for g in data.get("robot_grasps") or [] if g.get("trajectory")
              and g.get("arm") and g.get("joints")]
    robot = (data.get("robot") or {}).get("id")
    if not grasps or robot not in kb.robots:
        return None
    arms = plan_arms(kb.root, kb.robot(robot))
    if arms is None:
        return None
    initial = plan_pose(data["initial_pose"], "initial_pose")
    handover = plan_pose(data["object_pose"], "object_pose")
    lifter = next((g for g in grasps if "pickup" in g["joints"]), None)
    h2g2 = data.get("mode") == "H2G2"
    regrasp = data.get("regrasp")
    if lifter is None or (h2g2 and not (isinstance(regrasp, dict) and "midair_pose" in regrasp)):
        return None
    midair = plan_pose(regrasp["midair_pose"], "regrasp.midair_pose") if h2g2 else None
    carry = leg_poses(lambda q: arms.fk(lifter["arm"], q), lifter, "lift",
                      "midair" if h2g2 else "handover", initial,
                      midair if h2g2 else handover)
    if carry is None:
        return None
    if not h2g2:
        return Motion(initial, carry[0], carry_times=carry[1])
    taker = next((g for g in grasps if list(g["joints"])[:1] == ["midair"]), None)
    if taker is None:
        return None
    regrasp = leg_poses(lambda q: arms.fk(taker["arm"], q), taker, "midair", "handover",
                        midair, handover)
    if regrasp is None:
        return None
    return Motion(initial, carry[0], regrasp[0], carry_times=carry[1],
                  regrasp_carry_times=regrasp[1])


def plan_pose(data: Any, where: str) -> np.ndarray:
    """A pose of a plan's JSON (``where`` names it in the error) as a rigid (4, 4) matrix,
    its rotation made orthonormal again (the JSON keeps 6 decimals). Raises UsageError when
    it is not a 4x4 matrix of numbers or not a rotation and a translation."""
    try:
        m = np.asarray(data, dtype=float)
    except (TypeError, ValueError):
        m = None
    if m is None or m.shape != (4, 4) or not np.isfinite(m).all():
        raise UsageError(f"the plan's {where} must be a 4x4 matrix of numbers")
    u, sv, vt = np.linalg.svd(m[:3, :3])
    if np.abs(sv - 1.0).max() > 1e-3 or np.linalg.det(m[:3, :3]) <= 0 or \
            not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0]):
        raise UsageError(f"the plan's {where} is not a rigid transform (a rotation and a "
                         "translation)")
    m = m.copy()
    m[:3, :3] = u @ vt  # the JSON's 6 decimals, made orthonormal again
    return m


def plan_motion(data: dict, kb: KB | None = None) -> Motion:
    """The object's world poses along a plan's JSON result: pick-up at ``initial_pose``,
    carried to ``object_pose`` (through ``regrasp.midair_pose`` for H2G2; with ``kb`` and
    the plan's motion, along the arms' paths: :func:`arm_carry`). Raises UsageError when a
    pose is missing or not a rigid 4x4 matrix."""
    from handover.geometry.physics import Motion

    for key in ("initial_pose", "object_pose"):
        if data.get(key) is None:
            raise UsageError(f"the plan has no '{key}': it is not a feasible handover plan")
    pickup = plan_pose(data["initial_pose"], "initial_pose")
    handover = plan_pose(data["object_pose"], "object_pose")
    if kb is not None:
        try:
            along = arm_carry(kb, data)
        except (KeyError, TypeError, ValueError, IndexError) as e:
            raise UsageError(f"the plan's trajectory cannot be followed: {e!r}") from None
        if along is not None:
            return along
    if data.get("mode") == "H2G2":
        regrasp = data.get("regrasp")
        if not isinstance(regrasp, dict) or "midair_pose" not in regrasp:
            raise UsageError("the H2G2 plan has no 'regrasp.midair_pose'")
        midair = plan_pose(regrasp["midair_pose"], "regrasp.midair_pose")
        return Motion(pickup, midair[None], handover[None])
    return Motion(pickup, handover[None])
