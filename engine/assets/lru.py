"""A small least-recently-used map: the bound on every cache that outlives one plan.

What is costly to load and may be reused (a robot's arms with their reachability maps, a
parsed URDF, a batch worker's knowledge base) is kept in an :class:`LRU` of a stated size,
owned by whoever plans (a :class:`handover.Planner`), or by the module for a one-shot process
(the CLI, a batch worker). Keeping or dropping an entry never changes a result: what is cached
is a pure function of its key.

>>> kept = LRU(2)
>>> kept.fetch("a", lambda: 1), kept.fetch("b", lambda: 2), kept.fetch("a", lambda: 0)
(1, 2, 1)
>>> kept.fetch("c", lambda: 3)  # "b" was used least recently: it goes
3
>>> list(kept)
['a', 'c']
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterator
from typing import Generic, TypeVar

import numpy as np

__all__ = ["LRU", "content_key"]

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")


class LRU(Generic[K, V]):
    """At most ``size`` values by key; the least recently used goes first when one more is
    added. ``size`` : int >= 1."""

    def __init__(self, size: int) -> None:
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ValueError(f"an LRU keeps at least one entry: size must be an int >= 1, "
                             f"got {size!r}")
        self.size = size
        self._items: OrderedDict[K, V] = OrderedDict()

    def fetch(self, key: K, make: Callable[[], V]) -> V:
        """The value under ``key``, made by ``make()`` and kept on first use (an exception
        from ``make`` keeps nothing)."""
        if key in self._items:
            self._items.move_to_end(key)
            return self._items[key]
        value = make()
        self.put(key, value)
        return value

    def get(self, key: K, default: V | None = None) -> V | None:
        """The value under ``key`` (now the most recently used), or ``default``."""
        if key not in self._items:
            return default
        self._items.move_to_end(key)
        return self._items[key]

    def put(self, key: K, value: V) -> None:
        """Keep ``value`` under ``key`` (the most recently used), dropping the least recently
        used beyond ``size``."""
        self._items[key] = value
        self._items.move_to_end(key)
        while len(self._items) > self.size:
            self._items.popitem(last=False)

    def clear(self) -> None:
        """Drop every entry."""
        self._items.clear()

    def __contains__(self, key: object) -> bool:
        return key in self._items

    def __len__(self) -> int:
        return len(self._items)

    def __iter__(self) -> Iterator[K]:
        """The keys, least recently used first."""
        return iter(list(self._items))

    def values(self) -> list[V]:
        """The values, least recently used first (none counts as used)."""
        return list(self._items.values())

    def __repr__(self) -> str:
        return f"LRU(size={self.size}, {len(self)} kept)"


def content_key(*parts: np.ndarray | str) -> str:
    """A key for an :class:`LRU` from what the value is a function of: arrays (by dtype,
    shape and bytes) and strings (a spec's JSON), in order.

    >>> content_key(np.zeros(2), "a") == content_key(np.zeros(2), "a") != content_key(np.ones(2))
    True
    """
    h = hashlib.sha1()
    for part in parts:
        if isinstance(part, str):
            h.update(b"s%d:" % len(part))
            h.update(part.encode("utf-8"))
            continue
        a = np.ascontiguousarray(part)
        h.update(f"a{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()

