"""The arms' motion of the built-in plans as shipped: how long planning it costs a caller.

    .venv/bin/python benchmarks/motion_plans.py [--runs 3] [--receivers adult,elder]
        [--cultures common,korean] [--objects ball,hammer]

For each built-in object (and receiver, default ``adult``; and culture, default
``common``), a run plans the handover with its
motion, as ``Planner.plan(obj, motion=True)`` and ``handover plan`` do
(:func:`handover.engine.planner.plan` with ``motion=True``): the motion of the plan's chosen
grasps (:func:`handover.engine.plan.motion.motion_plan`) and, where a grasp's arm has no
motion, the plans the modes choose again without it (up to ``MOTION_TRIES``). Every call of
``motion_plan`` is timed in CPU seconds of this process (``time.process_time``: another
process on the other core does not count): ``shipped s``, the motion of the plan shipped;
``passed s``, the motion planned for plans passed over (their grasps had no motion; ``n``
how many); ``motion s``, both, what a caller pays for motion planning; ``plan s``, the whole
``plan(..., motion=True)`` call (the retry's plans without the failed grasps included).

Each run starts with new arms (a new ``arms_cache``) and a plan of the same query without
motion in them (the warm plan), so the plan's caches are warm and nothing the motion planner
solved in an earlier run (inverse kinematics is remembered) is; the best of ``--runs`` runs
(by ``motion s``) is printed. Target on the reference machine: <= 1 s of motion planning per
built-in plan (``motion s``); the slowest is printed against it.
"""

from __future__ import annotations

import argparse
import time

import handover.engine.plan.motion as motion
from handover.engine.assets.lru import LRU
from handover.engine.assets.robot import ARMS_KEPT
from handover.engine.load.loader import load_kb
from handover.engine.planner import plan
from handover.engine.spec.query import Query

OBJECTS = ("ball", "book", "bottle", "hammer", "knife", "mug", "pen", "scissors",
           "screwdriver", "tray")
TARGET = 1.0
"""s (CPU) of motion planning per built-in plan, shipped and passed over together."""


def one_run(kb, query: Query) -> dict:
    """One plan of ``query`` with motion in new arms after a warm plan without: the plan,
    the CPU seconds of each ``motion_plan`` call and its failure (None where planned), and
    the CPU seconds of the whole call."""
    cache = LRU(ARMS_KEPT)
    plan(kb, query, arms_cache=cache)  # warm: the plan's caches, not the motion's
    calls: list[tuple[float, object]] = []
    real = motion.motion_plan

    def timed(*args, **kwargs):
        began = time.process_time()
        found = real(*args, **kwargs)
        calls.append((time.process_time() - began, found.failure))
        return found

    motion.motion_plan = timed  # planner.add_motion imports it from the module per call
    try:
        began = time.process_time()
        planned = plan(kb, query, arms_cache=cache, motion=True)
        whole = time.process_time() - began
    finally:
        motion.motion_plan = real
    return {"planned": planned, "calls": calls, "whole": whole}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--receivers", default="adult")
    parser.add_argument("--cultures", default="common")
    parser.add_argument("--objects", default=",".join(OBJECTS))
    args = parser.parse_args()
    kb = load_kb()
    print(f"{'object':<12} {'receiver':<13} {'mode':<5} {'segments':>8} {'searched':>8} "
          f"{'duration':>8} {'shipped s':>9} {'passed s':>8} {'n':>2} {'motion s':>8} "
          f"{'plan s':>7}  failure / passed over")
    worst, worst_at = 0.0, "-"
    pairs = [(r, c) for c in args.cultures.split(",") for r in args.receivers.split(",")]
    for who, culture in pairs:
        receiver = who if culture == "common" else f"{who}/{culture}"  # the printed name
        for obj in args.objects.split(","):
            query = Query(object=obj, receiver=who, culture=culture)
            runs = [one_run(kb, query) for _ in range(max(1, args.runs))]
            best = min(runs, key=lambda r: sum(s for s, _ in r["calls"]))
            result = best["planned"].result
            if not best["calls"]:
                print(f"{obj:<12} {receiver:<13} {'-':<5} (no motion planned: "
                      f"{result.outcome})")
                continue
            calls = best["calls"]
            ok = calls[-1][1] is None
            shipped = calls[-1][0] if ok else 0.0
            passed = [(s, f) for s, f in calls if f is not None]
            total = sum(s for s, _ in calls)
            if total > worst:
                worst, worst_at = total, f"{obj}, {receiver}"
            segments = [s for g in result.robot_grasps for s in (g.trajectory or ())]
            searched = sum(s.planner != "direct" for s in segments)
            said = "; ".join(f.sentence() for _, f in passed)
            if not ok:
                said = "NO MOTION SHIPPED: " + said
            print(f"{obj:<12} {receiver:<13} {result.mode:<5} {len(segments):>8} "
                  f"{searched:>8} {sum(s.duration for s in segments):>8.2f} {shipped:>9.3f} "
                  f"{sum(s for s, _ in passed):>8.3f} {len(passed):>2} {total:>8.3f} "
                  f"{best['whole']:>7.3f}  {said}")
    print(f"slowest motion planning (shipped + passed over, CPU): {worst:.3f} s ({worst_at}); "
          f"target <= {TARGET:g} s: {'met' if worst <= TARGET else 'MISSED'}")


if __name__ == "__main__":
    main()
