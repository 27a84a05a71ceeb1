"""A bounded, thread-safe store of arrays for reuse within one process.

One home for the bookkeeping of :class:`~skdelay.gap._problem.RunCache` (simulator
runs), :class:`~skdelay.gap._indicators.FeatureCache` (indicator profiles) and the delay
systems' settled states (:mod:`skdelay.systems._base`): least
recently used entries leave first once more than ``max_bytes`` are held, hits and misses
are counted, and the store is not pickled (a joblib worker starts with an empty one:
shipping it with every task would cost more than it saves).  What is stored is the
caller's business; the store only guarantees that a key maps to what was put under it.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

__all__ = ["BoundedStore"]


class BoundedStore:
    """``key -> value`` with a byte budget (``nbytes`` given per entry), LRU eviction.

    The caches subclass it and add the one method that makes and keys their values.
    """

    def __init__(self, max_bytes):
        self.max_bytes = int(max_bytes)
        self._items = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()
        self.hits = self.misses = 0

    def get(self, key):
        """The value under ``key`` (now the most recently used), or None."""
        with self._lock:
            value = self._items.get(key)
            if value is None:
                return None
            self._items.move_to_end(key)
            self.hits += 1
            return value[0]

    def put(self, key, value, nbytes):
        """Store ``value`` (counted as ``nbytes``) unless it alone exceeds the budget."""
        if nbytes > self.max_bytes:
            return
        with self._lock:
            self.misses += 1
            if key not in self._items:
                self._items[key] = (value, int(nbytes))
                self._bytes += int(nbytes)
            while self._bytes > self.max_bytes:
                _, (_, old) = self._items.popitem(last=False)
                self._bytes -= old

    def __len__(self):
        return len(self._items)

    def __getstate__(self):
        return {"max_bytes": self.max_bytes}

    def __setstate__(self, state):
        self.__init__(state["max_bytes"])
