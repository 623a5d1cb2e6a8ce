"""The distribution installs one import package, ``handover``, and a user's own folders named
``geometry`` or ``engine`` do not shadow it."""

from __future__ import annotations

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
