"""Multidimensional dynamic time warping (paper § Dynamic Time Warping, Eqs. for H and g).

Local cost H(x, y) = Σ_d (r_x^d − t_y^d)² over the D scaled dimensions; accumulated cost g(x, y) = H(x, y) +
min{g(x−1, y), g(x−1, y−1), g(x, y−1)}. The warping path is dtaidistance's C code (docs/decisions/005);
:func:`accumulated_cost` and :func:`warping_path` are the textbook double loop (plots, the tests' oracle).
Demos are resampled on a common grid (:func:`common_rate`, about :data:`DTW_RATE_HZ`) and the warping is
interpolated back to full resolution (:func:`time_map`, :func:`inverse_time_map`)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.ndimage import gaussian_filter1d, uniform_filter1d

from studio.core.errors import InvalidInput

#: Largest resampled length of a series given to DTW.
MAX_POINTS = 2000
#: Smallest resampled length of the longest series (short gestures are sampled faster than DTW_RATE_HZ).
MIN_POINTS = 200
#: Resampling rate for DTW, Hz (lowered for very long demos, raised for short ones).
DTW_RATE_HZ = 50.0
#: Gaussian σ, in DTW grid steps, of the smoothing :func:`smooth_warp` gives an inverse time map.
WARP_SMOOTH_STEPS = 2.0


def _check(a: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] == 0:
        raise InvalidInput(f"The {name} series must be a non-empty (N, D) array (got shape {a.shape}).")
    if not np.all(np.isfinite(a)):
        raise InvalidInput(f"The {name} series contains missing or invalid values (NaN or infinity).")
    return a


def accumulated_cost(r: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The full accumulated cost matrix g, (R+1, T+1), infinite border, g[0, 0] = 0 (small inputs: O(R·T)
    memory; for plots and tests — :func:`dtw` never builds it)."""
    r, t = _check(r, "reference"), _check(t, "test")
    if r.shape[1] != t.shape[1]:
        raise InvalidInput(f"The two series must have the same dimensions (got {r.shape[1]} and {t.shape[1]}).")
    R, T = r.shape[0], t.shape[0]
    H = np.sum((r[:, None, :] - t[None, :, :]) ** 2, axis=2)
    G = np.full((R + 1, T + 1), np.inf)
    G[0, 0] = 0.0
    for x in range(1, R + 1):
        for y in range(1, T + 1):
            G[x, y] = H[x - 1, y - 1] + min(G[x - 1, y], G[x - 1, y - 1], G[x, y - 1])
    return G


def warping_path(G: np.ndarray) -> np.ndarray:
    """Optimal path (L, 2) of (reference index, test index) pairs from (0, 0) to (R−1, T−1), by backtracking
    the accumulated cost matrix ``G`` (R+1, T+1)."""
    R, T = G.shape[0] - 1, G.shape[1] - 1
    x, y = R, T
    path = [(x - 1, y - 1)]
    while x > 1 or y > 1:
        diag, up, left = G[x - 1, y - 1], G[x - 1, y], G[x, y - 1]
        if diag <= up and diag <= left:
            x, y = x - 1, y - 1
        elif up <= left:
            x -= 1
        else:
            y -= 1
        path.append((x - 1, y - 1))
    return np.array(path[::-1], dtype=np.int64)


