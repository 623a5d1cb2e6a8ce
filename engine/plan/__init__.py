"""Planning one query: the query resolved to a situation, the context (mesh, candidates,
presentations, receiver's sites, world), the compiled constraint graph, the decision table, the
modes (H1G1, H2G2, H2G1), the arms, placement, explanations and what-ifs."""
