"""How each rule kind is judged on candidates (one module per kind, named as its module in
:mod:`handover.engine.spec.kinds`), and the calls the planner makes: :func:`evaluate`,
:func:`detail`, :func:`not_applicable`.

Importing this package imports every judge module in it (sorted by name) and checks that every
registered rule kind has a judge.
"""

from __future__ import annotations

import importlib
import pkgutil

from handover.engine.plan.judge.base import (
    JUDGES,
    Judge,
    Outcome,
    angle_deg,
    bounds,
    check_complete,
    detail,
    evaluate,
    inapplicable,
    judges,
    not_applicable,
    unknown,
)

__all__ = ["JUDGES", "Judge", "Outcome", "angle_deg", "bounds", "detail", "evaluate",
           "inapplicable", "judges", "not_applicable", "unknown"]

for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _info.name != "base":
        importlib.import_module(f"{__name__}.{_info.name}")
check_complete()
