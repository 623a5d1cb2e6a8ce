"""Culture resolution through extends/overrides, and which rules bear on an object."""

from __future__ import annotations

import pytest

from handover.engine.errors import UsageError
from handover.engine.load.loader import load_kb
from handover.engine.spec.schema import Applies, ObjectSpec, RuleBase, parse_rule
from handover.engine.store.cultures import (
    applies_to_object,
    culture_chain,
    object_extents,
    object_size,
    object_tags,
    resolve_culture,
)


def rule(rid: str, **fields) -> RuleBase:
    fields.setdefault("kind", "quality")
    fields.setdefault("min_quality", 0.1)
    return parse_rule(dict(id=rid, why="test", **fields))


# ---------------------------------------------------------------- the built-in cultures


def test_common_is_its_own_file_order(builtin_kb):
    resolved = resolve_culture(builtin_kb, "common")
    assert [r.rule.id for r in resolved] == [r.id for r in builtin_kb.culture("common").rules]
    assert {r.culture for r in resolved} == {"common"}
    assert all(r.overrides == () for r in resolved)


def test_japanese_replaces_in_place_and_appends(builtin_kb):
    common = [r.id for r in builtin_kb.culture("common").rules]
    resolved = resolve_culture(builtin_kb, "japanese")
    ids = [r.rule.id for r in resolved]
    # the overriders stand where the rules they replace stood
    assert ids.index("tip_toward_giver") == common.index("sharp_tip_away")
    assert ids.index("handle_first") == common.index("handle_toward_receiver")
    assert "sharp_tip_away" not in ids and "handle_toward_receiver" not in ids
    # new rules come last, in file order
    assert ids[-3:] == ["two_hands_for_superiors", "offered_with_both_taken_with_the_whole_hand",
                        "business_card_faces_receiver"]
    assert len(ids) == len(common) + 3
    tip = resolved[ids.index("tip_toward_giver")]
    assert tip.culture == "japanese"
    assert [(o.rule.id, o.culture) for o in tip.overrides] == [("sharp_tip_away", "common")]
    assert tip.rule.hard and tip.rule.safety


def test_korean_extends_common(builtin_kb):
    assert culture_chain(builtin_kb, "korean") == (["korean", "common"], None)
    resolved = resolve_culture(builtin_kb, "korean")
    assert resolved[-1].rule.id == "taken_in_the_whole_hand_when_given_with_both"
    last = resolved[-2]
    assert (last.rule.id, last.culture, last.rule.mode) == (
        "two_hands_for_elders",
        "korean",
        "H2G1",
    )
    assert last.rule.applies.receiver_roles == ["elder", "superior"]


def test_resolution_is_deterministic(builtin_kb):
    first = [(r.rule.id, r.culture) for r in resolve_culture(builtin_kb, "japanese")]
    again = [(r.rule.id, r.culture) for r in resolve_culture(builtin_kb, "japanese")]
    assert first == again


def test_unknown_culture_is_a_usage_error(builtin_kb):
    with pytest.raises(UsageError, match="unknown culture 'klingon'"):
        resolve_culture(builtin_kb, "klingon")


# ---------------------------------------------------------------- chains


def test_override_chain_over_three_levels(make_kb):
    polite = """\
id: polite
name: Polite
rules:
  - id: tip_firm
    kind: axis
    axis: tip
    toward: toward_receiver
    min_deg: 120
    overrides: [tip_away]
    why: firmer
  - id: extra
    kind: clearance
    min_m: 0.1
    why: more room
"""
    formal = """\
id: formal
name: Formal
extends: polite
rules:
  - id: tip_back
    kind: axis
    axis: tip
    toward: away_from_receiver
    max_deg: 30
    overrides: [tip_firm, extra]
    why: firmest
"""
    kb = load_kb(make_kb({"etiquette/polite.yaml": polite, "etiquette/formal.yaml": formal}))
    resolved = resolve_culture(kb, "formal")
    assert [(r.rule.id, r.culture) for r in resolved] == [
        ("no_sharp", "common"),
        ("tip_back", "formal"),  # where tip_away stood; `extra` is gone
    ]
    tip = resolved[1]
    assert [o.rule.id for o in tip.overrides] == ["tip_firm", "extra"]
    assert [o.rule.id for o in tip.chain()] == ["tip_firm", "tip_away", "extra"]
    assert tip.chain()[1].culture == "common"


# ---------------------------------------------------------------- rules and objects


