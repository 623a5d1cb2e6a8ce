"""What would change the answer: the smallest changes that make an infeasible plan feasible.

Each change is verified by planning again with it (the same prepared context where only the
culture changes; a context prepared anew for another gripper, scene or receiver), and only
the changes that really give a feasible plan are listed, smallest first:

1. lift or loosen one non-safety rule (to the threshold the nearest candidate needs, where
   the rule has one), then another mode (when one was forced), another gripper, scene or
   receiver of the KB, then sets of several non-safety rules;
2. last, and marked ``safety: true``, sets that relax a safety rule.

The rules to relax are read from the exact decision tables of the modes tried
(:func:`engine.plan.blocking.blocking_sets`): each blocking set is a candidate change.

The changes are verified independently of each other, so they are verified in parallel where
the machine has the cores (:func:`verified`: forked processes, at most
:data:`WORKERS_ENV` of them, one per core by default); the answer is the same, to the byte,
with one process or several (each verification depends on its change alone).

>>> from handover import Planner
>>> planner = Planner()
>>> plan = planner.plan("tray", mode="h1g1", what_if=True)
>>> plan.feasible, sorted({c["kind"] for c in plan.to_dict()["what_if"]})
(False, ['mode', 'relax_rule'])
"""

from __future__ import annotations

import copy
import math
import multiprocessing
import os
import sys
import threading
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.assets.robot import RobotArms
    from handover.engine.load.loader import KB
    from handover.engine.plan.attempt import Attempt
    from handover.engine.plan.compiler import CompiledRule
    from handover.engine.plan.context import PlanContext
    from handover.engine.spec.query import Query

__all__ = ["Change", "what_if", "without_rules", "verified", "MAX_RULE_SETS", "MAX_WORKERS",
           "WORKERS_ENV"]

# How many blocking sets (of each of: without and with a safety rule) are tried.
MAX_RULE_SETS = 6
MODES = ("h1g1", "h2g2", "h2g1")
# Order of the kinds of change of the same size: a rule, then the plan's own options, then
# the world.
KIND_ORDER = {"relax_rule": 0, "mode": 1, "gripper": 2, "scene": 3, "receiver": 4}
WORKERS_ENV = "HANDOVER_WHAT_IF_WORKERS"
"""Environment variable: how many processes verify the changes (default, and for a value
that is no whole number: one per core this process may use, at most :data:`MAX_WORKERS`;
1: in this process, one after the other). Never more than the cores or the changes."""
MAX_WORKERS = 4
"""The default's bound: each forked process comes to hold its own copy of the pages it
touches (a few hundred MB for a plan's caches), and a KB offers about ten changes."""


@dataclass(frozen=True)
class Change:
    """One verified change. kind : relax_rule | mode | gripper | scene | receiver. rule : the
    rule relaxed (``a + b`` for several; None for other kinds). rules : every rule relaxed.
    safety : a safety rule is relaxed. detail : the change in words, and the plan it gives.
    size : how many things change (rules relaxed, or 1)."""

    kind: str
    rule: str | None
    safety: bool
    detail: str
    size: int = 1
    rules: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        out = {"kind": self.kind, "rule": self.rule, "safety": self.safety,
               "detail": self.detail}
        if self.rules:
            out["rules"] = list(self.rules)
        return out


def without_rules(kb: KB, rules: dict[str, object | None]) -> KB:
    """A copy of ``kb`` whose cultures drop each rule id of ``rules`` mapped to None and
    replace each mapped to a rule model (a loosened threshold). The KB itself is unchanged."""
    out = copy.copy(kb)
    out.cultures = dict(kb.cultures)
    for cid, culture in kb.cultures.items():
        if not any(r.id in rules for r in culture.rules):
            continue
        kept = [rules[r.id] if r.id in rules else r for r in culture.rules]
        out.cultures[cid] = culture.model_copy(update={"rules": [r for r in kept if r]})
    return out


def what_if(kb: KB, query: Query, ctx: PlanContext, attempt: Attempt, tried: list[Attempt],
            db=None, mesh=None) -> list[dict]:
    """The verified changes that make the infeasible plan of ``query`` feasible, smallest
    first, safety rules last (see the module docstring). ``ctx``, ``attempt``, ``tried``: the
    plan as made (:func:`engine.plan.modes.choose`); ``db``, ``mesh``: as given to the plan."""
    if attempt.feasible:
        return []
    jobs: list[Callable[[], Change | None]] = [
        partial(_relax, kb, query, ctx, rules, safety, measured)
        for rules, safety, measured in _rule_sets(tried or [attempt])]
    if query.mode != "auto":  # another forced mode
        jobs += [partial(_other_mode, kb, ctx, mode) for mode in MODES if mode != query.mode]
    jobs += [partial(_other_world, kb, kind, name, changed, db, mesh, ctx.arms_cache)
             for kind, name, changed in _world_options(kb, query)]
    changes = [c for c in verified(jobs, ctx.arms) if c is not None]
    changes.sort(key=lambda c: (c.safety, c.size, KIND_ORDER[c.kind], c.detail))
    return [c.as_dict() for c in changes]


