"""The arms' links in a plan: what they must not touch (:func:`link_targets`; the object
held and the hands taking it, row by row: :func:`held_contacts`), the screen of
the links fixed to the grasp frame before inverse kinematics (:func:`wrist_failures`), other
inverse-kinematics answers where the links touch something (:func:`clear_links`), the two
arms against each other (:func:`pair_contacts`), and the words the traces and reasons say
(:func:`hit_words`, :func:`links_words`, :func:`link_tally`). Used by
:mod:`handover.engine.plan.arms.solve` and :mod:`handover.engine.plan.arms.pairs`.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.arms.stages import (
    FLIP,
    STAGE_WORDS,
    ArmCheck,
    hit_words,
    objects_at,
    other_arm_idle,
    pose_key,
    row_keys,
    stage_poses,
)

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["LINK_STARTS", "LINK_POOL", "link_targets", "wrist_failures",
           "target_groups", "link_tally", "pair_contacts", "links_words", "clear_links",
           "held_contacts", "held_names", "rest_blocked"]

LINK_STARTS = 8
"""Other inverse-kinematics answers tried for a stage reached with the arm's links touching
something (in the canonical finger order, then the other): from this many of the start library's
configurations nearest the pose, those whose own links are clear first
(:meth:`~handover.engine.assets.robot.RobotArms.solve_each`)."""

LINK_POOL = 32
"""The nearest configurations of the start library :data:`LINK_STARTS` are chosen among."""

def link_targets(ctx: PlanContext, phase: Phase, side: str, stage: str):
    """What the links of the arm on ``side`` must not touch at ``stage``
    (:class:`~handover.geometry.bodies.Body`, world, names as :class:`~handover.engine.plan.world.
    World`'s): the scene's table (down to the floor) and obstacles, the receiver's body (at
    the handover without the arms that take the object: they reach for it, and their hands
    are the collision rules' concern), the robot's own body but what the arm's links
    always touch (:meth:`~handover.engine.assets.robot.RobotArms.spared`: its mount), and the other
    arm at its ``rest`` where it waits (:func:`~handover.engine.plan.arms.stages.other_arm_idle`;
    its links named ``body:robot:<link>``). Memoised in the context (one world per
    query)."""
    memo = ctx.memo.arm_link_targets
    receiving = tuple(phase.hands.receiving) if stage == "handover" else ()
    others = [o for o in ctx.arms.sides if o != side and ctx.arms.arm(o).rest is not None]
    idle = tuple(others) if other_arm_idle(phase, stage) else ()
    key = (side, receiving, idle)
    if key not in memo:
        from handover.geometry.bodies import concatenate

        body = _world_for(ctx, side, receiving)
        if idle:  # the other arm at rest, its links named as the robot's body
            body = concatenate([body, *(ctx.arms.rest_body(o).renamed("body:robot")
                                        for o in idle)])
        memo[key] = body
    return memo[key]

def _world_for(ctx: PlanContext, side: str, receiving: tuple[str, ...]):
    """The world's bodies without the receiving arms and without what the arm on ``side``
    always touches (:meth:`~handover.engine.assets.robot.RobotArms.spared`)."""
    body = ctx.world.without_receiving_arms(receiving)
    spared = {f"body:robot:{name}" for name in ctx.arms.spared(side)}
    return body.subset([name not in spared for name in body.names])

def rest_blocked(ctx: PlanContext, phase: Phase, side: str, stage: str,
                 pk: np.ndarray) -> list[tuple[tuple[str, str], ...]]:
    """Per row of presentation pk (n,): where the other arm waits at its ``rest`` while the
    arm on ``side`` works at ``stage`` (:func:`~handover.engine.plan.arms.stages.other_arm_idle`),
    the ``("rest:<other>:<link>", target)`` pairs of its links touching the scene, the
    receiver's body (without the receiving arms at the handover), the robot's own body but
    its mount, or the object held at that stage. Not empty: that arm cannot wait there, so
    the row is not held, whatever the working arm's joints (memoised per arm and pose)."""
    pk = np.asarray(pk, dtype=np.int64).reshape(-1)
    if not other_arm_idle(phase, stage):
        return [() for _ in pk]
    arms = ctx.arms
    memo = ctx.memo.rest_blocked
    receiving = tuple(phase.hands.receiving) if stage == "handover" else ()
    others = [o for o in arms.sides if o != side and arms.arm(o).rest is not None]
    world: list[tuple[str, str]] = []
    for other in others:
        key = (other, receiving)
        if key not in memo:
            found = arms.contacts(other, arms.arm(other).rest,
                                  bodies=[_world_for(ctx, other, receiving)],
                                  own_body=False)[0]
            memo[key] = tuple((f"rest:{other}:{link}", target) for link, target in found)
        world += memo[key]
    objects = objects_at(ctx, phase, stage, pk)
    name = f"object:{ctx.situation.obj.id}"
    return [tuple(world + [h for other in others for h in _rest_on_object(
        ctx, other, pose, name)]) if ctx.collider is not None else tuple(world)
        for pose in objects]

def held_names(ctx: PlanContext, phase: Phase, stage: str) -> tuple[str, ...]:
    """The targets :func:`held_contacts` tests at ``stage``: the object held
    (``object:<id>``), and at the handover the receiver's hands that take it
    (``body:receiver:<hand>_hand``)."""
    names = (f"object:{ctx.situation.obj.id}",)
    if stage == "handover":
        names += tuple(f"body:receiver:{hand}_hand" for hand in phase.hands.receiving)
    return names

def held_contacts(ctx: PlanContext, phase: Phase, side: str, stage: str, q: np.ndarray,
                  pk: np.ndarray) -> list[tuple[tuple[str, str], ...]]:
    """What :func:`link_targets` leaves out, per configuration q (n, dof) of the arm on
    ``side`` holding a row of presentation pk (n,) at ``stage``: ``(link, target)`` pairs
    where its links touch the object it holds (at the stage's pose, against its mesh:
    :class:`~handover.geometry.collision.ObjectCollider`'s ``capsules_collide`` and
    ``solids_collide``) or, at the handover, the receiver's hands that take it (their palm
    and finger boxes where the collision rules put them) and the arms reaching for it (from
    the shoulder to the palm). Links in chain order, the object first."""
    from handover.geometry.armcollision import posed_boxes, posed_capsules, segment_distances
    from handover.geometry.proximity import point_segment_distances

    arms = ctx.arms
    shapes = arms.arm(side).shapes
    q = np.atleast_2d(np.asarray(q, dtype=float))
    pk = np.asarray(pk, dtype=np.int64).reshape(-1)
    if not len(q):
        return []
    link_poses = arms.link_poses(side, q)
    objects = objects_at(ctx, phase, stage, pk)
    cap_a, cap_b = posed_capsules(shapes, link_poses)
    box_c, box_r = posed_boxes(shapes, link_poses)
    names = held_names(ctx, phase, stage)
    out = []
    for i in range(len(q)):
        touched = set()
        if ctx.collider is not None:
            collider = _placed(ctx, objects[i])
            if len(shapes.cap_link):
                hit = collider.capsules_collide(cap_a[i], cap_b[i], shapes.cap_radius)
                touched.update(shapes.cap_link[hit].tolist())
            if len(shapes.box_link):
                hit = collider.solids_collide(box_c[i], box_r[i], shapes.box_extents)
                touched.update(shapes.box_link[hit].tolist())
        found = [(shapes.links[j], names[0]) for j in sorted(touched)]
        if stage == "handover":
            for boxes, centre, reach, arm in _hand_boxes(ctx, phase, int(pk[i])):
                gap = point_segment_distances(centre, cap_a[i], cap_b[i]) - shapes.cap_radius
                near = segment_distances(cap_a[i], cap_b[i], arm.p0, arm.p1) <= (
                    shapes.cap_radius + arm.radius)
                if len(shapes.box_link) or (gap <= reach).any() or near.any():
                    hits = arms.contacts(side, q[i], boxes=boxes, bodies=[arm],
                                         own_body=False)[0]
                    found += list(dict.fromkeys(hits))
        out.append(tuple(found))
    return out

def _rest_on_object(ctx: PlanContext, other: str, pose: np.ndarray,
                    name: str) -> list[tuple[str, str]]:
    """``("rest:<other>:<link>", name)`` for the links of the arm ``other`` at its rest that
    touch the object at ``pose`` (4, 4), world (memoised per arm and pose)."""
    memo = ctx.memo.rest_on_object
    key = (other, np.round(pose, 12).tobytes())
    if key not in memo:
        body = ctx.arms.rest_body(other)
        collider = _placed(ctx, pose)
        hit = list(np.asarray(body.capsule_names)[collider.capsules_collide(
            body.p0, body.p1, body.radius)]) if len(body.capsule_names) else []
        if len(body.box_names):
            hit += list(np.asarray(body.box_names)[collider.solids_collide(
                body.poses[:, :3, 3], body.poses[:, :3, :3], body.extents)])
        memo[key] = [(f"rest:{other}:{link}", name) for link in dict.fromkeys(hit)]
    return memo[key]

def _placed(ctx: PlanContext, pose: np.ndarray):
    """The object's collider at ``pose`` (4, 4), world (memoised per pose)."""
    memo = ctx.memo.held_colliders
    key = np.round(pose, 12).tobytes()
    if key not in memo:
        memo[key] = ctx.collider.placed(pose)
    return memo[key]

def _hand_boxes(ctx: PlanContext, phase: Phase, k: int) -> list[tuple]:
    """Per receiving hand in presentation ``k``: its boxes named ``body:receiver:<hand>_hand``
    (world, at the handover), their centre and the radius of a sphere holding them (m), and
    the arm reaching for the object (a :class:`~handover.geometry.bodies.Body` of one
    capsule, ``body:receiver:<hand>_arm``, from the shoulder to the palm's centre, as thick
    as the upper arm: the elbow's bend is not known, the straight arm stands for it).
    Memoised per hands and presentation."""
    from handover.engine.plan.hand_features import hand_models
    from handover.geometry.bodies import Body
    from handover.geometry.hand import BOX_NAMES

    hands = phase.hands
    memo = ctx.memo.held_hand_boxes
    if (hands.key, k) not in memo:
        body = ctx.world.receiver_body
        out = []
        for hand, sites in zip(hands.receiving, hands.sites, strict=True):
            extents, poses, valid = hand_models(ctx, hands.region, sites, np.array([k]),
                                                hands.poses[k:k + 1])
            boxes = [(f"body:receiver:{hand}_hand", extents[0, b], poses[0, b])
                     for b in range(len(BOX_NAMES)) if valid[0, b]]
            if not boxes:
                continue
            corners = np.array([p[:3, 3] + p[:3, :3] @ (e * sign / 2.0)
                                for _, e, p in boxes for sign in _CORNERS])
            centre = corners.mean(axis=0)
            upper = body.capsule_names.index(f"{hand}_upper_arm")
            arm = Body(capsule_names=(f"body:receiver:{hand}_arm",),
                       p0=body.p0[upper][None], p1=poses[0, 0, :3, 3][None],  # palm
                       radius=body.radius[upper:upper + 1], box_names=(),
                       extents=np.zeros((0, 3)), poses=np.zeros((0, 4, 4)))
            out.append((boxes, centre, float(np.linalg.norm(corners - centre, axis=1).max()),
                        arm))
        memo[(hands.key, k)] = out
    return memo[(hands.key, k)]

_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)

