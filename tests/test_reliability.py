"""Reliability and safety of the tool itself: bad input, safety overrides, determinism,
atomic outputs (issue 8). Each test meets the tool where a user would: ``engine.cli.app.main``
in-process (capsys), and a few real runs of the installed ``handover`` script.

The fuzzing of item 5 is in ``tests/fuzz/test_plan_fuzz.py`` and ``tests/fuzz/test_kb_fuzz.py``.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml

import handover.engine.report.rerun.writer
import handover.geometry.atomic
import handover.geometry.mesh
from handover.engine.cli.app import main
from handover.engine.errors import (
    EXIT_BAD_MESH,
    EXIT_INFEASIBLE,
    EXIT_INTERNAL,
    EXIT_INVALID_KB,
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
)
from handover.engine.spec.schema import DOCUMENT_KINDS
from handover.engine.store.kb import builtin_kb_dir
from handover.engine.store.validate import validate_document
from handover.engine.store.yamlpos import load_yaml_with_marks

HANDOVER = Path(sys.executable).parent / "handover"
OBJECTS = sorted(p.stem for p in (builtin_kb_dir() / "objects").glob("*.yaml"))
MODES = ("auto", "h1g1", "h2g2", "h2g1")


def run(capsys, *args: str) -> tuple[int, str, str]:
    """``handover ARGS`` in this process: (exit code, stdout, stderr)."""
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def assert_clean(err: str) -> None:
    """What a user sees on stderr: no Python traceback, no warning with a source line."""
    assert "Traceback" not in err
    assert "internal error" not in err
    assert ".py:" not in err, err  # warnings.warn's "file.py:LINE: Category: ..." format


@pytest.fixture
def kb_copy(tmp_path):
    """``kb_copy(files) -> Path``: the built-in KB copied to ``tmp_path/kb`` with ``files``
    (relative path -> YAML text, or None to delete) written over it."""

    def make(files: dict[str, str | None] | None = None) -> Path:
        root = tmp_path / "kb"
        if not root.exists():
            shutil.copytree(builtin_kb_dir(), root,
                            ignore=shutil.ignore_patterns("schema", "__*"))  # fmt: skip
        for rel, text in (files or {}).items():
            path = root / rel
            if text is None:
                path.unlink()
                continue
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(textwrap.dedent(text), encoding="utf-8")
        return root

    return make


def box_object(oid: str, extents, *, mass: float = 0.2, position=(0, 0, 0)) -> str:
    """YAML of a one-box object with an untagged part ``body``."""
    return (
        f"id: {oid}\nname: {oid}\nmass: {mass}\n"
        f"geometry:\n  primitives:\n    - {{shape: box, part: body, extents: {list(extents)}, "
        f"position: {list(position)}}}\n"
        "parts:\n  body: {tags: []}\n"
    )


# ================================================================ 1. bad input


def test_malformed_yaml_is_located_with_exit_3(capsys, make_kb):
    root = make_kb({"objects/broken.yaml": "id: broken\nname: [unclosed\nmass: 1\n"})
    code, _, err = run(capsys, "--kb", str(root), "kb", "validate")
    assert code == EXIT_INVALID_KB
    assert "objects/broken.yaml:3:" in err and "YAML syntax" in err
    assert_clean(err)


def test_wrong_type_is_located_with_exit_3(capsys, make_kb):
    root = make_kb({"objects/stick.yaml": box_object("stick", [0.1, 0.02, 0.02])
                    .replace("mass: 0.2", "mass: heavy")})  # fmt: skip
    code, _, err = run(capsys, "--kb", str(root), "kb", "validate")
    assert code == EXIT_INVALID_KB
    assert "objects/stick.yaml:3:7: mass: Input should be a valid number" in err
    assert_clean(err)


@pytest.mark.parametrize(
    "args, message",
    [
        (["plan", "spoon"], "unknown object 'spoon' (known: ball, book,"),
        (["plan", "knife", "--culture", "martian"], "unknown culture 'martian' (known: common,"),
        (["plan", "knife", "--receiver", "king"], "unknown receiver 'king' (known: adult,"),
        (["plan", "knife", "--scene", "moon"], "unknown scene 'moon' (known: book_on_table,"),
        (["plan", "knife", "--gripper", "claw"], "unknown gripper 'claw' (known: parallel_jaw)"),
        (["plan", "knife", "--task", "juggle"], "object 'knife' has no task 'juggle'"),
        (["plan", "knife", "--mode", "h3g3"], "unknown mode 'h3g3': choose one of auto,"),
        (["plan", "knife", "--why-not", "99999"], "--why-not 99999: candidate ids run from 0"),
        (["kb", "show", "spoon"], "no object, culture, receiver, scene"),
        (["plan", "[/x]"], "unknown object '[/x]'"),  # rich markup in an id: shown as typed
        (["plan", "[red]knife"], "unknown object '[red]knife'"),
    ],
)
def test_unknown_ids_are_usage_errors(capsys, args, message):
    code, _, err = run(capsys, *args)
    assert code == EXIT_USAGE
    assert message in err
    assert_clean(err)


@pytest.mark.parametrize(
    "args, message",
    [
        (["plan"], "Missing argument 'OBJECT'"),
        (["plan", "knife", "extra"], "unexpected extra argument"),
        (["plan", "knife", "--bogus"], "No such option: --bogus"),
        (["--kb", "/etc/hostname", "plan", "knife"], "is a file"),
    ],
)
def test_command_line_mistakes_are_usage_errors(capsys, args, message):
    if args[:1] == ["--kb"] and not Path(args[1]).is_file():
        pytest.skip("needs a file to pass as --kb")
    code, out, err = run(capsys, *args)
    assert code == EXIT_USAGE
    assert message in out + err
    assert_clean(err)


def test_self_extending_culture(capsys, make_kb):
    root = make_kb({"etiquette/loop.yaml": "id: loop\nname: Loop\nextends: loop\nrules: []\n"})
    code, _, err = run(capsys, "--kb", str(root), "kb", "validate")
    assert code == EXIT_INVALID_KB
    assert "etiquette/loop.yaml:3:10: 'extends' forms a cycle: loop -> loop" in err


def test_override_of_a_missing_rule(capsys, make_kb):
    root = make_kb({"etiquette/strict.yaml": """\
        id: strict
        name: Strict
        rules:
          - {id: q, kind: quality, min_quality: 0.2, overrides: [no_such_rule], why: Good grip.}
        """})  # fmt: skip
    code, _, err = run(capsys, "--kb", str(root), "kb", "validate")
    assert code == EXIT_INVALID_KB
    assert "rule 'q' overrides 'no_such_rule', but no culture that 'strict' extends" in err


# ---------------------------------------------------------------- meshes


def write_mesh(path: Path, vertices, faces) -> Path:
    trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces), process=False).export(path)
    return path


@pytest.fixture
def meshes(tmp_path) -> dict[str, Path]:
    d = tmp_path / "meshes"
    d.mkdir()
    (d / "empty.stl").write_bytes(b"")
    (d / "flat.obj").write_text("v 0 0 0\nv 0.05 0 0\nv 0.1 0 0\nf 1 2 3\n")  # zero area
    box = trimesh.creation.box(extents=[0.05, 0.03, 0.1])
    fin = np.vstack([box.faces, [[0, 1, 8]]])  # a triangle hanging off one edge
    write_mesh(d / "fin.stl", np.vstack([box.vertices, [[0.0, 0.0, 0.12]]]), fin)
    write_mesh(d / "box.stl", box.vertices, box.faces)
    write_mesh(d / "far.stl", box.vertices + [5e4, 0, 0], box.faces)
    return {p.stem: p for p in d.iterdir()}


@pytest.mark.parametrize("command", ["plan", "grasps"])
@pytest.mark.parametrize(
    "name, message",
    [
        ("empty", "empty.stl: not a mesh"),
        ("flat", "flat.obj: the mesh has no area (all 1 faces are degenerate)"),
        ("far", "far.stl: a vertex lies 5e+04 m from the origin, beyond the limit of 10000 m"),
        ("missing", "missing.stl: mesh file not found"),
    ],
)
def test_bad_mesh_files_exit_5(capsys, meshes, command, name, message):
    path = meshes.get(name, meshes["box"].parent / f"{name}.stl")
    code, _, err = run(capsys, command, str(path))
    assert code == EXIT_BAD_MESH
    assert "bad mesh: " in err and message in err
    assert_clean(err)


def test_a_non_manifold_mesh_plans_with_one_warning_line(capsys, meshes):
    code, out, err = run(capsys, "plan", str(meshes["fin"]), "--json", "--no-db")
    assert code in (EXIT_OK, EXIT_INFEASIBLE)
    assert json.loads(out)["object"] == "fin"
    assert err.startswith("warning: ") and "fin.stl: the mesh is not watertight" in err
    assert err.count("\n") == 1  # one line, no "file.py:LINE: MeshWarning" and code line
    assert_clean(err)


def test_an_enormous_mesh_is_refused_with_the_limit(capsys, meshes, monkeypatch):

    monkeypatch.setattr(handover.geometry.mesh, "MAX_FACES", 10)  # the 12-face box is "too big"
    code, _, err = run(capsys, "plan", str(meshes["box"]))
    assert code == EXIT_BAD_MESH
    assert "12 faces is more than the limit of 10; decimate the mesh first" in err


def test_debug_shows_the_traceback_of_a_bad_mesh(capsys, meshes):
    from handover.geometry.mesh import MeshError

    with pytest.raises(MeshError, match="no area"):
        main(["--debug", "plan", str(meshes["flat"])])
    with pytest.raises(UsageError, match="unknown object"):
        main(["plan", "spoon", "--debug"])  # global option after the command works too


@pytest.mark.parametrize(
    "file, message",
    [
        ("../../outside.stl", "mesh file '../../outside.stl' leaves the KB folder"),
        ("/etc/outside.stl", "mesh file '/etc/outside.stl' is an absolute path"),
        ("../meshes/nowhere.stl", "mesh file '../meshes/nowhere.stl' does not exist"),
    ],
)
def test_mesh_files_outside_the_kb(capsys, make_kb, file, message):
    vase = f"id: vase\nname: Vase\nmass: 0.3\ngeometry:\n  mesh: {{file: '{file}', " \
           "default_part: body}\nparts:\n  body: {tags: []}\n"  # fmt: skip
    root = make_kb({"objects/vase.yaml": vase})
    code, _, err = run(capsys, "--kb", str(root), "kb", "validate")
    assert code == EXIT_INVALID_KB
    assert "objects/vase.yaml:5:" in err and message in err


def test_a_mesh_linked_from_outside_the_kb(capsys, make_kb, meshes):
    vase = "id: vase\nname: Vase\nmass: 0.3\ngeometry:\n  mesh: {file: ../meshes/vase.stl, " \
           "default_part: body}\nparts:\n  body: {tags: []}\n"  # fmt: skip
    root = make_kb({"objects/vase.yaml": vase})
    (root / "meshes").mkdir()
    (root / "meshes/vase.stl").symlink_to(meshes["box"])
    code, _, err = run(capsys, "--kb", str(root), "kb", "validate")
    assert code == EXIT_INVALID_KB
    assert "mesh file '../meshes/vase.stl' leads through a symbolic link to" in err
    assert "outside the KB folder" in err


def test_primitive_sizes_and_places_beyond_the_world(capsys, kb_copy):
    root = kb_copy({
        "objects/wide.yaml": box_object("wide", [1e300, 0.03, 0.1]),
        "objects/far.yaml": box_object("far", [0.03, 0.03, 0.1], position=[1e12, 0, 0]),
    })  # fmt: skip
    code, _, err = run(capsys, "--kb", str(root), "plan", "wide")
    assert code == EXIT_BAD_MESH and "box extents of 1e+300 m is beyond the limit" in err
    assert_clean(err)
    code, _, err = run(capsys, "--kb", str(root), "plan", "far")
    assert code == EXIT_BAD_MESH and "a vertex lies 1e+12 m from the origin" in err
    assert_clean(err)


# ---------------------------------------------------------------- objects vs gripper


def test_an_object_thinner_than_the_gripper_closes(capsys, kb_copy):
    jaw = (builtin_kb_dir() / "grippers/parallel_jaw.yaml").read_text()
    root = kb_copy({
        "grippers/parallel_jaw.yaml": jaw.replace("min_opening: 0.0", "min_opening: 0.04"),
        "objects/chip.yaml": box_object("chip", [0.03, 0.02, 0.01], mass=0.01),
    })  # fmt: skip
    code, out, err = run(capsys, "--kb", str(root), "plan", "chip", "--json")
    assert code == EXIT_INFEASIBLE
    result = json.loads(out)
    assert result["feasible"] is False and result["candidates"]["grasps"] == 0
    assert "the object has no geometric grasp for this gripper" in result["reason"]
    assert_clean(err)


def test_an_object_wider_than_any_opening_is_squeezed_and_taken_on_two_palms(capsys, kb_copy):
    root = kb_copy({"objects/crate.yaml": box_object("crate", [0.4, 0.4, 0.4], mass=0.5)})
    code, out, err = run(capsys, "--kb", str(root), "plan", "crate", "--json")
    assert code == 0
    result = json.loads(out)
    # no gripper spans it: the two grippers squeeze it (H2G1), and the receiver takes the
    # 40 cm box as people take a box, on their two palms under it
    assert result["mode"] == "H2G1"
    assert [g["hold"] for g in result["robot_grasps"]] == ["squeeze", "squeeze"]
    assert [h["grasp"]["name"] for h in result["human_grasps"]] == ["support", "support"]
    tried = {t["mode"]: t["reason"] for t in result["modes_tried"]}
    assert "two_hands_if_wide" in tried["H1G1"]  # one hand cannot span it: both are needed
    assert_clean(err)


# ---------------------------------------------------------------- scenes


SCENE = """\
    id: odd
    name: Odd
    support: {position: [0.55, 0.0, 0.75], size: [0.5, 1.0]}
    """


@pytest.mark.parametrize(
    "extra, message",
    [
        ("receiver: {position: [0.5, 0.0, 0.0]}\n",
         "scene 'odd': the receiver stands at (0.5, 0, 0), inside the table"),
        ("obstacles: [{id: shelf, position: [1.0, 0, 0.5], extents: [0.4, 0.4, 1.0]}]\n",
         "scene 'odd': the receiver stands at (1, 0, 0), inside obstacle 'shelf'"),
        ("object: {position: [3.0, 2.0]}\n",
         "scene 'odd': the object is placed at (3, 2), off the table (x 0.3..0.8, y -0.5..0.5)"),
        ("receiver: {position: [0.0, 0.0, 0.0]}\n",
         "scene 'odd': the receiver stands on the robot"),
        ("receiver: {position: [1.0, 0.0, 0.0], facing: [0, 0, 1]}\n",
         "scene 'odd': the receiver faces straight up or down"),
    ],
)  # fmt: skip
def test_impossible_scenes_are_kb_errors(capsys, kb_copy, extra, message):
    root = kb_copy({"scenes/odd.yaml": textwrap.dedent(SCENE) + extra})
    code, _, err = run(capsys, "--kb", str(root), "plan", "knife", "--scene", "odd")
    assert code == EXIT_INVALID_KB
    assert "scenes/odd.yaml:" in err and message in err
    assert_clean(err)


# ---------------------------------------------------------------- NaN and infinity


def numeric_paths(data, path=()):
    """Paths to every number (not bool) in plain YAML data."""
    if isinstance(data, bool):
        return
    if isinstance(data, int | float):
        yield path
    elif isinstance(data, dict):
        for key, value in data.items():
            yield from numeric_paths(value, (*path, key))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            yield from numeric_paths(value, (*path, i))


KB_FILES = sorted(
    p.relative_to(builtin_kb_dir()).as_posix()
    for kind in DOCUMENT_KINDS
    for p in (builtin_kb_dir() / kind).glob("*.yaml")
)


@pytest.mark.parametrize("rel", KB_FILES)
def test_nan_or_infinity_in_any_numeric_field_is_refused(rel):
    """Every number of every built-in KB file, replaced by .nan, .inf or -.inf, gives an
    error located on that line (never a model that carries the value into planning)."""
    model = DOCUMENT_KINDS[rel.split("/")[0]]
    text = (builtin_kb_dir() / rel).read_text(encoding="utf-8")
    data = yaml.safe_load(text)
    paths = list(numeric_paths(data))
    assert paths or rel.startswith(("etiquette/", "receivers/", "tests/")), f"{rel} has no number?"
    for path in paths:
        for value in (math.nan, math.inf, -math.inf):
            doc = json.loads(json.dumps(data))
            node = doc
            for key in path[:-1]:
                node = node[key]
            node[path[-1]] = value
            changed = yaml.safe_dump(doc, sort_keys=False)
            parsed, marks = load_yaml_with_marks(rel, text=changed)
            obj, issues = validate_document(parsed, marks, model, rel)
            where = f"{rel} {'.'.join(map(str, path))} = {value}"
            assert obj is None and issues, f"accepted {where}"
            line = marks.value(tuple(path))[0]
            assert any(i.line == line for i in issues), f"{where}: not located on line {line}"


def test_infinite_receiver_position_through_the_cli(capsys, kb_copy):
    root = kb_copy({"scenes/odd.yaml": textwrap.dedent(SCENE) +
                    "receiver: {position: [.inf, 0, 0]}\n"})  # fmt: skip
    code, _, err = run(capsys, "--kb", str(root), "plan", "knife", "--scene", "odd")
    assert code == EXIT_INVALID_KB
    assert "scenes/odd.yaml:4:23: receiver.position[0]: must be a finite number, not inf" in err


# ---------------------------------------------------------------- real processes


def test_a_real_process_shows_no_traceback_unless_debug(tmp_path):
    env = dict(os.environ, HANDOVER_DB=str(tmp_path / "db"))
    env.pop("HANDOVER_DEBUG", None)
    quiet = subprocess.run([str(HANDOVER), "plan", "spoon"], capture_output=True, text=True,
                           env=env, timeout=120)  # fmt: skip
    assert quiet.returncode == EXIT_USAGE
    assert quiet.stderr.startswith("error: unknown object 'spoon'")
    assert "Traceback" not in quiet.stderr
    loud = subprocess.run([str(HANDOVER), "--debug", "plan", "spoon"], capture_output=True,
                          text=True, env=env, timeout=120)  # fmt: skip
    assert loud.returncode != EXIT_OK
    assert "Traceback (most recent call last)" in loud.stderr
    assert "UnknownIdError: unknown object 'spoon'" in loud.stderr  # a UsageError


def test_a_real_process_on_an_empty_mesh(tmp_path):
    (tmp_path / "empty.stl").write_bytes(b"")
    proc = subprocess.run([str(HANDOVER), "grasps", str(tmp_path / "empty.stl")],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert proc.returncode == EXIT_BAD_MESH
    assert "empty.stl: not a mesh" in proc.stderr and "Traceback" not in proc.stderr


# ================================================================ 2. safety overrides


def test_validate_warns_of_the_japanese_safety_override(capsys):
    code, out, err = run(capsys, "kb", "validate")
    assert code == EXIT_OK and out.startswith("ok: ")
    (line,) = [x for x in err.splitlines() if "sharp_tip_away" in x]
    assert line.startswith("etiquette/japanese.yaml:")
    assert "warning: safety rule 'sharp_tip_away' (etiquette/common.yaml:" in line
    assert "overridden by 'tip_toward_giver': stricter than the common rule" in line


def test_plan_says_which_safety_rule_was_overridden_and_by_what(capsys):
    code, out, _ = run(capsys, "plan", "knife", "--culture", "japanese", "--json")
    assert code == EXIT_OK
    result = json.loads(out)
    (warning,) = result["warnings"]
    assert warning.startswith("safety rule sharp_tip_away overridden by tip_toward_giver "
                              "(etiquette/japanese.yaml:")  # fmt: skip
    rules = {e["rule"]: e for e in result["trace"]}
    assert "sharp_tip_away" not in rules  # replaced, and the trace says so:
    assert rules["tip_toward_giver"]["overrides_safety"] == {
        "rules": ["sharp_tip_away"],
        "reason": "stricter than the common rule: the point is turned back towards the giver "
        "(within 45 degrees), not merely away from the receiver",
    }
    code, out, _ = run(capsys, "plan", "knife", "--culture", "japanese", "--explain")
    assert "overrides SAFETY rule sharp_tip_away" in " ".join(out.split())
    code, out, _ = run(capsys, "plan", "knife", "--json")  # the common culture: no override
    result = json.loads(out)
    assert result["warnings"] == []
    assert "overrides_safety" not in {k for e in result["trace"] for k in e}
    assert "sharp_tip_away" in {e["rule"] for e in result["trace"]}


FAR_RECEIVER = """\
id: far
name: The receiver 2.5 m away
why: Nowhere they reach is within the robot's reach.
support: {position: [0.55, 0.0, 0.75], size: [0.5, 1.0], thickness: 0.03}
receiver: {position: [2.5, 0.0, 0.0], facing: [-1.0, 0.0, 0.0]}
object: {position: [0.33, 0.0]}
"""


def test_an_infeasible_plan_still_reports_the_override(capsys, kb_copy):
    root = kb_copy({"scenes/far.yaml": FAR_RECEIVER})
    code, out, _ = run(capsys, "--kb", str(root), "plan", "knife", "--culture", "japanese",
                       "--scene", "far", "--no-motion", "--json")  # fmt: skip
    result = json.loads(out)
    assert code == EXIT_INFEASIBLE, result["reason"]
    assert any("safety rule sharp_tip_away overridden" in w for w in result["warnings"])


LOOSE = """\
    id: loose
    name: Loose
    extends: {parent}
    rules:
      - id: tip_anywhere
        kind: axis
        axis: tip
        toward: away_from_receiver
        max_deg: 170
        overrides: [{target}]
        applies: {{object_tags_any: [sharp]}}
        why: Anything goes.
    """


def test_overriding_a_safety_rule_needs_a_reason(capsys, kb_copy):
    loose = LOOSE.format(parent="common", target="sharp_tip_away")
    root = kb_copy({"etiquette/loose.yaml": loose})
    code, _, err = run(capsys, "--kb", str(root), "kb", "validate")
    assert code == EXIT_INVALID_KB
    assert ("etiquette/loose.yaml:10:16: rule 'tip_anywhere' overrides the safety rule "
            "'sharp_tip_away' (etiquette/common.yaml:") in err  # fmt: skip
    assert "without 'override_safety: <reason>'" in err


def test_safety_is_not_lost_through_a_chain_of_cultures(capsys, kb_copy):
    """japanese replaced sharp_tip_away (with a reason); a culture extending japanese that
    replaces japanese's rule in turn weakens the same safety rule, and must say so too."""
    japanese = (builtin_kb_dir() / "etiquette/japanese.yaml").read_text()
    assert "safety: true" in japanese  # the chain test below must not rely on this tag:
    root = kb_copy({
        "etiquette/japanese.yaml": japanese.replace("    safety: true\n", ""),
        "etiquette/loose.yaml": LOOSE.format(parent="japanese", target="tip_toward_giver"),
    })  # fmt: skip
    code, _, err = run(capsys, "--kb", str(root), "kb", "validate")
    assert code == EXIT_INVALID_KB
    assert ("rule 'tip_anywhere' overrides 'tip_toward_giver' (etiquette/japanese.yaml:"
            in err)  # fmt: skip
    assert "which stands in for the safety rule 'sharp_tip_away'" in err


