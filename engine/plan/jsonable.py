"""JSON-able data for the result: numpy arrays and scalars to lists and floats rounded to
:data:`DECIMALS` (:func:`to_jsonable`), the deterministic JSON text (:func:`dumps`), and the
records read back from a result's JSON (:func:`read_back`, :func:`stored_json`).

:func:`dumps` writes the text itself: with ``indent``, the standard library's ``json`` takes
its pure-Python encoder (its C one serves ``indent=None`` only), some 15 ms for a 500 KB plan
answer (lists of 7-float joint samples, mostly), a good part of a warm plan service answer.
The writer here gives ``json.dumps(data, indent=2, ensure_ascii=False)`` byte for byte in
about a third of that (a list of numbers, or of equal lists of numbers, is one %-formatting)
and leaves to ``json.dumps`` whatever JSON-able data does not hold.

>>> import numpy as np
>>> to_jsonable({"p": np.array([0.1234567, -1e-9, np.nan])})
{'p': [0.123457, 0.0, None]}
"""

from __future__ import annotations

import json
import math
from itertools import chain
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
    ``to_dict()``), and is not walked again. Byte for byte
    ``json.dumps(data, indent=2, ensure_ascii=False) + "\\n"``, which writes it when ``data``
    holds what JSON-able data does not (a key not a string, a type not JSON's, a cycle)."""
    data = data if jsonable else to_jsonable(data)
    out: list[str] | None = []
    try:
        _write(data, out, "\n")
    except (_NotPlain, RecursionError, ValueError):  # ValueError: an int too long to write
        out = None
    if out is None:  # outside the except: json's own error, if any, without ours chained
        return json.dumps(data, indent=2, ensure_ascii=False) + "\n"
    out.append("\n")
    return "".join(out)


class _NotPlain(Exception):
    """A value :func:`_write` leaves to ``json.dumps``."""


_string = json.encoder.encode_basestring  # the C one where there is one, as json's
_NUMBERS = frozenset((float, int))
_LISTS = frozenset((list,))


def _number(value: float) -> str:
    """A float as json writes it: its repr, or ``NaN``, ``Infinity``, ``-Infinity``."""
    if value != value:
        return "NaN"
    if value in (math.inf, -math.inf):
        return "Infinity" if value > 0 else "-Infinity"
    return float.__repr__(value)


def _leaf(value: Any) -> str:
    """The text of a string, number, bool or None (exact types); raises _NotPlain else."""
    kind = type(value)
    if kind is str:
        return _string(value)
    if kind is float:
        return _number(value)
    if kind is int:
        return int.__repr__(value)
    if value is None:
        return "null"
    if value is True:
        return "true"
    if value is False:
        return "false"
    raise _NotPlain


def _numbers_text(count: int, newline: str) -> str:
    """The %-template of a list of ``count`` numbers at the indent ``newline`` starts."""
    inner = newline + "  "
    return "[" + inner + ("," + inner).join(["%r"] * count) + newline + "]"


def _table_text(rows: int, count: int, newline: str) -> str:
    """The %-template of a list of ``rows`` lists of ``count`` numbers each."""
    inner = newline + "  "
    return "[" + inner + ("," + inner).join([_numbers_text(count, inner)] * rows) + newline + "]"


def _write(value: Any, out: list[str], newline: str) -> None:
    """Append the text of ``value`` at the indent ``newline`` ("\\n" and 2 spaces a level)
    starts a line with, as json's pure-Python encoder writes it with ``indent=2``."""
    kind = type(value)
    if kind is dict:
        _write_dict(value, out, newline)
    elif kind is list or kind is tuple:
        _write_list(value, out, newline)
    else:
        out.append(_leaf(value))


def _write_dict(value: dict, out: list[str], newline: str) -> None:
    """A dict's text; raises _NotPlain for a key that is not a string."""
    if not value:
        out.append("{}")
        return
    inner = newline + "  "
    lead = "{" + inner
    for key, item in value.items():
        if type(key) is not str:  # json's text for such keys: json.dumps writes it
            raise _NotPlain
        kind = type(item)
        if kind is list or kind is dict or kind is tuple:
            out.append(f"{lead}{_string(key)}: ")
            _write(item, out, inner)
        else:
            out.append(f"{lead}{_string(key)}: {_leaf(item)}")
        lead = "," + inner
    out.append(newline + "}")


def _write_list(value: list | tuple, out: list[str], newline: str) -> None:
    """The bulk of a result is lists of numbers (points, poses) and lists of those (a pose
    matrix, a trajectory's samples): each is one %-formatting, ``%r`` writing a float or an
    int as json does, but for NaN and the infinities (then item by item)."""
    if not value:
        out.append("[]")
        return
    kinds = set(map(type, value))
    if kinds <= _NUMBERS:
        text = _numbers_text(len(value), newline) % tuple(value)
        if "n" not in text:  # "nan", "inf": a finite float's or an int's repr has no n
            out.append(text)
            return
    elif kinds == _LISTS:
        counts = set(map(len, value))
        if len(counts) == 1 and 0 not in counts:
            flat = tuple(chain.from_iterable(value))
            if set(map(type, flat)) <= _NUMBERS:
                text = _table_text(len(value), len(value[0]), newline) % flat
                if "n" not in text:
                    out.append(text)
                    return
    inner = newline + "  "
    lead = "[" + inner
    for item in value:
        kind = type(item)
        if kind is list or kind is dict or kind is tuple:
            out.append(lead)
            _write(item, out, inner)
        else:
            out.append(lead + _leaf(item))
        lead = "," + inner
    out.append(newline + "]")
