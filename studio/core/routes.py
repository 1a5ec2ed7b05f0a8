"""Demonstrations that take different routes (around an obstacle on either side): which demos go which way.

Two demos' *route distance* is the median distance of their points matched along the DTW alignment (smoothed,
evenly spaced along the path). The demos are grouped by average linkage (scipy); 2 or 3 groups are routes when
they are farther apart than :data:`ROUTE_SHARE` of the size and :data:`ROUTE_RATIO` times their own spread
(:data:`SINGLES_SHARE` for one demo a group), end at the same place and use the gripper alike. Why and the
figures: docs/decisions/060."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from studio.core.caches import LearningCaches
from studio.core.types import Demo

#: Groups are routes when they are this share of the demos' size apart (median distance along the alignment)…
ROUTE_SHARE = 0.14
#: …and this many times farther apart than any two demos of one group…
ROUTE_RATIO = 1.25
#: …or, when every group is one demo (as many routes as demos), this share of the size.
SINGLES_SHARE = 0.15
#: Points per curve compared.
N_CURVE = 200


@dataclass(frozen=True)
class Route:
    """One way the demonstrations go.

    Attributes:
        demos: indices of the demos that take it (into the list given to :func:`find_routes`), ascending.
        at: (3,) m, the mean of these demos where the routes are farthest apart.
    """

    demos: tuple[int, ...]
    at: tuple[float, float, float]


@dataclass(frozen=True)
class Routes:
    """The routes of a set of demonstrations (empty when they all go one way).

    Attributes:
        routes: two or three :class:`Route`, ordered by their first demo.
        where: (3,) m, the mean of all the demos where the routes are farthest apart (what they go around).
    """

    routes: tuple[Route, ...] = ()
    where: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __bool__(self) -> bool:
        return bool(self.routes)

    def __len__(self) -> int:
        return len(self.routes)

    @property
    def default(self) -> int:
        """The route learned unless the teacher chooses: the one most demos take (the first demo's on a tie)."""
        return max(range(len(self.routes)), key=lambda r: (len(self.routes[r].demos), -self.routes[r].demos[0]))


def _curves(demos: Sequence[Demo]) -> list[np.ndarray]:
    from studio.core.quality import curve

    return [curve(d, N_CURVE) for d in demos]


def _profile(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """DTW warping path (L, 2) of two curves and the distance of each matched pair."""
    from dtaidistance import dtw as dtai

    path = np.asarray(dtai.warping_path_fast(np.ascontiguousarray(a), np.ascontiguousarray(b)), dtype=np.int64)
    return path, np.linalg.norm(a[path[:, 0]] - b[path[:, 1]], axis=1)


def _bridged(cs: list[np.ndarray]) -> list[np.ndarray]:
    """Each curve with its own start and end offsets from the curves' mean start and end taken out, faded
    linearly along its length: ways that differ between shared ends stand out, ends that differ do not."""
    start = np.mean([c[0] for c in cs], axis=0)
    end = np.mean([c[-1] for c in cs], axis=0)
    out = []
    for c in cs:
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
        u = (s / s[-1] if s[-1] > 0 else np.linspace(0.0, 1.0, len(c)))[:, None]
        out.append(c - (1.0 - u) * (c[0] - start) - u * (c[-1] - end))
    return out


def route_distances(demos: Sequence[Demo], *, bridge: bool = False) -> np.ndarray:
    """(D, D) route distance of every two demos (m; see the module docstring); ``bridge``: compared with their
    start and end offsets faded out (:func:`_bridged`; for parts of a task whose ends move with the objects)."""
    cs = _curves(demos)
    if bridge:
        cs = _bridged(cs)
    n = len(cs)
    M = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            M[i, j] = M[j, i] = float(np.median(_profile(cs[i], cs[j])[1]))
    return M


def _split(M: np.ndarray, k: int) -> np.ndarray | None:
    from scipy.cluster.hierarchy import fcluster, linkage
    from scipy.spatial.distance import squareform

    labels = fcluster(linkage(squareform(M, checks=False), method="average"), k, criterion="maxclust")
    return labels if len(set(labels.tolist())) == k else None


def _is_split(M: np.ndarray, labels: np.ndarray, size: float) -> bool:
    groups = [np.flatnonzero(labels == g) for g in np.unique(labels)]
    within = max((float(M[np.ix_(g, g)].max()) for g in groups), default=0.0)
    between = min(float(M[np.ix_(a, b)].min()) for n, a in enumerate(groups) for b in groups[n + 1 :])
    if all(len(g) == 1 for g in groups):
        return between > SINGLES_SHARE * size
    return between > max(ROUTE_SHARE * size, ROUTE_RATIO * within)


def find_routes(demos: Sequence[Demo], *, bridge: bool = False) -> Routes:
    """Which demonstrations go which way (:class:`Routes`; empty with fewer than 2 demos or one route);
    ``bridge``: see :func:`route_distances`."""
    from studio.core.quality import extent

    demos = list(demos)
    if len(demos) < 2 or len({_gripper_actions(d) for d in demos}) > 1:
        return Routes()  # fewer than two, or not the same task (the gripper used differently)
    M = route_distances(demos, bridge=bridge)
    size = extent(demos)
    labels = None
    for k in range(min(3, len(demos)), 1, -1):
        cand = _split(M, k)
        if cand is not None and _is_split(M, cand, size):
            labels = cand
            break
    if labels is None:
        return Routes()
    groups = sorted((tuple(int(i) for i in np.flatnonzero(labels == g)) for g in np.unique(labels)), key=min)
    ends = [np.mean([demos[i].position[-1] for i in g], axis=0) for g in groups]
    if not bridge and max(float(np.linalg.norm(a - b)) for a in ends for b in ends) > ROUTE_SHARE * size:
        return Routes()  # not ways to the same place: different tasks (an odd demonstration is named elsewhere)
    return _where(demos, groups)


def _gripper_actions(demo: Demo) -> tuple[bool, ...]:
    """The demo's gripper actions in order (True: close)."""
    from studio.core.keypoints import gripper_events

    g = np.asarray(demo.gripper, dtype=np.float64)
    ev = gripper_events(np.asarray(demo.t), g)
    return tuple(bool(g[b] < g[a]) for a, b in zip(ev[0::2], ev[1::2], strict=True))


def _where(demos: list[Demo], groups: list[tuple[int, ...]]) -> Routes:
    """Each group's mean where the groups are farthest apart, on the first demo's curve aligned to the others."""
    cs = _curves(demos)
    base = cs[groups[0][0]]
    # every demo's point matched to each point of the first demo's curve
    matched = np.empty((len(cs), base.shape[0], 3))
    for i, c in enumerate(cs):
        path, _ = _profile(base, c)
        for k in range(3):
            matched[i, :, k] = np.bincount(path[:, 0], weights=c[path[:, 1], k], minlength=base.shape[0]) / np.maximum(
                np.bincount(path[:, 0], minlength=base.shape[0]), 1
            )
    means = np.stack([matched[list(g)].mean(axis=0) for g in groups])  # (R, N, 3)
    gap = np.min([np.linalg.norm(means[a] - means[b], axis=1) for a in range(len(groups)) for b in range(a)], axis=0)
    u = int(np.argmax(gap))
    where = matched[:, u].mean(axis=0)
    routes = tuple(
        Route(g, (float(m[u, 0]), float(m[u, 1]), float(m[u, 2]))) for g, m in zip(groups, means, strict=True)
    )
    return Routes(routes, (float(where[0]), float(where[1]), float(where[2])))


def routes_of(demos: Sequence[Demo], caches: LearningCaches | None = None) -> Routes:
    """Which demonstrations go which way (:func:`find_routes`, remembered per set of demos in ``caches``)."""
    demos = list(demos)
    return (caches or LearningCaches()).routes.get_set(demos, ("routes",), lambda: find_routes(demos))


__all__ = [
    "N_CURVE",
    "ROUTE_RATIO",
    "ROUTE_SHARE",
    "SINGLES_SHARE",
    "Route",
    "Routes",
    "find_routes",
    "route_distances",
    "routes_of",
]