_JOBS: list[Callable[[], Change | None]] = []  # what the forked processes verify
_ARMS: list[RobotArms] = []  # the plan's arms, whose inverse kinematics they send back


def _run_job(i: int) -> tuple[Change | None, dict]:
    arms = _ARMS[0] if _ARMS else None
    known = arms.answer_keys() if arms is not None else set()
    answer = _JOBS[i]()
    return answer, (arms.answers_since(known) if arms is not None else {})


def verified(jobs: list[Callable[[], Change | None]],
             arms: RobotArms | None = None) -> list[Change | None]:
    """Each job's answer (the change it verified, or None), in the jobs' order. With more
    than one job and more than one core (:data:`WORKERS_ENV`), the jobs run in processes
    forked from this one (they inherit the KB, the context and every cache, and send back
    the answer and the inverse-kinematics answers they solved for ``arms``, the plan's,
    which keeps them as if solved here: the next what-if is as warm as after one verified
    here); in this process, one after the other, where forking is not possible (not Linux,
    or a daemonic process, which may not have children), not safe (this process runs other
    threads) or not wanted (a service worker sets :data:`WORKERS_ENV` to 1)."""
    workers = _workers(len(jobs))
    if workers < 2:
        return [job() for job in jobs]
    _JOBS[:] = jobs
    _ARMS[:] = [arms] if arms is not None else []
    try:
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork")) as pool:
            done = list(pool.map(_run_job, range(len(jobs))))
    except BrokenProcessPool:  # a process died (killed, out of memory): verified here
        return [job() for job in jobs]
    finally:
        _JOBS.clear()
        _ARMS.clear()
    for _, solved in done:
        if arms is not None:
            arms.remember(solved)
    return [answer for answer, _ in done]


def _workers(jobs: int) -> int:
    """How many processes verify ``jobs`` changes (see :func:`verified`)."""
    if jobs < 2 or not sys.platform.startswith("linux") \
            or multiprocessing.current_process().daemon or threading.active_count() > 1:
        return 1  # a lock another thread holds would stay locked in a forked child
    asked = os.environ.get(WORKERS_ENV, "").strip()
    cores = len(os.sched_getaffinity(0))
    try:
        wanted = int(asked) if asked else min(cores, MAX_WORKERS)
    except ValueError:
        wanted = min(cores, MAX_WORKERS)
    return max(1, min(wanted, cores, jobs))


def _rule_sets(tried: list[Attempt]) -> list[tuple[list, bool, dict]]:
    """The blocking sets of every mode tried, each once: (compiled rules, safety, what each
    rule measured on the rows the set blocks), without a safety rule first, then by size
    and rows."""
    from handover.engine.plan.blocking import verified_sets

    seen: dict[tuple[str, ...], tuple[int, list, bool, dict]] = {}
    for a in tried:
        d = a.decision
        if d is None or d.n_rows == 0 or d.kept.any():
            continue
        exact = d.exact()
        by_id = {c.id: c for c in exact.hard}
        for ids, count, rows in verified_sets(d):
            rules = [by_id[i] for i in ids]
            measured = {c.id: exact.measured[c.id][rows] for c in rules
                        if c.id in exact.measured}
            best = seen.get(ids)
            if best is None or count > best[0]:
                seen[ids] = (int(count), rules, any(c.rule.safety for c in rules), measured)
    ranked = sorted(seen.items(), key=lambda kv: (kv[1][2], len(kv[0]), -kv[1][0], kv[0]))
    plain = [v[1:] for _, v in ranked if not v[2]][:MAX_RULE_SETS]
    safe = [v[1:] for _, v in ranked if v[2]][:MAX_RULE_SETS]
    return plain + safe


def _feasible(kb: KB, ctx: PlanContext, mode: str) -> Attempt | None:
    """The attempt planning ``ctx`` with ``kb`` gives, when feasible (infeasible attempts
    are not explained on the way: only feasibility is asked)."""
    from handover.engine.plan.modes import choose

    attempt, _, _ = choose(kb, ctx, mode, quick=True)
    return attempt if attempt.feasible else None


