"""handover-grasp's engine: where the knowledge base meets geometry.

Loading the KB: ``yamlpos`` (YAML with the position of every node), ``validate`` (data to
``schema`` models, each error at file:line), ``store`` (the ``KB``), ``lint`` (checks across
documents), ``loader`` (``load_kb``: the four in order). ``errors`` holds the project's errors
and exit codes, ``cli`` the ``handover`` command.
"""
