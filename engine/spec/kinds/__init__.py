"""The rule catalogue: one module per rule kind, each a pydantic model registered in
:data:`KINDS` with its fields, features, vectorised evaluation, description and colour.

Importing this package imports every kind module in it (sorted by name), so a new kind is
one new module here plus the YAML rules that use it.
"""

from __future__ import annotations

import importlib
import pkgutil

from handover.engine.spec.kinds.base import (
    FEATURES,
    KINDS,
    Outcome,
    RuleBase,
    angle_deg,
    bounds,
    register,
)

__all__ = ["FEATURES", "KINDS", "Outcome", "RuleBase", "angle_deg", "bounds", "register"]

for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _info.name != "base":
        importlib.import_module(f"{__name__}.{_info.name}")
