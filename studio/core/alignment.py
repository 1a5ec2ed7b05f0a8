"""Multidimensional dynamic time warping (paper § Dynamic Time Warping, Eqs. for H and g).

Local cost H(x, y) = Σ_d (r_x^d − t_y^d)² over the D = 8 scaled dimensions; accumulated cost
g(x, y) = H(x, y) + min{g(x−1, y), g(x−1, y−1), g(x, y−1)}.

Compiled speed without a compiler: the recursion is evaluated one **anti-diagonal** at a time (all cells
with x + y = d depend only on diagonals d−1 and d−2), each step is a handful of numpy operations on
contiguous slices — no Python loop over cells (tens of ms for
1000 × 1000 here versus about a second for a Python double loop over a 100 × 100 matrix).

Memory: whole 1 kHz trajectories would need 30,000² cells (7 GB). Demonstrations are instead averaged
and resampled on a common time grid of at most :data:`MAX_POINTS` samples (10 Hz for demos up to 100 s,
coarser for longer ones), and only two anti-diagonals of g plus one byte per cell (the move, for the
backtracking) are stored: at most ~2 MB whatever the demo length. DTW here only has to place key-points on
a common time line, and 100 ms of timing resolution is far below the spacing of key-points (≈ 1 s). The
warping is interpolated back to full resolution.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.ndimage import uniform_filter1d

from studio.core.errors import InvalidInput

#: Largest resampled length of a series given to DTW (bounds memory to MAX_POINTS² cells).
MAX_POINTS = 1000
#: Resampling rate for DTW when the demonstrations are short enough, Hz.
DTW_RATE_HZ = 10.0


def _check(a: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] == 0:
        raise InvalidInput(f"The {name} series must be a non-empty (N, D) array (got shape {a.shape}).")
    if not np.all(np.isfinite(a)):
        raise InvalidInput(f"The {name} series contains missing or invalid values (NaN or infinity).")
    return a


def _dtw_core(r: np.ndarray, t: np.ndarray, *, with_path: bool) -> tuple[float, np.ndarray | None]:
    """Anti-diagonal DTW: g(R, T) and, if asked, the optimal path (L, 2).

    Keeps only the two previous anti-diagonals of g (O(R) floats) plus one int8 move per cell for the
    backtracking (O(R·(R+T)) bytes); the local costs of a diagonal are computed on the fly from r and the
    reversed slice of t.
    """
    r, t = _check(r, "reference"), _check(t, "test")
    if r.shape[1] != t.shape[1]:
        raise InvalidInput(f"The two series must have the same dimensions (got {r.shape[1]} and {t.shape[1]}).")
    R, T = r.shape[0], t.shape[0]
    inf = np.inf
    bufs = [np.full(R + 1, inf), np.full(R + 1, inf), np.full(R + 1, inf)]
    bufs[0][0] = 0.0  # d = 0: g(0, 0) = 0; d = 1 is all border (inf)
    moves = np.empty((R + T + 1, R + 1), dtype=np.int8) if with_path else None
    trev = t[::-1]  # t[y − 1] for y = d − x is trev[T − d + x]
    for d in range(2, R + T + 1):
        prev2, prev1, cur = bufs[(d - 2) % 3], bufs[(d - 1) % 3], bufs[d % 3]
        x0, x1 = max(1, d - T), min(R, d - 1)
        up, left, diag = prev1[x0 - 1 : x1], prev1[x0 : x1 + 1], prev2[x0 - 1 : x1]
        diff = r[x0 - 1 : x1] - trev[T - d + x0 : T - d + x1 + 1]
        out = cur[x0 : x1 + 1]
        np.einsum("ij,ij->i", diff, diff, out=out)
        m1 = np.minimum(up, left)
        if moves is not None:
            mv = moves[d, x0 : x1 + 1]
            np.greater(up, left, out=mv, casting="unsafe")  # 1 if left is better than up
            mv += 1
            mv *= diag > m1  # 0: diagonal (preferred on ties), 1: up, 2: left
        np.minimum(m1, diag, out=m1)
        out += m1
        cur[x0 - 1] = inf
        if x1 + 1 <= R:
            cur[x1 + 1] = inf
    g = float(bufs[(R + T) % 3][R])
    if moves is None:
        return g, None
    x, y = R, T
    path = [(x - 1, y - 1)]
    mv_list = moves  # local
    while x > 1 or y > 1:
        m = mv_list[x + y, x]
        if m == 0:
            x, y = x - 1, y - 1
        elif m == 1:
            x -= 1
        else:
            y -= 1
        path.append((x - 1, y - 1))
    return g, np.array(path[::-1], dtype=np.int64)


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


def dtw(r: np.ndarray, t: np.ndarray) -> tuple[float, np.ndarray]:
    """DTW distance g(R, T) (sum of squared distances along the path) and the path (L, 2)."""
    g, path = _dtw_core(r, t, with_path=True)
    assert path is not None
    return g, path


def dtw_distance(r: np.ndarray, t: np.ndarray) -> float:
    """g(R, T) only."""
    return _dtw_core(r, t, with_path=False)[0]


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
    """The DTW resampling rate: DTW_RATE_HZ, lowered so the longest series has at most MAX_POINTS samples."""
    longest = max(max(durations), 1e-9)
    return min(DTW_RATE_HZ, (MAX_POINTS - 1) / longest)


def time_grid(t0: float, t1: float, rate: float) -> np.ndarray:
    n = max(2, math.floor((t1 - t0) * rate) + 1)
    return np.linspace(t0, t1, n)


def time_map(path: np.ndarray, ref_grid: np.ndarray, test_grid: np.ndarray) -> np.ndarray:
    """For each test grid sample, the mean reference time it is matched to (non-decreasing), (T,)."""
    j = path[:, 1]
    tot = np.bincount(j, weights=ref_grid[path[:, 0]], minlength=test_grid.shape[0])
    cnt = np.bincount(j, minlength=test_grid.shape[0])
    return tot / np.maximum(cnt, 1)


__all__ = [
    "DTW_RATE_HZ",
    "MAX_POINTS",
    "accumulated_cost",
    "common_rate",
    "dtw",
    "dtw_distance",
    "resample",
    "time_grid",
    "time_map",
    "warping_path",
]
