"""Time to turn a plan's JSON result into ROS 2 messages and to write them as an MCAP bag.

Run: ``.venv/bin/python benchmarks/moveit.py [--repeat 20] [--points 100 1000 10000]``

The built-in knife (H1G1), book (H2G2) and tray for a Korean elder (H2G1) are planned once
through the CLI; then ``moveit_messages`` and ``write_mcap`` are timed (median of
``--repeat``) with the bag's size. The knife's result is then given one arm trajectory of N
points (the pick-up joints moved a little each point, as a motion planner's path would be)
to show how the CDR encoding of ``mcap-ros2-support`` (pure Python) scales. The import of
``mcap_ros2.writer`` is timed apart, in a fresh interpreter.

Numbers only; nothing here passes or fails.
"""

from __future__ import annotations

import argparse
import copy
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from handover.engine.report.moveit import moveit_messages
from handover.engine.report.rosbag import write_mcap

PLANS = {
    "knife": ["knife"],
    "book": ["book"],
    "tray elder korean": ["tray", "--receiver", "elder", "--culture", "korean"],
}
HANDOVER = Path(sys.executable).parent / "handover"


def median_ms(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def long_trajectory(result: dict, n: int) -> dict:
    out = copy.deepcopy(result)
    g = out["robot_grasps"][0]
    names = out["robot"]["arms"][g["arm"]]["joints"]
    q0 = [g["joints"]["pickup"][j] for j in names]
    g["trajectory"] = [{"segment": "path", "joint_names": names,
                        "positions": [[v + 1e-3 * k for v in q0] for k in range(n)],
                        "times": [0.01 * (k + 1) for k in range(n)]}]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--points", type=int, nargs="+", default=[100, 1000, 10000])
    args = parser.parse_args()

    code = "import time; t = time.perf_counter(); import mcap_ros2.writer; " \
           "print(time.perf_counter() - t)"
    seconds = float(subprocess.run([sys.executable, "-c", code], capture_output=True,
                                   text=True, check=True).stdout)
    print(f"import mcap_ros2.writer (fresh interpreter): {1e3 * seconds:.0f} ms")

    results = {}
    for name, plan in PLANS.items():
        out = subprocess.run([str(HANDOVER), "plan", *plan, "--json"], capture_output=True,
                             text=True, check=True).stdout
        results[name] = json.loads(out)

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "plan.mcap"
        print(f"{'plan':<20}{'grasps':>7}{'trajs':>6}{'messages ms':>13}{'write ms':>10}"
              f"{'bag bytes':>11}")
        for name, result in results.items():
            plan = moveit_messages(result)
            build = median_ms(lambda r=result: moveit_messages(r), args.repeat)
            write = median_ms(lambda r=result: write_mcap(r, path), args.repeat)
            print(f"{name:<20}{len(plan.grasps):>7}{len(plan.trajectories):>6}{build:>13.2f}"
                  f"{write:>10.2f}{path.stat().st_size:>11}")
        print(f"\n{'trajectory points':<20}{'messages ms':>13}{'write ms':>10}{'bag bytes':>11}")
        for n in args.points:
            result = long_trajectory(results["knife"], n)
            repeat = max(1, args.repeat // max(1, n // 1000))
            build = median_ms(lambda r=result: moveit_messages(r), repeat)
            write = median_ms(lambda r=result: write_mcap(r, path), repeat)
            print(f"{n:<20}{build:>13.2f}{write:>10.2f}{path.stat().st_size:>11}")


if __name__ == "__main__":
    main()
