"""Hazards beyond tags: families of hazard tags declared in the KB (``kb/hazards``), hazards
measured on the geometry, and the age rules written for families. Objects are written here
into a copy of the built-in KB; what they are (bleach, pills, a candle, a coin cell) is in
their tags, or, for the coin cell, in nothing but its size."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from handover.engine.errors import KBError
from handover.engine.load.loader import load_kb
from handover.engine.planner import Planner
from handover.engine.store.kb import builtin_kb_dir

BLEACH = """\
id: bleach
name: A bottle of bleach
mass: 1.1
tags: [corrosive]
geometry:
  primitives:
    - {shape: box, part: bottle, extents: [0.09, 0.06, 0.22], position: [0, 0, 0.11]}
    - {shape: cylinder, part: cap, radius: 0.015, height: 0.03, position: [0, 0, 0.235]}
parts:
  bottle: {tags: [body]}
  cap: {tags: [cap]}
axes:
  up: [0, 0, 1]
"""

# A prescription pill bottle with its label on the side facing +x.
PILLS = """\
id: pills
name: A bottle of prescription pills
mass: 0.08
tags: [medication]
geometry:
  primitives:
    - {shape: cylinder, part: bottle, radius: 0.02, height: 0.075, position: [0, 0, 0.0375]}
    - {shape: cylinder, part: cap, radius: 0.019, height: 0.015, position: [0, 0, 0.0825]}
parts:
  bottle: {tags: [body]}
  cap: {tags: [cap]}
axes:
  up: [0, 0, 1]
  readable: [1, 0, 0]
"""

CANDLE = """\
id: candle
name: A lit candle in its holder
mass: 0.3
geometry:
  primitives:
    - {shape: cylinder, part: holder, radius: 0.045, height: 0.02, position: [0, 0, 0.01]}
    - {shape: cylinder, part: candle, radius: 0.012, height: 0.12, position: [0, 0, 0.08]}
    - {shape: cylinder, part: flame, radius: 0.005, height: 0.025, position: [0, 0, 0.1525]}
parts:
  holder: {tags: [grip]}
  candle: {tags: [body]}
  flame: {tags: [flame]}
axes:
  up: [0, 0, 1]
"""

# A CR2032 coin cell, 20 mm across and 3.2 mm thick, with no tag at all.
COIN_CELL = """\
id: coin_cell
name: A coin cell, untagged
mass: 0.003
geometry:
  primitives:
    - {shape: cylinder, part: cell, radius: 0.01, height: 0.0032, position: [0, 0, 0.0016],
       sections: 48}
parts:
  cell: {tags: []}
