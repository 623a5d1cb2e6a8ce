"""handover-grasp: knowledge-base driven grasp planning for robots handing objects to people.

The installed package holds ``handover.engine`` (knowledge meets geometry), ``handover.geometry``
(meshes, grasp candidates, collision; knows nothing of the knowledge base) and ``handover.kb``
(the built-in knowledge base, YAML).
"""
