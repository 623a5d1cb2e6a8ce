"""handover-grasp's engine: where the knowledge base meets geometry.

Modules: ``schema`` (the KB data model), ``loader`` (YAML to models with file:line),
``errors`` (the project's errors and exit codes), ``cli`` (the ``handover`` command).
"""
