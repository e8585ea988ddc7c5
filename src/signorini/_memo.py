"""A memo of values computed from large objects, kept while each object lives.

Keyed by identity through a weak reference: an entry never keeps its object
alive, and an object that reuses a freed one's address is not mistaken for it.
Used for figures of arrays that are passed again unchanged (a model key's
digests of the mesh, the symmetry figures of a read-only element stiffness).
"""

from __future__ import annotations

import threading
import weakref
from collections import OrderedDict


class ObjectMemo:
    """At most ``size`` values, least recently used dropped first (dead entries first)."""

    def __init__(self, size: int):
        self.size = size
        self._items: OrderedDict = OrderedDict()  # id -> (weak reference, value)
        self._lock = threading.Lock()

    def get(self, obj):
        """The value kept for this very object, or None."""
        with self._lock:
            kept = self._items.get(id(obj))
            if kept is None or kept[0]() is not obj:
                return None
            self._items.move_to_end(id(obj))
            return kept[1]

    def put(self, obj, value) -> None:
        """Keep ``value`` for ``obj`` (no-op for an object without weak references)."""
        try:
            ref = weakref.ref(obj)
        except TypeError:
            return
        with self._lock:
            self._items[id(obj)] = (ref, value)
            self._items.move_to_end(id(obj))
            if len(self._items) > self.size:
                dead = [k for k, (r, _) in self._items.items() if r() is None]
                for k in dead:
                    del self._items[k]
                while len(self._items) > self.size:
                    self._items.popitem(last=False)
