"""The decision table's summaries (rejections per rule, minimal blocking rule sets) against
a row-by-row count, for any pattern of failures."""

from __future__ import annotations

from collections import Counter
from types import SimpleNamespace
from unittest import mock

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from handover.engine.plan.blocking import blocking_sets
from handover.engine.plan.evaluate import Decision
from handover.engine.plan.judge import JUDGES, Judge, Outcome


def _decision(fails: np.ndarray) -> Decision:
    rows, n_hard = fails.shape
    first = np.where(fails.any(axis=1), fails.argmax(axis=1), -1)
    return Decision(
        gi=np.arange(rows), pk=np.zeros(rows, dtype=int),
        hard=[SimpleNamespace(id=f"rule_{h:02d}") for h in range(n_hard)], soft=[],
        fails=fails, checked=np.ones(rows, bool), kept=~fails.any(axis=1),
        score=np.zeros(rows), first_fail=first, soft_scores=np.zeros((rows, 0)),
    )  # fmt: skip


@settings(max_examples=60, deadline=None)
@given(
    rows=st.integers(1, 300),
    n_hard=st.sampled_from([1, 3, 10, 62, 63, 70]),
    density=st.floats(0.05, 0.9),
    seed=st.integers(0, 2**32 - 1),
)
def test_blocking_sets_and_rejections_match_a_row_by_row_count(rows, n_hard, density, seed):
    rng = np.random.default_rng(seed)
    fails = rng.random((rows, n_hard)) < density
    fails[:, 0] |= True  # every row fails: the plan is infeasible
    d = _decision(fails)
    patterns = Counter(frozenset(np.flatnonzero(row).tolist()) for row in fails)
    # a blocking set is minimal: no row fails only a proper part of it
    expected = {
        tuple(f"rule_{h:02d}" for h in sorted(p)): n for p, n in patterns.items()
        if not any(q < p for q in patterns)
    }
    ranked = sorted(expected.items(), key=lambda kv: (len(kv[0]), -kv[1], kv[0]))
    assert blocking_sets(d, limit=1000) == ranked
    assert d.rejected_by() == {
        f"rule_{h:02d}": c for h, c in sorted(Counter(fails.argmax(axis=1)).items())
    }


_READ_TRUTH = {kind: Judge(lambda rule, ctx, phase, gi, pk: rule.evaluate(ctx, phase, gi, pk))
               for kind in ("collision", "quality")}
"""Judges for the test's own rules: each reads the table it was made with."""


def _fast_path(truth: np.ndarray, collision: list[bool]) -> tuple[Decision, list]:
    """The decision the fast path builds over a known table ``truth`` (R, H): every other
    rule on every row, collision rules in order on the rows still alive; and rules whose
    evaluation reads ``truth`` (counting the rows each is asked about)."""
    rows, n_hard = truth.shape
    asked = [0] * n_hard

    def rule(h):
        def judge(ctx, phase, gi, pk):
            asked[h] += len(gi)
            fail = truth[gi, h]
            return Outcome(~fail, fail.astype(float), (~fail).astype(float), "", "")

        kind = "collision" if collision[h] else "quality"
        return SimpleNamespace(id=f"rule_{h:02d}", rule=SimpleNamespace(evaluate=judge,
                                                                         kind=kind))

    hard = [rule(h) for h in range(n_hard)]
    fails = np.zeros_like(truth)  # the test's rules judge through _READ_TRUTH
    checked = np.zeros_like(truth)
    cheap = [h for h in range(n_hard) if not collision[h]]
    fails[:, cheap], checked[:, cheap] = truth[:, cheap], True
    alive = ~fails.any(axis=1)
    for h in range(n_hard):
        if collision[h]:
            fails[alive, h], checked[alive, h] = truth[alive, h], True
            alive &= ~fails[:, h]
    first = np.where(fails.any(axis=1), fails.argmax(axis=1), -1)
    d = Decision(gi=np.arange(rows), pk=np.zeros(rows, dtype=int), hard=hard, soft=[],
                 fails=fails, checked=checked, kept=alive, score=np.zeros(rows),
                 first_fail=first, soft_scores=np.zeros((rows, 0)),
                 judged_in=(None, None))  # fmt: skip
    return d, asked


@settings(max_examples=80, deadline=None)
@given(
    rows=st.integers(1, 200),
    n_cheap=st.integers(1, 6),
    n_collision=st.integers(1, 3),
    density=st.floats(0.05, 0.8),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_exact_table_gives_the_blocking_sets_of_the_whole_truth(rows, n_cheap, n_collision,
                                                                    density, seed):
    """Blocking sets judged from the completed table are those of the table with every rule
    judged on every row: the sets, and how many rows each lets through."""
    rng = np.random.default_rng(seed)
    collision = [False] * n_cheap + [True] * n_collision
    truth = rng.random((rows, len(collision))) < density
    truth[:, 0] |= rng.random(rows) < 0.5
    truth[~truth.any(axis=1), -1] = True  # infeasible: every row fails something
    d, asked = _fast_path(truth, collision)
    with mock.patch.dict(JUDGES, _READ_TRUTH):
        _same_sets(d, truth, rows, n_cheap, n_collision, asked)


def _same_sets(d: Decision, truth: np.ndarray, rows: int, n_cheap: int, n_collision: int,
               asked: list) -> None:
    whole = Decision(gi=d.gi, pk=d.pk, hard=d.hard, soft=[], fails=truth,
                     checked=np.ones_like(truth), kept=d.kept, score=d.score,
                     first_fail=d.first_fail, soft_scores=d.soft_scores)  # fmt: skip
    assert blocking_sets(d, limit=1000) == blocking_sets(whole, limit=1000)
    # rows that cannot change the answer are not judged again
    assert sum(asked[n_cheap:]) <= rows * n_collision
