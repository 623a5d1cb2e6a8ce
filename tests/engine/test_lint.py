"""Semantic checks: each error class on a small broken KB, with file, line and message."""

from __future__ import annotations

from pathlib import Path

import pytest

from handover.engine.errors import KBError
from handover.engine.load.loader import load_kb


def line_of(text: str, needle: str, nth: int = 0) -> int:
    """1-based number of the ``nth`` line of ``text`` containing ``needle``."""
    return [i + 1 for i, line in enumerate(text.splitlines()) if needle in line][nth]


def problems(root: Path) -> list:
    with pytest.raises(KBError) as info:
        load_kb(root)
    return info.value.issues


def the_error(root: Path, needle: str):
    hits = [i for i in problems(root) if needle in i.message]
    assert len(hits) == 1, [str(i) for i in problems(root)]
    return hits[0]


def culture(rules: str, cid: str = "common", extends: str | None = None) -> str:
    head = f"id: {cid}\nname: {cid.title()}\n"
    if extends is not None:
        head += f"extends: {extends}\n"
    return head + "rules:\n" + rules


COMMON_RULES = """\
  - id: no_sharp
    kind: contact
    who: receiver
    forbid_tags: [sharp]
    safety: true
    why: Never hand over a blade first.
  - id: tip_away
    kind: axis
    axis: tip
    toward: toward_receiver
    min_deg: 100
    applies: {object_tags_any: [sharp]}
    why: Points away from people.
"""


def test_minimal_kb_is_clean(make_kb):
    kb = load_kb(make_kb())
    assert kb.warnings == []


# ---------------------------------------------------------------- ids


def test_duplicate_ids_across_files(make_kb):
    twin = "# the same id again\nid: adult\nname: Twin\n"
    issue = the_error(make_kb({"receivers/twin.yaml": twin}), "duplicate receiver id")
    assert (issue.file, issue.line, issue.col) == ("receivers/twin.yaml", 2, 5)
    assert "already defined in receivers/adult.yaml:1" in issue.message


# ---------------------------------------------------------------- rule references


def test_rule_tag_no_object_carries(make_kb):
    rules = (
        COMMON_RULES
        + """\
  - id: careful
    kind: contact
    who: giver
    forbid_tags: [hot, sharp]
    why: Hot things burn.
"""
    )
    text = culture(rules)
    issue = the_error(make_kb({"etiquette/common.yaml": text}), "names tag 'hot'")
    assert issue.file == "etiquette/common.yaml"
    line = line_of(text, "forbid_tags: [hot")
    assert (issue.line, issue.col) == (line, text.splitlines()[line - 1].index("hot") + 1)
    assert "no object or part carries" in issue.message


def test_rule_tag_in_applies_is_checked_too(make_kb):
    rules = COMMON_RULES.replace("object_tags_any: [sharp]", "object_tags_any: [sharpp]")
    text = culture(rules)
    issue = the_error(make_kb({"etiquette/common.yaml": text}), "names tag 'sharpp'")
    assert issue.line == line_of(text, "sharpp")


def test_override_of_unknown_rule(make_kb):
    text = culture(
        """\
  - id: firm
    kind: axis
    axis: tip
    toward: away_from_receiver
    max_deg: 45
    overrides: [tip_awya]
    why: x
""",
        "strict",
    )
    root = make_kb({"etiquette/strict.yaml": text})
    issue = the_error(root, "overrides 'tip_awya'")
    assert (issue.file, issue.line) == ("etiquette/strict.yaml", line_of(text, "overrides"))
    assert "no culture that 'strict' extends has a rule 'tip_awya'" in issue.message


def test_override_within_the_same_culture_is_not_an_override(make_kb):
    rules = (
        COMMON_RULES
        + """\
  - id: tip_away_more
    kind: axis
    axis: tip
    toward: toward_receiver
    min_deg: 120
    overrides: [tip_away]
    why: x
"""
    )
    issue = the_error(make_kb({"etiquette/common.yaml": culture(rules)}), "overrides 'tip_away'")
    assert "no culture that 'common' extends" in issue.message


def test_rule_overridden_twice_in_one_culture(make_kb):
    rule = """\
  - id: {id}
    kind: axis
    axis: tip
    toward: away_from_receiver
    max_deg: 45
    overrides: [tip_away]
    why: x
"""
    text = culture(rule.format(id="one") + rule.format(id="two"), "strict")
    issue = the_error(make_kb({"etiquette/strict.yaml": text}), "already overridden")
    assert issue.line == line_of(text, "overrides", 1)
    assert "rule 'tip_away' is already overridden by 'one' (etiquette/strict.yaml:4)" in (
        issue.message
    )


