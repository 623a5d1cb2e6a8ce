"""What a Planner keeps between plans, and how it is asked: the bounded cache (LRU) every
cache that outlives a plan uses, the arms (with their reachability maps) a Planner owns, and
``Planner.plan`` taking a Query or the query's fields as keywords."""

from __future__ import annotations

from dataclasses import fields

import pytest
import trimesh

from handover import Planner, Query
from handover.engine.assets import robot as robot_assets
from handover.engine.assets.lru import LRU
from handover.engine.assets.robot import ARMS_KEPT
from handover.engine.planner import QUERY_FIELDS, query_of


@pytest.fixture(scope="module")
def planner() -> Planner:
    return Planner()


# ------------------------------------------------------------------ the bounded cache


def test_an_lru_keeps_its_size_and_drops_the_least_recently_used():
    made: list[str] = []

    def make(key: str):
        def value() -> str:
            made.append(key)
            return key.upper()
        return value

    kept = LRU(2)
    assert kept.fetch("a", make("a")) == "A" and kept.fetch("b", make("b")) == "B"
    assert kept.fetch("a", make("a")) == "A"  # kept: not made again, and now the newest
    kept.fetch("c", make("c"))
    assert list(kept) == ["a", "c"] and len(kept) == 2 and "b" not in kept
    assert kept.fetch("b", make("b")) == "B"  # made again after it was dropped
    assert made == ["a", "b", "c", "b"]
    kept.put("d", "D")
    assert list(kept) == ["b", "d"] and kept.values() == ["B", "D"]
    kept.clear()
    assert len(kept) == 0


def test_a_failing_make_keeps_nothing():
    kept = LRU(1)

    def broken() -> int:
        raise RuntimeError("no")

    with pytest.raises(RuntimeError):
        kept.fetch("x", broken)
    assert "x" not in kept and len(kept) == 0


@pytest.mark.parametrize("size", [0, -1, 1.5, True, "2"])
def test_an_lru_of_no_room_is_refused(size):
    with pytest.raises(ValueError, match="size must be an int >= 1"):
        LRU(size)


# ------------------------------------------------------------------ the Planner owns its arms


def test_a_planner_keeps_its_robot_s_arms_and_their_maps_across_plans(planner):
    first = planner.plan("knife")
    second = planner.plan("mug", receiver="elder")
    assert first.context.arms is not None
    assert first.context.arms is second.context.arms  # loaded once for this planner
    assert len(planner.arms_cache) == 1 and planner.arms_cache.size == ARMS_KEPT
    arms = first.context.arms
    side = arms.sides[0]
    assert arms.reach_map(side) is arms.reach_map(side)  # the arms keep their maps
    assert any(m is arms.reach_map(side) for m in arms.kept_maps)


def test_two_planners_share_no_arms_and_plan_alike(planner):
    process = list(robot_assets.PLAN_ARMS)  # the arms of plans made without a planner
    other = Planner()
    mine, theirs = planner.plan("knife"), other.plan("knife")
    assert mine.context.arms is not theirs.context.arms
    assert mine.to_json() == theirs.to_json()
    assert list(robot_assets.PLAN_ARMS) == process  # neither planner used the process's


# ------------------------------------------------------------------ asking a Planner


def test_the_keywords_are_the_query_s_fields():
    assert QUERY_FIELDS == tuple(f.name for f in fields(Query))
    assert {"object", "receiver", "culture", "task", "scene", "mode", "gripper", "robot",
            "mesh_scale"} == set(QUERY_FIELDS)


def test_a_query_and_its_keywords_ask_the_same():
    asked, mesh = query_of("mug", receiver="elder", culture="korean", task=None)
    assert mesh is None
    assert asked == Query("mug", receiver="elder", culture="korean")
    assert query_of(Query("mug"), receiver="elder", culture="korean")[0] == asked
    assert query_of(object="mug", receiver="elder", culture="korean")[0] == asked
    # None keeps a default; a Query's own fields stay unless a keyword changes them.
    assert query_of("mug", receiver=None, mode=None)[0] == Query("mug")
    assert query_of(asked, mode="h2g1")[0] == Query("mug", receiver="elder",
                                                     culture="korean", mode="h2g1")


def test_a_mesh_is_planned_as_the_object_mesh():
    box = trimesh.creation.box((0.1, 0.06, 0.03))
    asked, mesh = query_of(box, mesh_scale=1.0)
    assert asked == Query("mesh") and mesh is box


