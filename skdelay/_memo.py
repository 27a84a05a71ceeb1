"""A bounded, thread-safe store of arrays for reuse within one process.

One home for the bookkeeping of :class:`~skdelay.gap._problem.RunCache` (simulator
runs), :class:`~skdelay.gap._indicators.FeatureCache` (indicator profiles) and the delay
systems' settled states (:mod:`skdelay.systems._base`): least
recently used entries leave first once more than ``max_bytes`` are held, hits and misses
are counted, and the entries are never pickled (shipping them with every joblib task
would cost more than it saves).  What is stored is the caller's business; the store only
guarantees that a key maps to what was put under it.

A store made with ``shared=True`` carries only a random token when pickled.  Unpickled
in another process (a joblib worker's task), it joins that process's store of its class,
under keys prefixed by the token: the tasks of one diagnosis that a worker runs one after
another reuse each other's entries, while stores of other diagnoses (other tokens) never
see them.  The joined store holds at most ``max_bytes`` for all tokens together (least
recently used first out) and lives as long as the worker; the store in the process that
made it stays private and goes with its owner.
"""

from __future__ import annotations

import secrets
import threading
from collections import OrderedDict

__all__ = ["BoundedStore"]

#: per class, the store that unpickled shared stores of this process join
_JOINED = {}
_JOINED_LOCK = threading.Lock()


class BoundedStore:
    """``key -> value`` with a byte budget (``nbytes`` given per entry), LRU eviction.

    The caches subclass it and add the one method that makes and keys their values.
    ``shared``: see the module notes (a copy unpickled in a worker joins the worker's
    store of this class, under this store's token).
    """

    def __init__(self, max_bytes, shared=False):
        self.max_bytes = int(max_bytes)
        self._items = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()
        self.hits = self.misses = 0
        self._token = secrets.token_bytes(16) if shared else None
        self._host = None  # the process's store this copy joined (None: its own entries)

    def _where(self, key):
        host = self._host
        return (self, key) if host is None else (host, (self._token, key))

    def get(self, key):
        """The value under ``key`` (now the most recently used), or None."""
        store, key = self._where(key)
        with store._lock:
            value = store._items.get(key)
            if value is None:
                return None
            store._items.move_to_end(key)
            store.hits += 1
            return value[0]

    def put(self, key, value, nbytes):
        """Store ``value`` (counted as ``nbytes``) unless it alone exceeds the budget."""
        store, key = self._where(key)
        if nbytes > store.max_bytes:
            return
        with store._lock:
            store.misses += 1
            if key not in store._items:
                store._items[key] = (value, int(nbytes))
                store._bytes += int(nbytes)
            while store._bytes > store.max_bytes:
                _, (_, old) = store._items.popitem(last=False)
                store._bytes -= old

    def __len__(self):
        if self._host is None:
            return len(self._items)
        with self._host._lock:  # this copy's entries in the store it joined
            return sum(1 for key in self._host._items if key[0] == self._token)

    def __getstate__(self):
        return {"max_bytes": self.max_bytes, "token": self._token}

    def __setstate__(self, state):
        self.__init__(state["max_bytes"])
        token = state.get("token")
        if token is not None:
            self._token = token
            with _JOINED_LOCK:
                host = _JOINED.get(type(self))
                if host is None:
                    host = _JOINED[type(self)] = BoundedStore(state["max_bytes"])
            self._host = host
