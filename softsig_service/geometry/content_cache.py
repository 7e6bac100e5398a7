"""A small thread-safe cache keyed by the content of arrays (a digest), for work done once per mesh.

A scanned object's mesh has tens of thousands of vertices: its convex hull and its principal axes take far longer
than a plan. They depend only on the vertices and faces, so they are built once per content and found again by
the digest, whatever object (or pose, or request) brings the same mesh.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Generic, TypeVar

import numpy as np

V = TypeVar("V")


def content_digest(*arrays: np.ndarray) -> str:
    """Hex BLAKE2b digest (128 bits) of the arrays' shapes, dtypes and bytes (C order)."""
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        c = np.ascontiguousarray(a)
        h.update(f"{c.dtype.str}{c.shape}".encode())
        h.update(c.tobytes())
    return h.hexdigest()


class ContentCache(Generic[V]):
    """Least-recently-used map from a content digest to a value built once (at most ``size`` entries).

    :meth:`get` builds a missing value outside the lock (two threads may build the same value once each; the
    first stored wins), so a slow build never blocks lookups of other contents.
    """

    def __init__(self, size: int = 64) -> None:
        self._size = size
        self._items: OrderedDict[str, V] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: str, build: Callable[[], V]) -> V:
        """The value for ``key``, built with ``build()`` on a miss."""
        with self._lock:
            hit = self._items.get(key)
            if hit is not None:
                self._items.move_to_end(key)
                return hit
        value = build()
        with self._lock:
            stored = self._items.setdefault(key, value)
            self._items.move_to_end(key)
            while len(self._items) > self._size:
                self._items.popitem(last=False)
            return stored

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)

    def clear(self) -> None:
        """Forget every entry."""
        with self._lock:
            self._items.clear()
