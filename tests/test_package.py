"""The distribution installs one import package, ``handover``, and a user's own folders named
``geometry`` or ``engine`` do not shadow it."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HANDOVER = Path(sys.executable).parent / "handover"


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
         "-w", str(out), str(ROOT)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    if proc.returncode != 0 and "setuptools" in proc.stderr:
        proc = subprocess.run(
            [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(ROOT)],
            capture_output=True, text=True, timeout=600,
        )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    (path,) = out.glob("handover_grasp-*.whl")
    return path


def test_the_wheel_holds_exactly_one_top_level_package(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/", 1)[0] for n in names}
    dist_info = {t for t in tops if t.endswith(".dist-info")}
    assert tops - dist_info == {"handover"}
    assert "handover/engine/planner.py" in names
    # every source package of the repository is in the wheel
    inits = sorted(ROOT.glob("engine/**/__init__.py")) + sorted(ROOT.glob("geometry/**/*.py"))
    for init in inits:
        rel = init.relative_to(ROOT).as_posix()
        assert f"handover/{rel}" in names, rel
    assert "handover/engine/spec/kinds/contact.py" in names
    assert "handover/engine/plan/modes/h2g1.py" in names
    assert "handover/geometry/collision.py" in names
    assert "handover/kb/etiquette/common.yaml" in names
    assert "handover/kb/schema/etiquette.json" in names
    (info,) = dist_info
    entry_points = zipfile.ZipFile(wheel).read(f"{info}/entry_points.txt").decode()
    assert "handover = handover.engine.cli:main" in entry_points


def _shadowing_folder(tmp_path: Path) -> Path:
    for name in ("geometry", "engine", "kb"):
        pkg = tmp_path / name
        pkg.mkdir()
        (pkg / "__init__.py").write_text(f"raise ImportError('the user\\'s own {name}')\n")
    return tmp_path


def test_a_users_geometry_folder_does_not_break_the_planner(tmp_path):
    cwd = _shadowing_folder(tmp_path)
    code = "from handover import Planner; print(Planner().plan('knife').mode)"
    proc = subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "H1G1"
    proc = subprocess.run([str(HANDOVER), "plan", "knife"], cwd=cwd, capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "mode H1G1: feasible" in proc.stdout


@pytest.mark.parametrize("script", sorted(p.name for p in (ROOT / "benchmarks").glob("*.py")))
def test_a_benchmark_runs_against_the_installed_package(wheel, tmp_path, script):
    """Every benchmark script imports ``handover`` as installed (here: the wheel itself on
    the path, as after a plain ``pip install .``), not the repository's folders: run from
    elsewhere, it starts and prints its usage. A script that put the repository root first
    on ``sys.path`` found ``handover/`` (the facade alone) there and failed with ``No module
    named 'handover.engine'``."""
    code = ("import runpy, sys; sys.argv = [sys.argv[1], '--help']; "
            "runpy.run_path(sys.argv[0], run_name='__main__')")
    probe = ("import sys, handover; assert handover.__file__.startswith(sys.argv[1]), "
             "handover.__file__")
    env = {**os.environ, "PYTHONPATH": str(wheel)}
    where = subprocess.run([sys.executable, "-c", probe, str(wheel)], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=120)  # fmt: skip
    assert where.returncode == 0, where.stderr  # the wheel's handover, not the tree's
    proc = subprocess.run([sys.executable, "-c", code, str(ROOT / "benchmarks" / script)],
                          cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "usage:" in proc.stdout
