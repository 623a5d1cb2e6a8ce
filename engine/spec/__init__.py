"""The knowledge base's data model: the pydantic models of every KB document (objects,
cultures, receivers, grippers, hands, robots, scenes, tests), their field types, the ``applies``
conditions and the rule kinds' fields (one registry, :mod:`.kinds`). Imports nothing else of
the engine but :mod:`handover.engine.errors`."""
