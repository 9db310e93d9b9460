"""Bounded, explicit caches for what depends only on an object model or a robot (SDF grids, FCL
shapes, surface samples): the caller owns one and passes it in. The one exception is ``memo``: a
bounded memo of a pure function of its arguments (a file's mesh, a description's pads), shared by
the process because it can never be stale; every memo is listed here (``memo_stats``) and can be
emptied (``clear_memos``)."""

from __future__ import annotations

import functools
import hashlib
import threading
from collections import OrderedDict
from typing import Callable, Hashable, TypeVar

import numpy as np

T = TypeVar("T")


_MISSING = object()


class BoundedCache:
    """Least-recently-used map of at most ``max_entries`` values, built on a miss by ``get``.
    Thread-safe: two threads missing the same key may both build it (the first stored wins)."""

    def __init__(self, max_entries: int = 64):
        if isinstance(max_entries, bool) or not isinstance(max_entries, int) or max_entries < 1:
            raise ValueError(f"max_entries: expected an integer >= 1, got {max_entries!r}")
        self.max_entries = max_entries
        self._entries: "OrderedDict[Hashable, object]" = OrderedDict()
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    def get(self, key: Hashable, build: Callable[[], T]) -> T:
        with self._lock:
            if key in self._entries:
                self._entries.move_to_end(key)
                self.hits += 1
                return self._entries[key]
            self.misses += 1
        value = build()  # outside the lock: builds may take long and release the GIL
        with self._lock:
            value = self._entries.setdefault(key, value)
            self._entries.move_to_end(key)
            while len(self._entries) > self.max_entries:
                self._entries.popitem(last=False)
        return value

    def get_many(self, keys, build_missing: Callable[[np.ndarray], list]) -> list:
        """The values of ``keys``; those not held are built in one call, ``build_missing(rows)`` (the
        indices of the missing keys) returning their values in that order."""
        with self._lock:
            held = [self._entries.get(k, _MISSING) for k in keys]
            for k, v in zip(keys, held):
                if v is not _MISSING:
                    self._entries.move_to_end(k)
            missing = np.array([i for i, v in enumerate(held) if v is _MISSING], dtype=int)
            self.hits += len(keys) - len(missing)
            self.misses += len(missing)
        if len(missing):
            for i, v in zip(missing, build_missing(missing)):
                held[i] = v
            with self._lock:
                for i in missing:
                    self._entries[keys[i]] = held[i]
                    self._entries.move_to_end(keys[i])
                while len(self._entries) > self.max_entries:
                    self._entries.popitem(last=False)
        return held

    def __len__(self) -> int:
        return len(self._entries)

    def clear(self) -> None:
        with self._lock:
            self._entries.clear()


def mesh_content_key(mesh) -> tuple:
    """A key that changes when the mesh's vertices or faces do: trimesh keeps a content hash
    that it recomputes only after an edit (microseconds when unchanged); any other mesh with
    ``vertices`` and ``faces`` is hashed in full."""
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    if type(mesh).__name__ == "Trimesh" and hasattr(mesh, "_data"):
        return ("trimesh", V.shape, F.shape, hash(mesh))
    h = hashlib.blake2b(digest_size=16)
    h.update(np.ascontiguousarray(V, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(F, dtype=np.int64).tobytes())
    return ("arrays", V.shape, F.shape, h.hexdigest())


_MEMOS: "dict[str, BoundedCache]" = {}  # every memo by its function's qualified name


def memo(max_entries: int, key: Callable[..., Hashable] = None):
    """Decorator: remember at most ``max_entries`` results of a pure function, keyed by its
    positional arguments (or by ``key(*args)``: a hashable summary of what the result depends on)."""

    def wrap(fn):
        cache = BoundedCache(max_entries)
        _MEMOS[f"{fn.__module__}.{fn.__qualname__}"] = cache

        @functools.wraps(fn)
        def call(*args):
            return cache.get(args if key is None else key(*args), lambda: fn(*args))

        call.cache = cache
        return call

    return wrap


def memo_stats() -> "dict[str, tuple[int, int, int]]":
    """Every memo's (entries, hits, misses), by function name."""
    return {name: (len(c), c.hits, c.misses) for name, c in _MEMOS.items()}


def clear_memos() -> None:
    """Empty every memo (their results are rebuilt on the next call)."""
    for cache in _MEMOS.values():
        cache.clear()
