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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Attempt
    from handover.engine.plan.context import PlanContext
    from handover.geometry.gripper import Gripper

__all__ = ["SUPPORT_DIRECTIONS", "SUPPORT_POOL", "Support", "wrist_point", "support_poses",
           "find_support"]

SUPPORT_DIRECTIONS = 8
"""Approach directions of the supporting gripper tried around the wrist."""
SUPPORT_POOL = 64
"""How many of the best one-hand rows are tried for a support, best first."""


@dataclass(frozen=True)
class Support:
    """A supporting gripper found for one giving row.

    row : the giving row of the H1G1 decision. pose : (4, 4) the supporting gripper's grasp
    pose, object frame. width : m, the wrist's thickness it closes around. wrist : (3,) m,
    object frame, the point it holds. checked : what it was checked against, each ``True`` =
    clear. tried : rows and directions tried before it.
    """

    row: int
    pose: np.ndarray
    width: float
    wrist: np.ndarray
    checked: dict
    tried: int


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
    seed = np.array([0.0, 0.0, 1.0]) if abs(a[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(a, seed)
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


def find_support(ctx: PlanContext, attempt: Attempt) -> tuple[Support | None, str]:
    """The best row of a feasible one-hand ``attempt`` whose giving arm's wrist the other
    gripper can support, collision-free, and the support; or None and why not."""
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
    tried = 0
    for r in ranking:
        i, k = int(d.gi[r]), int(d.pk[r])
        pose_k = hands.poses[k]
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
        if ok.any():
            j = int(np.argmax(ok))
            return Support(int(r), cand[j], width, cand[j][:3, 3].copy(),
                           {name: bool(v[j]) for name, v in clear.items()},
                           tried + j), ""
        tried += len(cand)
    said = ", ".join(f"{n} ({c})" for n, c in hits.items() if c)
    return None, (f"no collision-free support at the giving wrist for the best {len(ranking)} "
                  f"one-hand grasps ({tried} support poses hit: {said})")
