"""Plans whose grasps hold in the physics check (``handover plan --physics``, the service's
``physics``): the chosen grasps checked, and when they slip or drop, in order, the next
best candidates, the plan made again without the grasps that failed, the other modes (when
the mode is the planner's to choose), and the object set down within the receiver's reach
instead. What failed on the way stays in the answer's ``physics`` block and its warnings.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.errors import UsageError
from handover.engine.spec.query import MODES, Query

if TYPE_CHECKING:
    from handover.engine.planner import Plan
    from handover.engine.store.kb import KB

__all__ = ["physics_plan", "physics_of", "convex_cache"]


def convex_cache(db=None) -> Path:
    """The folder of the physics check's convex decompositions: ``convex`` in the grasp
    database's folder (the user's default one without a database)."""
    from handover.engine.assets.graspdb import default_db_dir

    root = getattr(db, "root", None)
    return Path(root if root is not None else default_db_dir()) / "convex"


def physics_plan(kb: KB, query: Query, planned: Plan, db=None, *,
                 why_not: tuple[int, ...] = (), what_if: bool = False, motion: bool = False,
                 rounds: int | None = None):
    """A handover plan whose chosen grasps hold in physics, when one can be found: the plan
    checked (:func:`physics_of`); when its grasps fail, planned again without the grasps
    that slipped or dropped (``query`` and the options as :func:`~handover.engine.planner.
    plan` planned it; :attr:`PlanContext.passed_over
    <handover.engine.plan.context.PlanContext.passed_over>`: the next best grasps, their
    arms solved as any chosen grasp's) and checked again, at most ``rounds`` times
    (:data:`handover.engine.plan.physics.FALLBACKS`). Returns the plan to answer with (the
    first that holds; the original when none does) and its
    :class:`~handover.engine.plan.physics.PlanPhysics`: the failed checks of the grasps
    passed over, and why each was."""
    from handover.engine.plan.physics import FALLBACKS, check_plan, failing_grasps
    from handover.engine.planner import plan

    start = time.perf_counter()
    replan = partial(plan, kb, why_not=why_not, db=db, what_if=what_if, motion=motion)
    first = physics_of(kb, planned, db)
    if first.passed and first.checked.result.robust:
        return planned, first
    if first.passed:
        return _robust_instead(kb, query, planned, first, replan, db,
                               FALLBACKS if rounds is None else rounds, start)
    cache = convex_cache(db)
    site = planned.context.candidates.site

    def with_site(ids: dict[int, str]) -> dict[int, str]:
        return _on_the_same_contacts(site, ids)

    failed = [first.checked, *first.failed]
    passed_over = {}
    for group in failed:
        passed_over.update(with_site(failing_grasps(group)))
    budget = FALLBACKS if rounds is None else rounds
    for done in range(1, budget + 1):
        again = replan(query, passed_over=passed_over)
        if again.outcome != "handover":
            break
        try:
            checked = check_plan(kb, again.result.to_dict(), cache)
        except UsageError:
            break
        if checked.passed:
            tried = [g.ids for g in failed]
            notes = [f"grasp {', '.join(map(str, ids))} passed over: "
                     f"{passed_over.get(ids[0], 'failed')}" for ids in tried if ids]
            warning = ("physics: the better-scored " + "; ".join(notes) + f" (with "
                       f"{len(passed_over)} grasps on the same contacts); the plan holds with "
                       + ", ".join(f"grasp {i}" for i in checked.checked.ids))
            again.result.warnings.append(warning)
            found = replace(checked, failed=tuple(failed), seconds=time.perf_counter() - start,
                            notes=tuple(notes), passed_over=tuple(passed_over.items()))
            if checked.checked.result.robust:
                return again, found
            return _robust_instead(kb, query, again, found, replan, db, budget - done, start,
                                   passed_over)
        failed.append(checked.checked)
        more = {i: w for i, w in with_site(failing_grasps(checked.checked)).items()
                if i not in passed_over}
        if not more:
            break
        passed_over.update(more)
    tried = (f"planned again without {len(passed_over)} grasps on contacts that slipped: "
             "none found holds")
    other = _other_mode_holds(kb, query, planned, replan, db)
    if other is not None:
        again, checked = other
        said = (f"physics: no grasp of the {planned.result.mode} plan holds ({tried}); "
                f"handed in {again.result.mode} instead, whose grasps hold")
        again.result.warnings.append(said)
        return again, replace(checked, failed=tuple(failed) + checked.failed,
                              seconds=time.perf_counter() - start,
                              notes=checked.notes + (said.removeprefix("physics: "),))
    placed = _set_down_holds(kb, query, planned, tried, passed_over, why_not, db)
    if placed is not None:
        again, checked, said = placed
        again.result.warnings.append(f"physics: {said}")
        return again, replace(checked, failed=tuple(failed) + checked.failed,
                              seconds=time.perf_counter() - start,
                              notes=checked.notes + (said,))
    return planned, replace(first, failed=tuple(failed[1:]),
                            seconds=time.perf_counter() - start,
                            notes=first.notes + (f"{tried}; the plan keeps its grasps",))


def _weak_runs(check) -> str:
    """How a group that holds in the nominal run fails the ensemble: ``"friction -30 %:
    dropped in lift, force -30 %: slipped in lift (margin 0.5)"``."""
    runs = [f"{p.label}: {'dropped' if r.dropped else 'slipped'} in {r.failed_in}"
            for p, r in check.result.runs if not r.passed]
    return f"{', '.join(runs)} (margin {check.result.margin:.2f})"


def _robust_instead(kb: KB, query: Query, planned: Plan, first, replan: Callable[..., Plan],
                    db, rounds: int, start: float, passed_over: dict[int, str] | None = None):
    """When the plan's grasps hold in the nominal run but not across the ensemble (a share
    below :class:`~handover.geometry.physics.Thresholds`' ``ensemble_fraction`` of the
    perturbed runs pass): planned again without them (and every roll and depth on their
    contacts), at most ``rounds`` times, for a plan whose grasps hold in the ensemble too;
    that plan, with a warning naming what it replaced and why, or else the plan as it was,
    with a warning that its grasps hold only at the nominal friction and force. The
    built-in hammer's head grasp drops in the lift at 30 % less friction or force; its claw
    grasp, scored the same, holds in every run. ``first`` : the plan's check (its ``failed``
    and ``passed_over`` kept: the grasps passed over before it, for slipping, ``passed_over``
    too, still passed over)."""
    from handover.engine.plan.physics import check_plan

    site = planned.context.candidates.site
    passed_over = dict(passed_over or {})
    weak = [first.checked]

    def pass_over(check) -> None:
        why = f"holds, but not in the ensemble: {_weak_runs(check)}"
        ids = {int(i): why for i in check.ids if i is not None}
        passed_over.update({i: w for i, w in _on_the_same_contacts(site, ids).items()
                            if i not in passed_over})

    pass_over(first.checked)
    stopped = "no replanning was left to look for others"
    for _ in range(rounds):
        again = replan(query, passed_over=passed_over)
        if again.outcome != "handover":
            stopped = "planned again without them, nothing else is handed over"
            break
        try:
            checked = check_plan(kb, again.result.to_dict(), convex_cache(db))
        except UsageError:
            stopped = "the next plan could not be checked"
            break
        if checked.passed and checked.checked.result.robust:
            notes = tuple(f"grasp {', '.join(map(str, w.ids))} passed over: it holds, but "
                          f"not in the ensemble: {_weak_runs(w)}" for w in weak)
            again.result.warnings.extend(  # what was passed over before, for slipping
                w for w in planned.result.warnings if w.startswith("physics: "))
            again.result.warnings.append(
                "physics: " + "; ".join(notes) + "; the plan holds in the "
                f"ensemble (margin {checked.checked.result.margin:.2f}) with "
                + ", ".join(f"grasp {i}" for i in checked.checked.ids))
            return again, replace(checked, failed=first.failed,
                                  seconds=time.perf_counter() - start,
                                  notes=first.notes + notes,
                                  passed_over=tuple(passed_over.items()))
        if not checked.passed:
            stopped = "the next plan's grasps do not hold at all"
            break
        weak.append(checked.checked)
        pass_over(checked.checked)
        stopped = f"none of the {len(weak) - 1} next plans checked holds in it either"
    said = (f"physics: the plan's grasps hold, but not in the ensemble: "
            f"{_weak_runs(first.checked)}; {stopped} (run it with care: pads wet or worn, "
            "or a weaker grip, may drop it)")
    planned.result.warnings.append(said)
    return planned, replace(first, seconds=time.perf_counter() - start,
                            notes=first.notes + (said.removeprefix("physics: "),))


def _other_mode_holds(kb: KB, query: Query, planned: Plan, replan: Callable[..., Plan],
                      db=None):
    """When the query leaves the mode to the planner (``auto``) and no grasp of the plan's
    mode holds in physics: the plan of the first other mode (H1G1, H2G2, H2G1 in order,
    each planned as if forced: its hard rules, the mode rules included, still hold) that
    hands the object over with grasps that hold (:func:`physics_of`), with its check; None
    when none does. A board pinched at one edge turns out of one gripper in the shake,
    and held through a midair regrasp it does not."""
    if query.mode != "auto":
        return None
    for mode in MODES:
        if mode == "auto" or mode.upper() == planned.result.mode:
            continue
        again = replan(replace(query, mode=mode))
        if again.outcome != "handover":
            continue
        try:
            checked = physics_of(kb, again, db)
        except UsageError:
            continue
        if checked.passed:
            return again, checked
    return None


def _on_the_same_contacts(site: np.ndarray, ids: dict[int, str]) -> dict[int, str]:
    """The failing grasps ``ids`` (id -> why) and every other roll and depth on the same
    contacts (``site`` : (n,) int, the contact site of each candidate)."""
    out = {}
    for i, why in ids.items():
        out[i] = why
        for j in np.flatnonzero(site == site[i]):
            out.setdefault(int(j), f"on the contacts of grasp {i}, which {why}")
    return out


def _set_down_holds(kb: KB, query: Query, planned: Plan, tried: str,
                    passed_over: dict[int, str], why_not: tuple[int, ...] = (), db=None):
    """When the query leaves the mode to the planner (``auto``) and no mode's grasps hold in
    physics: the object set down within the receiver's reach instead
    (:func:`handover.engine.planner.set_down`) by a grasp that holds in the check, from
    pick-up to where it is set down, as (plan, its check, the sentence saying why); None
    when no such placement is found. The grasps the handover's checks saw fail
    (``passed_over``) are passed over here too, and a placement grasp that fails is passed
    over for the next, at most :data:`~handover.engine.plan.physics.FALLBACKS` times. A
    kettle of hot water whose short top handle is the receiver's is held by a handle post
    for the handover and turns in the fingers in the shake; set down, its handle toward the
    receiver, as a careful person does, it is carried there by its handle."""
    from handover.engine.plan.physics import FALLBACKS, check_plan, failing_grasps
    from handover.engine.planner import set_down

    if query.mode != "auto":
        return None
    why = (f"no grasp of the {planned.result.mode} plan, nor of another mode, holds in the "
           f"physics check ({tried})")
    passed_over = dict(passed_over)
    site = planned.context.candidates.site
    for _ in range(FALLBACKS):
        placed = set_down(kb, query, why, db=db, why_not=why_not, passed_over=passed_over)
        if placed is None:
            return None
        try:
            checked = check_plan(kb, placed.result.to_dict(), convex_cache(db))
        except UsageError:
            return None
        if checked.passed:
            return placed, checked, (f"{why}; set down within the receiver's reach instead, "
                                     "carried there by a grasp that holds")
        more = {i: w for i, w in _on_the_same_contacts(
            site, failing_grasps(checked.checked)).items() if i not in passed_over}
        if not more:
            return None
        passed_over.update(more)
    return None


def physics_of(kb: KB, planned: Plan, db=None):
    """The physics check of a handover plan's chosen grasps
    (:func:`handover.engine.plan.physics.check_plan`), and when they fail, of the next best
    candidates (:func:`~handover.engine.plan.physics.check_alternatives`)."""
    from handover.engine.plan.physics import check_alternatives, check_plan

    data = planned.result.to_dict()
    cache = convex_cache(db)
    checked = check_plan(kb, data, cache)
    return check_alternatives(kb, planned.context, data, checked, cache)