# ================================================================ 3. determinism


def test_every_object_and_mode_gives_the_same_bytes_cold_warm_and_without_database(
    capsys, tmp_path
):
    """The grasp database changes how candidates are found, never what is planned: a cold
    database, a warm one and none give the same bytes. Without the arms' motion, which no
    database holds (its determinism, in one process and across processes, is tested in
    ``tests/engine/test_motion_plans.py`` and below)."""
    db = str(tmp_path / "db")
    for obj in OBJECTS:
        for mode in MODES:
            runs = [run(capsys, "plan", obj, "--mode", mode, "--json", "--no-motion", *extra)
                    for extra in (["--db", db], ["--db", db], ["--no-db"])]  # fmt: skip
            codes = {code for code, _, _ in runs}
            assert codes <= {EXIT_OK, EXIT_INFEASIBLE} and len(codes) == 1, (obj, mode)
            cold, warm, none = (out for _, out, _ in runs)
            assert cold == warm == none, f"{obj} --mode {mode}"
            assert_no_timings(json.loads(cold))


def test_a_plan_checked_in_physics_gives_the_same_bytes_twice(capsys, tmp_path):
    """The physics block holds what was simulated, not how long it took: a plan checked
    twice prints the same JSON (its wall time was in it, so no two runs agreed)."""
    db = str(tmp_path / "db")
    first, second = (run(capsys, "plan", "hammer", "--physics", "--json", "--db", db)
                     for _ in range(2))
    assert first[0] == second[0] == 0 and first[1] == second[1]
    data = json.loads(first[1])
    assert data["physics"]["passed"] and data["physics"]["chosen"]["simulated_seconds"] > 1.0
    assert_no_timings(data)


