"""``handover kb ...`` through its real entry points: a subprocess on the installed console
script, and ``engine.cli.app.main`` in-process."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest
import yaml

from handover.engine.cli.app import main
from handover.engine.spec.schema import DOCUMENT_KINDS
from handover.engine.store.kb import builtin_kb_dir
from handover.engine.store.validate import document_schema

HANDOVER = Path(sys.executable).parent / "handover"


def run(capsys, *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def kb_files() -> list[Path]:
    root = builtin_kb_dir()
    return sorted(p for kind in DOCUMENT_KINDS for p in (root / kind).glob("*.yaml"))


# ---------------------------------------------------------------- validate


def test_validate_as_a_subprocess_from_elsewhere(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "HANDOVER_KB"}
    proc = subprocess.run(
        [str(HANDOVER), "kb", "validate"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    n_objects = len(list((builtin_kb_dir() / "objects").glob("*.yaml")))
    assert proc.stdout.startswith(f"ok: {n_objects} objects, 3 cultures")


def test_validate_reports_every_error_with_exit_3(tmp_path, make_kb):
    root = make_kb(
        {
            "receivers/adult.yaml": "id: adult\nname: Adult\nrole: king\n",
            "robots/bot.yaml": "id: bot\nname: Bot\npayload_per_hand: 1\ngripper: claw\n",
        }
    )
    env = dict(os.environ, HANDOVER_KB=str(root))
    proc = subprocess.run(
        [str(HANDOVER), "kb", "validate"], capture_output=True, text=True, env=env, timeout=60
    )
    assert proc.returncode == 3
    assert "receivers/adult.yaml:3:7: role: must be one of" in proc.stderr
    assert "robots/bot.yaml:4:10: robot 'bot' has gripper 'claw'" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_validate_json(capsys, make_kb):
    root = make_kb({"receivers/adult.yaml": "id: adult\nname: Adult\nrole: king\n"})
    code, out, err = run(capsys, "--kb", str(root), "kb", "validate", "--json")
    assert code == 3
    data = json.loads(out)
    assert data["ok"] is False
    assert [(e["file"], e["line"]) for e in data["errors"]] == [("receivers/adult.yaml", 3)]
    code, out, _ = run(capsys, "kb", "validate", "--json")
    data = json.loads(out)
    assert code == 0 and data["ok"] is True
    assert data["counts"]["objects"] == len(list((builtin_kb_dir() / "objects").glob("*.yaml")))
    assert [w["file"] for w in data["warnings"]] == ["etiquette/japanese.yaml"]


def test_missing_kb_folder_is_a_usage_error(capsys, tmp_path):
    code, _, err = run(capsys, "--kb", str(tmp_path / "nope"), "kb", "validate")
    assert code == 2
    assert "does not exist" in err


# ---------------------------------------------------------------- list


def test_list_json_is_one_object(capsys):
    code, out, _ = run(capsys, "kb", "list", "--json")
    assert code == 0
    data = json.loads(out)
    assert list(data)[:5] == ["objects", "cultures", "receivers", "scenes", "grippers"]
    objects = {o["id"]: o for o in data["objects"]}
    assert set(objects) == {p.stem for p in (builtin_kb_dir() / "objects").glob("*.yaml")}
    assert set(objects["knife"]) == {"id", "name", "mass", "tags", "parts", "tasks"}
    assert objects["hammer"]["tasks"] == ["drive_nail", "pull_nail"]
    cultures = {c["id"]: c for c in data["cultures"]}
    assert cultures["common"]["extends"] is None
    assert cultures["korean"]["extends"] == "common"
    assert cultures["japanese"]["rules"] == 5


def test_list_text_names_everything(capsys):
    code, out, _ = run(capsys, "kb", "list")
    assert code == 0
    for word in ("objects", "knife", "cultures", "japanese", "receivers", "scenes", "idro"):
        assert word in out


# ---------------------------------------------------------------- show


def rule_line(culture: str, rule_id: str) -> int:
    text = (builtin_kb_dir() / f"etiquette/{culture}.yaml").read_text().splitlines()
    return next(i + 1 for i, line in enumerate(text) if line.strip() == f"- id: {rule_id}")


def test_show_knife_lists_parts_and_rules_with_sources(capsys):
    code, out, _ = run(capsys, "kb", "show", "knife")
    assert code == 0
    assert "handle, grip" in out and "blade, sharp" in out
    line = rule_line("common", "receiver_avoids_sharp")
    assert f"receiver_avoids_sharp (contact, hard safety)  etiquette/common.yaml:{line}" in out
    # a rule about book pages cannot bear on a knife and is listed as such
    assert "book_upright (etiquette/common.yaml:" in out.split("cannot apply:")[1]


def test_show_knife_japanese_json_resolves_overrides(capsys):
    code, out, _ = run(capsys, "kb", "show", "knife", "--culture", "japanese", "--json")
    assert code == 0
    data = json.loads(out)
    assert data["kind"] == "object" and data["culture"] == "japanese"
    assert [p["name"] for p in data["parts"]] == ["handle", "blade"]
    rules = {r["id"]: r for r in data["rules"]}
    assert "sharp_tip_away" not in rules
    tip = rules["tip_toward_giver"]
    assert tip["culture"] == "japanese"
    assert tip["source"] == f"etiquette/japanese.yaml:{rule_line('japanese', 'tip_toward_giver')}"
    assert tip["overrides"] == [
        {
            "id": "sharp_tip_away",
            "culture": "common",
            "source": f"etiquette/common.yaml:{rule_line('common', 'sharp_tip_away')}",
        }
    ]
    skipped = {r["id"] for r in data["not_applicable"]}
    assert {"book_upright", "mug_handle_to_dominant_hand", "receiver_off_ink"} <= skipped
    assert not skipped & set(rules)


@pytest.mark.parametrize(
    ("item", "kind"),
    [
        ("korean", "culture"),
        ("adult", "receiver"),
        ("table", "scene"),
        ("parallel_jaw", "gripper"),
        ("idro", "robot"),
        ("child_hand", "hand"),
    ],
)
def test_show_other_kinds(capsys, item, kind):
    code, out, _ = run(capsys, "kb", "show", item, "--json")
    assert code == 0
    data = json.loads(out)
    assert (data["kind"], data["id"]) == (kind, item)
    folder = "etiquette" if kind == "culture" else f"{kind}s"
    assert data["source"].startswith(f"{folder}/{item}.yaml:")


def test_show_culture_text(capsys):
    code, out, _ = run(capsys, "kb", "show", "japanese")
    assert code == 0
    assert "extends: common" in out
    assert "overrides: handle_toward_receiver (etiquette/common.yaml:" in out


def test_show_unknown_id_exits_2(capsys):
    code, _, err = run(capsys, "kb", "show", "spoon")
    assert code == 2
    assert "'spoon'" in err and "knife" in err
    code, _, err = run(capsys, "kb", "show", "knife", "--culture", "martian")
    assert code == 2 and "unknown culture 'martian'" in err


def test_show_same_id_in_two_kinds_needs_kind(capsys, make_kb):
    root = make_kb({"scenes/stick.yaml": "id: stick\nname: Stick scene\n"})
    code, _, err = run(capsys, "--kb", str(root), "kb", "show", "stick")
    assert code == 2 and "--kind" in err
    code, out, _ = run(capsys, "--kb", str(root), "kb", "show", "stick", "--kind", "scene")
    assert code == 0 and "Stick scene" in out


# ---------------------------------------------------------------- schema


def test_schema_validates_every_builtin_file(capsys):
    code, out, _ = run(capsys, "kb", "schema")
    assert code == 0
    combined = json.loads(out)
    jsonschema.Draft7Validator.check_schema(combined)
    any_doc = jsonschema.Draft7Validator(combined)
    for path in kb_files():
        data = yaml.safe_load(path.read_text())
        kind_schema = document_schema(path.parent.name)
        jsonschema.Draft7Validator.check_schema(kind_schema)
        assert list(jsonschema.Draft7Validator(kind_schema).iter_errors(data)) == [], path
        assert any_doc.is_valid(data), path


def test_schema_rejects_what_the_loader_rejects():
    validator = jsonschema.Draft7Validator(document_schema("objects"))
    knife = yaml.safe_load((builtin_kb_dir() / "objects/knife.yaml").read_text())
    assert validator.is_valid(knife)
    for broken in (
        {**knife, "colour": "red"},
        {**knife, "mass": -1},
        {k: v for k, v in knife.items() if k != "name"},
        {**knife, "axes": {"tip": [1, 0]}},
        {**knife, "source": {"file": "x"}},
    ):
        assert not validator.is_valid(broken)


def test_every_kb_file_has_the_modeline_of_its_kind():
    for path in kb_files():
        first = path.read_text().splitlines()[0]
        assert first == f"# yaml-language-server: $schema=../schema/{path.parent.name}.json", path
        assert (path.parent / f"../schema/{path.parent.name}.json").resolve().is_file()


def test_committed_schema_files_are_up_to_date(capsys, tmp_path):
    code, out, _ = run(capsys, "kb", "schema", "-o", str(tmp_path / "schema"), "--json")
    assert code == 0
    written = json.loads(out)["written"]
    assert len(written) == len(DOCUMENT_KINDS)
    for path in map(Path, written):
        committed = builtin_kb_dir() / "schema" / path.name
        assert committed.read_text() == path.read_text(), (
            f"{committed} is stale: run `handover kb schema -o kb/schema`"
        )


def test_schema_of_one_kind_to_a_file(capsys, tmp_path):
    target = tmp_path / "scenes.json"
    code, out, _ = run(capsys, "kb", "schema", "--kind", "scenes", "-o", str(target))
    assert code == 0 and out.strip() == f"wrote {target}"
    assert json.loads(target.read_text())["title"].startswith("handover-grasp KB: scenes/")
    code, _, err = run(capsys, "kb", "schema", "--kind", "spoons")
    assert code == 2 and "unknown document kind" in err


def test_kb_copied_elsewhere_still_validates(capsys, tmp_path):
    copy = tmp_path / "mykb"
    shutil.copytree(builtin_kb_dir(), copy, ignore=shutil.ignore_patterns("*.py", "__pycache__"))
    code, out, _ = run(capsys, "--kb", str(copy), "kb", "validate")
    assert code == 0 and str(copy) in out
