"""The robot's arms in the two-handed modes: which pair of arms holds H2G2's two grasps (one
picks the object up and holds it at the midair pose, the other takes it there and hands it over)
and H2G1's pair (the left arm the left grasp, the right arm the right one, the lifting arm at
pick-up too), confirmed by exact inverse kinematics on the pairs that decide the plan
(:mod:`~handover.engine.plan.arms.solve`: each arm's links clear of the world). Where both arms
hold the object at the same moment (H2G2's midair regrasp, H2G1's handover, and its pick-up when
both arms lift) their links must not touch each other either
(:func:`~handover.engine.plan.arms.links.pair_contacts`): a pair whose arms collide is passed
over, its failure naming the links ("the left arm's left_link6 hits other_arm:right_link6 at the
midair regrasp")."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.arms.links import pair_contacts, wrist_failures
from handover.engine.plan.arms.solve import CONFIRM_LIMIT, confirm, preferred_sides, screen
from handover.engine.plan.arms.stages import STAGE_WORDS, hit_words, pose_key

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["FIRST_TRIES", "choose_pair_h2g2", "choose_pair_h2g1", "side_reaches"]


FIRST_TRIES = 12
"""H2G2: first grasps tried with one second grasp and one assignment of the arms."""


def choose_pair_h2g2(ctx: PlanContext, first: Phase, second: Phase, firsts: np.ndarray,
                     seconds: np.ndarray, presentations: np.ndarray, free: np.ndarray,
                     limit: int | None = None, clear=None) -> tuple[tuple | None, list[str]]:
    """H2G2's first feasible pair whose arms hold both grasps exactly: the second grasp (the
    columns of ``free`` (F, M) in order: ``seconds`` (M,) grasps in ``presentations`` (M,))
    by one arm at the midair regrasp and the handover, the first grasp (``firsts`` (F,), in
    order, those its map's core holds first, then those only its whole map holds) by the
    other arm at
    pick-up and midair. Returns ((column, first grasp, first arm, second arm) or None,
    failures met); at most ``limit`` exact checks. ``clear(m, partners) -> (P,) bool``:
    which of the first grasps ``partners`` column ``m`` may be paired with beyond ``free``
    (asked only of the columns the search reaches: the second gripper's approach)."""
    limit = CONFIRM_LIMIT if limit is None else limit
    sides = ctx.arms.sides
    failures: list[str] = []
    if len(sides) < 2:
        return None, ["H2G2 needs two arms"]
    skip: set = set()  # (arm, first grasp) that cannot pick the grasp up
    tried = 0
    for m in np.flatnonzero(free.any(axis=0)):
        i2, k = int(seconds[m]), int(presentations[m])
        gi2, pk2 = np.array([i2]), np.array([k])
        _, mapped2 = screen(ctx, second, gi2, pk2, whole=True)
        partners = firsts[free[:, m]]
        if clear is not None:
            partners = partners[clear(int(m), partners)]
            if not len(partners):
                failures.append(f"grasp {i2}: its approach at the midair pose touches "
                                "every first grasp")
                continue
        for side2 in preferred_sides(ctx, second, i2, k):
            if tried >= limit:
                return None, failures
            if not mapped2[0, sides.index(side2)].all():
                continue
            side1 = next(s for s in sides if s != side2)
            held1 = first.but(arm=side1)
            _, core1 = screen(ctx, held1, partners, np.full(len(partners), k))
            _, mapped1 = screen(ctx, held1, partners, np.full(len(partners), k), whole=True)
            deep = core1[:, 0].all(axis=1)
            wrist2 = wrist_failures(ctx, second.but(arm=side2), side2, gi2, pk2)[0]
            if wrist2 is not None:  # its wrist hits something: no inverse kinematics
                failures.append(f"grasp {i2}: {wrist2}")
                continue
            tried += 1
            c2 = confirm(ctx, second.but(arm=side2), side2, gi2, pk2)[0]
            if not c2.ok:
                failures.append(f"grasp {i2}: {c2.failure()}")
                continue
            here = 0
            held = mapped1[:, 0].all(axis=1)
            ordered = np.concatenate([partners[deep], partners[held & ~deep]])
            wrists = wrist_failures(ctx, held1, side1, ordered, np.full(len(ordered), k))
            for f, wrist1 in zip(ordered, wrists, strict=True):
                if (side1, int(f)) in skip:
                    continue
                if wrist1 is not None:
                    if len(failures) < limit:
                        failures.append(f"grasp {int(f)}: {wrist1}")
                    if wrist1.endswith(STAGE_WORDS["pickup"]):
                        skip.add((side1, int(f)))
                    continue
                if here >= FIRST_TRIES or tried >= limit:
                    break
                here += 1
                tried += 1
                c1 = confirm(ctx, held1, side1, np.array([f]), pk2)[0]
                if not c1.ok:
                    failures.append(f"grasp {int(f)}: {c1.failure()}")
                    if not c1.held[0]:
                        skip.add((side1, int(f)))
                    continue
                touch = pair_contacts(ctx, "midair", (c1, int(f)), (c2, i2), k,
                                      pose_key(second))
                if touch:
                    failures.append(_pair_failure(side1, (int(f), i2), touch, "midair"))
                    continue
                return (int(m), int(f), side1, side2), failures
    return None, failures


def choose_pair_h2g1(ctx: PlanContext, phase: Phase, pairs: list[tuple],
                     picks: dict[int, bool], both_pick: np.ndarray,
                     limit: int | None = None) -> tuple[tuple | None, list[str], list[str]]:
    """H2G1's best pair (``pairs``: (score, left grasp, right grasp, presentation, ...) best
    first) whose arms hold it exactly: the left arm its left grasp and the right arm its right
    grasp at the handover, and the lifting arm at pick-up too (both when ``both_pick``, (N,)
    bool per candidate, holds for either grasp of the pair: too heavy for one hand, or a
    squeeze, which holds nothing alone), among the hands whose gripper is free at pick-up
    (``picks``: grasp -> bool), the two arms' links clear of each other at the handover (and
    at pick-up when both lift). Returns (the pair or None, the lifting hands, failures met);
    at most ``limit`` exact checks, a grasp an arm failed to hold in a presentation not
    tried again."""
    limit = CONFIRM_LIMIT if limit is None else limit
    failures: list[str] = []
    failed: set[tuple[str, int, int]] = set()  # (arm, grasp, presentation) not held
    # (arm, grasp) that cannot take the object off the table, whatever the presentation (its
    # pick-up pose is the same in every one): the pairs it would lift are passed over before
    # their handover is checked, so the exact checks go to pairs that may lift it
    no_lift: set[tuple[str, int]] = set()
    checks = 0
    for pair in pairs:
        il, ir, k = pair[1], pair[2], pair[3]
        if ("left", il, k) in failed or ("right", ir, k) in failed:
            continue
        both = bool(both_pick[il] or both_pick[ir])
        lifters = [(side, i) for side, i in (("left", il), ("right", ir)) if picks[i]]
        known = [lifter in no_lift for lifter in lifters]
        if lifters and (any(known) if both else all(known)):
            continue  # no hand of the pair can lift it
        if checks >= limit:
            break
        held = {}
        for side, i in (("left", il), ("right", ir)):
            at = phase.but(pickup=False, arm=side)
            wrist = wrist_failures(ctx, at, side, np.array([i]), np.array([k]))[0]
            if wrist is not None:  # its wrist hits something: no inverse kinematics
                failures.append(f"grasp {i}: {wrist}")
                failed.add((side, i, k))
                break
            checks += 1
            c = confirm(ctx, at, side, np.array([i]), np.array([k]))[0]
            if not c.ok:
                failures.append(f"grasp {i}: {c.failure()}")
                failed.add((side, i, k))
                break
            held[side] = (c, i)
        if len(held) < 2:
            continue
        touch = pair_contacts(ctx, "handover", held["left"], held["right"], k, pose_key(phase))
        if touch:
            failures.append(_pair_failure("left", (il, ir), touch, "handover"))
            continue
        lifts, lifted = [], {}
        for side, (_, i) in held.items():
            if not picks[i]:
                continue
            lift = phase.but(pickup=True, arm=side)
            wrist = wrist_failures(ctx, lift, side, np.array([i]), np.array([k]))[0]
            if wrist is not None:
                failures.append(f"grasp {i}: {wrist}")
                if wrist.endswith(STAGE_WORDS["pickup"]):
                    no_lift.add((side, i))
                continue
            c = confirm(ctx, lift, side, np.array([i]), np.array([k]))[0]
            if c.ok:
                lifts.append(side)
                lifted[side] = (c, i)
            else:
                failures.append(f"grasp {i}: {c.failure()}")
                if "pickup" in c.stages and not c.held[c.stages.index("pickup")]:
                    no_lift.add((side, i))
        if both and len(lifts) == 2:
            touch = pair_contacts(ctx, "pickup", lifted["left"], lifted["right"], k,
                                  pose_key(phase))
            if touch:
                failures.append(_pair_failure("left", (il, ir), touch, "pickup"))
                continue
            return pair, lifts, failures
        if not both and lifts:
            return pair, lifts[:1], failures
    return None, [], failures


def _pair_failure(side: str, grasps: tuple[int, int], touch, stage: str) -> str:
    """"grasps 3 and 7: the left arm's left_link6 hits other_arm:right_link6 at the
    handover"."""
    return (f"grasps {grasps[0]} and {grasps[1]}: the {side} arm's {hit_words(touch)} "
            f"{STAGE_WORDS[stage]}")


def side_reaches(ctx: PlanContext, phase: Phase, side: str, gi: np.ndarray,
                 pk: np.ndarray) -> np.ndarray:
    """(R,) bool: whether the map of the arm on ``side`` holds rows ``(gi, pk)`` at every
    stage of ``phase`` (False for every row when the robot has no arm there)."""
    if side not in ctx.arms.sides:
        return np.zeros(len(gi), dtype=bool)
    return screen(ctx, phase.but(arm=side), gi, pk)[1][:, 0].all(axis=1)