def wrist_failures(ctx: PlanContext, phase: Phase, side: str, gi: np.ndarray,
                   pk: np.ndarray) -> list[str | None]:
    """A screen before inverse kinematics: per row ``(gi, pk)`` ((R,) int), the clause
    :meth:`ArmCheck.failure` would give when the arm's links rigidly attached to the grasp
    frame (:meth:`~handover.engine.assets.robot.RobotArms.distal`: its last link and flange) touch
    :func:`link_targets` at a stage of ``phase`` ("the right arm's right_link7 hits
    body:robot:torso at pick-up"), None where they are clear at every stage. Exact for
    those links: any configuration holding the row puts them there. Memoised per (arm,
    row, stages, hands)."""
    gi, pk, names, keys = row_keys(side, phase, gi, pk)
    memo = ctx.memo.arm_wrists
    todo = [r for r, key in enumerate(keys) if key not in memo]
    if todo:
        rows = np.array(todo)
        poses = stage_poses(ctx, phase, gi[rows], pk[rows])
        said: list[str | None] = [None] * len(rows)
        for stage in names:
            found = ctx.arms.distal_contacts(side, poses[stage],
                                             bodies=[link_targets(ctx, phase, side, stage)])
            for r, f in enumerate(found):
                if f and said[r] is None:
                    said[r] = f"the {side} arm's {hit_words(f)} {STAGE_WORDS[stage]}"
        for r, words in zip(todo, said, strict=True):
            memo[keys[r]] = words
    return [memo[key] for key in keys]

