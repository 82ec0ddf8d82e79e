"""The library's memo caches: one mechanism, safe to share between threads.

``seatkit serve`` runs designs on threads and a build may run its baseline
on a second one, so a cache that lives in a module is shared by threads.
Two kinds cover every cache of the library:

- :class:`LRUCache`: values by a hashable key (a cage's topology and a
  subdivision level), the least recently used dropped beyond ``maxsize``;
- :class:`IdentityCache`: values computed from particular live objects (a
  body, a skin's vertex array), keyed by their identity through weak
  references: an entry is dropped when one of its objects is collected, and
  an object at a recycled address is never mistaken for an old one.

Both hold a lock only to look up and to store, never while a value is
made (making one can take a second, and other keys must not wait for it);
two threads that miss the same key at once both make the value and both
get the one stored first, so the same key always gives the same object.
Functions of hashable arguments use :func:`functools.lru_cache` instead.
"""

from __future__ import annotations

import hashlib
import threading
import weakref
from collections import OrderedDict
from typing import Any, Callable, Hashable

__all__ = ["LRUCache", "IdentityCache", "content_key", "value_key"]


class _Cache:
    """The entries (oldest first) and the lock both caches keep."""

    def __init__(self, maxsize: int | None):
        self.maxsize = maxsize
        self._data: OrderedDict = OrderedDict()
        # re-entrant: a weak reference's callback may run (garbage
        # collection) while this thread holds the lock
        self._lock = threading.RLock()

    def _store(self, key, entry) -> None:
        """Store ``entry`` (under the lock) and drop the least recently used beyond ``maxsize``."""
        self._data[key] = entry
        while self.maxsize is not None and len(self._data) > self.maxsize:
            self._data.popitem(last=False)

    def __len__(self) -> int:
        with self._lock:
            return len(self._data)

    def clear(self) -> None:
        with self._lock:
            self._data.clear()


class LRUCache(_Cache):
    """A thread-safe least-recently-used cache of ``maxsize`` values by hashable keys."""

    def __init__(self, maxsize: int):
        super().__init__(int(maxsize))

    def get(self, key: Hashable, make: Callable[[], Any]) -> Any:
        """The value of ``key``, made by ``make()`` (outside the lock) when it is not cached."""
        with self._lock:
            if key in self._data:
                self._data.move_to_end(key)
                return self._data[key]
        value = make()
        with self._lock:
            if key in self._data:  # another thread stored it meanwhile: everyone gets the same object
                self._data.move_to_end(key)
                return self._data[key]
            self._store(key, value)
        return value

    def peek(self, key: Hashable) -> Any:
        """The value of ``key`` if it is cached, else None (nothing is made, its recency unchanged)."""
        with self._lock:
            return self._data.get(key)


class IdentityCache(_Cache):
    """A thread-safe cache of values by the identity of live objects (and a hashable tag).

    Parameters
    ----------
    maxsize : int, optional
        Most entries kept (the least recently used dropped first); ``None``:
        entries live as long as their objects. A value that refers to its
        own key objects keeps them alive, so such a cache needs a
        ``maxsize``.
    """

    def __init__(self, maxsize: int | None = None):
        super().__init__(maxsize)

    def get(self, objects: tuple, make: Callable[[], Any], tag: Hashable = None) -> Any:
        """The value for ``objects`` (and ``tag``), made by ``make()`` when it is not cached.

        Objects that cannot be weakly referenced (a list) are not cached:
        ``make()`` is called every time.
        """
        key = (tuple(id(o) for o in objects), tag)
        with self._lock:
            hit = self._live(key, objects)
            if hit is not None:
                return hit[1]
        value = make()
        try:
            refs = tuple(weakref.ref(o, self._forget(key)) for o in objects)
        except TypeError:
            return value
        with self._lock:
            hit = self._live(key, objects)
            if hit is not None:
                return hit[1]
            self._store(key, (refs, value))
        return value

    def _live(self, key, objects):
        """The entry of ``key`` if it is of these very objects (moved to the recent end), else None."""
        hit = self._data.get(key)
        if hit is None or any(ref() is not o for ref, o in zip(hit[0], objects)):
            return None
        self._data.move_to_end(key)
        return hit

    def _forget(self, key):
        def forget(ref):
            with self._lock:
                hit = self._data.get(key)
                if hit is not None and any(r is ref for r in hit[0]):
                    del self._data[key]

        return forget


def content_key(*arrays) -> bytes:
    """A key of arrays by their contents: a 16-byte digest (BLAKE2b) of each one's type, shape and bytes, in order.

    For a cache whose values depend on what arrays hold, not on which
    objects they are (a tessellation made again from the same control
    points, the same bodies in another picture's scene).
    """
    digest = hashlib.blake2b(digest_size=16)
    for array in arrays:
        _feed_array(digest, array)
    return digest.digest()


def value_key(*values) -> bytes:
    """A key of values by their contents: a 16-byte digest (BLAKE2b) of each one, in order, tagged with its kind.

    A value is None, a string, an integer (of any width: a random stream's
    state), an array or a number (by :func:`content_key`'s type, shape and
    bytes), or a tuple, list or dict of them (a dict in the order of its
    sorted keys). For a cache of a function of such arguments.
    """
    digest = hashlib.blake2b(digest_size=16)
    for value in values:
        _feed_value(digest, value)
    return digest.digest()


def _feed_array(digest, array) -> None:
    import numpy as np

    a = np.ascontiguousarray(array)
    digest.update(f"{a.dtype.str}{a.shape}".encode())
    digest.update(a.data)


def _feed_value(digest, value) -> None:
    if value is None:
        digest.update(b"N")
    elif isinstance(value, (str, int)):
        digest.update(f"{type(value).__name__}{value!r};".encode())
    elif isinstance(value, dict):
        digest.update(f"D{len(value)}".encode())
        for key in sorted(value):
            digest.update(f"|{key}=".encode())
            _feed_value(digest, value[key])
    elif isinstance(value, (tuple, list)):
        digest.update(f"T{len(value)}".encode())
        for v in value:
            _feed_value(digest, v)
    else:
        digest.update(b"A")
        _feed_array(digest, value)
