"""The rule catalogue is declared once per kind: each registered kind has its schema (the
YAML fields an editor completes), a vectorised evaluation, a description and its own colour."""

from __future__ import annotations

import json

import numpy as np
import pytest

from handover.engine.plan import judge
from handover.engine.plan.hands import hands as plan_hands
from handover.engine.plan.phase import Phase, Roles
from handover.engine.plan.prepare import prepare
from handover.engine.spec.kinds import FEATURES, KINDS
from handover.engine.spec.query import Query
from handover.engine.spec.schema import RULE_KINDS, parse_rule
from handover.engine.store.validate import document_schema


@pytest.fixture(scope="module")
def knife_ctx(builtin_kb):
    return prepare(builtin_kb, Query(object="knife"))


def test_the_catalogue_is_the_registry():
    assert tuple(KINDS) == RULE_KINDS
    assert len(RULE_KINDS) >= 10


def test_every_kind_has_its_own_colour_and_a_summary():
    colours = [k.colour for k in KINDS.values()]
    assert len(set(colours)) == len(colours)
    assert all(k.summary for k in KINDS.values())


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_kind_is_in_the_editor_schema_with_its_own_fields(kind):
    schema = json.loads(json.dumps(document_schema("etiquette")))
    rules = schema["properties"]["rules"]["items"]
    mapping = rules["discriminator"]["mapping"]
    ref = mapping[kind].rsplit("/", 1)[1]
    fields = schema["definitions"][ref]["properties"]
    assert set(KINDS[kind].example) <= set(fields)
    assert {"id", "kind", "why", "hard", "applies"} <= set(fields)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_kind_parses_describes_and_evaluates_vectorised(kind, knife_ctx):
    rule = parse_rule({"id": f"a_{kind}", "kind": kind, "why": "test", **KINDS[kind].example})
    assert type(rule) is KINDS[kind]
    text = rule.describe()
    assert text and text != kind
    assert set(rule.features()) <= set(FEATURES)
    ctx = knife_ctx
    hands = plan_hands(ctx, Roles(want=frozenset({"handle"})))
    phase = Phase("H1G1", hands=hands)
    rows = 50
    gi = np.arange(rows) % ctx.n
    pk = np.arange(rows) % ctx.k
    out = judge.evaluate(rule, ctx, phase, gi, pk)
    assert out.passed.shape == (rows,) and out.passed.dtype == bool
    assert out.measured.shape == (rows,) and out.score.shape == (rows,)
    assert np.all((out.score >= 0) & (out.score <= 1))
    # One row at a time says the same as all rows at once (vectorised, not order-dependent).
    for r in (0, rows // 2, rows - 1):
        one = judge.evaluate(rule, ctx, phase, gi[r:r + 1], pk[r:r + 1])
        assert one.passed[0] == out.passed[r]
        np.testing.assert_allclose(one.score[0], out.score[r])


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_a_field_of_another_kind_is_refused(kind):
    other = next(k for k in sorted(KINDS) if set(KINDS[k].example) - set(KINDS[kind].example)
                 and not set(KINDS[k].example) & set(KINDS[kind].model_fields))
    stray = next(iter(set(KINDS[other].example) - set(KINDS[kind].model_fields)))
    with pytest.raises(ValueError, match=stray):
        parse_rule({"id": "x", "kind": kind, "why": "t", **KINDS[kind].example,
                    stray: KINDS[other].example[stray]})