def test_repeated_rule_id_without_overrides(make_kb):
    text = culture(
        """\
  - id: tip_away
    kind: axis
    axis: tip
    toward: away_from_receiver
    max_deg: 45
    why: x
""",
        "strict",
    )
    issue = the_error(make_kb({"etiquette/strict.yaml": text}), "repeats the rule")
    assert (issue.file, issue.line) == ("etiquette/strict.yaml", 4)
    assert "of culture 'common' (etiquette/common.yaml:" in issue.message
    assert "say 'overrides: [tip_away]'" in issue.message


def test_rule_id_twice_in_one_culture(make_kb):
    text = culture(COMMON_RULES + COMMON_RULES.split("  - id: tip_away")[0])
    issue = the_error(make_kb({"etiquette/common.yaml": text}), "appears twice")
    assert issue.line == line_of(text, "id: no_sharp", 1)


# ---------------------------------------------------------------- extends


@pytest.mark.parametrize(
    ("files", "expected"),
    [
        ({"a": "a"}, "'extends' forms a cycle: a -> a"),
        ({"a": "b", "b": "a"}, "'extends' forms a cycle: a -> b -> a"),
    ],
)
def test_extends_cycles(make_kb, files, expected):
    texts = {
        f"etiquette/{cid}.yaml": culture("  []\n", cid, extends=parent).replace("rules:\n  []", "")
        for cid, parent in files.items()
    }
    root = make_kb(texts)
    issues = [i for i in problems(root) if "cycle" in i.message]
    assert sorted(i.file for i in issues) == sorted(texts)  # each culture on the cycle
    first = next(i for i in issues if i.file == "etiquette/a.yaml")
    assert expected in first.message
    assert first.line == 3  # the `extends:` line


def test_extends_unknown_culture(make_kb):
    text = "id: strict\nname: Strict\nextends: comon\n"
    issue = the_error(make_kb({"etiquette/strict.yaml": text}), "extends 'comon'")
    assert (issue.line, issue.col) == (3, 10)
    assert issue.message == "culture 'strict' extends 'comon', which does not exist"


def test_implicit_common_must_exist(make_kb):
    root = make_kb(
        {"etiquette/common.yaml": None, "etiquette/strict.yaml": "id: strict\nname: S\n"}
    )
    issue = the_error(root, "extends 'common'")
    assert issue.line == 1
    assert "(implicitly: no 'extends' given)" in issue.message


# ---------------------------------------------------------------- safety overrides


SAFETY_OVERRIDE = """\
  - id: relaxed
    kind: contact
    who: receiver
    forbid_tags: [sharp]
    hard: false
    overrides: [no_sharp]
    why: x
"""


def test_safety_override_without_reason_is_an_error(make_kb):
    text = culture(SAFETY_OVERRIDE, "lax")
    issue = the_error(make_kb({"etiquette/lax.yaml": text}), "overrides the safety rule")
    assert issue.line == line_of(text, "overrides")
    assert "without 'override_safety: <reason>'" in issue.message


def test_safety_override_with_reason_is_a_warning(make_kb):
    text = culture(SAFETY_OVERRIDE + "    override_safety: trained chefs only\n", "lax")
    kb = load_kb(make_kb({"etiquette/lax.yaml": text}))
    (warning,) = kb.warnings
    assert warning.severity == "warning"
    assert warning.line == line_of(text, "override_safety")
    assert warning.message == (
        "safety rule 'no_sharp' (etiquette/common.yaml:4) overridden by 'relaxed': "
        "trained chefs only"
    )


# ---------------------------------------------------------------- objects


def stick(**changes: str) -> str:
    text = """\
id: stick
name: Stick
mass: 0.1
geometry:
  primitives:
    - {shape: box, part: grip, extents: [0.1, 0.02, 0.02], position: [-0.05, 0, 0]}
    - {shape: box, part: point, extents: [0.1, 0.01, 0.01], position: [0.05, 0, 0]}
parts:
  grip: {tags: [handle]}
  point: {tags: [sharp]}
axes:
  tip: [1, 0, 0]
"""
    for old, new in changes.items():
        text = text.replace(old.replace("_", " "), new)
    return text


def test_primitive_part_not_declared(make_kb):
    text = stick(**{"part: point": "part: pointy"})
    issue = the_error(make_kb({"objects/stick.yaml": text}), "part 'pointy'")
    assert (issue.line, issue.col) == (7, text.splitlines()[6].index("pointy") + 1)
    assert "is not declared in the object's parts (declared: grip, point)" in issue.message


