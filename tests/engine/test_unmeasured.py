"""No rule passes without measuring: a rule that cannot measure what it is about says
``unknown`` (with why, and how to fix the KB), and a hard rule that is unknown never lets a
candidate through; a rule with nothing to judge in a phase says ``not_applicable``, never
``pass``.

Every rule kind is swept over degenerate situations built here (an object tagged as a hazard
with no axes and no opening, a phase without the receiver, two hands before the partner is
known), and every row it passes must carry a finite measurement."""

from __future__ import annotations

import numpy as np
import pytest

from handover.engine.load.loader import load_kb
from handover.engine.plan import judge
from handover.engine.plan.hands import hands as plan_hands
from handover.engine.plan.judge import Outcome
from handover.engine.plan.phase import Phase, Roles
from handover.engine.plan.prepare import prepare
from handover.engine.planner import Planner
from handover.engine.spec.kinds import KINDS
from handover.engine.spec.query import Query
from handover.engine.spec.schema import parse_rule

# A crate tagged, as a whole, as sharp and as an open container, but with no named axis and
# solid walls: no rule about where its tip points or what enters its opening can measure it.
CRATE = """\
id: crate
name: A solid crate tagged as hazards it cannot show
mass: 0.4
tags: [sharp, open_container]
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.05, 0.04, 0.06], position: [0, 0, 0.03]}
parts:
  body: {tags: [handle]}
"""

VOCABULARY = """\
id: common
name: Common
rules:
  - id: tip_away
    kind: axis
    axis: tip
    toward: toward_receiver
    min_deg: 100
    safety: true
    applies: {object_tags_any: [sharp]}
    why: Points away from people.
vocabulary:
  handle: The part made to be held.
  sharp: An edge that cuts.
  open_container: Open at the top.
"""


@pytest.fixture(scope="module")
def crate_kb(tmp_path_factory):
    from tests.conftest import MINIMAL_KB, write_files

    root = tmp_path_factory.mktemp("unmeasured") / "kb"
    write_files(root, MINIMAL_KB)
    write_files(root, {"objects/crate.yaml": CRATE, "etiquette/common.yaml": VOCABULARY})
    return load_kb(root, urdf=False)


@pytest.fixture(scope="module")
def crate_ctx(crate_kb):
    return prepare(crate_kb, Query(object="crate", robot="bot", scene="table"))


def phases(ctx) -> dict[str, Phase]:
    """The phases a rule is judged in, the degenerate ones included."""
    hands = plan_hands(ctx, Roles(want=frozenset({"handle"})))
    return {
        "one hand, receiver there": Phase("H1G1", hands=hands),
        "pick-up, receiver away": Phase("H2G2", hands=hands, receiver_present=False),
        "two hands, partner unknown": Phase("H2G1", hands=hands),
    }


def example_rules(kind: str) -> list:
    """The kind's minimal rule, and the same rule applying to the crate by its tags."""
    base = {"id": f"a_{kind}", "kind": kind, "why": "test", **KINDS[kind].example}
    return [parse_rule(base),
            parse_rule(base | {"id": f"b_{kind}", "applies": {"object_tags_any": ["sharp"]}})]


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_no_kind_passes_a_row_it_did_not_measure(kind, crate_ctx):
    ctx = crate_ctx
    rows = 40
    gi = np.arange(rows) % ctx.n
    pk = np.arange(rows) % ctx.k
    for rule in example_rules(kind):
        if judge.not_applicable(rule, ctx) is not None:
            continue  # inactive: the trace says not_applicable with the reason
        for name, phase in phases(ctx).items():
            out = judge.evaluate(rule, ctx, phase, gi, pk)
            where = f"{rule.id} ({name})"
            if out.inapplicable is not None:
                assert out.inapplicable.strip(), where
                continue
            passed_unmeasured = out.passed & ~np.isfinite(out.measured)
            assert not passed_unmeasured.any(), f"{where} passes rows it did not measure"
            assert not (out.passed & out.unknown).any(), where
            assert np.all(out.score[out.unknown] == 0.0), where
            if out.unknown.any():
                assert len(out.unknown_why) > 30, where


