"""Compile a culture's rules, for one query, into a constraint graph.

The graph (networkx DiGraph) has feature nodes (``feature:<name>``: quantities computed on
candidates, with a cost) and rule nodes (``rule:<id>``), with an edge from each feature a rule
reads to the rule, and an ``overrides`` edge from each overriding rule to the rule it
replaced (which stays in the graph, inactive, so the explanation can show it). Rules whose
conditions do not hold for this query, or that cannot apply to this object, are inactive
with a reason.

Evaluation order: the active rules, hard before soft, each ranked by the cost of the most
expensive feature it reads (collision last), ties kept in KB order. It is a topological
order of the graph, since features never depend on rules.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import networkx as nx

from handover.engine.errors import KBError, KBIssue
from handover.engine.plan import judge
from handover.engine.plan.phase import Roles
from handover.engine.spec.applies import Facts, check
from handover.engine.spec.kinds import FEATURES
from handover.engine.spec.schema import RuleBase

if TYPE_CHECKING:
    from handover.engine.load.loader import KB
    from handover.engine.plan.context import PlanContext

__all__ = ["CompiledRule", "ConstraintGraph", "compile", "query_facts", "giver_forbid",
           "graph_to_dot"]


@dataclass
class CompiledRule:
    """A rule as compiled for one query.

    culture : id of the culture that wrote it. overrides : ids of the rules it replaced.
    active : it is evaluated. reason : why not, when inactive. cost : of its features.
    """

    rule: RuleBase
    culture: str
    overrides: tuple[str, ...] = ()
    overridden_sources: tuple[str, ...] = ()
    overridden_safety: tuple[str, ...] = ()
    active: bool = True
    reason: str | None = None
    features: tuple[str, ...] = ()
    cost: float = 0.0

    @property
    def id(self) -> str:
        return self.rule.id

    @property
    def source(self) -> str:
        return str(self.rule.source)


@dataclass
class ConstraintGraph:
    """The compiled constraints of one query and mode.

    graph : feature and rule nodes (see module docstring). order : active rules in
    evaluation order. inactive : the rest, each with its reason. mode : the mode compiled for.
    """

    graph: nx.DiGraph
    order: list[CompiledRule]
    inactive: list[CompiledRule]
    mode: str
    overridden: list[CompiledRule] = field(default_factory=list)
    kb_order: list[str] = field(default_factory=list)
    giver_forbid: frozenset[str] = frozenset()
    """The tags the robot may not hold (:func:`giver_forbid` of the culture's rules on the
    query's facts in this mode)."""

    @property
    def hard(self) -> list[CompiledRule]:
        return [c for c in self.order if c.rule.hard]

    @property
    def soft(self) -> list[CompiledRule]:
        return [c for c in self.order if not c.rule.hard]

    def roles(self, task_tags: tuple[str, ...] = ()) -> Roles:
        """Which parts the people may hold, from the active contact rules: the receiver
        should hold a part tagged as the task says (``task_tags``), else as the receiver
        contact rules require; hard contact rules forbid tags to the receiver or the giver."""
        want: set[str] = set(task_tags)
        receiver_forbid: set[str] = set()
        giver_forbid: set[str] = set()
        for c in self.order:
            rule = c.rule
            if rule.kind != "contact":
                continue
            if rule.who == "receiver":
                if rule.hard:
                    receiver_forbid.update(rule.forbid_tags)
                if not task_tags:
                    want.update(rule.require_tags)
            elif rule.hard and not rule.own_tags:  # own tags: the judge finds those parts
                giver_forbid.update(rule.forbid_tags)
        return Roles(frozenset(want), frozenset(receiver_forbid), frozenset(giver_forbid))

    def mode_rules(self) -> tuple[CompiledRule | None, CompiledRule | None]:
        """The active mode rule that requires a mode (the first hard one in KB order) and
        the one that prefers one (the highest-weighted soft one; of equal weights, one with
        alternatives to bend to, a culture's accepted form, before one without; then KB
        order)."""
        modes = [c for c in self.order if c.rule.kind == "mode"]
        modes.sort(key=lambda c: self.position(c.id))
        required = next((c for c in modes if c.rule.hard), None)
        soft = [c for c in modes if not c.rule.hard]
        preferred = max(soft, key=lambda c: (c.rule.weight, bool(c.rule.bends_to)),
                        default=None)  # the first of ties
        return required, preferred

    def also_preferring(self, preferred: CompiledRule | None) -> list[CompiledRule]:
        """The other active soft mode rules that ask for ``preferred``'s mode (KB order):
        relaxed with it where that mode is not given."""
        if preferred is None:
            return []
        same = [c for c in self.order if c.rule.kind == "mode" and not c.rule.hard
                and c is not preferred and c.rule.mode == preferred.rule.mode]
        return sorted(same, key=lambda c: self.position(c.id))

    def position(self, rule_id: str) -> int:
        """The rule's index in KB order (base culture first)."""
        return self.kb_order.index(rule_id)

    def by_id(self, rule_id: str) -> CompiledRule:
        for c in self.order + self.inactive + self.overridden:
            if c.id == rule_id:
                return c
        raise KeyError(rule_id)


def query_facts(ctx: PlanContext, mode: str, rules: Iterable[RuleBase] = ()) -> Facts:
    """What a rule's ``applies`` is judged on for this query in ``mode``. ``rules`` (the
    culture's resolved rules) say which parts the robot may hold: the tags forbidden by those
    hard giver contact rules whose conditions hold (judged before this fact is known), for
    ``single_grasps`` (whether one gripper can take the object at all)."""
    f, s = ctx.facts, ctx.situation
    facts = Facts(tags=f.tags, mass=f.mass, size=f.size, min_width=f.min_width,
                  payload=f.payload, max_opening=f.max_opening, role=s.receiver.role,
                  age=s.receiver.years,
                  task=s.task_id, mode=mode)
    forbid = giver_forbid(rules, facts)
    return replace(facts, single_grasps=ctx.single_grasps(forbid))


def giver_forbid(rules: Iterable[RuleBase], facts: Facts) -> frozenset[str]:
    """The tags the robot may not hold: those forbidden by the hard giver contact rules of
    ``rules`` whose conditions hold on ``facts`` (judged before ``single_grasps`` is known)."""
    forbid: set[str] = set()
    for rule in rules:
        if (rule.kind == "contact" and rule.who == "giver" and rule.hard
                and not rule.own_tags and check(rule.applies, facts)[0] is True):
            forbid.update(rule.forbid_tags)
    return frozenset(forbid)


def compile(kb: KB, ctx: PlanContext, mode: str = "H1G1") -> ConstraintGraph:  # noqa: A001
    """Compile the query's culture into a constraint graph for ``mode``: once per context,
    KB and mode (kept in ``ctx``; a what-if's KB is another KB, compiled anew). The graph is
    a value: nothing changes it once compiled.

    Raises KBError (with the rules' file:line) when the graph has a cycle (rules overriding
    each other in a loop).
    """
    kept = ctx.memo.graphs.get(mode)
    if kept is not None and kept[0] is kb:
        return kept[1]
    cg = _compile(kb, ctx, mode)
    ctx.memo.graphs[mode] = (kb, cg)  # the KB kept with it: its identity is the key
    return cg


def _compile(kb: KB, ctx: PlanContext, mode: str) -> ConstraintGraph:
    """See :func:`compile`."""
    from handover.engine.store.cultures import resolve_culture

    resolved = resolve_culture(kb, ctx.situation.query.culture)
    facts = query_facts(ctx, mode, [rr.rule for rr in resolved])
    forbid = giver_forbid([rr.rule for rr in resolved], facts)
    graph = nx.DiGraph()
    for name, (cost, varies, text) in FEATURES.items():
        graph.add_node(f"feature:{name}", kind="feature", cost=cost, varies=varies, text=text)

    compiled: list[CompiledRule] = []
    overridden: list[CompiledRule] = []
    for rr in resolved:
        chain = list(_override_chain(rr))
        features = tuple(rr.rule.features())
        cost = max((FEATURES[f][0] for f in features), default=0.0)
        holds, why = check(rr.rule.applies, facts)
        reason = None if holds else why
        if holds:
            reason = judge.not_applicable(rr.rule, ctx)
        item = CompiledRule(
            rule=rr.rule,
            culture=rr.culture,
            overrides=tuple(o.rule.id for o in chain),
            overridden_sources=tuple(str(o.rule.source) for o in chain),
            overridden_safety=tuple(o.rule.id for o in chain if o.rule.safety),
            active=reason is None,
            reason=reason,
            features=features,
            cost=cost,
        )
        compiled.append(item)
        node = f"rule:{rr.rule.id}"
        graph.add_node(
            node,
            kind="rule",
            hard=rr.rule.hard,
            active=item.active,
            reason=reason,
            source=str(rr.rule.source),
            culture=rr.culture,
            cost=cost,
        )
        for f in features:
            graph.add_edge(f"feature:{f}", node, kind="reads")
        for old in chain:
            old_node = f"rule:{old.rule.id}@{old.culture}"
            graph.add_node(old_node, kind="rule", hard=old.rule.hard, active=False,
                           reason=f"overridden by {rr.rule.id} ({rr.rule.source})",
                           source=str(old.rule.source), culture=old.culture, cost=0.0)
            graph.add_edge(node, old_node, kind="overrides")
            overridden.append(CompiledRule(rule=old.rule, culture=old.culture, active=False,
                                           reason=f"overridden by {rr.rule.id}"))

    if not nx.is_directed_acyclic_graph(graph):
        cycle = nx.find_cycle(graph)
        issues = []
        for u, _v in cycle:
            src = graph.nodes[u].get("source", "<graph>:0")
            file, _, line = src.rpartition(":")
            issues.append(KBIssue(file or src, int(line or 0), 0,
                                  f"rule {u} is part of an override cycle"))
        raise KBError(issues)

    position = {c.id: i for i, c in enumerate(compiled)}
    active = [c for c in compiled if c.active]
    order = sorted(active, key=lambda c: (not c.rule.hard, c.cost, position[c.id]))
    inactive = [c for c in compiled if not c.active]
    return ConstraintGraph(graph=graph, order=order, inactive=inactive, mode=mode,
                           overridden=overridden, kb_order=[c.id for c in compiled],
                           giver_forbid=forbid)


def _override_chain(rr) -> list:
    out = []
    stack = list(rr.overrides)
    while stack:
        item = stack.pop(0)
        out.append(item)
        stack.extend(item.overrides)
    return out


def graph_to_dot(cg: ConstraintGraph) -> str:
    """The graph in Graphviz dot: features as ellipses, hard rules as boxes, soft rules as
    rounded boxes, inactive rules grey, override edges dashed."""
    lines = ["digraph constraints {", "  rankdir=LR;", '  node [fontname="Helvetica"];']
    for node, data in sorted(cg.graph.nodes(data=True)):
        label = node.split(":", 1)[1]
        if data["kind"] == "feature":
            lines.append(f'  "{node}" [shape=ellipse, label="{label}\\ncost {data["cost"]:g}"];')
        else:
            style = "rounded" if not data.get("hard", True) else "solid"
            colour = "black" if data.get("active") else "grey"
            lines.append(
                f'  "{node}" [shape=box, style="{style}", color={colour}, '
                f'fontcolor={colour}, label="{label}\\n{data.get("source", "")}"];'
            )
    for u, v, data in sorted(cg.graph.edges(data=True)):
        style = "dashed" if data.get("kind") == "overrides" else "solid"
        lines.append(f'  "{u}" -> "{v}" [style={style}];')
    lines.append("}")
    return "\n".join(lines) + "\n"