def test_mesh_parts_not_declared(make_kb):
    text = """\
id: stick
name: Stick
mass: 0.1
geometry:
  mesh:
    file: stick.stl
    default_part: body
    regions:
      - {part: grip, center: [0, 0, 0], extents: [1, 1, 1]}
      - {part: point, center: [0, 0, 0], extents: [1, 1, 1]}
parts:
  grip: {tags: [handle]}
  point: {tags: [sharp]}
axes: {tip: [1, 0, 0]}
"""
    root = make_kb({"objects/stick.yaml": text, "objects/stick.stl": "solid\n"})
    issue = the_error(root, "part 'body'")
    assert issue.line == line_of(text, "default_part")
    text = text.replace("part: point,", "part: tip,").replace(
        "default_part: body", "default_part: grip"
    )
    issue = the_error(make_kb({"objects/stick.yaml": text}), "part 'tip'")
    assert issue.line == line_of(text, "part: tip")


@pytest.mark.parametrize(
    ("file", "expected"),
    [
        ("missing.stl", "mesh file 'missing.stl' does not exist (looked for objects/missing.stl)"),
        ("/etc/passwd", "is an absolute path"),
        ("../../outside.stl", "leaves the KB folder"),
    ],
)
def test_mesh_file_problems(make_kb, file, expected):
    text = f"""\
id: vase
name: Vase
mass: 0.5
geometry:
  mesh: {{file: "{file}", default_part: body}}
parts: {{body: {{}}}}
"""
    root = make_kb({"objects/vase.yaml": text})
    (root.parent / "outside.stl").write_text("solid\n")
    issue = the_error(root, "mesh file")
    assert (issue.file, issue.line) == ("objects/vase.yaml", 5)
    assert expected in issue.message


def test_task_axis_and_tags_and_default(make_kb):
    text = (
        stick()
        + """\
tasks:
  stab:
    receiver_tags: [handle, blunt]
    present:
      - {axis: tipp, toward: away_from_receiver}
default_task: poke
"""
    )
    issues = problems(make_kb({"objects/stick.yaml": text}))
    by_line = {i.line: i.message for i in issues}
    assert (
        "task 'stab' presents axis 'tipp', which object 'stick' does not define"
        in (by_line[line_of(text, "axis: tipp")])
    )
    assert "no part of 'stick' carries it" in by_line[line_of(text, "receiver_tags")]
    assert (
        "default_task 'poke' is not one of the object's tasks (stab)"
        == (by_line[line_of(text, "default_task")])
    )


def test_axis_rule_on_an_axis_no_object_defines(make_kb):
    rules = COMMON_RULES.replace("axis: tip", "axis: point")
    text = culture(rules)
    issue = the_error(make_kb({"etiquette/common.yaml": text}), "axis 'point'")
    assert issue.line == line_of(text, "axis: point")
    assert "which no object defines" in issue.message


def test_axis_rule_on_an_object_without_the_axis_warns(make_kb):
    knife = stick().replace("id: stick", "id: knife").replace("axes:\n  tip: [1, 0, 0]\n", "")
    kb = load_kb(make_kb({"objects/knife.yaml": knife}))
    (warning,) = kb.warnings
    assert "rule 'tip_away' applies to object 'knife' (objects/knife.yaml:1)" in warning.message


KEEP_OUT = """\
  - id: out_of_the_opening
    kind: keep_out
    tags: [open_container]
    of: [gripper, receiver_hand]
    safety: true
    why: Nothing goes into an open container.
"""


def cup(shape: str) -> str:
    body = ("{shape: cylinder, part: body, radius: 0.04, height: 0.1, position: [0, 0, 0.05]}"
            if shape == "solid" else
            "{shape: cup, part: body, radius: 0.04, height: 0.1, thickness: 0.004, "
            "position: [0, 0, 0.05]}")
    return ("id: cup\nname: Cup\nmass: 0.3\ntags: [open_container]\ngeometry:\n"
            f"  primitives:\n    - {body}\nparts:\n  body: {{tags: [handle]}}\n"
            "axes:\n  up: [0, 0, 1]\n")


@pytest.mark.parametrize("shape", ["solid", "hollow"])
def test_an_open_container_without_an_opening_to_measure_warns(make_kb, shape):
    root = make_kb({"etiquette/common.yaml": culture(COMMON_RULES + KEEP_OUT),
                    "objects/cup.yaml": cup(shape)})
    found = [w for w in load_kb(root).warnings if "cannot measure it" in w.message]
    if shape == "hollow":
        assert found == []
        return
    (warning,) = found
    assert warning.file == "objects/cup.yaml" and warning.line == 1
    assert "tagged open_container" in warning.message
    assert "no cup, bowl or tube primitive" in warning.message
    assert "out_of_the_opening" in warning.message
    # planning loads skip the deep checks (they build every object's geometry)
    assert not [w for w in load_kb(root, urdf=False).warnings
                if "cannot measure it" in w.message]


