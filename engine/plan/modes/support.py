"""The supporting hand: one gripper gives (H1G1), the robot's other gripper supports the
giving arm's wrist, as a person gives with the right hand while the left supports the right
wrist or forearm (Korean etiquette accepts it where both hands would be proper).

The planner has no arm model, so the wrist is defined from the gripper's geometry (object
frame, giving grasp ``[n o a p]``):

- the flange, where the gripper is bolted to the arm, is the palm's back face:
  ``p - (finger_length / 2 + palm_a) a`` (the robot's ``tcp`` says the same: 0.11 m for the
  Robotiq-like gripper);
- the wrist is the arm's last link just behind it, a cylinder along ``-a`` as thick as the
  palm is along ``n`` (``WRIST = palm_n``); the support grasps it at ``W``, far enough
  behind the flange that the supporting gripper (its palm ``palm_n`` wide along the wrist)
  clears the giving palm by the gripper's clearance:
  ``W = flange - (palm_n / 2 + clearance) a``;
- the supporting gripper closes across the wrist (width ``WRIST``): its approach ``a_s`` is
  perpendicular to ``a``, its closing direction ``o_s = a_s x a``, so its ``n_s = a``.
  ``SUPPORT_DIRECTIONS`` approaches are tried around the wrist, the most upward in the world
  first (a hand supporting from below).

A support is kept when its gripper, with the object at the handover pose, touches neither the
object, nor the table, obstacles and bodies at the handover
(:func:`~handover.engine.plan.features.handover_targets`), nor the receiver's hands
(:func:`~handover.engine.plan.hand_features.receiver_hand_boxes`), nor the giving gripper. It joins
after pick-up (as H2G1's second hand does), so it is not checked against the table there.

With arms, both grippers are held by arms solved by exact inverse kinematics, as every other
grasp of a plan: the giving row by the arm a one-hand plan would give it
(either arm, the nearer first: :func:`~handover.engine.plan.arms.solve.confirm`), the
supporting gripper by the other arm
at the handover (:func:`support_arm`: within its joint limits, in either finger order, its
links clear of the table, obstacles and bodies, of the object and the receiver's hands, and
of the giving arm's links). A row whose support no arm reaches is passed over; when none is
left the bend is not offered, and the reason says what the arms could not do.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Attempt
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase
    from handover.geometry.gripper import Gripper

__all__ = ["SUPPORT_DIRECTIONS", "SUPPORT_POOL", "Support", "SupportArm", "wrist_point",
           "support_poses", "support_arm", "find_support"]

SUPPORT_DIRECTIONS = 8
"""Approach directions of the supporting gripper tried around the wrist."""
SUPPORT_POOL = 64
"""How many of the best one-hand rows are tried for a support, best first."""


@dataclass(frozen=True)
class SupportArm:
    """The arm that holds the supporting gripper at the handover.

    side : the arm. q : (dof,) its joint values (rad; m for a prismatic joint). swapped :
    held turned half a turn about its approach (the fingers swapped). against : what its
    links were found clear of (``scene:table``, ``body:robot``, ``object:<id>``, ...).
    giving : the side of the giving arm, whose links it was found clear of too.
    """

    side: str
    q: np.ndarray
    swapped: bool
    against: tuple[str, ...]
    giving: str


@dataclass(frozen=True)
class Support:
    """A supporting gripper found for one giving row.

    row : the giving row of the H1G1 decision. pose : (4, 4) the supporting gripper's grasp
    pose, object frame. width : m, the wrist's thickness it closes around. wrist : (3,) m,
    object frame, the point it holds. checked : what it was checked against, each ``True`` =
    clear. tried : rows and directions tried before it. giving : the giving row's arm
    check (:class:`~handover.engine.plan.arms.stages.ArmCheck`) and arm : the supporting
    arm (:class:`SupportArm`), with arms; None for a robot without arms.
    """

    row: int
    pose: np.ndarray
    width: float
    wrist: np.ndarray
    checked: dict
    tried: int
    giving: Any = None
    arm: SupportArm | None = None


def wrist_point(gripper: Gripper, grasp: np.ndarray) -> np.ndarray:
    """(..., 3) m: the giving arm's wrist point ``W`` for grasp poses ``grasp`` (..., 4, 4),
    in their frame (see the module docstring)."""
    a = grasp[..., :3, 2]
    back = gripper.finger_length / 2.0 + gripper.palm[2] + gripper.palm[0] / 2.0 \
        + gripper.clearance
    return grasp[..., :3, 3] - back * a


def support_poses(gripper: Gripper, grasp: np.ndarray, up: np.ndarray,
                  directions: int = SUPPORT_DIRECTIONS) -> np.ndarray:
    """(D, 4, 4): the supporting gripper's grasp poses around the wrist of ``grasp`` (4, 4),
    in its frame, ordered by how much their approach points along ``up`` (3,) (most upward
    first; ties by angle)."""
    a = grasp[:3, 2]
    ref = np.array([0.0, 0.0, 1.0]) if abs(a[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(a, ref)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    angles = 2.0 * np.pi * np.arange(directions) / directions
    a_s = np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2  # (D, 3) perpendicular
    order = np.lexsort((angles, -np.round(a_s @ up, 9)))
    a_s = a_s[order]
    o_s = np.cross(a_s, a)
    o_s /= np.linalg.norm(o_s, axis=1, keepdims=True)
    n_s = np.cross(o_s, a_s)  # = a
    poses = np.tile(np.eye(4), (directions, 1, 1))
    poses[:, :3, 0], poses[:, :3, 1], poses[:, :3, 2] = n_s, o_s, a_s
    poses[:, :3, 3] = wrist_point(gripper, grasp)
    return poses


def support_arm(ctx: PlanContext, phase: Phase, giving: Any, poses: np.ndarray,
                presentation: int) -> tuple[SupportArm | None, int, list[str]]:
    """The first of the supporting gripper's world poses ``poses`` (D, 4, 4) at the handover
    that the arm other than ``giving``'s (an :class:`~handover.engine.plan.arms.stages.
    ArmCheck` of the giving row in ``phase``) holds: exact inverse kinematics within its
    joint limits (the finger order nearer its start library first, then the other), its links
    clear of the world at the handover (:func:`~handover.engine.plan.arms.links.link_targets`,
    both arms working), of the object and the receiver's hands
    (:func:`~handover.engine.plan.arms.links.held_contacts`) and of the giving arm's links at
    its handover configuration. Returns (the arm or None, the index into ``poses``, the
    failures met)."""
    from handover.engine.assets.robot import IK_RESTARTS
    from handover.engine.plan.arms.links import held_contacts, link_targets, target_groups
    from handover.engine.plan.arms.stages import canonical_first, hit_words, pose_words

    arms = ctx.arms
    give = giving.side
    others = [s for s in arms.sides if s != give]
    if not others:
        return None, -1, [f"the robot has no arm besides the {give} one to support it"]
    side = others[0]
    q_give = giving.q[giving.stages.index("handover")]
    working = phase.but(mode="H2G1", arm=side)  # both arms at work: neither waits at rest
    body = link_targets(ctx, working, side, "handover")
    against = target_groups((*body.names, f"object:{ctx.situation.obj.id}",
                             *(f"body:receiver:{h}_hand" for h in phase.hands.receiving)))
    tries, turned = canonical_first(poses, arms.start_distance, side)
    failures: list[str] = []
    for j in range(len(poses)):
        for second in (False, True):
            sol = arms.solve(side, tries[int(second)][j:j + 1], restarts=IK_RESTARTS)
            if not sol.ok[0]:
                if second:
                    failures.append(f"the {side} arm cannot reach {pose_words(poses[j])} at "
                                    "the giving wrist within its joint limits")
                continue
            q = sol.q[0]
            found = arms.contacts(side, q[None], bodies=[body], own_body=False,
                                  other=(give, q_give))[0]
            found += list(held_contacts(ctx, working, side, "handover", q[None],
                                        np.array([presentation]))[0])
            if found:
                named = [(link, target if target.startswith(("scene:", "body:", "object:"))
                          else f"other_arm:{target}") for link, target in found]
                failures.append(f"the {side} arm's {hit_words(named)} at the giving wrist")
                continue
            return SupportArm(side, q, bool(turned[j] != second), against, give), j, failures
    return None, -1, failures


def find_support(ctx: PlanContext, attempt: Attempt) -> tuple[Support | None, str]:
    """The best row of a feasible one-hand ``attempt`` whose giving arm's wrist the other
    gripper can support, collision-free (with arms: both held by arms solved by inverse
    kinematics, :func:`support_arm`), and the support; or None and why not."""
    from handover.engine.plan.arms.solve import confirm, preferred_sides, reach_rule
    from handover.engine.plan.features import handover_targets
    from handover.engine.plan.hand_features import receiver_hand_boxes
    from handover.geometry.collision import BoxWorld, grippers_collide

    g = ctx.gripper
    width = float(g.palm[0])
    if width > g.max_opening + 1e-12:
        return None, (f"the gripper opens {g.max_opening:g} m, less than the wrist's "
                      f"{width:g} m")
    d, hands = attempt.decision, attempt.phase.hands
    ranking = d.ranking()[:SUPPORT_POOL]
    poses = ctx.gripper_poses()
    targets = handover_targets(ctx, hands)
    hits: dict[str, int] = {}
    armed = attempt.graph is not None and reach_rule(attempt.graph, ctx) is not None
    arm_failures: list[str] = []
    tried = 0
    for r in ranking:
        i, k = int(d.gi[r]), int(d.pk[r])
        pose_k = hands.poses[k]
        givers: list = [None]
        if armed:  # the giving row held by an arm (either, the nearer first), then supported
            givers = []
            for side in preferred_sides(ctx, attempt.phase, i, k):
                held_by = confirm(ctx, attempt.phase.but(arm=side), side, np.array([i]),
                                  np.array([k]))[0]
                if held_by.ok:
                    givers.append(held_by)
                else:
                    arm_failures.append(f"grasp {i}: {held_by.failure()}")
            if not givers:
                continue
        up = pose_k[:3, :3].T @ np.array([0.0, 0.0, 1.0])  # world up, object frame
        cand = support_poses(g, poses[i], up)
        posed = g.posed_boxes(cand, width)
        inv = np.linalg.inv(pose_k)
        clear = {
            "object": ~ctx.collider.gripper_collides(g, cand, width),
            "giving gripper": ~grippers_collide(g, np.repeat(poses[i][None], len(cand), 0),
                                                ctx.candidates.width[i], cand, width),
        }
        world = targets.moved(inv).posed_hits(posed) if len(targets) else \
            np.zeros((len(cand), 0), bool)
        clear["table, obstacles and bodies"] = ~world.any(axis=1)
        boxes = receiver_hand_boxes(ctx, hands, k, (i,))
        clear["receiver's hands"] = (~BoxWorld(boxes).moved(inv).posed_hits(posed).any(axis=1)
                                     if boxes else np.ones(len(cand), bool))
        ok = np.logical_and.reduce(list(clear.values()))
        for name, free in clear.items():
            hits[name] = hits.get(name, 0) + int((~free).sum())
        for p in np.flatnonzero(world.any(axis=0)):
            hits[targets.names[p]] = hits.get(targets.names[p], 0) + int(world[:, p].sum())
        free = np.flatnonzero(ok)
        if len(free) and armed:  # the other arm must hold one of them
            for giving in givers:
                held, j, met = support_arm(ctx, attempt.phase.but(arm=giving.side), giving,
                                           pose_k @ cand[free], k)
                arm_failures += met[:2]
                if held is not None:
                    j = int(free[j])
                    return Support(int(r), cand[j], width, cand[j][:3, 3].copy(),
                                   {name: bool(v[j]) for name, v in clear.items()},
                                   tried + j, giving, held), ""
        elif len(free):
            j = int(free[0])
            return Support(int(r), cand[j], width, cand[j][:3, 3].copy(),
                           {name: bool(v[j]) for name, v in clear.items()},
                           tried + j), ""
        tried += len(cand)
    said = ", ".join(f"{n} ({c})" for n, c in hits.items() if c)
    arms_said = ("; the arms: " + "; ".join(dict.fromkeys(arm_failures[:4]))
                 if arm_failures else "")
    return None, (f"no support at the giving wrist for the best {len(ranking)} one-hand "
                  f"grasps that is collision-free and that the arms hold ({tried} support "
                  f"poses hit: {said or 'nothing'}{arms_said})")
