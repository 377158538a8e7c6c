"""Results computed once per process, in caches the caller can see and clear.

Every cache of the package is one of these, named, and listed by `caches()`
(`clear_all()` empties them): the start and rest poses of a scenario and an
object (station/start_pose.py) are pure functions of their inputs, so a kept
result is the result; episode.episode.ThrowCache keeps simulated throws the same
way and registers itself here too, and `lru_cache` lists a functools cache
(the toss's trajectories, the arm's joint limits).
"""

import functools

_CACHES: dict = {}


class Memo:
    """A pure function's results by key, computed once (`get`)."""

    def __init__(self, name: str):
        if name in _CACHES:
            raise ValueError(f"Memo: a cache named {name!r} exists already")
        self.name = name
        self._kept: dict = {}
        _CACHES[name] = self

    def get(self, key, compute):
        """The result kept for `key`, or compute() kept and returned."""
        if key not in self._kept:
            self._kept[key] = compute()
        return self._kept[key]

    def __len__(self) -> int:
        return len(self._kept)

    def clear(self) -> None:
        self._kept.clear()


def register(name: str, cache) -> None:
    """Lists another kind of cache (with a `clear()`) under `name`."""
    if name in _CACHES:
        raise ValueError(f"register: a cache named {name!r} exists already")
    _CACHES[name] = cache


def lru_cache(name: str, maxsize: int | None = None):
    """A decorator: functools.lru_cache(maxsize) of a pure function, listed
    under `name` (so that `clear_all()` empties it too)."""
    def decorate(function):
        cached = functools.lru_cache(maxsize=maxsize)(function)
        cached.clear = cached.cache_clear
        register(name, cached)
        return cached
    return decorate


def caches() -> dict:
    """Every cache of the package by name."""
    return dict(_CACHES)


def clear_all() -> None:
    """Empties every cache: the next episode computes everything again."""
    for cache in _CACHES.values():
        cache.clear()