def assert_no_timings(data, path="") -> None:
    """No wall-clock value in the JSON: no key with a word naming seconds, time or duration
    (``generation.seconds`` was one; ``regrasp.second`` is the second grasp)."""
    timing = {"seconds", "sec", "ms", "time", "times", "timing", "timings", "duration", "elapsed"}
    # the planned motion's own clock: when each sample of a trajectory is reached, and how
    # long the motion takes (seeded, the same every run), not how long planning took; and
    # how much of its protocol a physics check simulated
    planned = {".robot_grasps.trajectory.times", ".motion.duration",
               *(f".physics.{group}.simulated_seconds"
                 for group in ("chosen", "alternatives_failed", "alternative_holds"))}
    if isinstance(data, dict):
        for key, value in data.items():
            if f"{path}.{key}" in planned:
                continue
            assert not timing & set(key.lower().split("_")), f"{path}.{key}"
            assert_no_timings(value, f"{path}.{key}")
    elif isinstance(data, list):
        for item in data:
            assert_no_timings(item, path)


QUERIES = [
    ["plan", "knife"],
    ["plan", "hammer", "--scene", "hammer_by_wall"],
    ["plan", "mug", "--culture", "korean", "--receiver", "elder"],
    ["grasps", "scissors"],
    ["kb", "show", "knife", "--culture", "japanese"],
]


