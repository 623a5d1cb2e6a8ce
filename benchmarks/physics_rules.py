"""The analytic holding rules (``kind: torque``: twist, tip, weight, derived from the
gripper's grip force and friction) against the physics check, grasp by grasp.

Run: ``.venv/bin/python benchmarks/physics_rules.py [--objects hammer,tray] [--top 6]``

For every built-in object and a few written here (a 45 cm steel bar, a 1.2 m broomstick, a
dinner plate, a heavy box, a closed laptop, a long wooden board), the default plan (adult
receiver) gives a motion (pick-up to the handover pose) and a presentation. Its candidates
within the gripper's opening are judged by the KB's hard ``torque`` rules at that
presentation (exactly as the planner judges them) and split into those the rules keep and
those they reject; the ``--top`` best of each (by grasp quality, then nearest the centre of
mass for those kept and farthest for those rejected, so both sides of the limit are seen)
are simulated alone (H1G1, the nominal run, no ensemble). The table prints each grasp's use
of what the pads hold per rule, the rules' verdict, the physics verdict (holds / slips /
drops, the slip in mm and deg) and whether they agree; then the counts. Candidates whose
fingers would start inside the object (the check refuses them) are counted apart. The
broomstick is the known disagreement: held at its middle it turns in the shake (+-15 deg at
2 Hz about the closing axis: its inertia about that line, 0.048 kg m^2, asks 2 N m of twist
against the pads' 0.9), which the rules, judging the weight alone, keep.

Then the squeeze (two arms pressing closed jaws on opposite faces, H2G1): crates written
here too wide for the gripper, each planned with the shipped robot; the chosen pair judged
by the holding rules and simulated at several squeeze forces (the robot's ``squeeze_force``
replaced; the pair is the plan's at the strongest), the rules' verdict against the
physics.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402

from handover.engine.load.loader import load_kb  # noqa: E402
from handover.engine.plan.judge.torque import uses  # noqa: E402
from handover.engine.plan.physics import gripper_hand, object_model, plan_motion  # noqa: E402
from handover.engine.planner import plan  # noqa: E402
from handover.engine.spec.query import Query  # noqa: E402
from handover.engine.tools.holding import convex_cache  # noqa: E402
from handover.geometry.physics import Grasp, Motion, check  # noqa: E402

SQUEEZED = ("crate", "big_crate")
FORCES = (10.0, 15.0, 20.0, 30.0, 45.0)

OWN_OBJECTS = {
    "steel_bar": """id: steel_bar
name: Steel bar (45 cm, 2 x 2 cm)
mass: 1.2
tags: [tool]
geometry:
  primitives:
    - {shape: box, part: bar, extents: [0.45, 0.02, 0.02], position: [0, 0, 0.01]}
parts:
  bar: {tags: [handle]}
""",
    "broomstick": """id: broomstick
name: Broomstick (1.2 m, 25 mm, wood), across the table (along it, it cannot lie there)
mass: 0.4
tags: [tool]
geometry:
  primitives:
    - {shape: cylinder, part: stick, radius: 0.0125, height: 1.2, position: [0, 0, 0.0125],
       rotation_deg: [90, 0, 0]}
parts:
  stick: {tags: [handle]}
""",
    "plate": """id: plate
name: Dinner plate (26 cm, loaded)
mass: 0.6
tags: [plate]
geometry:
  primitives:
    - {shape: cylinder, part: plate, radius: 0.13, height: 0.012, position: [0, 0, 0.006]}
parts:
  plate: {tags: [rim]}
axes:
  up: [0, 0, 1]
""",
    "heavy_box": """id: heavy_box
name: Box of screws (12 x 6 x 6 cm)
mass: 1.4
tags: [box]
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.12, 0.06, 0.06], position: [0, 0, 0.03]}
parts:
  body: {tags: [body]}
""",
    "crate": """id: crate
name: Crate (25 x 30 x 15 cm)
mass: 1.2
tags: [box, flat]
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.25, 0.3, 0.15], position: [0, 0, 0.075]}
parts:
  body: {tags: [body]}