def _relax(kb: KB, query: Query, ctx: PlanContext, rules: list[CompiledRule],
           safety: bool, measured: dict[str, np.ndarray]) -> Change | None:
    """The change that relaxes ``rules`` (each to the threshold the nearest candidate needs
    where one loosened threshold does it, else lifted), verified; None when it does not
    make the plan feasible."""
    ids = tuple(c.id for c in rules)
    label = " + ".join(ids)
    loosened = {c.id: _loosened(c, measured.get(c.id)) for c in rules}
    tries = []
    if all(v is not None for v in loosened.values()):
        tries.append(({i: v[0] for i, v in loosened.items()},
                      "; ".join(f"{i}: {v[1]}" for i, v in loosened.items())))
    tries.append(({i: None for i in ids}, f"lift {label}"))
    for change, said in tries:
        attempt = _feasible(without_rules(kb, change), ctx, query.mode)
        if attempt is not None:
            marks = ", ".join(c.id for c in rules if c.rule.safety)
            warn = f" (relaxes the safety rule{'s' if ',' in marks else ''} {marks})" \
                if safety else ""
            return Change("relax_rule", label, safety,
                          f"{said}{warn}: feasible in {attempt.mode}", len(ids), ids)
    return None


def _loosened(c: CompiledRule, measured: np.ndarray | None) -> tuple[object, str] | None:
    """``c``'s rule with its one violated bound moved to the value the nearest blocked
    candidate ``measured`` (the rule's values on the rows the set blocks), and that change
    in words; None when the rule has no single numeric bound (or was not measured)."""
    rule = c.rule
    bounds = {name: value for name, value in rule.model_dump().items()
              if (name.startswith(("min", "max"))) and isinstance(value, (int, float))
              and not isinstance(value, bool)}
    if len(bounds) != 1 or measured is None:
        return None
    name, value = next(iter(bounds.items()))
    measured = np.asarray(measured, dtype=float)
    measured = measured[np.isfinite(measured)]
    if not len(measured):
        return None
    if name.startswith("max"):
        beyond = measured[measured > value]
        if not len(beyond):
            return None
        new = _outward(float(beyond.min()), up=True)
    else:
        beyond = measured[measured < value]
        if not len(beyond):
            return None
        new = _outward(float(beyond.max()), up=False)
    return rule.model_copy(update={name: new}), f"{name} {value:g} -> {new:g}"


def _outward(value: float, up: bool) -> float:
    """``value`` rounded away from the bound it must pass (3 decimals)."""
    f = math.ceil if up else math.floor
    return f(value * 1000.0 - (1e-6 if up else -1e-6)) / 1000.0


def _other_mode(kb: KB, ctx: PlanContext, mode: str) -> Change | None:
    """Another forced ``mode`` (the plan forced one), when it is feasible."""
    attempt = _feasible(kb, ctx, mode)
    if attempt is None:
        return None
    return Change("mode", None, False, f"--mode {mode}: feasible in {attempt.mode}")


def _world_options(kb: KB, query: Query) -> list[tuple[str, str, Query]]:
    """Every other gripper, scene and receiver of the KB: (kind, id, the query with it)."""
    from handover.engine.spec.query import DEFAULTS

    robot = kb.robots.get(query.robot)
    gripper = query.gripper or (robot.gripper if robot is not None else None)
    options = [("gripper", g, replace(query, gripper=g)) for g in sorted(kb.grippers)
               if g != gripper]
    options += [("scene", s, replace(query, scene=s)) for s in sorted(kb.scenes)
                if s != (query.scene or DEFAULTS["scene"])]
    options += [("receiver", r, replace(query, receiver=r)) for r in sorted(kb.receivers)
                if r != query.receiver]
    return options


def _other_world(kb: KB, kind: str, name: str, changed: Query, db, mesh,
                 arms_cache) -> Change | None:
    """The ``changed`` query (another gripper, scene or receiver), prepared with the plan's
    ``db``, ``mesh`` and ``arms_cache``, when it is feasible."""
    from handover.engine.plan.prepare import prepare

    try:
        ctx = prepare(kb, changed, db, mesh=mesh, arms_cache=arms_cache)
    except Exception:  # noqa: BLE001 - a change that cannot even be prepared is no answer
        return None
    attempt = _feasible(kb, ctx, changed.mode)
    if attempt is None:
        return None
    return Change(kind, None, False, f"--{kind} {name}: feasible in {attempt.mode}")
