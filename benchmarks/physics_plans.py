"""The physics check of plans (``handover plan --physics``): time per plan, and the analytic
``torque_limit`` rule against the simulation on the built-in objects' grasp candidates.

Run: ``.venv/bin/python benchmarks/physics_plans.py [--objects hammer,knife] [--sample 8]``

Tables:
1. each built-in object's default plan (adult receiver): its mode, the parts held, whether
   the chosen grasps hold, the slip, the ensemble's margin (6 perturbed runs), and the time
   of the check with the ensemble (wall and CPU of this process, seconds) besides the
   time of planning.
2. the torque rule against the physics: for each object, ``--sample`` candidates drawn
   (seeded) from all its geometric candidates, each carried through the default plan's
   motion alone (H1G1, the plan's presentation; no ensemble): the rule's torque (mass g
   times the lever from the grasp to the centre of mass, N m) and verdict (<= the rule's
   ``max_nm``) against the simulated verdict. Candidates whose fingers would start inside
   the object (the check refuses them) are counted apart.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402

from handover.engine.load.loader import load_kb  # noqa: E402
from handover.engine.plan.physics import (  # noqa: E402
    check_plan,
    gripper_hand,
    object_model,
    plan_motion,
)
from handover.engine.planner import plan  # noqa: E402
from handover.engine.spec.kinds.torque import GRAVITY  # noqa: E402
from handover.engine.spec.query import Query  # noqa: E402
from handover.geometry.physics import Grasp, check  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--objects", default="", help="comma-separated ids (default: all)")
    parser.add_argument("--sample", type=int, default=8, help="candidates per object")
    args = parser.parse_args()
    kb = load_kb(None)
    objects = [o for o in args.objects.split(",") if o] or sorted(kb.objects)
    limit = next(r.max_nm for c in kb.cultures.values() for r in c.rules
                 if r.id == "torque_limit")
    rng = np.random.default_rng(0)
    print("1. default plans with --physics (check = nominal + 6 ensemble runs)")
    print(f"{'object':12s} {'mode':5s} {'parts':28s} {'holds':5s} {'mm':>6s} {'deg':>6s} "
          f"{'margin':>6s} {'plan s':>7s} {'check s':>7s} {'cpu s':>6s}")
    agreement = []
    for oid in objects:
        t0 = time.perf_counter()
        planned = plan(kb, Query(oid))
        t1, c1 = time.perf_counter(), time.process_time()
        data = planned.result.to_dict()
        if data["outcome"] != "handover":
            print(f"{oid:12s} {data['outcome']}")
            continue
        ph = check_plan(kb, data)
        t2, c2 = time.perf_counter(), time.process_time()
        n = ph.checked.result.nominal
        parts = "+".join("/".join(sorted(set(g["parts"]))) for g in data["robot_grasps"])
        print(f"{oid:12s} {data['mode']:5s} {parts:28s} {str(n.passed):5s} "
              f"{n.max_translation_mm:6.2f} {n.max_rotation_deg:6.2f} "
              f"{ph.checked.result.margin:6.2f} {t1 - t0:7.2f} {t2 - t1:7.2f} {c2 - c1:6.2f}")
        # table 2's rows: sampled candidates through this plan's motion, alone
        obj = object_model(kb, kb.objects[oid])
        hand = gripper_hand(kb, kb.grippers[data["gripper"]["id"]])
        motion = plan_motion(data)
        if data["mode"] != "H1G1":  # carry to the handover pose straight from the pick-up
            from handover.geometry.physics import Motion

            motion = Motion(motion.pickup, motion.regrasp_carry if motion.regrasp_carry
                            is not None else motion.carry)
        cands = planned.context.candidates
        poses, widths, lever = cands.poses(), cands.width, cands.com_distance
        pick = rng.choice(len(cands), size=min(args.sample, len(cands)), replace=False)
        for i in np.sort(pick):
            torque = kb.objects[oid].mass * GRAVITY * float(lever[i])
            try:
                r = check(obj, [Grasp(hand, poses[i], float(widths[i]))], motion)
                verdict = r.passed
            except ValueError:
                verdict = None
            agreement.append((oid, int(i), torque, torque <= limit + 1e-12, verdict))
    print(f"\n2. torque_limit ({limit:g} N m) against the physics, sampled candidates")
    print(f"{'object':12s} {'id':>6s} {'torque':>7s} {'rule':5s} {'physics':7s}")
    for oid, i, torque, rule, verdict in agreement:
        print(f"{oid:12s} {i:6d} {torque:7.3f} {'pass' if rule else 'fail':5s} "
              f"{'-' if verdict is None else 'holds' if verdict else 'slips':7s}")
    rows = [(r, v) for *_, r, v in agreement if v is not None]
    both = sum(r and v for r, v in rows)
    print(f"\nrule pass & holds {both}, rule pass & slips {sum(r and not v for r, v in rows)}, "
          f"rule fail & holds {sum((not r) and v for r, v in rows)}, rule fail & slips "
          f"{sum((not r) and (not v) for r, v in rows)}; not simulable "
          f"{sum(v is None for *_, v in agreement)}")


if __name__ == "__main__":
    main()