""",
    "big_crate": """id: big_crate
name: Crate (30 x 40 x 20 cm)
mass: 1.2
tags: [box, flat]
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.3, 0.4, 0.2], position: [0, 0, 0.1]}
parts:
  body: {tags: [body]}
""",
    "laptop": """id: laptop
name: Closed laptop (23 x 33 x 1.8 cm)
mass: 1.3
tags: [flat]
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.23, 0.33, 0.018], position: [0, 0, 0.009]}
parts:
  body: {tags: [body]}
""",
    "board": """id: board
name: Oak board (60 x 8 x 2 cm)
mass: 0.9
tags: [board]
geometry:
  primitives:
    - {shape: box, part: board, extents: [0.6, 0.08, 0.02], position: [0, 0, 0.01]}
parts:
  board: {tags: [board]}
""",
}


def _kb_with_own_objects(folder: Path):
    root = folder / "kb"
    shutil.copytree(Path(load_kb(None).root), root)
    for oid, text in OWN_OBJECTS.items():
        (root / "objects" / f"{oid}.yaml").write_text(text)
    return load_kb(root)


def _pick(cands, use: np.ndarray, kept: np.ndarray, top: int) -> list[int]:
    """The ``top`` best kept and ``top`` best rejected rows (quality first; the kept
    nearest the centre of mass, the rejected farthest, first)."""
    out = []
    for side, sign in ((kept, 1.0), (~kept, -1.0)):
        rows = np.flatnonzero(side)
        order = np.lexsort((sign * cands.com_distance[rows], -np.round(cands.quality[rows], 2)))
        out += [int(r) for r in rows[order][:top]]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--objects", default="", help="comma-separated ids (default: all)")
    parser.add_argument("--top", type=int, default=6, help="candidates per verdict and object")
    parser.add_argument("--load-factor", type=float, default=None,
                        help="judge with this load factor instead of the rules' own")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        kb = _kb_with_own_objects(Path(tmp))
        objects = [o for o in args.objects.split(",") if o] or sorted(
            o for o in kb.objects if o not in SQUEEZED)
        rules = [r for r in kb.cultures["common"].rules if r.kind == "torque" and r.hard]
        if args.load_factor is not None:
            rules = [r.model_copy(update={"load_factor": args.load_factor}) for r in rules]
        names = [r.id for r in rules]
        print(f"{'object':11s} {'id':>5s} {'parts':14s} " + " ".join(f"{n[:9]:>9s}" for n in
                                                                   names)
              + f" {'rules':5s} {'physics':7s} {'mm':>6s} {'deg':>6s} agree")
        counts = {(a, b): 0 for a in (True, False) for b in (True, False)}
        refused = 0
        seconds = []
        for oid in objects:
            planned = plan(kb, Query(oid))
            data = planned.result.to_dict()
            if data["outcome"] != "handover":
                print(f"{oid:11s} {data['outcome']}: no plan to take the motion from")
                continue
            ctx = planned.context
            motion = plan_motion(data)
            if motion.regrasp_carry is not None:  # H2G2: straight to the handover pose
                motion = Motion(motion.pickup, motion.regrasp_carry)
            k = int(data["presentation"]["index"])
            cands = ctx.candidates
            fits = np.flatnonzero(cands.width <= ctx.gripper.max_opening + 1e-12)
            pk = np.full(len(fits), k)
            use = np.stack([uses(r, ctx, fits, pk, np.ones(len(fits))) for r in rules], 1)
            kept = (use <= 1.0 + 1e-12).all(axis=1)
            obj = object_model(kb, kb.objects[oid], convex_cache())
            hand = gripper_hand(kb, ctx.situation.gripper)
            poses = ctx.gripper_poses()
            for j in _pick(cands.take(fits), use, kept, args.top):
                i = int(fits[j])
                parts = "/".join(sorted({cands.part_names[p] for p in cands.parts[i]}))
                t0 = time.perf_counter()
                try:
                    r = check(obj, [Grasp(hand, poses[i], float(cands.width[i]))], motion)
                except ValueError:
                    refused += 1
                    continue
                seconds.append(time.perf_counter() - t0)
                verdict = "holds" if r.passed else "drops" if r.dropped else "slips"
                agree = bool(kept[j]) == r.passed
                counts[(bool(kept[j]), r.passed)] += 1
                print(f"{oid:11s} {i:5d} {parts[:14]:14s} "
                      + " ".join(f"{u:9.2f}" for u in use[j])
                      + f" {'keep' if kept[j] else 'rej':5s} {verdict:7s} "
                      f"{min(r.max_translation_mm, 999):6.1f} {r.max_rotation_deg:6.1f} "
                      f"{'yes' if agree else 'NO'}")
        total = sum(counts.values())
        agree = counts[(True, True)] + counts[(False, False)]
        print(f"\nkept & holds {counts[(True, True)]}, kept & fails {counts[(True, False)]}, "
              f"rejected & holds {counts[(False, True)]}, rejected & fails "
              f"{counts[(False, False)]}; agreement {agree}/{total}"
              f" ({100.0 * agree / max(total, 1):.0f} %); of the kept, "
              f"{counts[(True, True)]}/{counts[(True, True)] + counts[(True, False)]} hold; "
              f"not simulable {refused}; {np.median(seconds):.3f} s median per check")
        squeeze_table(kb, rules)


def squeeze_table(kb, rules) -> None:
    """The squeeze pairs of :data:`SQUEEZED`: rules against physics at each of :data:`FORCES`."""
    from dataclasses import replace

    from handover.engine.plan.judge.torque import pair_uses

    print("\nsqueeze (H2G1, closed jaws on opposite faces), squeeze force N per arm")
    print(f"{'object':11s} {'force':>5s} " + " ".join(f"{n[:9]:>9s}" for n in
                                                     [r.id for r in rules])
          + f" {'rules':5s} {'physics':7s} {'mm':>6s} {'deg':>6s} agree")
    robot_id = kb.robots[next(iter(kb.robots))].id
    for oid in SQUEEZED:
        spec = kb.robots[robot_id]  # the pair planned at the strongest squeeze, then judged
        kb.robots[robot_id] = spec.model_copy(update={"squeeze_force": max(FORCES)})
        try:
            planned = plan(kb, Query(oid, robot=robot_id))
        finally:
            kb.robots[robot_id] = spec
        data = planned.result.to_dict()
        if data["outcome"] != "handover":
            print(f"{oid:11s} {data['outcome']}: {data['reason'][:120]}")
            continue
        ctx = planned.context
        ids = np.array([g["id"] for g in data["robot_grasps"]])
        k = np.full(2, int(data["presentation"]["index"]))
        for force in FORCES:
            robot = ctx.situation.robot.model_copy(update={"squeeze_force": force})
            at = replace(ctx, situation=replace(ctx.situation, robot=robot))
            use = [float(max(pair_uses(r, at, ids, ids[::-1], k))) for r in rules]
            keep = max(use) <= 1.0 + 1e-12
            checked = _check_at(kb, data, force)
            n = checked.checked.result.nominal
            verdict = "holds" if n.passed else "drops" if n.dropped else "slips"
            print(f"{oid:11s} {force:5.0f} " + " ".join(f"{u:9.2f}" for u in use)
                  + f" {'keep' if keep else 'rej':5s} {verdict:7s} "
                  f"{min(n.max_translation_mm, 999):6.1f} {n.max_rotation_deg:6.1f} "
                  f"{'yes' if keep == n.passed else 'NO'}")


def _check_at(kb, data, force):
    """The plan's check with its robot's squeeze force replaced by ``force``."""
    import copy

    from handover.engine.plan.physics import check_plan

    robot = data["query"]["robot"]
    spec = kb.robots[robot]
    kb.robots[robot] = spec.model_copy(update={"squeeze_force": force})
    try:
        return check_plan(kb, copy.deepcopy(data), convex_cache())
    finally:
        kb.robots[robot] = spec


if __name__ == "__main__":
    main()
