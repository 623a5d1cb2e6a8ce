"""The KB as data: YAML parsed with the position of every node (:mod:`.yamlpos`), documents
validated into the :mod:`handover.engine.spec` models with every error at file:line
(:mod:`.validate`), the store of documents by kind and id (:mod:`.kb`) and cultures resolved
through ``extends``/``overrides`` (:mod:`.cultures`)."""
