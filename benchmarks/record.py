"""Time to write a plan's rerun recording, and its size, for many candidates.

Run: ``.venv/bin/python benchmarks/record.py [--sizes 500 5000 20000] [--repeat 3]``

Each size is a synthetic plan: N grasp candidates on a 1,280-face capsule split in two parts,
24 presentations (N x 24 decision rows), nine hard rules (one of each kind but ``mode``), two
soft rules, seeded random failures so that every stage has candidates and one is chosen, a
trace of 12 rule decisions. ``write_recording`` is timed after rerun has been imported once
(its import is timed apart, in a fresh interpreter: every process that records pays it
once). A last line times the real knife plan and its recording, when the KB loads.

Numbers only; nothing here passes or fails.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from handover.engine.plan.attempt import Attempt
from handover.engine.plan.compiler import CompiledRule
from handover.engine.plan.context import PlanContext
from handover.engine.plan.evaluate import Decision
from handover.engine.plan.phase import Hands, Phase
from handover.engine.plan.presentation import presentation_rotations
from handover.engine.plan.receiver_sites import ReceiverRegion, ReceiverSites
from handover.engine.plan.records import RobotGrasp
from handover.engine.report.rerun.writer import write_recording
from handover.engine.report.result import PlanResult
from handover.engine.spec.schema import parse_rule
from handover.geometry.candidates import SOURCE_ANTIPODAL, CandidateSet
from handover.geometry.frames import perpendicular, unit
from handover.geometry.gripper import Gripper
from handover.geometry.hand import HumanHand
from handover.geometry.mesh import PartMesh, capsule

K = 24
HARD = [
    parse_rule(dict(id="no_sharp", kind="contact", who="giver", forbid_tags=["sharp"], why="-")),
    parse_rule(dict(id="tip_away", kind="axis", axis="tip", toward="toward_receiver",
                    min_deg=100, why="-")),
    parse_rule(dict(id="task", kind="task_present", why="-")),
    parse_rule(dict(id="quality_floor", kind="quality", min_quality=0.05, why="-")),
    parse_rule(dict(id="torque", kind="torque", max_nm=1.5, why="-")),
    parse_rule(dict(id="giver_half", kind="giver_side", max_fraction=0.5, why="-")),
    parse_rule(dict(id="approach", kind="approach", max_deg=100, why="-")),
    parse_rule(dict(id="apart", kind="clearance", min_m=0.06, why="-")),
    parse_rule(dict(id="collision_free", kind="collision", against=["scene", "receiver_hand"],
                    why="-")),
]  # fmt: skip
SOFT = [
    parse_rule(dict(id="q", kind="quality", hard=False, min_quality=0.5, why="-")),
    parse_rule(dict(id="handle_first", kind="axis", hard=False, axis="tip",
                    toward="toward_receiver", min_deg=90, why="-")),
]  # fmt: skip


def synthetic_plan(n: int, seed: int = 0) -> tuple[PlanResult, PlanContext, Attempt]:
    """A plan with ``n`` random grasp candidates (see the module docstring)."""
    rng = np.random.default_rng(seed)
    mesh = capsule(0.015, 0.2, transform=_y_to_x(), sections=32)
    face_part = (np.asarray(mesh.triangles_center)[:, 0] > 0.02).astype(np.int64)
    part_mesh = PartMesh(mesh, face_part, ["handle", "blade"], np.zeros(3))
    centre = np.column_stack([rng.uniform(-0.1, 0.1, n), np.zeros(n), np.zeros(n)])
    o = unit(rng.normal(size=(n, 3)) * [0.1, 1.0, 1.0])
    a = unit(np.cross(o, perpendicular(o)))
    nn = np.cross(o, a)
    contacts = np.stack([centre - 0.015 * o, centre + 0.015 * o], axis=1)
    parts = np.repeat((centre[:, 0] > 0.02).astype(np.int64)[:, None], 2, axis=1)
    cands = CandidateSet(
        centre=centre, n=nn, o=o, a=a, width=np.full(n, 0.03), contacts=contacts,
        normals=np.stack([-o, o], axis=1), faces=np.zeros((n, 2), dtype=np.int64), parts=parts,
        site=np.arange(n), roll=np.zeros(n), overlap_area=np.zeros(n),
        source=np.full(n, SOURCE_ANTIPODAL, dtype=np.int8), quality=rng.uniform(0, 1, n),
        com_distance=np.zeros(n), part_names=["handle", "blade"],
    )  # fmt: skip
    toward = np.array([1.0, 0.0, 0.0])
    rotations = presentation_rotations(toward)
    poses = np.tile(np.eye(4), (K, 1, 1))
    poses[:, :3, :3] = rotations
    poses[:, :3, 3] = [0.5, 0.0, 1.0]
    initial = np.eye(4)
    initial[:3, 3] = [0.5, 0.0, 0.765]
    table = np.eye(4)
    table[:3, 3] = [0.6, 0.0, 0.725]
    sites = ReceiverSites(site=np.tile([-0.07, 0.0, 0.0], (K, 1)),
                          part=np.zeros(K, dtype=np.int64), thickness=np.full(K, 0.03),
                          valid=np.ones(K, dtype=bool))  # fmt: skip
    region = ReceiverRegion(points=np.zeros((2, 3)), parts=np.zeros(2, dtype=np.int64),
                            axis=np.array([1.0, 0.0, 0.0]), tags=("handle",))  # fmt: skip
    ctx = PlanContext(
        situation=SimpleNamespace(obj=SimpleNamespace(axes={"tip": (1.0, 0.0, 0.0)}),
                                  toward=toward),
        part_mesh=part_mesh, part_tags=[{"handle"}, {"blade", "sharp"}], candidates=cands,
        generation={"antipodal": n}, gripper=Gripper.default(),
        hand=HumanHand(palm=(0.08, 0.09, 0.03), finger_length=0.08, finger_thickness=0.02,
                       grip_width=0.08),
        rotations=rotations, initial=initial, scene=None,
        scene_box_list=[("table", np.array([0.8, 1.2, 0.05]), table)], facts=None,
    )  # fmt: skip
    gi = np.repeat(np.arange(n), K)
    pk = np.tile(np.arange(K), n)
    fails = rng.random((n * K, len(HARD))) < 0.08
    fails[gi == 0] = False  # grasp 0 passes everywhere: it is chosen in presentation 0
    kept = ~fails.any(axis=1)
    score = np.where(kept, rng.uniform(0, 0.9, n * K), np.nan)
    score[0] = 1.0
    decision = Decision(
        gi=gi, pk=pk, hard=[CompiledRule(r, "common") for r in HARD],
        soft=[CompiledRule(r, "common") for r in SOFT], fails=fails, checked=np.ones_like(fails),
        kept=kept, score=score, first_fail=np.where(fails.any(1), fails.argmax(1), -1),
        soft_scores=np.repeat(score[:, None], len(SOFT), axis=1),
    )  # fmt: skip
    hands = Hands(key=("benchmark", 1), region=region, sites=(sites,), s_range=np.zeros((K, 2)),
                  poses=poses, location=np.zeros(K, dtype=np.int64), located=np.ones(K, bool),
                  measured={}, hits=((),) * K)
    attempt = Attempt("H1G1", True, None, None, decision, Phase("H1G1", hands=hands))
    grasp = RobotGrasp(gripper="right", pose=cands.poses()[0], pose_world=cands.poses()[0],
                       width=0.03, contacts=contacts[0], parts=("handle", "handle"), score=1.0,
                       id=0, quality=float(cands.quality[0]))  # fmt: skip
    trace = [{"grasp": 0, "hand": "right", "rule": r.id, "kind": r.kind, "hard": r.hard,
              "status": "pass" if r.hard else "scored", "measured": 0.0, "unit": "",
              "threshold": "-", "score": 1.0, "weight": None, "why": r.why,
              "source": "x.yaml:1", "culture": "common", "note": None}
             for r in HARD + SOFT]  # fmt: skip
    result = PlanResult(
        object="bar", query={"culture": "common", "scene": "table", "mode": "auto"},
        mode="H1G1", feasible=True, reason=None, object_pose=poses[0],
        receiver={"position": [1.0, 0, 0], "facing": [-1.0, 0, 0], "role": "adult"},
        robot_grasps=[grasp], human_grasps=[], gripper={}, trace=trace,
        candidates={"generated": n * K, "kept": int(kept.sum())}, initial_pose=initial,
        presentation={"index": 0, "axes_world": {"tip": [1, 0, 0]}},
    )  # fmt: skip
    return result, ctx, attempt


def _y_to_x() -> np.ndarray:
    """(4, 4): the capsule's z axis laid along x."""
    t = np.eye(4)
    t[:3, :3] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]
    return t


