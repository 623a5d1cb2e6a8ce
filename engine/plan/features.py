"""Features the rule kinds read: quantities computed on candidate rows, vectorised. Those of
the receiver's hands (their boxes, the grasp each row takes, how they fit) are in
:mod:`handover.engine.plan.hand_features`.

Each function takes the plan context and, where the answer depends on the attempt, its
:class:`~handover.engine.plan.phase.Phase` explicitly. Memoised values (the scene collision of a
grasp at pick-up, the receiver's hand boxes of one presentation) are pure functions of their
key, so memoising them never changes an outcome.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.assets.lru import LRU, content_key

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Hands
    from handover.geometry.bodies import Body
    from handover.geometry.interior import Interior

__all__ = [
    "tag_mask",
    "axis_world",
    "collision_scene",
    "collision_receiver_hand",
    "collision_other_gripper",
    "COLLISION_BITS",
    "collision_targets",
    "collision_handover",
    "handover_targets",
    "open_interior",
    "keep_out_gripper",
    "keep_out_receiver_hand",
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


def _per_row(ctx: PlanContext, memo: dict[tuple, np.ndarray], hands: Hands, gi: np.ndarray,
             pk: np.ndarray, compute) -> np.ndarray:
    """(R,) int64: ``compute(gi, pk)`` memoised per row (grasp, presentation) under the
    hands' key in ``memo`` (a field of the context's :class:`~handover.engine.plan.context.
    Memo`): a row judged by an earlier mode or an explanation is not judged again (the value
    is a pure function of the row and the hands)."""
    known = memo.get(hands.key)
    if known is None:
        known = memo[hands.key] = np.full(ctx.n * ctx.k, -1, dtype=np.int64)
    idx = np.asarray(gi, dtype=np.int64) * ctx.k + np.asarray(pk, dtype=np.int64)
    todo = np.unique(idx[known[idx] < 0])
    if len(todo):
        known[todo] = compute(todo // ctx.k, todo % ctx.k)
    return known[idx]


def collision_handover(ctx: PlanContext, hands: Hands, gi: np.ndarray,
                       pk: np.ndarray) -> np.ndarray:
    """(R,) int64 bit mask: which of :func:`handover_targets` the gripper at grasp ``gi``
    touches with the object offered in presentation ``pk`` (bit ``HANDOVER_BIT + p``).
    Memoised per row."""
    return _per_row(ctx, ctx.memo.collision_handover, hands, gi, pk,
                    lambda g, k: _collision_handover(ctx, hands, g, k))


def _collision_handover(ctx: PlanContext, hands: Hands, gi: np.ndarray,
                        pk: np.ndarray) -> np.ndarray:
    """:func:`collision_handover`, computed."""
    targets = handover_targets(ctx, hands)
    out = np.zeros(len(gi), dtype=np.int64)
    if len(targets) == 0:
        return out
    weights = np.left_shift(np.int64(1), HANDOVER_BIT + np.arange(len(targets), dtype=np.int64))
    posed = ctx.gripper_boxes()
    origin, g_reach = gripper_spheres(ctx)
    # Every gripper box lies within ``reach`` of the object frame's origin, and within
    # ``g_reach`` of its grasp's origin: a target farther (the exact distance from a point to
    # a capsule or box, not a bounding sphere: a table's sphere holds the whole room) is
    # never touched, and is not box-tested.
    reach = float(np.linalg.norm(origin[gi], axis=1).max()) + g_reach if len(gi) else 0.0
    for k in np.unique(pk):  # the targets move into the object frame, not every gripper out
        rows = np.flatnonzero(pk == k)
        pose = hands.poses[k]
        near = targets.point_distances(pose[:3, 3][None])[0] <= reach
        if not near.any():
            continue
        local = targets.subset(near).moved(np.linalg.inv(pose))
        rows = rows[(local.point_distances(origin[gi[rows]]) <= g_reach).any(axis=1)]
        if not len(rows):
            continue
        sel = gi[rows]
        hits = local.posed_hits(
            posed._replace(centres=posed.centres[sel], rotations=posed.rotations[sel]))
        out[rows] = hits.astype(np.int64) @ weights[near]
    return out


def tag_mask(ctx: PlanContext, tags, part_tags: list[set[str]] | None = None) -> np.ndarray:
    """(P,) bool: which parts carry any of ``tags`` (in ``part_tags``, default the
    context's)."""
    want = set(tags)
    return np.array([bool(t & want) for t in (part_tags or ctx.part_tags)] or [False],
                    dtype=bool)


def axis_world(ctx: PlanContext, axis: str) -> np.ndarray:
    """(K, 3) the object's named axis in the world, per presentation."""
    v = np.asarray(ctx.situation.obj.axes[axis], dtype=float)
    v = v / np.linalg.norm(v)
    return ctx.rotations @ v


def collision_scene(ctx: PlanContext, gi: np.ndarray) -> np.ndarray:
    """(R,) bool: the gripper at grasp ``gi`` collides with the scene at pick-up (the object
    at its initial pose). Memoised per candidate; computed only for candidates not yet
    known."""
    if ctx.memo.collision_scene is None:
        ctx.memo.collision_scene = np.full(ctx.n, -1, dtype=np.int8)
    known = ctx.memo.collision_scene
    todo = np.unique(gi[known[gi] < 0])
    if len(todo):
        poses = np.einsum("ij,njk->nik", ctx.initial, ctx.gripper_poses()[todo])
        hit = ctx.scene.gripper_collides(ctx.gripper, poses, ctx.candidates.width[todo])
        known[todo] = hit.astype(np.int8)
    return known[gi].astype(bool)


def collision_receiver_hand(ctx: PlanContext, hands: Hands, gi: np.ndarray,
                            pk: np.ndarray) -> np.ndarray:
    """(R,) bool: the gripper at grasp ``gi`` in presentation ``pk`` touches every grasp
    option of a receiving hand (:func:`receiver_choice`)."""
    from handover.engine.plan.hand_features import receiver_choice

    choice = receiver_choice(ctx, hands, gi, pk)
    hit = np.zeros(len(gi), dtype=bool)
    for h, sites in enumerate(hands.sites):
        hit |= (choice[:, h] < 0) & np.asarray(sites.valid, dtype=bool)[pk]
    return hit


def gripper_spheres(ctx: PlanContext) -> tuple[np.ndarray, float]:
    """(N, 3) grasp origins (object frame) and the radius (m) around each that holds every
    box of its gripper (memoised)."""
    if ctx.memo.gripper_spheres is None:
        posed = ctx.gripper_boxes()
        origin = ctx.gripper_poses()[:, :3, 3]
        if len(origin):
            spread = np.linalg.norm(posed.centres - origin[:, None, :], axis=2).max()
            reach = float(spread + 0.5 * np.linalg.norm(posed.extents, axis=1).max())
        else:
            reach = 0.0
        ctx.memo.gripper_spheres = (origin, reach)
    return ctx.memo.gripper_spheres


def collision_other_gripper(ctx: PlanContext, other: int, gi: np.ndarray) -> np.ndarray:
    """(R,) bool: the gripper at grasp ``gi`` hits the other gripper holding grasp ``other``
    (both on the object, object frame)."""
    from handover.geometry.collision import grippers_collide

    poses, widths = ctx.gripper_poses(), ctx.candidates.width
    partner = np.repeat(poses[other][None], len(gi), axis=0)
    return grippers_collide(ctx.gripper, poses[gi], widths[gi], partner,
                            np.full(len(gi), widths[other]), paired=True)


def open_interior(ctx: PlanContext, tags: tuple[str, ...]) -> Interior:
    """The openings no hand may enter (object frame): every opening of an object tagged with
    one of ``tags``, else the cavities of the hollow primitives of the parts so tagged
    (:func:`engine.assets.objects.object_interior`). Memoised per tags."""
    from handover.engine.assets.objects import object_interior

    memo = ctx.memo.interior
    key = tuple(sorted(tags))
    if key not in memo:
        obj = ctx.situation.obj
        parts = None if set(obj.tags) & set(tags) else {
            name for name, part in obj.parts.items() if set(part.tags) & set(tags)}
        memo[key] = object_interior(None, obj, ctx.part_mesh, parts=parts)
    return memo[key]


KEEP_OUT: LRU[str, np.ndarray] = LRU(16)
"""Per candidate, the gripper boxes that reach into an object's opening, by what that is a
function of (the grasps, :meth:`~handover.engine.plan.context.PlanContext.grasps_key`, and
the opening's tags), filled in as rows are asked: a warm plan of the same object and gripper
tests no box it tested before (this process's)."""


def keep_out_gripper(ctx: PlanContext, interior: Interior, key: tuple,
                     gi: np.ndarray) -> np.ndarray:
    """(R,) int64 bit mask: which of the gripper's boxes (bit b: ``gripper_boxes().names[b]``)
    at grasp ``gi`` reach into ``interior`` (object frame, :func:`open_interior` of the tags
    ``key``). Memoised per candidate under ``key``, and across plans (:data:`KEEP_OUT`)."""
    posed = ctx.gripper_boxes()
    memo = ctx.memo.keep_out_gripper
    if key not in memo:
        shared = content_key(ctx.grasps_key(), "\0".join(key))
        memo[key] = KEEP_OUT.fetch(shared, lambda: np.full(ctx.n, -1, dtype=np.int64))
    known = memo[key]
    todo = np.unique(gi[known[gi] < 0])
    if len(todo):
        mask = np.zeros(len(todo), dtype=np.int64)
        for b in range(len(posed.names)):
            enter = interior.boxes_enter(posed.centres[todo, b], posed.rotations[todo],
                                         posed.extents[b] / 2.0)
            mask |= np.where(enter, 1 << b, 0)
        known[todo] = mask
    return known[gi]


def keep_out_receiver_hand(ctx: PlanContext, hands: Hands, tags: tuple[str, ...],
                           k: int) -> tuple[str, ...]:
    """The receiver's hand boxes (``"right palm"``, ...) that reach into the openings of
    ``tags`` (:func:`open_interior`) in presentation ``k`` (memoised per hands, tags and
    presentation)."""
    key = (hands.key, tuple(sorted(tags)), k)
    found = ctx.memo.keep_out_receiver.get(key)
    if found is None:
        found = ctx.memo.keep_out_receiver[key] = _receiver_hand_entering(
            ctx, hands, open_interior(ctx, tags), k)
    return found


def _receiver_hand_entering(ctx: PlanContext, hands: Hands, interior: Interior,
                            k: int) -> tuple[str, ...]:
    """See :func:`keep_out_receiver_hand`."""
    from handover.engine.plan.hand_features import hand_model

    names, boxes = [], []
    for hand, sites in zip(hands.receiving, hands.sites, strict=False):
        for name, ext, pose in hand_model(ctx, hands.region, sites, k, hands.poses[k]):
            names.append(f"{hand} {name}")
            boxes.append((ext, np.linalg.inv(hands.poses[k]) @ pose))
    if not boxes:
        return ()
    enter = interior.boxes_enter(np.array([b[1][:3, 3] for b in boxes]),
                                 np.array([b[1][:3, :3] for b in boxes]),
                                 np.array([b[0] for b in boxes]) / 2.0)
    return tuple(n for n, e in zip(names, enter, strict=True) if e)