def test_a_sharp_object_without_a_tip_axis_is_unknown_not_passed(crate_ctx):
    rule = parse_rule({"id": "tip_away", "kind": "axis", "axis": "tip",
                       "toward": "toward_receiver", "min_deg": 100, "why": "t",
                       "applies": {"object_tags_any": ["sharp"]}})
    assert judge.not_applicable(rule, crate_ctx) is None  # the crate is what it is about
    phase = phases(crate_ctx)["one hand, receiver there"]
    out = judge.evaluate(rule, crate_ctx, phase, np.arange(5), np.zeros(5, int))
    assert out.unknown.all() and not out.passed.any()
    assert "axis 'tip'" in out.unknown_why
    # a rule about every object with such an axis (no tag condition) does not concern it
    general = parse_rule({"id": "g", "kind": "axis", "axis": "tip", "toward": "up",
                          "max_deg": 90, "why": "t"})
    assert "no axis 'tip'" in judge.not_applicable(general, crate_ctx)


@pytest.mark.parametrize(("fields", "phase_name"), [
    ({"kind": "collision", "against": ["other_gripper"]}, "one hand, receiver there"),
    ({"kind": "hand_fit"}, "pick-up, receiver away"),
    ({"kind": "clearance", "min_m": 0.05}, "pick-up, receiver away"),
    ({"kind": "torque", "max_nm": 1.0}, "two hands, partner unknown"),
])
def test_a_rule_with_nothing_to_judge_in_a_phase_says_so(crate_ctx, fields, phase_name):
    rule = parse_rule({"id": "r", "why": "t", **fields})
    out = judge.evaluate(rule, crate_ctx, phases(crate_ctx)[phase_name], np.arange(3),
                         np.zeros(3, int))
    assert out.inapplicable


def test_an_unknown_row_never_passes_whatever_the_judge_computed():
    out = Outcome(np.array([True, True, False]), np.array([1.0, 2.0, 3.0]), np.ones(3),
                  "<= 5", "m", np.array([False, True, False]), "not measured: test")
    assert out.passed.tolist() == [True, False, False]
    assert out.score.tolist() == [1.0, 0.0, 1.0]
    assert np.isnan(out.measured[1])
    with pytest.raises(ValueError, match="why"):
        Outcome(np.ones(2, bool), np.ones(2), np.ones(2), "", "", np.ones(2, bool))


def test_a_plan_blocked_by_a_rule_that_cannot_measure_says_what_and_how_to_fix_it(crate_kb):
    plan = Planner(kb=crate_kb, db=False).plan("crate", robot="bot", mode="h1g1")
    assert plan.outcome == "infeasible"
    assert "not measured" in plan.reason
    assert "tip_away" in plan.reason and "axis 'tip'" in plan.reason
    assert "give the object an axis 'tip'" in plan.reason


def test_an_open_container_without_an_opening_is_unknown_not_passed(crate_ctx):
    rule = parse_rule({"id": "keep", "kind": "keep_out", "tags": ["open_container"],
                       "of": ["gripper", "receiver_hand"], "why": "t"})
    assert judge.not_applicable(rule, crate_ctx) is None
    phase = phases(crate_ctx)["one hand, receiver there"]
    out = judge.evaluate(rule, crate_ctx, phase, np.arange(5), np.zeros(5, int))
    assert out.unknown.all() and not out.passed.any()
    assert "no 'up' axis" in out.unknown_why  # the crate names none: nothing to look along


def test_a_mesh_without_the_region_of_its_sharp_part_is_not_handed_over(make_kb):
    """A knife from a mesh file whose blade has no region: no face is the blade, so no rule
    about sharp parts could tell a hand on it; before, they were all 'not applicable' and
    the receiver could be handed the blade."""
    import trimesh

    root = make_kb({"objects/mesh_knife.yaml": """\
        id: mesh_knife
        name: A mesh knife whose blade has no region
        mass: 0.15
        geometry:
          mesh: {file: ../meshes/mesh_knife.stl, default_part: handle}
        parts:
          handle: {tags: [handle]}
          blade: {tags: [sharp]}
        axes:
          tip: [1, 0, 0]
        """})
    handle = trimesh.creation.box((0.11, 0.02, 0.025))
    handle.apply_translation([-0.055, 0, 0])
    blade = trimesh.creation.box((0.15, 0.002, 0.03))
    blade.apply_translation([0.075, 0, 0])
    (root / "meshes").mkdir()
    trimesh.boolean.union([handle, blade], engine="manifold").export(
        root / "meshes" / "mesh_knife.stl")
    plan = Planner(kb=root, db=False).plan("mesh_knife", robot="bot", mode="h1g1")
    assert plan.outcome == "infeasible"
    assert "not measured" in plan.reason and "no_sharp" in plan.reason
    assert "part 'blade'" in plan.reason and "regions of its mesh" in plan.reason
