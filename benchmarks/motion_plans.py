"""The arms' motion of the built-in plans: how long planning it takes on top of the plan.

    .venv/bin/python benchmarks/motion_plans.py [--runs 3] [--receivers adult,child]
        [--objects ball,hammer]

For each built-in object (and receiver), the plan is made once (warm caches), then its motion
(:func:`handover.engine.plan.motion.motion_plan`) is planned ``--runs`` times: the median wall
time, the segments and how many needed a search (OMPL's RRTConnect) rather than the straight
line, the motion's duration, and the failing segment where there is one. Target on the
reference machine: <= 1 s of motion planning per built-in plan.
"""

from __future__ import annotations

import argparse
import statistics
import time

from handover.engine.load.loader import load_kb
from handover.engine.plan.motion import motion_plan
from handover.engine.planner import plan
from handover.engine.spec.query import Query

OBJECTS = ("ball", "book", "bottle", "hammer", "knife", "mug", "pen", "scissors",
           "screwdriver", "tray")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--receivers", default="adult")
    parser.add_argument("--objects", default=",".join(OBJECTS))
    args = parser.parse_args()
    kb = load_kb()
    print(f"{'object':<12} {'receiver':<13} {'mode':<5} {'segments':>8} {'searched':>8} "
          f"{'motion s':>9} {'median s':>9}  failure")
    worst = 0.0
    for receiver in args.receivers.split(","):
        for obj in args.objects.split(","):
            planned = plan(kb, Query(object=obj, receiver=receiver))
            result = planned.result
            if result.outcome != "handover" or planned.context.arms is None:
                print(f"{obj:<12} {receiver:<13} {'-':<5} (no handover: {result.outcome})")
                continue
            times, found = [], None
            for _ in range(max(1, args.runs)):
                t = time.perf_counter()
                found = motion_plan(planned.context, planned.attempt, result.robot_grasps)
                times.append(time.perf_counter() - t)
            segments = [s for t in found.trajectories for s in t]
            searched = sum(s.planner != "direct" for s in segments)
            median = statistics.median(times)
            worst = max(worst, median)
            failure = "" if found.failure is None else found.failure.sentence()
            print(f"{obj:<12} {receiver:<13} {result.mode:<5} {len(segments):>8} "
                  f"{searched:>8} {sum(s.duration for s in segments):>9.2f} "
                  f"{median:>9.3f}  {failure}")
    print(f"slowest motion planning: {worst:.3f} s (target <= 1 s: "
          f"{'met' if worst <= 1.0 else 'MISSED'})")


if __name__ == "__main__":
    main()
