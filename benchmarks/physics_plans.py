"""The physics check of plans (``handover plan --physics``): time per plan.

Run: ``.venv/bin/python benchmarks/physics_plans.py [--objects hammer,knife]``

Each built-in object's default plan (adult receiver): its mode, the parts held, whether the
chosen grasps hold, the slip, the ensemble's margin (6 perturbed runs), and the time of the
check with the ensemble (wall and CPU of this process, seconds) besides the time of
planning. The analytic holding rules against the physics, grasp by grasp:
``benchmarks/physics_rules.py``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]


from handover.engine.load.loader import load_kb  # noqa: E402
from handover.engine.plan.physics import (  # noqa: E402
    check_plan,
)
from handover.engine.planner import plan  # noqa: E402
from handover.engine.spec.query import Query  # noqa: E402
from handover.engine.tools.holding import convex_cache  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--objects", default="", help="comma-separated ids (default: all)")
    args = parser.parse_args()
    kb = load_kb(None)
    objects = [o for o in args.objects.split(",") if o] or sorted(kb.objects)
    print("1. default plans with --physics (check = nominal + 6 ensemble runs)")
    print(f"{'object':12s} {'mode':5s} {'parts':28s} {'holds':5s} {'mm':>6s} {'deg':>6s} "
          f"{'margin':>6s} {'plan s':>7s} {'check s':>7s} {'cpu s':>6s}")
    for oid in objects:
        t0 = time.perf_counter()
        planned = plan(kb, Query(oid))
        t1, c1 = time.perf_counter(), time.process_time()
        data = planned.result.to_dict()
        if data["outcome"] != "handover":
            print(f"{oid:12s} {data['outcome']}")
            continue
        ph = check_plan(kb, data, convex_cache())
        t2, c2 = time.perf_counter(), time.process_time()
        n = ph.checked.result.nominal
        parts = "+".join("/".join(sorted(set(g["parts"]))) for g in data["robot_grasps"])
        print(f"{oid:12s} {data['mode']:5s} {parts:28s} {str(n.passed):5s} "
              f"{n.max_translation_mm:6.2f} {n.max_rotation_deg:6.2f} "
              f"{ph.checked.result.margin:6.2f} {t1 - t0:7.2f} {t2 - t1:7.2f} {c2 - c1:6.2f}")


if __name__ == "__main__":
    main()