@pytest.mark.parametrize("query", QUERIES, ids=lambda q: "-".join(q))
def test_separate_processes_give_the_same_bytes(capsys, db_with_maps, query):
    """Processes with different hash seeds (set and dict order would show), the first one
    with a cold database (the robot's maps only), the second with a warm one, print what
    this process prints."""
    code, here, _ = run(capsys, *query, "--json")
    seeds = ("0", "4242") if query[0] == "plan" else ("1",)
    for seed in seeds:
        env = dict(os.environ, PYTHONHASHSEED=seed, HANDOVER_DB=str(db_with_maps))
        proc = subprocess.run([str(HANDOVER), *query, "--json"], capture_output=True,
                              text=True, env=env, timeout=180)  # fmt: skip
        assert proc.returncode == code, proc.stderr
        assert proc.stdout == here, f"PYTHONHASHSEED={seed}"


def test_ties_go_to_the_lower_row(builtin_kb):
    """The ranking is score descending, then row index: equal scores are common (a ball, a
    symmetric book), and the choice among them must not depend on anything else."""
    from handover.engine.planner import plan
    from handover.engine.spec.query import Query

    ties = 0
    for obj in ("ball", "book", "hammer", "scissors"):
        decision = plan(builtin_kb, Query(object=obj)).attempt.decision
        order = decision.ranking()
        score = decision.score[order]
        assert (np.diff(score) <= 0).all()
        same = score[1:] == score[:-1]
        assert (order[1:][same] > order[:-1][same]).all()
        ties += int(same.sum())
    assert ties > 0  # the property was exercised


