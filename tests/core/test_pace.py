"""The pace of a skill: long rests of a demonstration shortened (motion untouched, ends kept, the gripper's
moves never counted as rest), and a joint trajectory timed again at another speed within the limits."""

from __future__ import annotations

import numpy as np
import pytest

from studio.core.errors import InvalidInput
from studio.core.frames import Contact, DemoObjects
from studio.core.kinematics import ACCELERATION_LIMITS, Baxter
from studio.core.pace import KEEP_S, PAUSE_S, WINDOW_S, at_speed, remove_pauses, resting, take_clock, without_pauses
from studio.core.timing import limit_ratio, retime
from studio.core.types import Demo, JointTrajectory

V = Baxter.load().velocity_limits("left")
A = np.asarray(ACCELERATION_LIMITS)
RATE = 200.0


def paused_demo(pause_s: float = 5.0, noise: float = 0.0, grip_in_pause: bool = False) -> Demo:
    """1 s moving 20 cm along x, ``pause_s`` resting, 1 s moving back; at ``RATE`` Hz."""
    t1 = np.arange(0, 1.0, 1 / RATE)
    t2 = np.arange(1.0, 1.0 + pause_s, 1 / RATE)
    t3 = np.arange(1.0 + pause_s, 2.0 + pause_s + 1e-9, 1 / RATE)
    x = np.concatenate([0.2 * t1, np.full(len(t2), 0.2), 0.2 - 0.2 * (t3 - t3[0])])
    t = np.concatenate([t1, t2, t3])
    rng = np.random.default_rng(0)
    pos = np.column_stack([0.6 + x, np.zeros_like(x), np.zeros_like(x)]) + noise * rng.standard_normal((len(t), 3))
    ori = np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1))
    grip = np.full(len(t), 100.0)
    if grip_in_pause:  # the gripper closes slowly during the rest: that is work, not a pause
        k = (t >= 1.0) & (t < 1.0 + pause_s)
        grip[k] = 100.0 - 100.0 * (t[k] - 1.0) / pause_s
        grip[t >= 1.0 + pause_s] = 0.0
    return Demo(t, pos, ori, grip, name="paused")


def test_a_long_rest_is_shortened_and_the_motion_keeps_its_pace() -> None:
    d = paused_demo(5.0, noise=2e-4)  # 0.2 mm sensor noise while resting
    t = without_pauses(d)
    assert t[0] == d.t[0] and np.all(np.diff(t) > 0) and len(t) == len(d.t)
    # the rest is found within a speed window of its ends, then lasts KEEP_S
    assert d.duration - 5.0 + KEEP_S <= t[-1] - t[0] <= d.duration - 5.0 + KEEP_S + 2 * WINDOW_S
    moving = ~resting(d)
    moving = moving[:-1] & moving[1:]
    np.testing.assert_allclose(np.diff(t)[moving], np.diff(np.asarray(d.t))[moving])  # motion untouched
    short = remove_pauses(d)
    assert short.duration < d.duration / 2 and np.array_equal(short.position, d.position)


def test_short_rests_and_a_demo_without_rests_stay_as_they_are() -> None:
    d = paused_demo(0.2)
    np.testing.assert_allclose(without_pauses(d), d.t)


def test_the_gripper_moving_during_a_rest_of_the_hand_is_not_a_pause() -> None:
    d = paused_demo(5.0, grip_in_pause=True)
    assert without_pauses(d)[-1] == pytest.approx(d.t[-1], abs=1e-9)


def _take(parts: list[tuple[float, float]], noise: float = 4e-4) -> Demo:
    """A take at 100 Hz (Baxter's joint states) of ``(seconds, speed m/s)`` parts along x, with sensor noise."""
    t, x, t0, x0 = [], [], 0.0, 0.6
    for dur, v in parts:
        tt = np.arange(0.0, dur, 0.01)
        t.append(t0 + tt)
        x.append(x0 + v * tt)
        t0, x0 = t0 + dur, x0 + v * dur
    tt, xx = np.concatenate(t), np.concatenate(x)
    pos = np.column_stack([xx, np.zeros_like(xx), np.zeros_like(xx)])
    pos += noise * np.random.default_rng(1).standard_normal(pos.shape)
    return Demo(tt, pos, np.tile([1.0, 0.0, 0.0, 0.0], (len(tt), 1)), np.full(len(tt), 100.0), name="take")


