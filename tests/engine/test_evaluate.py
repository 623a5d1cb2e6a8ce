"""The decision table's summaries (rejections per rule, minimal blocking rule sets) against
a row-by-row count, for any pattern of failures."""

from __future__ import annotations

from collections import Counter
from types import SimpleNamespace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from handover.engine.evaluate import Decision


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
    assert d.blocking_sets(limit=1000) == ranked
    assert d.rejected_by() == {
        f"rule_{h:02d}": c for h, c in sorted(Counter(fails.argmax(axis=1)).items())
    }