def test_batch_rows_hold_the_grasps_plan_prints(capsys, tmp_path):
    from handover.engine.tools.batch import read_rows

    out = tmp_path / "rows.parquet"
    code, _, _ = run(capsys, "batch", "--objects", "knife,hammer", "--out", str(out),
                     "--no-db", "--no-progress", "-j", "1")  # fmt: skip
    assert code == EXIT_OK
    rows = {r["object"]: r for r in read_rows(out)}
    for obj in ("knife", "hammer"):
        _, printed, _ = run(capsys, "plan", obj, "--json", "--no-db", "--no-motion")
        assert json.loads(rows[obj]["grasps"]) == json.loads(printed)["robot_grasps"]


# ================================================================ 4. atomic outputs


@pytest.fixture
def umask():
    """``umask(mask)`` sets the process umask for the test; restored afterwards."""
    old = os.umask(0o022)
    os.umask(old)
    yield lambda mask: os.umask(mask)
    os.umask(old)


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_outputs_get_the_umask_mode(capsys, tmp_path, umask, mask, mode):
    umask(mask)
    db = tmp_path / "db"
    code, _, _ = run(capsys, "plan", "pen", "-o", str(tmp_path / "out/pen.json"),
                     "--rrd", str(tmp_path / "out/pen.rrd"), "--db", str(db))  # fmt: skip
    assert code == EXIT_OK
    assert run(capsys, "kb", "schema", "-o", str(tmp_path / "schema"))[0] == EXIT_OK
    assert run(capsys, "batch", "--objects", "pen", "--out", str(tmp_path / "b.parquet"),
               "--db", str(db), "--no-progress", "-j", "1")[0] == EXIT_OK  # fmt: skip
    written = [tmp_path / "out/pen.json", tmp_path / "out/pen.rrd", tmp_path / "b.parquet",
               *(tmp_path / "schema").iterdir(), *db.rglob("*")]  # fmt: skip
    assert len(written) >= 5 + len(DOCUMENT_KINDS) - 1
    for path in written:  # folders (the KB cache's) as mkdir makes them
        want = (0o777 & ~mask) if path.is_dir() else mode
        assert path.stat().st_mode & 0o777 == want, path
    leftovers = [p for p in tmp_path.rglob("*") if p.name.endswith(".tmp")]
    assert leftovers == []


