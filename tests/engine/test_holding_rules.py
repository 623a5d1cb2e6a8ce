"""The holding rules (``kind: torque``: twist, tip, weight) take their limits from the
query's gripper (grip force, pad friction, torsional friction), not from a constant: a grasp
far out on a bar twists out, a tray held at its rim tips out, a weaker gripper holds less,
and a rule's ``max_nm`` can only make the limit stricter."""

from __future__ import annotations

import numpy as np
import pytest

from handover.engine.load.loader import load_kb
from handover.engine.plan import judge
from handover.engine.plan.hands import hands as plan_hands
from handover.engine.plan.phase import Phase, Roles
from handover.engine.plan.prepare import prepare
from handover.engine.spec.query import Query
from handover.engine.spec.schema import parse_rule

BAR = """\
id: bar
name: A 30 cm steel bar of 1 kg
mass: 1.0
geometry:
  primitives:
    - {shape: box, part: bar, extents: [0.3, 0.024, 0.03], position: [0, 0, 0.015]}
parts:
  bar: {tags: [handle]}
"""

WEAK = """\
id: weak_jaw
name: A jaw closing with 20 N
max_opening: 0.085
finger_length: 0.04
finger_width: 0.022
finger_thickness: 0.01
palm: [0.06, 0.13, 0.08]
friction: 0.5
grip_force: 20
"""


def rule(about: str, **extra) -> object:
    return parse_rule({"id": f"hold_{about}", "kind": "torque", "about": about, "why": "t",
                       **extra})


@pytest.fixture(scope="module")
def bar_kb(tmp_path_factory):
    from tests.conftest import MINIMAL_KB, write_files

    root = tmp_path_factory.mktemp("holding") / "kb"
    write_files(root, MINIMAL_KB)
    write_files(root, {"objects/bar.yaml": BAR, "grippers/weak_jaw.yaml": WEAK})
    return load_kb(root, urdf=False)


def judged(ctx, r, rows=None) -> tuple[np.ndarray, object]:
    """The rule on every candidate (or ``rows``) at presentation 0, one hand."""
    phase = Phase("H1G1", hands=plan_hands(ctx, Roles(want=frozenset({"handle"}))))
    gi = np.arange(ctx.n) if rows is None else np.asarray(rows)
    return gi, judge.evaluate(r, ctx, phase, gi, np.zeros(len(gi), dtype=np.int64))


def off_centre(ctx) -> np.ndarray:
    """(N,) m, each grasp's distance from the bar's centre of mass along the bar."""
    return np.abs(ctx.candidates.centre[:, 0])


def test_a_bar_is_held_near_its_centre_of_mass_and_not_at_its_ends(bar_kb):
    ctx = prepare(bar_kb, Query(object="bar", robot="bot", scene="table"))
    gi, out = judged(ctx, rule("all"))
    x = off_centre(ctx)[gi]
    near, far = x < 0.02, x > 0.13
    assert near.any() and far.any()
    assert out.passed[near].all()
    assert (out.measured[far] > out.measured[near].max()).all()
    # Jaws closing across the bar's sides as it lies (closing axis level): 13-15 cm out the
    # weight twists it about that axis with 1 x 9.81 x 1.4 x 0.13 = 1.8 N m or more, beyond
    # the 2 F (mu rho + mu_t) <= 1.6 N m that 70 N pads of 22 x 40 mm hold on a face.
    level = np.abs(ctx.candidates.o[gi, 2]) < 0.1
    assert (far & level).any()
    assert not out.passed[far & level].any()
    # Jaws closing on its top and bottom hold more: the weight tips it about their pads'
    # plane, against the pads' pressure couple and their friction across its 3 cm
    assert out.passed[far & ~level].any()


