"""The loader: YAML to models, every problem located file:line:col, nothing executed."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from handover.engine.errors import KBError, UsageError
from handover.engine.load.loader import load_kb
from handover.engine.store.kb import builtin_kb_dir, resolve_kb_dir
from handover.engine.store.yamlpos import load_yaml_with_marks


def line_of(text: str, needle: str, nth: int = 0) -> int:
    """1-based number of the ``nth`` line of ``text`` containing ``needle``."""
    return [i + 1 for i, line in enumerate(text.splitlines()) if needle in line][nth]


def col_of(text: str, needle: str, nth: int = 0) -> int:
    line = text.splitlines()[line_of(text, needle, nth) - 1]
    return line.index(needle) + 1


def errors_of(root: Path) -> list:
    with pytest.raises(KBError) as info:
        load_kb(root)
    return info.value.issues


def only_error(root: Path):
    issues = errors_of(root)
    assert len(issues) == 1, [str(i) for i in issues]
    return issues[0]


STICK_BAD_KEY = """\
id: stick
name: Stick
mass: 0.1
colour: red
geometry:
  primitives:
    - shape: box
      part: grip
      extents: [0.1, 0.02, 0.02]
      psition: [0, 0, 0]
    - {shape: box, part: point, extents: [0.1, 0.01, 0.01]}
parts:
  grip: {tags: [handle]}
  point: {tags: [sharp]}
axes:
  tip: [1, 0, 0]
