"""Curves the quality measures compare: a demo's positions smoothed and resampled along its path, and the
distances between two curves (normalised DTW, discrete Fréchet) and among many (the spread R)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.ndimage import uniform_filter1d

from studio.core.errors import InvalidInput
from studio.core.types import Demo

#: Points per curve for the shape comparisons (evenly spaced along the path).
N_POINTS = 600
#: Pairs of curves measured together by :func:`frechet_many` (their distance matrices are held at once).
_FRECHET_BATCH = 16
#: Low-pass applied before any comparison, seconds (tremor and sensor noise are not the path).
SMOOTH_S = 0.05


def samples(t: np.ndarray, seconds: float) -> int:
    """Samples spanning ``seconds`` at the mean sampling interval of ``t`` (at least 1)."""
    dt = float(t[-1] - t[0]) / (len(t) - 1) if len(t) > 1 else 1.0
    return max(1, round(seconds / max(dt, 1e-12)))


def smoothed(demo: Demo) -> np.ndarray:
    """(N, 3) positions low-passed by a :data:`SMOOTH_S` moving average."""
    return uniform_filter1d(
        np.asarray(demo.position, dtype=np.float64), samples(demo.t, SMOOTH_S), axis=0, mode="nearest"
    )


def arc_length(pos: np.ndarray) -> np.ndarray:
    """(N,) cumulative path length of (N, 3) positions, from 0."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1))])


def arc_resample(pos: np.ndarray, n: int = N_POINTS) -> np.ndarray:
    """(n, 3) points evenly spaced along the path through ``pos`` (a still path gives n copies of its point)."""
    pos = np.asarray(pos, dtype=np.float64)
    s = arc_length(pos)
    if s[-1] <= 1e-12:
        return np.repeat(pos[:1], n, axis=0)
    keep = np.concatenate([[True], np.diff(s) > 0])
    grid = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(grid, s[keep], pos[keep, k]) for k in range(3)])


def curve(demo: Demo, n: int = N_POINTS) -> np.ndarray:
    """A demonstration (or a learned trajectory) as the curve the measures compare: smoothed, arc-resampled."""
    return arc_resample(smoothed(demo), n)


def ndtw(a: np.ndarray, b: np.ndarray) -> float:
    """Normalised DTW of two curves (M, 3), (N, 3): the paper's DTW cost g (sum of squared distances along the
    optimal alignment) ÷ the alignment's length — the mean squared distance between matched points, m²."""
    from dtaidistance import dtw as dtai

    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    path = np.asarray(dtai.warping_path_fast(a, b), dtype=np.int64)
    diff = a[path[:, 0]] - b[path[:, 1]]
    return float(np.einsum("ij,ij->", diff, diff) / path.shape[0])


def frechet(a: np.ndarray, b: np.ndarray) -> float:
    """Discrete Fréchet distance of two curves (M, D), (N, D): the shortest leash that walks both forward."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.ndim != 2 or b.ndim != 2:
        raise InvalidInput("Fréchet distance needs two non-empty curves of the same dimension.")
    return float(frechet_many(a[None], b[None])[0])


def frechet_pairs(pairs: Sequence[tuple[np.ndarray, np.ndarray]]) -> list[float]:
    """The discrete Fréchet distance of each pair of curves, as :func:`frechet` gives it, measured together
    (:func:`frechet_many`) where the pairs' shapes agree."""
    out = [0.0] * len(pairs)
    groups: dict[tuple[tuple[int, ...], tuple[int, ...]], list[int]] = {}
    for k, (a, b) in enumerate(pairs):
        groups.setdefault((np.shape(a), np.shape(b)), []).append(k)
    for ks in groups.values():
        values = frechet_many(np.stack([pairs[k][0] for k in ks]), np.stack([pairs[k][1] for k in ks]))
        for k, v in zip(ks, values, strict=True):
            out[k] = float(v)
    return out


def frechet_many(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(K,) discrete Fréchet distances of K pairs of curves, a (K, M, D) and b (K, N, D), computed together.

    F(i, j) = max(‖a_i − b_j‖, min(F(i−1, j), F(i−1, j−1), F(i, j−1))), evaluated one anti-diagonal at a
    time (all cells with i + j = d depend only on diagonals d − 1 and d − 2; in the flattened distance matrix
    a diagonal is a slice with stride N − 1, each cell holding the K pairs' distances side by side).
    """
    from scipy.spatial.distance import cdist

    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.ndim != 3 or b.ndim != 3 or a.shape[0] != b.shape[0] or a.shape[2] != b.shape[2] or not a.size or not b.size:
        raise InvalidInput("Fréchet distance needs two non-empty curves of the same dimension.")
    K, R, T = a.shape[0], a.shape[1], b.shape[1]
    if K > _FRECHET_BATCH:
        return np.concatenate(
            [frechet_many(a[k : k + _FRECHET_BATCH], b[k : k + _FRECHET_BATCH]) for k in range(0, K, _FRECHET_BATCH)]
        )
    flat = np.empty((R * T, K))  # the K pairs' distances side by side, cell after cell
    for k in range(K):
        flat[:, k] = cdist(a[k], b[k]).ravel()
    step = max(T - 1, 1)
    inf = np.inf
    bufs = [np.full((R + 1, K), inf), np.full((R + 1, K), inf), np.full((R + 1, K), inf)]
    bufs[0][0] = 0.0
    for d in range(2, R + T + 1):
        prev2, prev1, cur = bufs[(d - 2) % 3], bufs[(d - 1) % 3], bufs[d % 3]
        x0, x1 = max(1, d - T), min(R, d - 1)
        first = (x0 - 1) * (T - 1) + d - 2  # cell (x0 − 1, d − x0 − 1)
        local = flat[first : first + (x1 - x0) * step + 1 : step]
        best = np.minimum(prev1[x0 - 1 : x1], prev1[x0 : x1 + 1])
        np.minimum(best, prev2[x0 - 1 : x1], out=best)
        np.maximum(local, best, out=cur[x0 : x1 + 1])
        cur[x0 - 1] = inf
        if x1 + 1 <= R:
            cur[x1 + 1] = inf
    return bufs[(R + T) % 3][R].copy()


def time_normalised_mean(demos: Sequence[Demo], n: int = 2000) -> np.ndarray:
    """B1: (n, 3) the demos' positions, each resampled over 0…1 of its own duration, averaged sample by sample."""
    u = np.linspace(0.0, 1.0, n)
    out = np.zeros((n, 3))
    for d in demos:
        tt = (d.t - d.t[0]) / max(d.duration, 1e-12)
        p = smoothed(d)
        out += np.column_stack([np.interp(u, tt, p[:, k]) for k in range(3)])
    return out / len(demos)


def extent(demos: Sequence[Demo]) -> float:
    """Size of what was shown: the median over demos of the largest side of the position bounding box, m."""
    return float(np.median([d.extent for d in demos]))


def spread(curves: Sequence[np.ndarray]) -> tuple[float, np.ndarray]:
    """R, the mean pairwise normalised DTW of curves (m²), and the (D, D) matrix of them (0 on the diagonal)."""
    n = len(curves)
    M = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            M[i, j] = M[j, i] = ndtw(curves[i], curves[j])
    r = float(M[np.triu_indices(n, 1)].mean()) if n > 1 else float("nan")
    return r, M
