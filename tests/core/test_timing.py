"""Timing within the joint velocity and acceleration limits (studio.core.timing, toppra): the taught pace kept
where feasible, slowed only where a limit requires, never faster than taught, rest to rest, posture changes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from studio.core.errors import InvalidInput
from studio.core.kinematics import ACCELERATION_LIMITS, Baxter
from studio.core.timing import limit_ratio, retime

V = Baxter.load().velocity_limits("left")
A = np.asarray(ACCELERATION_LIMITS)


def _rest_to_rest(duration: float, amplitude: np.ndarray, n: int = 60) -> tuple[np.ndarray, np.ndarray]:
    """Knots of a smooth rest-to-rest joint motion (minimum-jerk) of ``amplitude`` rad over ``duration`` s."""
    s = np.linspace(0.0, duration, n)
    u = s / duration
    prog = u**3 * (10 - 15 * u + 6 * u * u)
    return s, np.outer(prog, amplitude)


def test_a_motion_within_the_limits_keeps_its_duration_exactly() -> None:
    s, q = _rest_to_rest(3.0, np.array([0.5, -0.3, 0.2, 0.6, 0.4, -0.5, 0.8]))  # peaks ~0.4 rad/s, ~0.6 rad/s²
    tm = retime([(s, q)], V, A, rate_hz=1000.0)
    assert tm.duration == pytest.approx(3.0, abs=2e-3)
    np.testing.assert_allclose(tm.s, tm.t, atol=2e-3)  # executed at the taught pace throughout
    assert limit_ratio(tm.q, 1000.0, V, A) <= 1.0


def test_a_motion_too_fast_for_the_limits_slows_down_only_as_much_as_needed() -> None:
    # 1.2 rad of s0 in 0.8 s: minimum-jerk peaks at 2.25 rad/s (limit 1.5) and 11.5 rad/s² (limit 4)
    s, q = _rest_to_rest(0.8, np.array([1.2, 0, 0, 0, 0, 0, 0]))
    tm = retime([(s, q)], V, A, rate_hz=1000.0)
    assert limit_ratio(tm.q, 1000.0, V, A) <= 1.0
    # bang-bang bound at the limits: 1.2 rad at ≤ 1.5 rad/s and ≤ 4 rad/s² takes ≥ 1.2/1.5 + 1.5/4 = 1.175 s;
    # time-optimal along the minimum-jerk path (which spends its speed unevenly) is not much more
    assert 1.17 <= tm.duration <= 1.6
    # never faster than taught: the skill time advances at most one second per second
    assert np.all(np.diff(tm.s) <= 1e-3 * (1 + 1e-6))
    assert tm.q[0] == pytest.approx(q[0]) and np.abs(tm.q[-1] - q[-1]).max() < 1e-9


def test_slower_pace_takes_longer() -> None:
    s, q = _rest_to_rest(2.0, np.array([0.3, 0.2, 0, 0, 0, 0, 0]))
    tm = retime([(s, q)], V, A, rate_hz=500.0, pace=0.5)
    assert tm.duration == pytest.approx(4.0, abs=5e-3)
    assert np.allclose(np.diff(tm.t), 1 / 500)


def test_starts_and_ends_at_rest_even_when_the_path_is_moving_at_its_ends() -> None:
    s = np.linspace(0.0, 2.0, 41)
    q = np.outer(s, np.full(7, 0.3))  # constant 0.3 rad/s from the first instant
    tm = retime([(s, q)], V, A, rate_hz=1000.0)
    v0 = np.abs(tm.q[1] - tm.q[0]).max() * 1000
    v1 = np.abs(tm.q[-1] - tm.q[-2]).max() * 1000
    assert v0 <= A.max() * 1e-3 + 1e-9 and v1 <= A.max() * 1e-3 + 1e-9
    assert limit_ratio(tm.q, 1000.0, V, A) <= 1.0
    assert 2.0 < tm.duration < 2.2  # ramps of ~0.3/4 s at each end


def test_between_pieces_the_arm_rests_changes_posture_in_a_straight_line_and_goes_on() -> None:
    s1, q1 = _rest_to_rest(1.0, np.full(7, 0.2))
    s2, q2 = _rest_to_rest(1.0, np.full(7, -0.2))
    s2 = s2 + 1.5  # the skill time between the pieces (1.0–1.5 s) is out of reach
    q2 = q2 + 1.0
    tm = retime([(s1, q1), (s2, q2)], V, A, rate_hz=1000.0, s_range=(0.0, 3.0))
    assert tm.reconfiguring.any()
    move = tm.q[tm.reconfiguring]
    d = (move - q1[-1]) / (q2[0] - q1[-1])  # straight line: every joint at the same fraction
    assert np.allclose(d, d[:, :1], atol=1e-9)
    # piece, move (0.8 rad at ≤ 1.5 rad/s, ≤ 4 rad/s²: ~0.93 s, more than the 0.5 s skipped), piece, and
    # the last 0.5 s of the skill range held at the end
    assert 3.3 < tm.duration < 3.5 and tm.s[-1] == pytest.approx(3.0)
    assert limit_ratio(tm.q, 1000.0, V, A) <= 1.0


def test_a_short_gap_in_the_same_posture_takes_the_skill_time() -> None:
    s1, q1 = _rest_to_rest(1.0, np.full(7, 0.1))
    s2 = s1 + 2.0
    q2 = q1[::-1].copy()  # comes back from where the first piece ended
    tm = retime([(s1, q1), (s2, q2)], V, A, rate_hz=1000.0)
    assert tm.duration == pytest.approx(3.0, abs=3e-3)  # the 1 s gap is held for 1 s, nothing more


def test_bad_input() -> None:
    with pytest.raises(InvalidInput):
        retime([], V, A)
    s, q = _rest_to_rest(1.0, np.full(7, 0.1))
    with pytest.raises(InvalidInput):
        retime([(s, q)], V, A, pace=0.0)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10_000), st.floats(0.3, 4.0))
def test_random_paths_always_respect_both_limits_at_1khz(seed: int, duration: float) -> None:
    rng = np.random.default_rng(seed)
    n = 12
    s = np.linspace(0.0, duration, n)
    q = np.cumsum(rng.normal(0.0, 0.25, (n, 7)), axis=0)
    tm = retime([(s, q)], V, A, rate_hz=1000.0)
    assert limit_ratio(tm.q, 1000.0, V, A) <= 1.0 + 1e-9
    assert np.all(np.diff(tm.s) >= -1e-12) and np.all(np.diff(tm.s) <= 1e-3 * (1 + 1e-6))
    assert tm.duration >= duration - 1e-3
