"""Batch throughput (objects per second): 1 and 2 local workers, and a local Ray instance.

    .venv/bin/python benchmarks/batch.py [--meshes 20] [--runs 3] [--cultures all]
        [--no-ray] [--profile]

The objects are the built-in KB objects and ``--meshes`` generated mesh files (boxes,
cylinders, small icospheres of assorted sizes, seeded); each is planned for every culture
given. Each run starts from an empty output and an empty grasp database ("cold"), then runs
again with the database filled ("warm"). Times are medians of ``--runs`` and count the batch
only (Ray's start-up is shown apart). Target: 2 workers at least 1.7x the throughput of 1.
``--profile`` prints cProfile's view of the 1-worker batch (where the time goes).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import logging
import os
import pstats
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from handover.engine.load.loader import load_kb
from handover.engine.tools import batch


def make_meshes(folder: Path, count: int, seed: int = 0) -> None:
    """``count`` graspable shapes (5 to 12 cm long, 2 to 4 cm thick) as STL files."""
    import trimesh

    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(count):
        kind = ("box", "cylinder", "sphere")[i % 3]
        if kind == "box":
            mesh = trimesh.creation.box(extents=(rng.uniform(0.05, 0.12),
                                                 *rng.uniform(0.02, 0.04, 2)))  # fmt: skip
        elif kind == "cylinder":
            radius, height = rng.uniform(0.01, 0.02), rng.uniform(0.05, 0.12)
            mesh = trimesh.creation.cylinder(radius=radius, height=height, sections=32)
        else:
            mesh = trimesh.creation.icosphere(subdivisions=3, radius=rng.uniform(0.01, 0.015))
        mesh.export(folder / f"{i:03d}_{kind}.stl")


def _spin(n: int) -> int:
    total = 0
    for i in range(n):
        total += i
    return total


def calibrate(n: int = 4_000_000) -> float:
    """How much faster two processes of pure Python run than one, right now: 2.0 on an idle
    2-core machine, less when something else is using a core (read the ratios with it)."""
    import multiprocessing as mp

    t = time.perf_counter()
    _spin(n)
    _spin(n)
    one = time.perf_counter() - t
    ctx = mp.get_context("fork") if sys.platform == "linux" else mp.get_context()
    with ctx.Pool(2) as pool:
        pool.map(_spin, [1000, 1000])  # start-up out of the timing
        t = time.perf_counter()
        pool.map(_spin, [n, n])
        two = time.perf_counter() - t
    return one / two


def run_once(kb, units, tmp: Path, workers: int, ray: str | None, db: Path) -> tuple[float, int]:
    out = tmp / f"out{time.perf_counter_ns()}.parquet"
    t = time.perf_counter()
    report = batch.run_batch(kb, units, out, db_root=db, workers=workers, ray_address=ray)
    seconds = time.perf_counter() - t
    errors = sum(1 for r in report.rows if r["error"])
    return seconds, errors


def measure(kb, units, tmp: Path, configs: dict, runs: int) -> dict:
    """Objects/s of each config ``label -> (workers, ray address)``, cold and warm. Rounds
    interleave the configs, so a load that comes and goes hits them alike; ``ratio`` is
    the median over rounds of each config's speed relative to the first config."""
    secs = {label: {"cold": [], "warm": []} for label in configs}
    errors = dict.fromkeys(configs, 0)
    for k in range(runs):
        for label, (workers, ray) in configs.items():
            db = tmp / f"db_{k}_{workers}_{ray}"
            for kind in ("cold", "warm"):
                s, e = run_once(kb, units, tmp, workers, ray, db)
                secs[label][kind].append(s)
                errors[label] = max(errors[label], e)
    n = len(units)
    first = next(iter(configs))
    out = {}
    for label in configs:
        out[label] = {"errors": errors[label]}
        for kind in ("cold", "warm"):
            out[label][kind] = n / statistics.median(secs[label][kind])
            out[label][f"ratio_{kind}"] = statistics.median(
                a / b for a, b in zip(secs[first][kind], secs[label][kind], strict=True)
            )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", type=int, default=20)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--cultures", default="all")
    ap.add_argument("--no-ray", action="store_true")
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args()
    kb = load_kb()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        make_meshes(tmp / "meshes", args.meshes)
        names = ",".join(sorted(kb.objects))
        units = batch.expand(kb, names, [args.cultures]) + batch.expand(
            kb, str(tmp / "meshes"), [args.cultures])  # fmt: skip
        queries = sum(len(u.queries) for u in units)
        print(f"## batch throughput: {len(units)} objects ({len(kb.objects)} KB + "
              f"{args.meshes} meshes), {queries} queries, {os.cpu_count()} cores, "
              f"median of {args.runs} (objects/s)")  # fmt: skip
        batch._preload()  # imports are not the batch's work
        print(f"machine: load average {os.getloadavg()[0]:.2f}; two processes of pure Python "
              f"run {calibrate():.2f}x one (2.00 = both cores free)")  # fmt: skip
        one, two = "1 worker (in process)", "2 workers (local pool)"
        results = measure(kb, units, tmp, {one: (1, None), two: (2, None)}, args.runs)
        if not args.no_ray:
            try:
                import ray
            except ImportError:
                print("ray is not installed: pip install 'handover-grasp[ray]'")
            else:
                t = time.perf_counter()
                ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
                         logging_level=logging.ERROR)  # fmt: skip
                print(f"ray.init (local, 2 CPUs): {time.perf_counter() - t:.2f} s")
                try:
                    label = "Ray, local instance (2 CPUs)"
                    results.update(measure(kb, units, tmp, {label: (2, "auto")}, args.runs))
                finally:
                    ray.shutdown()
        print(f"(machine, after: load average {os.getloadavg()[0]:.2f}, "
              f"parallel {calibrate():.2f}x)")  # fmt: skip
        print(f"{'backend':<30} {'cold':>8} {'warm':>8} {'failed rows':>12}")
        for label, r in results.items():
            print(f"{label:<30} {r['cold']:8.2f} {r['warm']:8.2f} {r['errors']:>12}")
        for kind in ("cold", "warm"):
            ratio = results[two][f"ratio_{kind}"]
            verdict = "met" if ratio >= 1.7 else "MISSED"
            print(f"2 workers / 1 worker ({kind}, median of per-round ratios): {ratio:.2f}x "
                  f"(target >= 1.7x: {verdict})")  # fmt: skip
        if args.profile:
            prof = cProfile.Profile()
            prof.enable()
            run_once(kb, units, tmp, 1, None, tmp / "db_profile")
            prof.disable()
            buf = io.StringIO()
            pstats.Stats(prof, stream=buf).sort_stats("cumulative").print_stats(30)
            print("\n## cProfile of the 1-worker batch (cold), by cumulative time")
            print(buf.getvalue())


if __name__ == "__main__":
    main()
