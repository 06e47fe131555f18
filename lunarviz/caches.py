"""One registry of lunarviz's in-process caches; :func:`release_caches` empties every one.

Caches are keyed by content, never by object identity: hashable argument values (levels,
names, numbers) and, for files, :func:`file_key` (path, size and modification time) for
:func:`memoize`; a digest of a mesh's vertices and faces (:func:`mesh_digest`) or of arrays
(:func:`array_digest`) for :class:`BoundedCache`.
"""

from __future__ import annotations

import functools
import gc
import hashlib
import sys
from collections import OrderedDict
from pathlib import Path
from typing import Callable

import numpy as np

#: the ``clear`` of every registered cache
_CLEARERS: list[Callable[[], None]] = []


def register(clear: Callable[[], None]) -> None:
    """Register a cache's own ``clear`` (one that must also close what it holds: files, kernels)."""
    _CLEARERS.append(clear)


def memoize(maxsize: int):
    """:func:`functools.lru_cache` of ``maxsize`` entries, registered for :func:`release_caches`."""

    def deco(fn):
        cached = functools.lru_cache(maxsize=maxsize)(fn)
        _CLEARERS.append(cached.cache_clear)
        return cached

    return deco


class BoundedCache:
    """A mapping of at most ``maxsize`` entries, the least recently used dropped first (a dated
    sweep adds a turned Moon at every date: dropping the oldest instead evicted the Sun and the
    Earth, used at every date too, every few dates), registered for :func:`release_caches`."""

    def __init__(self, maxsize: int):
        self.maxsize = maxsize
        self._data: OrderedDict = OrderedDict()
        _CLEARERS.append(self._data.clear)

    def get(self, key, default=None):
        try:
            value = self._data[key]
        except KeyError:
            return default
        try:
            self._data.move_to_end(key)
        except KeyError:  # (dropped meanwhile by another thread: the value is still good)
            pass
        return value

    def __contains__(self, key) -> bool:
        return key in self._data

    def __len__(self) -> int:
        return len(self._data)

    def clear(self) -> None:
        self._data.clear()

    def __setitem__(self, key, value) -> None:
        while len(self._data) >= self.maxsize:
            self._data.popitem(last=False)
        self._data[key] = value


def file_key(path) -> tuple:
    """A content key of a file for a cache: its resolved path, size and modification time
    [ns], so a file rewritten in the same process is read again. A path that cannot be
    read keys by its text (the reader then raises its own error)."""
    p = Path(path)
    try:
        st = p.stat()
    except OSError:
        return (str(path), -1, -1)
    return (str(p.resolve()), st.st_size, st.st_mtime_ns)


def array_digest(*arrays: np.ndarray) -> str:
    """A content key of arrays: BLAKE2b of their dtypes, shapes and bytes."""
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.view(np.uint8).reshape(-1) if a.size else b"")
    return h.hexdigest()


def mesh_digest(mesh) -> tuple:
    """A content key of a mesh's vertices and faces, computed once where they cannot change: a
    dated sweep keys the same three meshes at every date (BLAKE2b of a level-6 Moon: 5 ms each
    time). Read-only arrays that own their data (the packaged spheres'): their
    :func:`array_digest`, kept on the mesh; a trimesh mesh's tracked arrays: trimesh's own fast
    hashes (recomputed only after a change), with their dtypes and shapes; else
    :func:`array_digest` every time."""
    arrays = (mesh.vertices, mesh.faces)
    if all(type(a) is np.ndarray and not a.flags.writeable and a.base is None for a in arrays):
        memo = getattr(mesh, "_lunarviz_digest", None)
        if memo is not None and memo[0] is arrays[0] and memo[1] is arrays[1]:
            return memo[2]
        key = (array_digest(*arrays),)
        try:
            object.__setattr__(mesh, "_lunarviz_digest", (*arrays, key))  # (frozen dataclasses too)
        except AttributeError:  # (a mesh type without attributes of its own)
            pass
        return key
    tracked = getattr(sys.modules.get("trimesh.caching"), "TrackedArray", None)  # (never imported here)
    if tracked is not None and all(isinstance(a, tracked) for a in arrays):
        return tuple(x for a in arrays for x in (hash(a), a.dtype.str, a.shape))
    return (array_digest(*arrays),)


def release_caches() -> None:
    """Empty every registered cache (meshes, Embree scenes, maps, ephemerides, BRDF tables);
    their memory returns once nothing else holds them. For one-shot commands that go on to
    write large outputs, and for tests that need a cold start."""
    for clear in _CLEARERS:
        clear()
    gc.collect()
