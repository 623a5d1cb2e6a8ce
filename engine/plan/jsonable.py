"""JSON-able data for the result: numpy arrays and scalars to lists and floats rounded to
:data:`DECIMALS` (:func:`to_jsonable`), the deterministic JSON text (:func:`dumps`), and the
records read back from a result's JSON (:func:`read_back`, :func:`stored_json`).

>>> import numpy as np
>>> to_jsonable({"p": np.array([0.1234567, -1e-9, np.nan])})
{'p': [0.123457, 0.0, None]}
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

__all__ = ["DECIMALS", "to_jsonable", "dumps", "read_back", "stored_json"]

DECIMALS = 6
"""Decimals floats keep in the JSON result: micrometres and microradians."""


def to_jsonable(value: Any) -> Any:
    """Numpy arrays and scalars to lists and floats, rounded to ``DECIMALS``; NaN/inf to None;
    dict keys to strings. Idempotent (JSON-able data comes back equal)."""
    kind = type(value)
    if kind is float:  # the commonest leaf first (a result holds some 10^4 of them)
        return _float(value)
    if kind is str or kind is int or kind is bool or value is None:
        return value
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "f" and value.ndim:
            return _rounded(value)
        return to_jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return _float(float(value))
    return value


def _float(value: float) -> float | None:
    """``value`` rounded to ``DECIMALS``, None when not finite, never -0.0."""
    if not math.isfinite(value):
        return None
    r = round(value, DECIMALS)
    return 0.0 if r == 0 else r


def _rounded(values: np.ndarray) -> list:
    """A float array as nested lists of floats each exactly ``round(x, DECIMALS)`` (NaN and
    infinities None, no -0.0): what :func:`to_jsonable` gives for ``values.tolist()``, in
    numpy. ``rint(x * 10**d) / 10**d`` is that double wherever ``x * 10**d`` was not rounded
    across a half (the quotient of an integer below 2**53 by 10**d is rounded correctly, as
    Python's ``round`` rounds the decimal it computes exactly); the few values near a half,
    and magnitudes beyond 2**53 / 10**d, take Python's ``round``."""
    x = np.asarray(values, dtype=float)
    scaled = x * 10.0**DECIMALS
    out = np.rint(scaled) / 10.0**DECIMALS + 0.0  # + 0.0: -0.0 becomes 0.0
    finite = np.isfinite(x)
    with np.errstate(invalid="ignore"):  # infinities: not finite, below
        near_half = np.abs(scaled - np.floor(scaled) - 0.5) <= 4 * np.abs(np.spacing(scaled))
    exact = finite & ~near_half & (np.abs(scaled) < 2.0**52)
    if exact.all():
        return out.tolist()
    flat, good = out.ravel().astype(object), exact.ravel()
    for k in np.flatnonzero(~good):
        flat[k] = _float(float(x.flat[k]))
    return flat.reshape(x.shape).tolist()


def read_back(record: Any, data: dict) -> Any:
    """``record`` (a record built from its own JSON ``data``, e.g. a plan the service sent)
    whose ``to_dict()`` gives ``data`` back exactly (the JSON's rounded numbers, not those
    recomputed from them)."""
    object.__setattr__(record, "_json", to_jsonable(data))
    return record


def stored_json(record: Any) -> dict | None:
    """The JSON a record was read back from (:func:`read_back`), None for one built here."""
    return record.__dict__.get("_json")


def dumps(data: Any, jsonable: bool = False) -> str:
    """Deterministic JSON text (indent 2, key order as built, trailing newline) of ``data``
    made JSON-able by :func:`to_jsonable`; ``jsonable``: ``data`` is so already (a
    ``to_dict()``), and is not walked again."""
    return json.dumps(data if jsonable else to_jsonable(data), indent=2,
                      ensure_ascii=False) + "\n"