def import_seconds() -> float:
    """Seconds to ``import rerun`` in a fresh interpreter."""
    code = "import time; t = time.perf_counter(); import rerun; print(time.perf_counter() - t)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)  # fmt: skip
    return float(out.stdout.strip())


def time_recording(n: int, repeat: int, folder: Path) -> tuple[float, int]:
    """Median seconds of ``write_recording`` and the file's size in bytes."""
    result, ctx, attempt = synthetic_plan(n)
    path = folder / f"synthetic-{n}.rrd"
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        write_recording(result, ctx, path, attempt)
        times.append(time.perf_counter() - t)
    return statistics.median(times), path.stat().st_size


def knife(folder: Path) -> str:
    """Plan time and recording time of the real knife plan (first recording of a process
    pays rerun's import; this one runs after the synthetic ones, so it does not)."""
    try:
        from handover.engine.load.loader import load_kb
        from handover.engine.planner import plan
        from handover.engine.spec.query import Query

        kb = load_kb(None)
        t = time.perf_counter()
        planned = plan(kb, Query(object="knife"))
        result, ctx = planned.result, planned.context
        t_plan = time.perf_counter() - t
    except Exception as e:  # noqa: BLE001 - a benchmark reports, it does not stop
        return f"knife: not measured ({type(e).__name__}: {e})"
    path = folder / "knife.rrd"
    t = time.perf_counter()
    planned.record(path)
    t_rec = time.perf_counter() - t
    return (f"knife ({ctx.n} grasps x {ctx.k} presentations, {result.mode or 'infeasible'}): "
            f"plan {t_plan * 1e3:.0f} ms, recording {t_rec * 1e3:.0f} ms, "
            f"{path.stat().st_size / 1e3:.0f} kB")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[500, 5000, 20000])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cpus")
    print(f"import rerun (fresh interpreter, once per process): {import_seconds() * 1e3:.0f} ms")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        time_recording(50, 1, folder)  # warm-up: rerun imported, caches filled
        print(f"{'candidates':>10} {'rows':>9} {'record ms':>10} {'size kB':>9} {'B/cand':>7}")
        for n in args.sizes:
            seconds, size = time_recording(n, args.repeat, folder)
            print(f"{n:>10} {n * K:>9} {seconds * 1e3:>10.1f} {size / 1e3:>9.0f} "
                  f"{size / n:>7.0f}")  # fmt: skip
        print(knife(folder))


if __name__ == "__main__":
    main()