def target_groups(names) -> tuple[str, ...]:
    """The targets' names grouped as the traces say them: ``scene:<id>`` as they are, a
    body's parts as the body (``body:receiver:torso`` -> ``body:receiver``); the scene
    first, then the receiver, then the robot, each in order."""
    groups = dict.fromkeys(":".join(n.split(":")[:2]) for n in names)
    rank = {"scene": 0, "body:receiver": 1, "body:robot": 2}
    return tuple(sorted(groups, key=lambda g: rank.get(g.split(":")[0], rank.get(g, 3))))

_HIT = re.compile(r" hits? (\S+)")

def link_tally(failures: list[str]) -> dict[str, int]:
    """What the arms' links hit in failures of exact checks and wrist screens (clauses of
    :meth:`ArmCheck.failure`, :func:`wrist_failures` and the pair checks): target -> how
    many failures name it, most first."""
    tally: dict[str, int] = {}
    for clause in failures:
        for target in dict.fromkeys(_HIT.findall(clause)):
            tally[target] = tally.get(target, 0) + 1
    return dict(sorted(tally.items(), key=lambda kv: (-kv[1], kv[0])))

def pair_contacts(ctx: PlanContext, stage: str, a: tuple[ArmCheck, int],
                  b: tuple[ArmCheck, int], presentation: int,
                  poses_key) -> tuple[tuple[str, str], ...]:
    """Where both arms hold the object at ``stage`` (H2G2's midair regrasp, H2G1's handover
    and its pick-up by both arms): ``(link of a, "other_arm:<link of b>")`` pairs of arm a's
    links touching arm b's, each arm at its check's configuration there (``a``, ``b``:
    (check, grasp)); ``poses_key``: the phase's
    :func:`~handover.engine.plan.arms.stages.pose_key`. Memoised in the context both ways, so
    the trace of either grasp says the pair was checked (:func:`links_words`)."""
    memo = ctx.memo.arm_pairs
    (ca, ia), (cb, ib) = a, b
    key = (ca.side, ia, cb.side, ib, presentation, poses_key, stage)
    if key not in memo:
        qa, qb = ca.q[ca.stages.index(stage)], cb.q[cb.stages.index(stage)]
        found = ctx.arms.contacts(ca.side, qa, other=(cb.side, qb), own_body=False)[0]
        memo[key] = tuple((la, f"other_arm:{lb}") for la, lb in found)
        memo[(cb.side, ib, ca.side, ia, presentation, poses_key, stage)] = tuple(
            (lb, f"other_arm:{la}") for la, lb in found)
    return memo[key]