def test_a_weaker_gripper_holds_less_of_the_same_bar(bar_kb):
    strong = prepare(bar_kb, Query(object="bar", robot="bot", scene="table"))
    weak = prepare(bar_kb, Query(object="bar", robot="bot", scene="table", gripper="weak_jaw"))
    _, at70 = judged(strong, rule("all"))
    _, at20 = judged(weak, rule("all"))
    assert len(at20.passed) == len(at70.passed)  # the same candidates (same finger sizes)
    # the load is the same: what it uses of the pads scales as 70 / 20
    np.testing.assert_allclose(at20.measured, at70.measured * 70 / 20, rtol=1e-9)
    assert at20.passed.sum() < at70.passed.sum()
    assert not (at20.passed & ~at70.passed).any()
    assert "20 N" in at20.threshold and "70 N" in at70.threshold


def test_max_nm_only_makes_the_limit_stricter(bar_kb):
    ctx = prepare(bar_kb, Query(object="bar", robot="bot", scene="table"))
    _, derived = judged(ctx, rule("twist"))
    _, loose = judged(ctx, rule("twist", max_nm=100.0))
    _, strict = judged(ctx, rule("twist", max_nm=0.2))
    np.testing.assert_array_equal(loose.passed, derived.passed)
    assert strict.passed.sum() < derived.passed.sum()
    assert not (strict.passed & ~derived.passed).any()


def test_a_loaded_tray_held_at_its_rim_by_one_gripper_tips_out():
    kb = load_kb(None)
    ctx = prepare(kb, Query(object="tray"))
    rim = ctx.candidates.part_names.index("rim")
    rows = np.flatnonzero((ctx.candidates.parts == rim).all(axis=1)
                          & (ctx.candidates.width <= ctx.gripper.max_opening))
    assert len(rows)
    _, tip = judged(ctx, rule("tip"), rows)
    _, weight = judged(ctx, rule("weight"), rows)
    assert not tip.passed.any()  # 2.5 kg some 17 cm from a 1 cm wall: several N m
    assert weight.passed.all()  # the pads' friction would carry its 25 N (2 mu F = 70 N)


def test_the_built_in_tray_held_by_two_grippers_at_its_rims_passes_them_all():
    from handover import Planner

    r = Planner().plan("tray").to_dict()
    assert r["mode"] == "H2G1"
    entries = [e for e in r["trace"] if e["rule"] in ("torque_limit", "tipping_limit",
                                                      "grip_holds_weight")]
    assert len(entries) == 6 and all(e["status"] == "pass" for e in entries)
    for e in entries:
        assert 0.0 <= e["measured"] <= 1.0
        assert e["holds"]["weight_n"] == pytest.approx(70.0)  # 2 x 0.5 x 70 N


def test_a_grasp_is_judged_through_the_carry_s_turn_not_only_at_its_ends(bar_kb):
    """Turned over end for end about its length between pick-up and the handover, the bar
    lies flat at both ends of the carry, where jaws closing on its top and bottom feel its
    weight as a tip; halfway it is on its side, and the same weight twists those jaws about
    their closing axis (1 x 9.81 x 1.4 x 0.13 = 1.8 N m 13 cm out, beyond what the pads
    hold). The physics check carries it along that turn (the geodesic); so do the rules."""
    from scipy.spatial.transform import Rotation

    def twist(turn_deg: float):
        ctx = prepare(bar_kb, Query(object="bar", robot="bot", scene="table"))
        turn = Rotation.from_euler("x", turn_deg, degrees=True).as_matrix()
        ctx.rotations = (turn @ ctx.initial[:3, :3])[None]  # one presentation: the turn
        gi, out = judged(ctx, rule("twist"))
        x = off_centre(ctx)[gi]
        flat_jaws = np.abs(ctx.candidates.o[gi, 2]) > 0.9  # closing on its top and bottom
        return x, flat_jaws, out

    x, flat_jaws, still = twist(0.0)
    far = (x > 0.13) & flat_jaws
    assert far.any() and still.passed[far].all()  # no turn: their twist is nil
    x2, flat2, over = twist(180.0)
    assert (x2 == x).all() and (flat2 == flat_jaws).all()  # the same candidates
    assert not over.passed[far].any()  # on its side halfway, they twist out
    # and the nearer the centre of mass, the less they use: 1.4 m g d over the same pads
    near = (x < 0.02) & flat_jaws
    assert over.passed[near].all()
    assert over.measured[far].min() > over.measured[near].max()