def test_object_tags_are_object_and_part_tags(builtin_kb):
    assert object_tags(builtin_kb.object("knife")) == {
        "kitchen",
        "tool",
        "knife",
        "handle",
        "grip",
        "blade",
        "sharp",
    }


def test_applies_by_tags(builtin_kb):
    knife, mug, ball = (builtin_kb.object(i) for i in ("knife", "mug", "ball"))
    sharp = rule("r", applies=Applies(object_tags_any=["sharp", "pointed"]))
    assert applies_to_object(sharp, knife) is True
    assert applies_to_object(sharp, ball) is False
    handle_not_cup = rule(
        "r", applies=Applies(object_tags_any=["handle"], object_tags_none=["drinkware"])
    )
    assert applies_to_object(handle_not_cup, knife) is True
    assert applies_to_object(handle_not_cup, mug) is False
    assert applies_to_object(rule("r"), ball) is True


def test_applies_by_mass_and_size(builtin_kb):
    tray, knife = builtin_kb.object("tray"), builtin_kb.object("knife")
    heavy = rule("r", applies=Applies(min_mass=1.0))
    assert applies_to_object(heavy, tray) is True  # 2.5 kg
    assert applies_to_object(heavy, knife) is False  # 0.2 kg
    # the knife: a 0.12 m handle and a 0.20 m blade end to end
    assert object_size(knife) == pytest.approx(0.32)
    assert applies_to_object(rule("r", applies=Applies(min_size=0.3)), knife) is True
    assert applies_to_object(rule("r", applies=Applies(min_size=0.33)), knife) is False


def test_query_conditions_are_not_judged_here(builtin_kb):
    ball = builtin_kb.object("ball")
    for applies in (
        Applies(receiver_roles=["elder"]),
        Applies(tasks=["cut"]),
        Applies(modes=["H2G1"]),
        Applies(exceeds_payload=True),
    ):
        assert applies_to_object(rule("r", applies=applies), ball) is True


def test_extents_of_rotated_primitives(builtin_kb):
    # the screwdriver: handle cylinder (r 16 mm, 0.1 m) and shaft turned onto x,
    # from x = -0.1 (handle end) to 0.098 (tip end); 32 mm across its handle
    lo, hi = object_extents(builtin_kb.object("screwdriver"))
    assert lo == pytest.approx((-0.1, -0.016, -0.016))
    assert hi == pytest.approx((0.098, 0.016, 0.016))
    # a cylinder tilted 45 degrees about y: half extents h/2 sin45 + r cos45 along x and z
    obj = ObjectSpec(
        id="t",
        name="t",
        mass=1,
        geometry={
            "primitives": [
                {
                    "shape": "cylinder",
                    "part": "a",
                    "radius": 0.1,
                    "height": 0.4,
                    "rotation_deg": [0, 45, 0],
                },
            ]
        },
        parts={"a": {}},
    )
    lo, hi = object_extents(obj)
    s = 0.5**0.5
    assert hi == pytest.approx((0.2 * s + 0.1 * s, 0.1, 0.2 * s + 0.1 * s))
    assert lo == pytest.approx(tuple(-h for h in hi))


def test_mesh_size_depends_on_geometry():
    obj = ObjectSpec(
        id="v",
        name="v",
        mass=1,
        geometry={"mesh": {"file": "v.stl", "default_part": "a"}},
        parts={"a": {}},
    )
    assert object_size(obj) is None
    assert applies_to_object(rule("r", applies=Applies(min_size=0.1)), obj) is None
    # a condition that fails settles it, geometry or not
    assert applies_to_object(rule("r", applies=Applies(min_size=0.1, min_mass=2)), obj) is False


def test_describe_rule_says_what_it_asks(builtin_kb):
    rules = {r.id: r for r in builtin_kb.culture("common").rules}
    assert rules["receiver_avoids_sharp"].describe() == (
        "receiver never holds a part tagged sharp"
    )
    assert rules["giver_avoids_sharp"].describe() == (
        "giver never holds a part tagged sharp"
    )
    assert rules["sharp_tip_away"].describe() == (  # safety: judged on the way too
        "axis 'tip' at least 100 deg from toward_receiver, also while carried"
    )
    assert rules["open_container_upright"].describe() == (  # on_the_way: true
        "axis 'up' at most 20 deg from up, also while carried"
    )
    assert rules["book_upright"].describe() == "axis 'up' at most 20 deg from up"