def links_words(ctx: PlanContext, phase: Phase, check: ArmCheck, grasp: int,
                presentation: int) -> str:
    """What a held grasp's arm links were found clear of, for its trace: "clear of
    scene:table, body:receiver, body:robot at pick-up and at the midair regrasp; of the
    right arm's links at the midair regrasp" (the other arm where a mode checked the pair:
    :func:`pair_contacts`)."""
    words = (f"clear of {', '.join(check.against) or 'nothing'} "
             f"{' and '.join(STAGE_WORDS[s] for s in check.stages)}")
    other = getattr(phase, "other_grasp", None)
    if other is None:
        return words
    memo = ctx.memo.arm_pairs
    for side in ctx.arms.sides:
        said = [s for s in check.stages if memo.get(
            (check.side, grasp, side, other, presentation, pose_key(phase), s)) == ()]
        if side != check.side and said:
            words += (f"; of the {side} arm's links "
                      f"{' and '.join(STAGE_WORDS[s] for s in said)}")
    return words

def clear_links(arms, side: str, body, poses: np.ndarray, rows: np.ndarray,
                 stage: tuple[np.ndarray, ...], hits: list[list[tuple]], t: int,
                 held=None) -> None:
    """At one stage: test the links of the arm at the reached ``rows`` against ``body``
    (and ``held(rows, q)``: the contacts :func:`held_contacts` finds for those rows at
    configurations q (m, dof)); for those touching something, take the first of
    :data:`LINK_STARTS` other answers in the row's finger order (``swapped``: the grasp held
    turned half a turn about ``a``; the order holds at every stage, the object held in
    between) whose links are clear, updating ``stage`` (q (n, dof), swapped (n,), position
    and rotation errors (n,), views of the stage's column) in place; ``hits[r][t]`` records
    what row r's links still touch."""
    if not len(rows):
        return
    q, swapped, pos_err, rot_err = stage

    def touching(at: np.ndarray, qs: np.ndarray) -> list[list[tuple[str, str]]]:
        found = arms.contacts(side, qs, bodies=[body], own_body=False)
        if held is not None and len(at):
            found = [[*f, *h] for f, h in zip(found, held(at, qs), strict=True)]
        return found

    found = touching(rows, q[rows])
    bad = np.array([r for r, f in zip(rows, found, strict=True) if f], dtype=np.int64)
    for r, f in zip(rows, found, strict=True):
        hits[r][t] = tuple(f)
    if not len(bad):
        return
    targets = np.where(swapped[bad, None, None], poses[bad] @ FLIP, poses[bad])  # (b, 4, 4)
    sol = arms.solve_each(side, targets, LINK_STARTS, avoid=[body], pool=LINK_POOL)
    good = np.argwhere(sol.ok)  # (g, 2): target, start
    clear = np.zeros(sol.ok.shape, dtype=bool)
    if len(good):
        touch = touching(bad[good[:, 0]], sol.q[good[:, 0], good[:, 1]])
        clear[good[:, 0], good[:, 1]] = [not f for f in touch]
    for j, r in enumerate(bad):
        if not clear[j].any():
            continue
        s = int(np.argmax(clear[j]))
        q[r] = sol.q[j, s]
        pos_err[r], rot_err[r] = sol.position_error[j, s], sol.rotation_error[j, s]
        hits[r][t] = ()