# ---------------------------------------------------------------- tags nobody handles


def tag_warnings(kb) -> list:
    return [w for w in kb.warnings if "is used by no rule and no task" in w.message]


def test_a_tag_no_rule_or_task_uses_warns_at_its_line(make_kb):
    text = stick(**{"point: {tags: [sharp]}": "point: {tags: [sharp, toxik]}"})
    text = text.replace("mass: 0.1\n", "mass: 0.1\ntags: [garden]\n")
    kb = load_kb(make_kb({"objects/stick.yaml": text}))
    by_tag = {w.message.split("'")[1]: w for w in tag_warnings(kb)}
    assert set(by_tag) == {"toxik", "garden"}
    toxik, garden = by_tag["toxik"], by_tag["garden"]
    assert toxik.file == "objects/stick.yaml" and toxik.severity == "warning"
    line = line_of(text, "toxik")
    assert (toxik.line, toxik.col) == (line, text.splitlines()[line - 1].index("toxik") + 1)
    assert "part 'point' of 'stick'" in toxik.message and "hazard nobody handles" in toxik.message
    assert garden.line == line_of(text, "tags: [garden]")
    assert "object 'stick'" in garden.message


def test_a_tag_is_used_by_any_rule_field_a_task_or_a_vocabulary(make_kb):
    text = stick(**{"point: {tags: [sharp]}": "point: {tags: [sharp, hot, spout, label, glass]}"})
    text += "tasks:\n  read:\n    receiver_tags: [label]\n"
    rules = COMMON_RULES + """\
  - id: cool_hands
    kind: contact
    who: receiver
    forbid_tags: [hot]
    why: Hot parts burn.
  - id: nothing_in_the_spout
    kind: keep_out
    tags: [spout]
    of: [gripper]
    why: Keep fingers out of a spout.
"""
    common = culture(rules) + "vocabulary:\n  glass: Made of glass.\n  handle: Held.\n"
    kb = load_kb(make_kb({"objects/stick.yaml": text, "etiquette/common.yaml": common}))
    assert tag_warnings(kb) == []
    # a rule in another culture counts as well
    other = culture(COMMON_RULES) + "vocabulary:\n  glass: Made of glass.\n  handle: Held.\n"
    lax = culture("""\
  - id: cool_hands
    kind: contact
    who: receiver
    forbid_tags: [hot, spout]
    why: Hot parts burn.
""", "lax")
    kb = load_kb(make_kb({"objects/stick.yaml": text, "etiquette/common.yaml": other,
                          "etiquette/lax.yaml": lax}))
    assert tag_warnings(kb) == []


def test_a_rule_may_name_a_tag_its_vocabulary_documents_before_any_object_carries_it(make_kb):
    rules = COMMON_RULES + """\
  - id: careful
    kind: contact
    who: giver
    forbid_tags: [hot, sharp]
    why: Hot things burn.
  - id: spray_away
    kind: axis
    axis: nozzle
    toward: toward_receiver
    min_deg: 100
    applies: {object_tags_any: [nozzle]}
    why: Never spray anyone.
"""
    vocab = "vocabulary:\n  hot: Burns.\n  nozzle: Sprays, along the axis nozzle.\n"
    kb = load_kb(make_kb({"etiquette/common.yaml": culture(rules) + vocab}))
    assert kb.culture("common").vocabulary["hot"] == "Burns."
    # undocumented, the same rules are errors at the tag and at the axis
    text = culture(rules)
    found = problems(make_kb({"etiquette/common.yaml": text}))
    hot = next(i for i in found if "names tag 'hot'" in i.message)
    assert hot.line == line_of(text, "forbid_tags: [hot")
    assert "no culture's vocabulary documents" in hot.message
    assert any("axis 'nozzle'" in i.message and i.line == line_of(text, "axis: nozzle")
               for i in found)


def test_a_keep_out_rule_s_tags_are_checked_like_any_rule_tag(make_kb):
    rules = COMMON_RULES + """\
  - id: nothing_in_the_cup
    kind: keep_out
    tags: [open_contianer]
    of: [gripper]
    why: Keep fingers out.
"""
    text = culture(rules)
    issue = the_error(make_kb({"etiquette/common.yaml": text}), "names tag 'open_contianer'")
    assert issue.line == line_of(text, "tags: [open_contianer]")