@pytest.mark.parametrize("args, kwargs, message", [
    (("knife",), {"recevier": "elder"}, "unknown query field recevier"),
    (("knife",), {"object": "mug"}, "two objects"),
    ((), {"receiver": "elder"}, "no object to plan"),
    ((42,), {}, "cannot plan a int"),
])  # fmt: skip
def test_bad_questions_are_value_errors_that_say_why(args, kwargs, message):
    with pytest.raises(ValueError, match=message):
        query_of(*args, **kwargs)


def test_planning_a_query_gives_the_plan_of_its_keywords(planner):
    by_query = planner.plan(Query("mug", receiver="elder", culture="korean"))
    by_keywords = planner.plan("mug", receiver="elder", culture="korean")
    assert by_query.mode == "H2G1"
    assert by_query.to_json() == by_keywords.to_json()
    with pytest.raises(ValueError, match="unknown query field"):
        planner.plan("mug", colour="red")


# ------------------------------------------------------------------ what a process keeps


def _forget_everything_kept() -> None:
    """Empty every cache this process keeps across plans (the Planner's own are new)."""
    from handover.engine.plan import corridors, features, hands, prepare
    from handover.engine.plan.judge import torque

    for kept in (hands.RECEIVER_SITES, prepare.PART_MESHES, corridors.OBJECT_DISTANCE,
                 features.KEEP_OUT, torque.PATCHES, torque.TABLES):
        kept.clear()


def test_what_is_kept_across_plans_never_changes_a_plan(tmp_path):
    """Plans that share an object but differ in what the kept values are computed from (the
    receiver and their hand, the culture, the scene, and the object and the hand
    edited between plans, under the same ids) give, after one another, the bytes each gives
    with nothing kept."""
    import shutil

    import yaml

    from handover.engine.store.kb import builtin_kb_dir

    edited = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), edited)
    mug = yaml.safe_load((edited / "objects" / "mug.yaml").read_text())
    mug["mass"] = 2.0 * float(mug["mass"])  # heavier: another load for the receiver's grasps
    (edited / "objects" / "mug.yaml").write_text(yaml.safe_dump(mug, sort_keys=False))
    hand = (edited / "hands" / "adult_hand.yaml").read_text()
    assert "grip_width: 0.09 " in hand
    (edited / "hands" / "adult_hand.yaml").write_text(
        hand.replace("grip_width: 0.09 ", "grip_width: 0.07 "))
    queries = [(None, dict(receiver="adult")), (None, dict(receiver="child")),
               (None, dict(receiver="elder", culture="korean")),
               (None, dict(scene="hammer_by_wall")), (edited, dict(receiver="adult")),
               (edited, dict(receiver="elder"))]
    _forget_everything_kept()
    db = tmp_path / "db"  # the candidates, which a plan's bytes never depend on, made once
    planners = {None: Planner(db=db), edited: Planner(edited, db=db)}
    warm = [planners[kb].plan("mug", **asked).to_json() for kb, asked in queries]
    for (kb, asked), made in zip(queries, warm, strict=True):
        _forget_everything_kept()
        alone = Planner(kb, db=db).plan("mug", **asked).to_json()
        assert made == alone, (str(kb), asked)
    assert warm[0] != warm[4]  # the edits change the plan: the test can tell


# ------------------------------------------------------------------ what a context keeps


@pytest.mark.parametrize("obj", ["mug", "book"])
def test_a_mode_planned_again_in_its_context_chooses_as_a_fresh_context_would(obj):
    """A grasp passed over (no motion for it, or it slipped) makes the planner decide again
    in the same context, reusing the rules' tables it judged; what it then chooses is what
    a new context told to pass over the same grasps chooses."""
    from handover.engine.load.loader import load_kb
    from handover.engine.plan.prepare import prepare
    from handover.engine.planner import decide

    kb, query = load_kb(), Query(object=obj)
    ctx = prepare(kb, query, None)
    first = decide(kb, ctx, query.mode)
    dropped = {c.grasp: "passed over for this test" for c in first.attempt.chosen}
    ctx.passed_over = dict(dropped)
    again = decide(kb, ctx, query.mode)  # the same context: its tables kept
    assert ctx.memo.decisions and ctx.memo.graphs
    fresh_ctx = prepare(kb, query, None)
    fresh_ctx.passed_over = dict(dropped)
    fresh = decide(kb, fresh_ctx, query.mode)
    assert again.outcome == fresh.outcome == "handover"
    chosen = [(c.grasp, c.presentation, c.gripper) for c in again.attempt.chosen]
    assert chosen == [(c.grasp, c.presentation, c.gripper) for c in fresh.attempt.chosen]
    assert not set(dropped) & {c.grasp for c in again.attempt.chosen}
    assert again.attempt.score == fresh.attempt.score