def _pair(r: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r, t = _check(r, "reference"), _check(t, "test")
    if r.shape[1] != t.shape[1]:
        raise InvalidInput(f"The two series must have the same dimensions (got {r.shape[1]} and {t.shape[1]}).")
    if r.shape[1] == 1:  # dtaidistance's 1-D routines take flat arrays
        return np.ascontiguousarray(r[:, 0]), np.ascontiguousarray(t[:, 0])
    return np.ascontiguousarray(r), np.ascontiguousarray(t)


def dtw(r: np.ndarray, t: np.ndarray) -> tuple[float, np.ndarray]:
    """DTW distance g(R, T) (sum of squared distances along the path) and the path (L, 2) of
    (reference index, test index) pairs from (0, 0) to (R−1, T−1)."""
    from dtaidistance import dtw as dtai

    a, b = _pair(r, t)
    R, T = len(a), len(b)
    if R == 1 or T == 1:  # one path only (and dtaidistance's low-memory variant aborts on 1 × 1)
        n = max(R, T)
        path = np.column_stack(
            [np.arange(n) if R > 1 else np.zeros(n, np.int64), np.arange(n) if T > 1 else np.zeros(n, np.int64)]
        )
    else:
        path = np.asarray(dtai.warping_path_fast(a, b, use_lowmem=max(R, T) > 1000), dtype=np.int64).reshape(-1, 2)
    A, B = a.reshape(len(a), -1), b.reshape(len(b), -1)
    diff = A[path[:, 0]] - B[path[:, 1]]
    return float(np.einsum("ij,ij->", diff, diff)), path


def dtw_distance(r: np.ndarray, t: np.ndarray) -> float:
    """g(R, T) only."""
    from dtaidistance import dtw as dtai

    a, b = _pair(r, t)
    d = dtai.distance_fast(a, b, use_pruning=False, use_ndim=a.ndim == 2)
    return float(d) ** 2


def resample(t: np.ndarray, X: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Values of X (N, D) at times ``grid``: averaged over one grid step first (no aliasing), then linear."""
    X = np.asarray(X, dtype=np.float64)
    if grid.shape[0] > 1 and t.shape[0] > 1:
        step = float(grid[1] - grid[0])
        dt = float(np.median(np.diff(t)))
        w = max(1, round(step / dt))
        if w > 1:
            X = uniform_filter1d(X, w, axis=0, mode="nearest")
    return np.column_stack([np.interp(grid, t, X[:, j]) for j in range(X.shape[1])])


def common_rate(durations: Sequence[float]) -> float:
    """The DTW resampling rate: DTW_RATE_HZ, raised so the longest series has at least MIN_POINTS samples and
    lowered so it has at most MAX_POINTS."""
    longest = max(max(durations), 1e-9)
    return min(max(DTW_RATE_HZ, (MIN_POINTS - 1) / longest), (MAX_POINTS - 1) / longest)


def time_grid(t0: float, t1: float, rate: float) -> np.ndarray:
    n = max(2, math.floor((t1 - t0) * rate) + 1)
    return np.linspace(t0, t1, n)


def time_map(path: np.ndarray, ref_grid: np.ndarray, test_grid: np.ndarray) -> np.ndarray:
    """For each test grid sample, the mean reference time it is matched to (non-decreasing), (T,)."""
    j = path[:, 1]
    tot = np.bincount(j, weights=ref_grid[path[:, 0]], minlength=test_grid.shape[0])
    cnt = np.bincount(j, minlength=test_grid.shape[0])
    return tot / np.maximum(cnt, 1)


def inverse_time_map(mapped: np.ndarray, test_grid: np.ndarray, ref_times: np.ndarray) -> np.ndarray:
    """For reference times, the test time they are matched to: the inverse of :func:`time_map` (``mapped``,
    non-decreasing reference time per test grid sample), evaluated at ``ref_times``; flat stretches (several
    test samples matched to one reference time) are replaced by their mean test time."""
    x, inv = np.unique(np.asarray(mapped, dtype=np.float64), return_inverse=True)
    y = np.bincount(inv, weights=test_grid) / np.bincount(inv)
    if x.shape[0] == 1:
        return np.full(np.shape(ref_times), y[0])
    return np.interp(ref_times, x, y)


def smooth_warp(w: np.ndarray, sigma: float = WARP_SMOOTH_STEPS) -> np.ndarray:
    """A time map sampled on a uniform grid (non-decreasing, (n,)), smoothed by a Gaussian of ``sigma`` samples.

    A DTW warping path is a staircase: the map interpolated from it changes slope abruptly at grid samples
    (from 0 where one series waits to 10× where it hurries), so a demonstration played through it jumps in
    speed (docs/decisions/003). DTW only knows the match to about a grid step, so the map is
    smoothed over a couple of steps. Both ends are reflected oddly (w(−x) = 2 w(0) − w(x)): the first and last
    values are kept exactly, a linear map is unchanged, and the kernel being positive keeps it non-decreasing.
    """
    w = np.asarray(w, dtype=np.float64)
    n = w.shape[0]
    if sigma <= 0 or n < 3:
        return w.copy()
    pad = min(n - 1, math.ceil(4.0 * sigma))
    x = np.pad(w, pad, mode="reflect", reflect_type="odd")
    return gaussian_filter1d(x, sigma, mode="nearest", truncate=4.0)[pad : pad + n]


__all__ = [
    "DTW_RATE_HZ",
    "MAX_POINTS",
    "MIN_POINTS",
    "WARP_SMOOTH_STEPS",
    "accumulated_cost",
    "common_rate",
    "dtw",
    "dtw_distance",
    "inverse_time_map",
    "resample",
    "smooth_warp",
    "time_grid",
    "time_map",
    "warping_path",
]