"""

RECEIVERS = {
    "three": "id: three\nname: Three years old\nrole: child\nage: 3\nstature: 0.95\n"
             "hand: child_hand\n",
}


@pytest.fixture(scope="module")
def kb_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("families") / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    for name, text in {"bleach": BLEACH, "pills": PILLS, "candle": CANDLE,
                       "coin_cell": COIN_CELL}.items():
        (root / "objects" / f"{name}.yaml").write_text(text, encoding="utf-8")
    for name, text in RECEIVERS.items():
        (root / "receivers" / f"{name}.yaml").write_text(text, encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def planner(kb_dir):
    return Planner(kb=kb_dir, db=False)


# ---------------------------------------------------------------- refused to young children


@pytest.mark.parametrize(("obj", "rule", "because"), [
    ("bleach", "no_chemicals_or_medicines_to_young_children", "chemical: implied by corrosive"),
    ("pills", "no_chemicals_or_medicines_to_young_children", None),
    ("candle", "no_hazards_to_young_children", "hot: implied by flame"),
    ("coin_cell", "no_swallowables_to_young_children", "swallowable: measured"),
])
@pytest.mark.parametrize("receiver", ["three", "child"])  # 3 and 7.5 years old
def test_young_children_are_not_handed_chemicals_medicines_flames_or_swallowables(
        planner, obj, rule, because, receiver):
    plan = planner.plan(obj, receiver=receiver)
    assert plan.outcome == "refuse", plan.reason
    assert rule in plan.reason
    if because is not None:  # the object's file does not say it: the reason says where from
        assert because in plan.reason
    assert plan.to_dict().get("placement") is None  # not set down within their reach either


def test_an_untagged_coin_cell_is_swallowable_by_its_size_alone(planner):
    plan = planner.plan("coin_cell", receiver="child")
    assert "20.0 mm across" in plan.reason or "3.2 mm long" in plan.reason
    assert "31.7 mm x 57.1 mm cylinder" in plan.reason


def test_the_age_decides_an_adult_is_handed_the_bleach(planner):
    plan = planner.plan("bleach", receiver="adult")
    assert plan.outcome == "handover", plan.reason


# ---------------------------------------------------------------- supervision, 8 to 14


@pytest.mark.parametrize(("obj", "rule"), [
    ("scissors", "point_away_from_children"),  # pointed, not sharp (closed blades)
    ("knife", "sharp_handle_first_for_children"),
    ("candle", "flame_upright_for_children"),
])
def test_a_ten_year_old_is_handed_points_blades_and_flames_with_a_supervisor(planner, obj,
                                                                             rule):
    plan = planner.plan(obj, receiver="child_10")
    assert plan.outcome == "handover", plan.reason
    assert any("an adult should supervise" in w for w in plan.warnings), plan.warnings
    assert {e["status"] for e in plan.trace
            if e["rule"] == rule and e["stage"] != "pick"} == {"pass"}


def test_an_adult_is_handed_scissors_without_a_supervisor(planner):
    plan = planner.plan("scissors", receiver="adult")
    assert not any("supervise" in w for w in plan.warnings)


# ---------------------------------------------------------------- labels


def test_a_pill_bottle_s_label_faces_the_receiver(planner):
    result = planner.plan("pills", receiver="adult").to_dict()
    assert result["outcome"] == "handover", result["reason"]
    label = np.asarray(result["object_pose"])[:3, :3] @ np.array([1.0, 0.0, 0.0])
    to_receiver = np.asarray(result["receiver"]["position"], float) \
        - np.asarray(result["handover_point"]["position"], float)
    to_receiver[2] = 0.0
    cos = label @ to_receiver / np.linalg.norm(to_receiver)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))) <= 45.0
    entry = next(e for e in result["trace"] if e["rule"] == "readable_faces_receiver")
    assert entry["status"] == "scored" and entry["score"] > 0.8


def test_a_business_card_in_japan_is_handed_text_to_the_receiver_or_not_at_all(kb_dir):
    card = ("id: card\nname: A business card\nmass: 0.002\ntags: [business_card]\n"
            "geometry:\n  primitives:\n    - {shape: box, part: card, extents: [0.091, 0.055, "
            "0.0004], position: [0, 0, 0.0002]}\nparts:\n  card: {tags: [body]}\n")
    root = kb_dir.parent / "cards"
    shutil.copytree(kb_dir, root)
    (root / "objects" / "card.yaml").write_text(card, encoding="utf-8")
    plan = Planner(kb=root, db=False).plan("card", culture="japanese")
    # the card names no readable side: the hard rule cannot measure it, and blocks
    assert not plan.feasible
    assert "business_card_faces_receiver" in plan.reason and "not measured" in plan.reason
    assert "axis 'readable'" in plan.reason


# ---------------------------------------------------------------- the vocabulary, as KB data


def test_the_families_are_in_the_kb_with_their_meaning_and_sources(kb_dir):
    from handover.engine.store.hazards import tag_families

    families = tag_families(load_kb(kb_dir, urdf=False))
    assert {"chemical"} <= families.implied["corrosive"]
    assert {"chemical"} <= families.implied["toxic"]
    assert {"hot"} <= families.implied["flame"]
    assert {"swallowable"} <= families.implied["battery"]
    for tag in ("corrosive", "toxic", "medication", "flame", "swallowable", "battery"):
        assert families.declared[tag].means and families.declared[tag].sources, tag
    (measured,) = families.measured
    assert measured.tag == "swallowable"
    assert (measured.fits_cylinder.diameter, measured.fits_cylinder.length) == (0.0317, 0.0571)


def kb_errors(root) -> list:
    with pytest.raises(KBError) as info:
        load_kb(root, urdf=False)
    return info.value.issues


def line_of(text: str, needle: str) -> int:
    return next(i + 1 for i, line in enumerate(text.splitlines()) if needle in line)


HEAD = "id: workshop\nname: Workshop hazards\n"
BROKEN = {
    "an unknown implied tag": (
        HEAD + "tags:\n  solvent:\n    means: A solvent.\n    implies: [chemicl]\n",
        "implies: [chemicl]", "implies 'chemicl', which no hazards file declares"),
    "a cycle": (
        HEAD + "tags:\n  solvent:\n    means: A solvent.\n    implies: [varnish]\n"
        "  varnish:\n    means: A varnish.\n    implies: [solvent]\n",
        "implies: [varnish]", "a cycle of implications (solvent -> varnish -> solvent)"),
    "a measured hazard naming no tag": (
        HEAD + "measured:\n  - fits_cylinder: {diameter: 0.03, length: 0.05}\n"
        "    why: Small enough.\n", "- fits_cylinder", "missing required field 'tag'"),
    "a measured hazard naming an undeclared tag": (
        HEAD + "measured:\n  - {tag: tiny, fits_cylinder: {diameter: 0.03, length: 0.05},"
        " why: Small enough.}\n", "tag: tiny", "measured hazard 'tiny' is not a hazard tag"),
    "a tag declared twice": (
        HEAD + "tags:\n  corrosive:\n    means: Eats metal.\n", "corrosive:",
        "hazard tag 'corrosive' is declared twice"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_broken_hazard_vocabulary_is_a_kb_error_at_its_line(make_kb, case):
    text, needle, message = BROKEN[case]
    household = (builtin_kb_dir() / "hazards" / "household.yaml").read_text(encoding="utf-8")
    root = make_kb({"hazards/household.yaml": household, "hazards/workshop.yaml": text})
    hits = [i for i in kb_errors(root) if message in i.message]
    assert hits, [str(i) for i in kb_errors(root)]
    assert (hits[0].file, hits[0].line) == ("hazards/workshop.yaml", line_of(text, needle))