def test_the_builtin_vocabulary_has_rules_for_every_hazard(builtin_kb):
    from handover.engine.load.lint import rule_tags, vocabulary
    from handover.engine.store.hazards import tag_families

    hazards = ["sharp", "pointed", "needle", "hot", "liquid", "open_container", "fragile",
               "nozzle", "heavy", "small", "chemical", "medication", "swallowable", "flame",
               "battery", "magnet"]
    common = builtin_kb.culture("common")
    named = {tag for r in common.rules for tag, _ in rule_tags(r)}
    families = tag_families(builtin_kb)
    for tag in hazards:  # declared with what it means, and a rule for it or its family
        assert tag in families.declared and tag in vocabulary(builtin_kb), tag
        assert families.expand([tag]) & named, tag
    assert any(r.kind == "axis" and r.axis == "nozzle" and r.safety for r in common.rules)
    assert tag_warnings(builtin_kb) == []


def test_rule_task_no_object_has(make_kb):
    rules = COMMON_RULES.replace(
        "applies: {object_tags_any: [sharp]}", "applies: {tasks: [juggle]}"
    )
    issue = the_error(make_kb({"etiquette/common.yaml": culture(rules)}), "task 'juggle'")
    assert "which no object has" in issue.message


def test_part_without_geometry_warns(make_kb):
    text = stick().replace("  point: {tags: [sharp]}\n", "  point: {tags: [sharp]}\n  cap: {}\n")
    kb = load_kb(make_kb({"objects/stick.yaml": text}))
    (warning,) = kb.warnings
    assert warning.line == line_of(text, "cap:")
    assert warning.message == "part 'cap' has no geometry (no primitive or region names it)"


# ---------------------------------------------------------------- people and robot


def test_receiver_hand_unknown(make_kb):
    text = "id: adult\nname: Adult\nhand: big_hand\n"
    issue = the_error(make_kb({"receivers/adult.yaml": text}), "hand 'big_hand'")
    assert (issue.line, issue.col) == (3, 7)
    assert "does not exist (hands: adult_hand)" in issue.message


def test_robot_gripper_unknown(make_kb):
    text = "id: bot\nname: Bot\npayload_per_hand: 1.5\ngripper: claw\n"
    issue = the_error(make_kb({"robots/bot.yaml": text}), "gripper 'claw'")
    assert issue.line == 4


def test_scene_obstacle_ids_repeat(make_kb):
    text = """\
id: table
name: Table
obstacles:
  - {id: box, position: [0, 0, 0], extents: [1, 1, 1]}
  - {id: box, position: [1, 0, 0], extents: [1, 1, 1]}
"""
    issue = the_error(make_kb({"scenes/table.yaml": text}), "obstacle id 'box'")
    assert issue.line == 5


# ---------------------------------------------------------------- no cascades


def test_a_broken_object_does_not_make_rules_look_unused(make_kb):
    root = make_kb({"objects/stick.yaml": stick().replace("mass: 0.1", "mass: heavy")})
    issues = problems(root)
    assert [i.file for i in issues] == ["objects/stick.yaml"]


def test_a_broken_hands_file_does_not_make_receivers_look_wrong(make_kb):
    root = make_kb({"hands/adult_hand.yaml": "id: adult_hand\nname: [\n"})
    assert {i.file for i in problems(root)} == {"hands/adult_hand.yaml"}


GRIPPER_MESHES = """\
meshes:
  palm: {palm}
  finger: {finger}
"""


@pytest.mark.parametrize(
    ("palm", "finger", "part", "expected"),
    [
        ("palm.stl", "missing.stl", "finger",
         "mesh file 'missing.stl' does not exist (looked for grippers/missing.stl)"),
        ("../../outside.stl", "finger.stl", "palm", "leaves the KB folder"),
        ("/etc/palm.stl", "finger.stl", "palm", "is an absolute path"),
    ],
)  # fmt: skip
def test_gripper_mesh_file_problems(make_kb, palm, finger, part, expected):
    root = make_kb({"grippers/palm.stl": "solid\n", "grippers/finger.stl": "solid\n"})
    gripper = root / "grippers/jaw.yaml"  # the minimal KB's gripper, given meshes
    text = gripper.read_text() + GRIPPER_MESHES.format(palm=palm, finger=finger)
    gripper.write_text(text)
    (root.parent / "outside.stl").write_text("solid\n")
    issue = the_error(root, "mesh file")
    assert (issue.file, issue.line) == ("grippers/jaw.yaml", line_of(text, f"  {part}:"))
    assert expected in issue.message