def test_a_take_starts_at_its_first_motion_ends_at_its_last_and_its_pauses_are_shortened() -> None:
    d = _take([(6.0, 0.0), (2.0, 0.05), (20.0, 0.0), (2.0, -0.05), (8.0, 0.0)])  # still, move, think, move, still
    c = take_clock([d])
    assert c.take == pytest.approx(37.99, abs=0.02)
    # from the first motion to the last, with a moment (KEEP_S) of stillness at each end
    assert 6.0 - KEEP_S - 2 * WINDOW_S <= c.source[0] <= 6.0 - KEEP_S
    assert 30.0 + KEEP_S <= c.source[-1] <= 30.0 + KEEP_S + 2 * WINDOW_S
    assert len(c.pauses) == 1 and c.pauses[0][1] - c.pauses[0][0] > 20.0 - 2 * WINDOW_S
    assert 4.0 + 3 * KEEP_S <= c.duration <= 4.0 + 3 * KEEP_S + 4 * WINDOW_S  # a motion's start and end kept whole
    assert c.removed == pytest.approx(c.pauses[0][1] - c.pauses[0][0] - KEEP_S)
    taught = c.demo(d)
    assert taught.t[0] == 0.0 and np.all(np.diff(taught.t) > 0) and len(taught.t) == c.last - c.first + 1
    np.testing.assert_array_equal(taught.position, d.position[c.first : c.last + 1])  # the same samples
    # a grasp at 9 s into the take (1 s after the pause began) comes at the pause's end, less KEEP_S
    objs = c.objects(DemoObjects((), (Contact(31.0, "release", "block", ()),)))
    assert objs.contacts[0].t == pytest.approx(c.duration, abs=0.05)
    kept = take_clock([d], keep=True)
    assert kept.removed == 0.0 and 24.0 + 2 * KEEP_S <= kept.duration <= 24.0 + 2 * KEEP_S + 2 * WINDOW_S


def test_a_slow_careful_drag_is_motion_not_a_pause() -> None:
    for v in (0.005, 0.01):  # 5 mm/s and 1 cm/s, with a real robot's noise (0.4 mm at 100 Hz)
        c = take_clock([_take([(2.0, 0.0), (30.0, v), (2.0, 0.0)])])
        assert c.pauses == () and abs(c.duration - 30.0 - 2 * KEEP_S) <= 2 * WINDOW_S, v


def test_a_short_stop_stays_and_a_still_take_is_kept_whole() -> None:
    c = take_clock([_take([(2.0, 0.05), (PAUSE_S * 0.6, 0.0), (2.0, 0.05)])])
    assert c.pauses == () and c.duration == pytest.approx(c.take)  # moving at both ends: nothing cut
    still = take_clock([_take([(5.0, 0.0)])])
    assert still.first == 0 and still.duration == pytest.approx(4.99, abs=0.02)


def test_bad_keep() -> None:
    with pytest.raises(InvalidInput):
        without_pauses(paused_demo(), keep=0.0)


def _joint_trajectory(duration: float = 4.0, rate: float = 500.0) -> JointTrajectory:
    s = np.linspace(0.0, duration, 60)
    u = s / duration
    q_knots = np.outer(u**3 * (10 - 15 * u + 6 * u * u), [0.4, -0.3, 0.2, 0.5, 0.3, -0.4, 0.6])
    tm = retime([(s, q_knots)], V, A, rate_hz=rate)
    m = len(tm.t)
    grip = np.where(tm.s < duration / 2, 100.0, 0.0)
    return JointTrajectory(tm.t, tm.q, np.zeros(m), np.zeros(m), np.ones(m, bool), "left", grip, skill_time=tm.s)


def test_a_faster_skill_takes_less_time_within_the_limits_and_keeps_its_path() -> None:
    jt = _joint_trajectory()
    fast = at_speed(jt, 2.0, V, A)
    assert fast.t[-1] - fast.t[0] == pytest.approx((jt.t[-1] - jt.t[0]) / 2, rel=0.1)
    assert limit_ratio(fast.q, 500.0, V, A) <= 1.0
    np.testing.assert_allclose(fast.q[0], jt.q[0], atol=1e-9)
    np.testing.assert_allclose(fast.q[-1], jt.q[-1], atol=1e-6)
    # the gripper closes at the same point of the skill, half-way, now at half the time
    t_close = fast.t[np.argmax(np.asarray(fast.gripper) < 50)] - fast.t[0]
    assert t_close == pytest.approx((jt.t[-1] - jt.t[0]) / 4, abs=0.15)


def test_a_slower_skill_takes_longer_and_as_taught_is_unchanged() -> None:
    jt = _joint_trajectory()
    slow = at_speed(jt, 0.5, V, A)
    assert slow.t[-1] - slow.t[0] == pytest.approx(2 * (jt.t[-1] - jt.t[0]), rel=0.05)
    assert at_speed(jt, 1.0, V, A) is jt


def test_faster_than_the_limits_allow_is_slowed_to_them() -> None:
    jt = _joint_trajectory(duration=1.2)  # already near the limits at its taught pace
    fast = at_speed(jt, 4.0, V, A)
    assert limit_ratio(fast.q, 500.0, V, A) <= 1.0
    assert fast.t[-1] - fast.t[0] > (jt.t[-1] - jt.t[0]) / 4


def test_speeds_out_of_range_are_refused() -> None:
    with pytest.raises(InvalidInput):
        at_speed(_joint_trajectory(), 10.0, V, A)