"""


# ---------------------------------------------------------------- the built-in KB


def test_builtin_kb_loads_every_file(builtin_kb):
    root = builtin_kb_dir()
    for folder, attr in [("objects", "objects"), ("etiquette", "cultures"), ("scenes", "scenes")]:
        stems = {p.stem for p in (root / folder).glob("*.yaml")}
        assert set(getattr(builtin_kb, attr)) == stems
    assert builtin_kb.root == root.absolute()


def test_builtin_sources_point_at_the_yaml(builtin_kb):
    knife = builtin_kb.object("knife")
    text = (builtin_kb_dir() / "objects/knife.yaml").read_text()
    assert knife.source.file == "objects/knife.yaml"
    assert knife.source.line == line_of(text, "id: knife")
    assert knife.parts["blade"].source.line == line_of(text, "blade:") + 1
    common = (builtin_kb_dir() / "etiquette/common.yaml").read_text()
    for k, rule in enumerate(builtin_kb.culture("common").rules):
        assert rule.source.file == "etiquette/common.yaml"
        lines = common.splitlines()
        assert lines[rule.source.line - 1].strip() == f"- id: {rule.id}"
        assert lines[rule.source.line - 1].index("id:") + 1 == rule.source.col
        assert rule.source.path == ("rules", k)
        assert str(rule.source) == f"etiquette/common.yaml:{rule.source.line}"


def test_builtin_kb_has_no_surprising_warnings(builtin_kb):
    # the one intended warning: Japanese etiquette overrides a safety rule with a stricter one
    assert [w.file for w in builtin_kb.warnings] == ["etiquette/japanese.yaml"]
    assert "safety rule 'sharp_tip_away'" in builtin_kb.warnings[0].message


# ---------------------------------------------------------------- schema errors


def test_unknown_keys_point_at_the_key_and_suggest(make_kb):
    root = make_kb({"objects/stick.yaml": STICK_BAD_KEY})
    issues = errors_of(root)
    by_line = {i.line: i for i in issues}
    colour = by_line[line_of(STICK_BAD_KEY, "colour:")]
    assert colour.file == "objects/stick.yaml"
    assert colour.col == 1
    assert "unknown field 'colour'" in colour.message
    typo = by_line[line_of(STICK_BAD_KEY, "psition:")]
    assert typo.col == col_of(STICK_BAD_KEY, "psition")
    assert "geometry.primitives[0]: unknown field 'psition'" in typo.message
    assert "did you mean 'position'?" in typo.message
    assert len(issues) == 2


def test_wrong_type_points_at_the_value(make_kb):
    text = "id: adult\nname: Adult\nstature: tall\n"
    issue = only_error(make_kb({"receivers/adult.yaml": text}))
    assert (issue.file, issue.line, issue.col) == ("receivers/adult.yaml", 3, 10)
    assert issue.message.startswith("stature: ")
    assert "'tall'" in issue.message


def test_missing_field_points_at_the_mapping(make_kb):
    text = "# a comment\nid: jaw\nname: Jaw\nmax_opening: 0.085\nfinger_length: 0.04\n"
    text += "finger_width: 0.02\nfinger_thickness: 0.01\n"  # no palm
    issue = only_error(make_kb({"grippers/jaw.yaml": text}))
    assert (issue.line, issue.col) == (2, 1)
    assert issue.message == "missing required field 'palm'"


def test_missing_field_in_a_nested_rule(make_kb):
    text = """\
        id: common
        name: Common
        rules:
          - id: no_sharp
            kind: contact
            who: receiver
            forbid_tags: [sharp]
            why: x
          - id: tip_away
            kind: axis
            axis: tip
            toward: toward_receiver
            min_deg: 100
        """
    issue = only_error(make_kb({"etiquette/common.yaml": text}))
    assert (issue.line, issue.col) == (9, 5)
    assert issue.message == "rules[1]: missing required field 'why'"


@pytest.mark.parametrize("value", [".nan", ".inf", "-.inf"])
def test_nan_and_inf_are_errors(make_kb, value):
    text = f"id: adult\nname: Adult\nstature: {value}\n"
    issue = only_error(make_kb({"receivers/adult.yaml": text}))
    assert issue.line == 3
    assert "finite" in issue.message


def test_a_field_of_another_rule_kind_points_at_the_field(make_kb):
    text = """\
        id: common
        name: Common
        rules:
          - id: no_sharp
            kind: contact
            who: receiver
            forbid_tags: [sharp]
            axis: tip
            why: x
        """
    issue = only_error(make_kb({"etiquette/common.yaml": text}))
    assert issue.line == 8  # the stray field itself
    assert issue.message.startswith("rules[0]: unknown field 'axis'; ContactRule takes: ")
    assert "who, forbid_tags, require_tags" in issue.message


def test_a_rule_kind_s_own_validator_points_at_the_rule(make_kb):
    text = """\
        id: common
        name: Common
        rules:
          - id: no_sharp
            kind: contact
            who: receiver
            why: x
        """
    issue = only_error(make_kb({"etiquette/common.yaml": text}))
    assert issue.line == 4
    assert issue.message == "rules[0]: a 'contact' rule needs forbid_tags or require_tags"


def test_bad_id_and_yaml_booleans_are_explained(make_kb):
    text = "id: Adult\nname: Adult\n"
    issue = only_error(make_kb({"receivers/adult.yaml": text}))
    assert issue.message.startswith("id: 'Adult' is not a valid id/tag")
    stick = (
        "id: stick\nname: Stick\nmass: 0.1\ntags: [on]\n"
        "geometry: {primitives: [{shape: sphere, part: a, radius: 0.1}]}\nparts: {a: {}}\n"
    )
    root = make_kb({"objects/stick.yaml": stick})
    issue = next(i for i in errors_of(root) if i.file == "objects/stick.yaml")
    assert issue.line == 4
    assert "YAML reads `on` as bool: put it in quotes" in issue.message


def test_source_key_is_not_accepted(make_kb):
    text = "id: adult\nname: Adult\nsource: {file: x.yaml, line: 3}\n"
    issue = only_error(make_kb({"receivers/adult.yaml": text}))
    assert (issue.line, issue.message) == (3, "unknown field 'source'")


# ---------------------------------------------------------------- YAML level


def test_duplicate_yaml_keys_are_errors(make_kb):
    text = "id: adult\nname: Adult\nstature: 1.7\nstature: 1.6\n"
    issue = only_error(make_kb({"receivers/adult.yaml": text}))
    assert (issue.line, issue.col) == (4, 1)
    assert "duplicate key 'stature' (first at line 3)" in issue.message


def test_python_tags_are_reported_not_executed(make_kb, tmp_path):
    marker = tmp_path / "executed"
    text = f'id: adult\nname: !!python/object/apply:os.system ["touch {marker}"]\n'
    issue = only_error(make_kb({"receivers/adult.yaml": text}))
    assert not marker.exists()
    assert (issue.line, issue.col) == (2, 7)
    assert "YAML tag '!!python/object/apply:os.system' is not allowed" in issue.message


@pytest.mark.parametrize("tag", ["!include other.yaml", "!!set {a, b}", "!!binary aGk="])
def test_other_tags_are_reported(make_kb, tag):
    issue = only_error(make_kb({"receivers/adult.yaml": f"id: adult\nname: {tag}\n"}))
    assert issue.line == 2
    assert "is not allowed" in issue.message


def test_syntax_error_has_a_position(make_kb):
    text = "id: adult\nname: [Adult\nrole: adult\n"
    issue = only_error(make_kb({"receivers/adult.yaml": text}))
    assert issue.file == "receivers/adult.yaml"
    assert issue.line == 3
    assert issue.message.startswith("YAML syntax:")


def test_recursive_alias_is_an_error(make_kb):
    text = "id: adult\nname: Adult\nx: &a [*a]\n"
    issue = only_error(make_kb({"receivers/adult.yaml": text}))
    assert "recursive alias" in issue.message


def test_alias_bombs_are_stopped(make_kb):
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 7)]
    issue = only_error(make_kb({"receivers/adult.yaml": "\n".join(lines) + "\n"}))
    assert "too large" in issue.message


def test_merge_keys_work(make_kb):
    text = "base: &b {name: Adult, role: elder}\n<<: *b\nid: adult\n"
    # 'base' is not a receiver field: merging works, the stray key is reported
    issue = only_error(make_kb({"receivers/adult.yaml": text}))
    assert "unknown field 'base'" in issue.message


@pytest.mark.parametrize(
    ("text", "expected"),
    [("", "empty file"), ("- a\n- b\n", "expected a ReceiverProfile mapping at the top")],
)
def test_empty_or_non_mapping_documents(make_kb, text, expected):
    issue = only_error(make_kb({"receivers/adult.yaml": text}))
    assert expected in issue.message


def test_non_utf8_file(make_kb):
    root = make_kb()
    (root / "receivers/adult.yaml").write_bytes(b"id: adult\nname: Ad\xffult\n")
    issue = only_error(root)
    assert (issue.line, issue.col) == (2, 9)
    assert "UTF-8" in issue.message


def test_control_characters_are_located(make_kb):
    issue = only_error(make_kb({"receivers/adult.yaml": "id: adult\nname: A\x07dult\n"}))
    assert (issue.line, issue.col) == (2, 8)
    assert issue.message == "character #x0007 is not allowed in YAML"


def test_every_error_of_every_file_at_once(make_kb):
    root = make_kb(
        {
            "receivers/adult.yaml": "id: adult\nname: Adult\nrole: king\n",
            "hands/adult_hand.yaml": "id: adult_hand\nname: [\n",
            "scenes/table.yaml": "id: table\nname: Table\nobstacles: [{id: box}]\n",
        }
    )
    files = sorted({i.file for i in errors_of(root)})
    assert files == ["hands/adult_hand.yaml", "receivers/adult.yaml", "scenes/table.yaml"]


def test_load_yaml_with_marks(tmp_path):
    path = tmp_path / "x.yaml"
    path.write_text("a:\n  b: [1, 2.5]\n  'c': x\n")
    data, marks = load_yaml_with_marks(path)
    assert data == {"a": {"b": [1, 2.5], "c": "x"}}
    assert marks.value(("a", "b", 1)) == (2, 10)
    assert marks.key(("a", "c")) == (3, 3)
    assert marks.value(("a", "nothing", 3)) == marks.value(("a",))
    path.write_text("a: 1\na: 2\n")
    with pytest.raises(KBError):
        load_yaml_with_marks(path)


# ---------------------------------------------------------------- folders, files, lookups


def test_folder_decides_the_kind_and_yml_loads(make_kb):
    root = make_kb(
        {
            "receivers/adult.yaml": None,
            "receivers/adult.yml": "id: adult\nname: Adult\n",
            "notes/readme.yaml": "anything: 1\n",
            "stray.yaml": "id: stray\n",
        }
    )
    kb = load_kb(root)
    assert kb.receiver("adult").source.file == "receivers/adult.yml"
    warned = {w.file: w for w in kb.warnings}
    assert warned["notes/readme.yaml"].severity == "warning"
    assert "folder 'notes'" in warned["notes/readme.yaml"].message
    assert "the KB root" in warned["stray.yaml"].message


def test_unknown_ids_are_usage_errors_naming_the_known(make_kb):
    kb = load_kb(make_kb())
    with pytest.raises(UsageError, match=r"unknown object 'stik' \(known: stick\)\. Did you mean"):
        kb.object("stik")
    for getter in ("culture", "receiver", "gripper", "hand", "robot", "scene"):
        with pytest.raises(UsageError, match=f"unknown {getter} 'nope'"):
            getattr(kb, getter)("nope")


def test_id_differing_from_file_name_warns(make_kb):
    kb = load_kb(make_kb({"receivers/adult.yaml": "id: grown_up\nname: Adult\n"}))
    assert kb.receiver("grown_up")
    assert any("differs from its file name" in w.message for w in kb.warnings)


def test_resolve_kb_dir(tmp_path, monkeypatch):
    monkeypatch.delenv("HANDOVER_KB", raising=False)
    assert resolve_kb_dir(None) == builtin_kb_dir().absolute()
    monkeypatch.setenv("HANDOVER_KB", str(tmp_path))
    assert resolve_kb_dir(None) == tmp_path
    other = tmp_path / "other"
    other.mkdir()
    assert resolve_kb_dir(other) == other
    with pytest.raises(UsageError, match="does not exist"):
        resolve_kb_dir(tmp_path / "missing")
    with pytest.raises(UsageError):
        load_kb(tmp_path / "missing")


def test_empty_folder_is_an_error(tmp_path):
    with pytest.raises(KBError, match="no KB documents"):
        load_kb(tmp_path)


def test_mesh_path_is_relative_to_the_object_file(make_kb):
    obj = """\
        id: vase
        name: Vase
        mass: 0.5
        geometry:
          mesh: {file: ../../meshes/vase.stl, default_part: body}
        parts: {body: {}}
        """
    root = make_kb({"objects/flowers/vase.yaml": obj, "meshes/vase.stl": "solid x\nendsolid x\n"})
    kb = load_kb(root)
    assert kb.mesh_path(kb.object("vase")) == root / "meshes/vase.stl"
    assert kb.mesh_path(kb.object("stick")) is None


def test_nothing_is_cached_between_loads(make_kb):
    root = make_kb()
    first = load_kb(root)
    (root / "receivers/adult.yaml").write_text("id: adult\nname: Changed\n")
    assert load_kb(root).receiver("adult").name == "Changed"
    assert first.receiver("adult").name == "Adult"


def test_loaded_numbers_are_plain(builtin_kb):
    gripper = builtin_kb.gripper("parallel_jaw")
    assert gripper.max_opening == 0.085
    assert all(math.isfinite(v) for v in gripper.palm)
