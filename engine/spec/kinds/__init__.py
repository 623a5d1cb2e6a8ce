"""The rule catalogue: one module per rule kind, each a pydantic model registered in
:data:`KINDS` with its fields, features, description and colour (how it is judged on
candidates: :mod:`handover.engine.plan.judge`).

Importing this package imports every kind module in it (sorted by name), so a new kind is
one new module here plus the YAML rules that use it.
"""

from __future__ import annotations

import importlib
import pkgutil

from handover.engine.spec.kinds.base import FEATURES, KINDS, RuleBase, register

__all__ = ["FEATURES", "KINDS", "RuleBase", "register"]

for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _info.name != "base":
        importlib.import_module(f"{__name__}.{_info.name}")
