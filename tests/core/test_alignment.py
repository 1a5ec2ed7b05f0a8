"""Multidimensional DTW: hand-computed values, properties, and the compiled library (dtaidistance) vs the textbook
double loop."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from studio.core.alignment import accumulated_cost, dtw, dtw_distance, smooth_warp, time_map, warping_path
from studio.core.errors import InvalidInput


def test_single_sample_series():
    g, path = dtw(np.array([[1.0, 0.0]]), np.array([[1.0, 0.0]]))
    assert g == 0.0 and path.tolist() == [[0, 0]]
    g, path = dtw(np.array([[0.0]]), np.array([[1.0], [2.0], [0.0]]))
    assert g == 5.0 and path.tolist() == [[0, 0], [0, 1], [0, 2]]


def test_hand_computed_example():
    # r = [0, 2], t = [1, 1, 3]: H = [[1, 1, 9], [1, 1, 1]];
    # g = [[1, 2, 11], [2, 2, 3]]  ->  distance 3 along (0,0) (0,1) (1,2)
    g, path = dtw(np.array([[0.0], [2.0]]), np.array([[1.0], [1.0], [3.0]]))
    assert g == 3.0
    assert path.tolist() == [[0, 0], [0, 1], [1, 2]]
    G = accumulated_cost(np.array([[0.0], [2.0]]), np.array([[1.0], [1.0], [3.0]]))
    assert G[1:, 1:].tolist() == [[1.0, 2.0, 11.0], [2.0, 2.0, 3.0]]


def test_time_warped_copy_has_zero_distance():
    g, path = dtw(np.array([[0.0], [1.0], [2.0]]), np.array([[0.0], [1.0], [1.0], [2.0]]))
    assert g == 0.0
    assert path.tolist() == [[0, 0], [1, 1], [1, 2], [2, 3]]


def test_multidimensional_cost_sums_squared_differences_over_dimensions():
    r = np.array([[0.0, 0, 0, 0, 0, 0, 0, 0]])
    t = np.array([[1.0, 2, 0, 0, 0, 0, 0, 3]])
    assert dtw_distance(r, t) == 1 + 4 + 9


_series = st.integers(1, 12).flatmap(
    lambda n: arrays(np.float64, (n, 3), elements=st.floats(-10, 10, allow_nan=False, allow_subnormal=False))
)


@settings(max_examples=60, deadline=None)
@given(_series, _series)
def test_properties_symmetric_zero_on_identity_and_equal_to_double_loop(a, b):
    g, path = dtw(a, b)
    G = accumulated_cost(a, b)
    assert g == pytest.approx(G[-1, -1], rel=1e-9, abs=1e-9)
    # the library's path is optimal like the textbook backtracking's (on ties they may pick different ones)
    ref = warping_path(G)
    assert g == pytest.approx(float(np.sum((a[ref[:, 0]] - b[ref[:, 1]]) ** 2)), rel=1e-9, abs=1e-9)
    assert g == pytest.approx(dtw_distance(b, a), rel=1e-9, abs=1e-9)
    assert dtw_distance(a, a) == 0.0
    # the path is monotone, continuous and spans both series
    assert path[0].tolist() == [0, 0] and path[-1].tolist() == [len(a) - 1, len(b) - 1]
    steps = np.diff(path, axis=0)
    assert np.all((steps >= 0) & (steps <= 1)) and np.all(steps.sum(axis=1) >= 1)
    # the cost along the path is the distance
    assert g == pytest.approx(float(np.sum((a[path[:, 0]] - b[path[:, 1]]) ** 2)), rel=1e-9, abs=1e-9)


def test_time_map_is_monotone():
    rng = np.random.default_rng(0)
    a = np.cumsum(rng.random((80, 2)), axis=0)
    b = np.cumsum(rng.random((60, 2)), axis=0)
    _, path = dtw(a, b)
    m = time_map(path, np.arange(80) * 0.1, np.arange(60) * 0.1)
    assert np.all(np.diff(m) >= 0) and 0.0 <= m[0] < m[-1] <= 7.9
    assert m[0] == pytest.approx(np.mean(path[path[:, 1] == 0, 0]) * 0.1)


def test_smoothed_warp_keeps_its_ends_order_and_straight_stretches():
    # a DTW staircase: the test series waits (slope 0), then hurries (slope 3), then keeps pace
    x = np.arange(200.0)
    w = np.concatenate([np.full(50, 10.0), 10.0 + 3.0 * np.arange(1, 51), 160.0 + np.arange(1, 101)])
    s = smooth_warp(w, 2.0)
    assert s[0] == pytest.approx(w[0]) and s[-1] == pytest.approx(w[-1])
    assert np.all(np.diff(s) >= -1e-12)
    assert np.abs(np.diff(s, 2)).max() < 0.5 * np.abs(np.diff(w, 2)).max()  # no abrupt change of speed
    assert np.abs(s - w).max() < 3.0  # moved by about a grid step at most
    assert np.allclose(smooth_warp(2.0 * x + 1.0, 2.0), 2.0 * x + 1.0)
    assert np.array_equal(smooth_warp(w, 0.0), w)


def test_long_series_memory_is_bounded():
    # 6000 x 6000 in full would be 288 MB of doubles; the low-memory path holds at most 1000 x 1000 blocks.
    # Measured in a fresh process (the C library's allocations are invisible to tracemalloc).
    import subprocess
    import sys

    code = (
        "import numpy as np\n"
        "from studio.core.alignment import dtw\n"
        "def hwm():\n"
        "    return int([l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1])\n"
        "rng = np.random.default_rng(1)\n"
        "a, b = rng.normal(size=(6000, 8)), rng.normal(size=(6000, 8))\n"
        "dtw(a[:10], b[:10])\n"
        "before = hwm()\n"
        "g, p = dtw(a, b)\n"
        "print(hwm() - before, len(p))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True)
    grew_kb, n = map(int, out.stdout.split())
    assert n >= 6000
    assert grew_kb < 80_000


def test_bad_input():
    with pytest.raises(InvalidInput):
        dtw(np.zeros((0, 3)), np.zeros((3, 3)))
    with pytest.raises(InvalidInput):
        dtw(np.zeros((2, 3)), np.zeros((3, 2)))
    with pytest.raises(InvalidInput):
        dtw(np.array([[np.nan]]), np.array([[1.0]]))
