"""Loading a knowledge base: :func:`.loader.load_kb` parses and validates every file
(:mod:`handover.engine.store`), then runs the checks across documents (:mod:`.lint`, which needs
the assets to check a robot's URDF and its arms' rest poses)."""