def test_a_failed_write_keeps_the_old_file(capsys, tmp_path, monkeypatch):

    out, rrd = tmp_path / "pen.json", tmp_path / "pen.rrd"
    out.write_text("old json")
    rrd.write_bytes(b"old recording")

    def half_written(result, ctx, decision, tmp, physics=None):
        Path(tmp).write_bytes(b"half a recording")
        raise RuntimeError("the disk went away")

    monkeypatch.setattr(handover.engine.report.rerun.writer, "_write", half_written)
    code, _, err = run(capsys, "plan", "pen", "--rrd", str(rrd), "--no-db")
    assert code == EXIT_INTERNAL and "the disk went away" in err
    assert rrd.read_bytes() == b"old recording"

    def no_rename(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(handover.geometry.atomic.os, "replace", no_rename)
    code, _, err = run(capsys, "plan", "pen", "-o", str(out), "--no-db")
    assert code == EXIT_USAGE
    assert f"-o {out}: cannot write there (No space left on device)" in err
    assert out.read_text() == "old json"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pen.json", "pen.rrd"]


@pytest.mark.parametrize(
    "args",
    [
        ["plan", "pen", "--no-db", "-o", "{blocker}/x.json"],
        ["plan", "pen", "--no-db", "--rrd", "{blocker}/x.rrd"],
        ["kb", "schema", "-o", "{blocker}/schema"],
        ["batch", "--objects", "pen", "--no-db", "--no-progress", "--out", "{blocker}/x.pq"],
    ],
)
def test_unwritable_outputs_are_usage_errors(capsys, tmp_path, args):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    code, _, err = run(capsys, *(a.format(blocker=blocker) for a in args))
    assert code == EXIT_USAGE
    assert "cannot write there" in err and str(blocker) in err
    assert_clean(err)


def test_output_piped_to_a_reader_that_stops_early_ends_quietly(tmp_path):
    """``handover plan knife --explain | head -2``: the command ends as ``cat`` would, by
    SIGPIPE, with nothing on stderr (not exit 1, "a bug")."""
    import signal

    cli = ("import sys; from handover.engine.cli import main; "
           "sys.argv = ['handover', *sys.argv[1:]]; main()")
    proc = subprocess.Popen([sys.executable, "-c", cli, "plan", "pen", "--no-motion",
                             "--explain"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader is gone before the command writes a byte
    err = proc.stderr.read().decode()
    assert proc.wait(120) == -signal.SIGPIPE, err
    assert err == ""
