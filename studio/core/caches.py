"""What learning remembers between calls, in one object its owner keeps (:class:`LearningCaches`).

Every entry depends only on the demonstrations it was computed from (held weakly: a deleted demo's entries go
with it) and the key it names, never on a clock or a global: a fresh object gives the same results, only
slower. Safe to share between threads without a lock (a race only computes an entry twice)."""

from __future__ import annotations

import weakref
from collections.abc import Callable, Hashable, Sequence
from typing import Any

import numpy as np

from studio.core.keypoints import KeypointCache
from studio.core.types import Demo


class AlignmentCache:
    """Values computed from a few demonstrations (in order) and a key, e.g. the DTW time maps between two demos,
    reused while only the thresholds change.

    The alignment of a demo to the reference depends on the two demos, the common DTW rate and the feature
    scale, not on ε: a slider move (or the auto-tune) that keeps the same reference re-uses it. Entries are
    held with weak references to the demos (a deleted demo's maps go with it) and at most :attr:`size` are
    kept.
    """

    def __init__(self, size: int = 64) -> None:
        self.size = size
        self._maps: dict[tuple, tuple[tuple[weakref.ref, ...], Any]] = {}

    def get(self, ref: Demo, demo: Demo, key: tuple, compute: Callable[[], Any]) -> Any:
        return self.get_set((ref, demo), key, compute)

    def get_set(self, demos: Sequence[Demo], key: tuple, compute: Callable[[], Any]) -> Any:
        """The value for these demos (in this order) and key, computed once while they all live."""
        k = (*(id(d) for d in demos), len(demos), *key)
        hit = self._maps.get(k)
        if hit is not None and len(hit[0]) == len(demos) and all(r() is d for r, d in zip(hit[0], demos, strict=True)):
            return hit[1]
        value = compute()
        _trim(self._maps, self.size - 1)
        self._maps[k] = (tuple(weakref.ref(d) for d in demos), value)
        return value


def _trim(d: dict, size: int) -> None:
    """Drop the oldest entries of ``d`` down to ``size`` (another thread's change is no error)."""
    while len(d) > size:
        try:
            d.pop(next(iter(d)), None)
        except (StopIteration, RuntimeError):
            return


class Memo:
    """At most ``size`` values by a hashable key (the oldest dropped first)."""

    def __init__(self, size: int = 64) -> None:
        self.size = size
        self._values: dict[Hashable, Any] = {}

    def get(self, key: Hashable, compute: Callable[[], Any]) -> Any:
        hit = self._values.get(key)
        if hit is not None:
            return hit
        value = compute()
        _trim(self._values, self.size - 1)
        self._values[key] = value
        return value

    def clear(self) -> None:
        self._values.clear()


class DemoCurves:
    """The demos' comparison curves (``n`` points) and spread, computed once per set of demos (the slider moves
    ε only)."""

    def __init__(self, n: int, spread: bool = True) -> None:
        self._n, self._spread = n, spread
        self._entry: tuple[tuple, tuple, tuple[list[np.ndarray], float]] | None = None

    def get(self, demos: Sequence[Demo]) -> tuple[list[np.ndarray], float]:
        from studio.core import quality

        key = tuple(id(d) for d in demos)
        entry = self._entry
        if entry is not None and key == entry[0] and all(r() is d for r, d in zip(entry[1], demos, strict=True)):
            return entry[2]
        curves = [quality.curve(d, self._n) for d in demos]
        r = quality.spread(curves)[0] if self._spread and len(curves) > 1 else float("nan")
        self._entry = (key, tuple(weakref.ref(d) for d in demos), (curves, r))
        return curves, r


class LearningCaches:
    """Everything learning reuses across calls: each demo's derived series (``keypoints``), the DTW maps
    (``alignments``), the ways the demos go (``routes``), the plain-mean share chosen per path (``shares``) and
    the demos' comparison curves of the live preview and of the plain-mean check. The controller owns one;
    a call given none makes its own."""

    def __init__(self, keypoints: KeypointCache | None = None) -> None:
        from studio.core.quality import N_POINTS

        self.keypoints = keypoints if keypoints is not None else KeypointCache()
        self.alignments = AlignmentCache()
        self.routes = AlignmentCache(16)
        self.shares = Memo(64)
        self.preview_curves = DemoCurves(300)
        self.guard_curves = DemoCurves(N_POINTS, spread=False)


__all__ = ["AlignmentCache", "DemoCurves", "LearningCaches", "Memo"]
