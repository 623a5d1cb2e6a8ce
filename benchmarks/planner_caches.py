"""What a Planner's caches save and hold: the first plan of a new Planner (its robot's arms
loaded, their reachability maps read from the database folder) against its next plans (the
arms and maps kept), and the memory the kept maps take.

    .venv/bin/python benchmarks/planner_caches.py [--objects knife,mug,tray] [--runs 3]

Times are medians of ``--runs``; the grasp database is the default one (warm: the candidates
are read, not generated), so the difference is the arms. Wall-clock numbers on a shared
machine vary by 30-50 %; the ratio is what holds.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from handover import Planner  # noqa: E402


def seconds(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def map_bytes(planner: Planner) -> tuple[int, int]:
    """(maps kept, bytes of their bits in memory, one byte per bit) over every robot the
    planner keeps."""
    maps = [m for arms in planner.arms_cache.values() if arms is not None
            for m in arms.kept_maps]
    return len(maps), sum(m.bits.nbytes for m in maps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", default="knife,mug,tray")
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    objects = args.objects.split(",")
    Planner().plan(objects[0])  # imports, the database entries, the maps on disk
    first, warm = [], {o: [] for o in objects}
    for _ in range(args.runs):
        planner = Planner()
        first.append(seconds(lambda p=planner: p.plan(objects[0])))
        for o in objects:
            warm[o].append(seconds(lambda p=planner, o=o: p.plan(o)))
    print(f"## A Planner's arms cache (median of {args.runs} new planners, seconds)")
    print(f"first plan of a new Planner ({objects[0]}): {statistics.median(first):.3f}"
          " (loads the arms, reads their maps)")
    for o in objects:
        print(f"next plan, {o:<10} {statistics.median(warm[o]):.3f}")
    count, size = map_bytes(planner)
    print(f"kept: {len(planner.arms_cache)} robot(s) of at most {planner.arms_cache.size}, "
          f"{count} reachability maps, {size / 1e6:.1f} MB in memory")


if __name__ == "__main__":
    main()
