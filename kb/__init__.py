"""The built-in knowledge base (YAML data, installed with the package).

Not code: this file only makes the folder findable with ``importlib.resources`` when
handover-grasp is installed as a wheel.
"""
