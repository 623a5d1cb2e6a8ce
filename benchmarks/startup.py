"""Start-up cost of the command line, as whole processes, against the bare imports it needs,
and the cold plan with a 10- and a 500-object KB.

    .venv/bin/python benchmarks/startup.py [--runs 7] [--objects 10,500] [--importtime]
                                            [--profile]

Times (median of ``--runs``; the commands of a table take turns, run by run, so that a drift
of the machine's speed weighs on each alike): ``python -c pass``; ``python -c "import numpy,
trimesh, fcl, networkx, pydantic, yaml"`` (the libraries a plan cannot do without);
``handover --help``; ``handover plan knife --json``. Target: the plan within 2x the bare
imports (lazy imports, no work at start-up). ``--importtime`` lists the slowest top-level
imports of each command (``python -X importtime``); ``--profile`` shows cProfile's view of
the plan process.

Then, for each size of ``--objects``: a KB folder in a temporary folder holding the built-in
KB and copies of its objects under new ids up to that many objects, and the cold ``handover
--kb DIR plan knife --json`` (a new process; the KB read through the validated cache of the
grasp database folder, after one untimed run that fills it), beside the full load and check
of that KB (``load_kb``, what a plan paid for every object before the cache). Target: the
500-object KB plans within 10 % of the 10-object one.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PY = sys.executable
HANDOVER = str(Path(PY).parent / "handover")
BARE = "import numpy, trimesh, fcl, networkx, pydantic, yaml"
CLI = ("import sys; from handover.engine.cli import main; "
       "sys.argv = ['handover', *sys.argv[1:]]; main()")


def run(cmds: list[list[str]], runs: int, env: dict) -> list[tuple[float, int]]:
    """Per command of ``cmds``: its median wall time in s and its exit code, after one
    untimed run of each. The commands take turns, run by run, so that a drift of this
    machine's speed (other work, the CPU's clock) weighs on all of them alike."""
    codes = [subprocess.run(cmd, capture_output=True, env=env).returncode for cmd in cmds]
    times: list[list[float]] = [[] for _ in cmds]
    for _ in range(runs):
        for cmd, spent in zip(cmds, times, strict=True):
            t = time.perf_counter()
            subprocess.run(cmd, capture_output=True, env=env)
            spent.append(time.perf_counter() - t)
    return [(statistics.median(spent), code) for spent, code in zip(times, codes, strict=True)]


def importtime(args: list[str], env: dict, top: int = 12) -> None:
    """The slowest imports of ``handover ARGS`` (cumulative, top-level packages)."""
    proc = subprocess.run([PY, "-X", "importtime", "-c", CLI, *args], capture_output=True,
                          text=True, env=env)  # fmt: skip
    rows = []
    for line in proc.stderr.splitlines():
        m = re.match(r"import time:\s+(\d+) \|\s+(\d+) \|( *)(\S+)", line)
        if m and len(m.group(3)) <= 1:  # top-level imports only
            rows.append((int(m.group(2)), m.group(4)))
    total = sum(us for us, _ in rows)
    print(f"\n## slowest top-level imports of `handover {' '.join(args)}` "
          f"(total {total / 1e6:.3f} s)")  # fmt: skip
    for us, name in sorted(rows, reverse=True)[:top]:
        print(f"{us / 1e6:8.3f} s  {name}")


def profile(args: list[str], env: dict, top: int = 30) -> None:
    proc = subprocess.run([PY, "-m", "cProfile", "-s", "cumtime", HANDOVER, *args],
                          capture_output=True, text=True, env=env)  # fmt: skip
    lines = proc.stdout.splitlines()
    start = next((i for i, line in enumerate(lines) if "ncalls" in line), 0)
    print(f"\n## cProfile of `handover {' '.join(args)}` (cumulative)")
    print("\n".join(lines[max(0, start - 2) : start + top]))


def kb_of(n: int, folder: Path) -> Path:
    """The built-in KB with copies of its objects (ids ``<id>_<k>``) up to ``n`` objects."""
    from handover.engine.store.kb import builtin_kb_dir

    root = folder / f"kb{n}"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    shipped = sorted((root / "objects").glob("*.yaml"))
    for k in range(max(0, n - len(shipped))):
        src = shipped[k % len(shipped)]
        text = src.read_text(encoding="utf-8")
        new = f"{src.stem}_{k}"
        (root / "objects" / f"{new}.yaml").write_text(
            text.replace(f"\nid: {src.stem}\n", f"\nid: {new}\n", 1), encoding="utf-8")
    return root


def kb_sizes(sizes: list[int], runs: int, env: dict) -> None:
    print(f"\n## cold `handover --kb DIR plan knife --json` by KB size, median of {runs} (s)")
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(env, HANDOVER_DB=str(Path(tmp) / "db"))
        roots = {n: kb_of(n, Path(tmp)) for n in sizes}
        timed = run([[HANDOVER, "--kb", str(roots[n]), "plan", "knife", "--json"]
                     for n in sizes], runs, env)
        times = {}
        for n, (t, code) in zip(sizes, timed, strict=True):
            load = subprocess.run(
                [PY, "-c", "import sys, time; from handover.engine.load.loader import load_kb; "
                 "load_kb(sys.argv[1], urdf=False); t = time.perf_counter(); "
                 "load_kb(sys.argv[1], urdf=False); print(time.perf_counter() - t)",
                 str(roots[n])], capture_output=True, text=True, env=env).stdout.strip()
            times[n] = t
            print(f"{n:4d} objects: plan {t:7.3f}   exit {code}   (full load and check of the "
                  f"KB: {float(load):.3f} s)")
        small, large = times[min(sizes)], times[max(sizes)]
        verdict = "met" if large <= 1.1 * small else "MISSED"
        print(f"{max(sizes)} / {min(sizes)} objects = {large / small:.3f} (target <= 1.10: "
              f"{verdict})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--objects", default="10,500",
                    help="KB sizes for the cold plan (comma list; empty: skip)")
    ap.add_argument("--importtime", action="store_true")
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args()
    env = dict(os.environ)
    cases = [
        ("python -c pass", [PY, "-c", "pass"]),
        ("bare imports", [PY, "-c", BARE]),
        ("handover --help", [HANDOVER, "--help"]),
        ("handover plan knife --json", [HANDOVER, "plan", "knife", "--json"]),
    ]
    print(f"## whole-process times, median of {args.runs} (s)")
    results = {}
    for (label, _), (t, code) in zip(cases, run([c for _, c in cases], args.runs, env),
                                     strict=True):
        results[label] = t
        print(f"{label:<28} {t:7.3f}   exit {code}")
    bare = results["bare imports"]
    plan = results["handover plan knife --json"]
    verdict = "met" if plan <= 2 * bare else "MISSED"
    print(
        f"plan / bare imports = {plan / bare:.2f} (target <= 2: {verdict}); "
        f"--help / bare imports = {results['handover --help'] / bare:.2f}"
    )
    sizes = [int(v) for v in args.objects.split(",") if v.strip()]
    if sizes:
        kb_sizes(sizes, args.runs, env)
    if args.importtime:
        importtime(["--help"], env)
        importtime(["plan", "knife", "--json"], env)
    if args.profile:
        profile(["plan", "knife", "--json"], env)


if __name__ == "__main__":
    main()
