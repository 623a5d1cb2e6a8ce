"""Features the rule kinds read: quantities computed on candidate rows, vectorised.

Each function takes the plan context and, where the answer depends on the attempt, its
:class:`~handover.engine.attempt.Phase` explicitly. Memoised values (the scene collision of a
grasp at pick-up, the receiver's hand boxes of one presentation) are pure functions of their
key, so memoising them never changes an outcome.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.attempt import Hands
    from handover.engine.context import PlanContext
    from handover.engine.presentation import ReceiverRegion, ReceiverSites
    from handover.geometry.bodies import Body

__all__ = [
    "tag_mask",
    "axis_world",
    "collision_scene",
    "hand_model",
    "receiver_hand_boxes",
    "collision_receiver_hand",
    "collision_other_gripper",
    "COLLISION_BITS",
    "collision_targets",
    "collision_handover",
    "handover_targets",
]

# Bits of a collision rule's measured value: which targets were hit. At the handover, bit
# ``HANDOVER_BIT + p`` is the world's target primitive p (``scene:table``, ``body:...``).
COLLISION_BITS = {"scene": 1, "receiver_hand": 2, "other_gripper": 4}
HANDOVER_BIT = 3
LABELS = {"scene": "scene at pick-up", "receiver_hand": "receiver_hand",
          "other_gripper": "other_gripper"}


def collision_targets(measured: float, handover_names: tuple[str, ...] = ()) -> list[str]:
    """The targets a collision rule's measured bit mask names (e.g. 3 -> scene at pick-up,
    receiver_hand); ``handover_names``: the world's targets at the handover, in bit order."""
    bits = int(measured) if np.isfinite(measured) else 0
    out = [LABELS[name] for name, bit in COLLISION_BITS.items() if bits & bit]
    out += [name for p, name in enumerate(handover_names) if bits & (1 << (HANDOVER_BIT + p))]
    return out


def handover_targets(ctx: PlanContext, hands: Hands) -> Body:
    """What a gripper at the handover must not touch: the scene, the robot's body and the
    receiver's body but the arms that take the object."""
    return ctx.world.without_receiving_arms(hands.receiving)


def collision_handover(ctx: PlanContext, hands: Hands, gi: np.ndarray,
                       pk: np.ndarray) -> np.ndarray:
    """(R,) int64 bit mask: which of :func:`handover_targets` the gripper at grasp ``gi``
    touches with the object offered in presentation ``pk`` (bit ``HANDOVER_BIT + p``)."""
    targets = handover_targets(ctx, hands)
    out = np.zeros(len(gi), dtype=np.int64)
    if len(targets) == 0:
        return out
    weights = np.left_shift(np.int64(1), HANDOVER_BIT + np.arange(len(targets), dtype=np.int64))
    posed = ctx.gripper_boxes()
    for k in np.unique(pk):  # the targets move into the object frame, not every gripper out
        rows = np.flatnonzero(pk == k)
        local = targets.moved(np.linalg.inv(hands.poses[k]))
        sel = gi[rows]
        hits = local.posed_hits(
            posed._replace(centres=posed.centres[sel], rotations=posed.rotations[sel]))
        out[rows] = hits.astype(np.int64) @ weights
    return out


def tag_mask(ctx: PlanContext, tags) -> np.ndarray:
    """(P,) bool: which parts carry any of ``tags``."""
    want = set(tags)
    return np.array([bool(t & want) for t in ctx.part_tags] or [False], dtype=bool)


def axis_world(ctx: PlanContext, axis: str) -> np.ndarray:
    """(K, 3) the object's named axis in the world, per presentation."""
    v = np.asarray(ctx.situation.obj.axes[axis], dtype=float)
    v = v / np.linalg.norm(v)
    return ctx.rotations @ v


def collision_scene(ctx: PlanContext, gi: np.ndarray) -> np.ndarray:
    """(R,) bool: the gripper at grasp ``gi`` collides with the scene at pick-up (the object
    at its initial pose). Memoised per candidate; computed only for candidates not yet
    known."""
    known = ctx.memo.setdefault("collision_scene", np.full(ctx.n, -1, dtype=np.int8))
    todo = np.unique(gi[known[gi] < 0])
    if len(todo):
        poses = np.einsum("ij,njk->nik", ctx.initial, ctx.gripper_poses()[todo])
        hit = ctx.scene.gripper_collides(ctx.gripper, poses, ctx.candidates.width[todo])
        known[todo] = hit.astype(np.int8)
    return known[gi].astype(bool)


def hand_model(ctx: PlanContext, region: ReceiverRegion, sites: ReceiverSites, k: int,
               pose: np.ndarray) -> list:
    """One receiver hand (palm and finger boxes, world) at ``sites`` in presentation ``k``
    with the object at ``pose`` (4, 4); empty where that hand has no site."""
    if not sites.valid[k]:
        return []
    rot = pose[:3, :3]
    site = rot @ sites.site[k] + pose[:3, 3]
    axis = rot @ (sites.axis[k] if sites.axis is not None else region.axis)
    approach = _hand_approach(axis, ctx.situation.toward)
    return ctx.hand.boxes(site, axis, approach, float(sites.thickness[k]))


def _hand_approach(axis: np.ndarray, toward: np.ndarray) -> np.ndarray:
    """Direction the receiver's hand moves in to grasp: from the receiver toward the robot,
    made perpendicular to the part's axis; from above when the axis points at the robot."""
    move = -toward - np.dot(-toward, axis) * axis
    if np.linalg.norm(move) < 0.3:
        move = np.array([0.0, 0.0, -1.0]) - axis[2] * axis
    return move / np.linalg.norm(move)


def receiver_hand_boxes(ctx: PlanContext, hands: Hands, k: int) -> list:
    """Every receiver hand's boxes (world) at its sites in presentation ``k``."""
    memo = ctx.memo.setdefault("hand_boxes", {})
    key = (hands.key, k)
    if key not in memo:
        memo[key] = [b for sites in hands.sites
                     for b in hand_model(ctx, hands.region, sites, k, hands.poses[k])]
    return memo[key]


def collision_receiver_hand(ctx: PlanContext, hands: Hands, gi: np.ndarray,
                            pk: np.ndarray) -> np.ndarray:
    """(R,) bool: the gripper at grasp ``gi`` in presentation ``pk`` hits a receiver hand."""
    from handover.geometry.collision import BoxWorld

    out = np.zeros(len(gi), dtype=bool)
    # The grippers are posed once in the object frame; each presentation's hands are moved
    # into it (two boxes per hand, instead of every gripper into the world).
    posed = ctx.gripper_boxes()
    for k in np.unique(pk):
        rows = np.flatnonzero(pk == k)
        boxes = receiver_hand_boxes(ctx, hands, int(k))
        if not boxes:
            continue
        world = BoxWorld(boxes).moved(np.linalg.inv(hands.poses[k]))
        sel = gi[rows]
        out[rows] = world.posed_hits(
            posed._replace(centres=posed.centres[sel], rotations=posed.rotations[sel])
        ).any(axis=1)
    return out


def collision_other_gripper(ctx: PlanContext, other: int, gi: np.ndarray) -> np.ndarray:
    """(R,) bool: the gripper at grasp ``gi`` hits the other gripper holding grasp ``other``
    (both on the object, object frame)."""
    from handover.geometry.collision import grippers_collide

    poses, widths = ctx.gripper_poses(), ctx.candidates.width
    partner = np.repeat(poses[other][None], len(gi), axis=0)
    return grippers_collide(ctx.gripper, poses[gi], widths[gi], partner,
                            np.full(len(gi), widths[other]), paired=True)
