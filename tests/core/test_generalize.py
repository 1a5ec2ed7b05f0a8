"""Generalized trajectory: spline through timed points, unit sign-continuous quaternions, step gripper; IK."""

from __future__ import annotations

import numpy as np
import pytest

from studio.core.errors import InvalidInput
from studio.core.generalize import generalize, gripper_steps, joint_trajectory
from studio.core.kinematics import Baxter


def _points():
    t = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    pos = np.array(
        [[0.6, 0.3, 0.1], [0.65, 0.3, 0.05], [0.7, 0.3, 0.0], [0.7, 0.3, 0.0], [0.7, 0.2, 0.1], [0.6, 0.2, 0.1]]
    )
    down = np.array([0.0, 0.0, 1.0, 0.0])
    q = np.tile(down, (6, 1))
    q[3] = -q[3]  # the same orientation written as −q must not make the spline pass through zero
    g = np.array([100.0, 100.0, 100.0, 40.0, 40.0, 40.0])
    return t, np.column_stack([pos, q, g])


def test_interpolates_without_smoothing_and_samples_at_rate():
    t, P = _points()
    tr = generalize(t, P, rate_hz=200.0, smoothing=0.0)
    assert tr.t[0] == 0.0 and tr.t[-1] == pytest.approx(5.0) and np.allclose(np.diff(tr.t), 1 / 200)
    idx = np.round(t * 200).astype(int)
    assert np.allclose(tr.position[idx], P[:, :3], atol=1e-6)


def test_quaternions_unit_and_sign_continuous():
    t, P = _points()
    tr = generalize(t, P, rate_hz=100.0)
    assert np.allclose(np.linalg.norm(tr.orientation, axis=1), 1.0)
    assert np.all(np.einsum("ij,ij->i", tr.orientation[1:], tr.orientation[:-1]) > 0.99)


def test_gripper_is_a_step_with_learned_levels_between_event_points():
    t, P = _points()
    P[:3, 7] = [99.0, 100.0, 101.0]
    tr = generalize(t, P, rate_hz=100.0)
    levels = np.unique(tr.gripper)
    assert levels.tolist() == [pytest.approx(40.0), pytest.approx(100.0)]
    switch = tr.t[np.flatnonzero(np.diff(tr.gripper))[0] + 1]
    assert switch == pytest.approx(2.5, abs=0.011)  # half-way between the last open and first closed point
    lv, sw = gripper_steps(t, P[:, 7], np.ones(6))
    assert lv.tolist() == pytest.approx([100.0, 40.0]) and sw.tolist() == [2.5]


def test_smoothing_spline_regression_is_smoother_than_interpolation():
    t = np.linspace(0, 10, 21)
    rng = np.random.default_rng(0)
    pos = np.column_stack([np.sin(t / 3), np.cos(t / 3), t / 10]) + rng.normal(0, 0.01, (21, 3))
    P = np.column_stack([pos, np.tile([1.0, 0, 0, 0], (21, 1)), np.full(21, 100.0)])
    rough = generalize(t, P, rate_hz=100.0, smoothing=0.0)
    smooth = generalize(t, P, rate_hz=100.0, smoothing=1.0)
    curv = [np.abs(np.diff(d.position, 2, axis=0)).sum() for d in (rough, smooth)]
    assert curv[1] < curv[0]


def test_few_points_and_bad_input():
    t, P = _points()
    tr = generalize(t[:2], P[:2], rate_hz=10.0)
    assert len(tr) == 11
    with pytest.raises(InvalidInput):
        generalize(t, P[:, :7])
    with pytest.raises(InvalidInput):
        generalize(t, np.where(np.eye(6, 8) > 0, np.nan, P))


def test_joint_trajectory_tracks_within_a_millimetre_and_respects_limits():
    b = Baxter.load()
    q0 = b.neutral("left")
    # a reachable Cartesian path: FK of a smooth joint motion
    ts = np.linspace(0, 4, 9)
    Q = q0 + 0.25 * np.sin(np.outer(ts / 4 * np.pi, [1, 0.5, -0.5, 0.7, 0.3, -0.4, 0.6]))
    pos, ori = b.fk_batch("left", Q)
    P = np.column_stack([pos, ori, np.full(9, 100.0)])
    tr = generalize(ts, P, rate_hz=500.0, smoothing=0.0)
    jt = joint_trajectory(tr, "left", q0, b)
    assert jt.q.shape[1] == 7 and jt.arm == "left" and np.allclose(np.diff(jt.t), 1 / 500)
    # it starts moving at once, so the robot needs a few tens of milliseconds to get up to speed, no more
    assert tr.duration <= jt.t[-1] - jt.t[0] <= tr.duration + 0.1
    assert jt.position_error.max() < 1e-3 and jt.orientation_error.max() < 0.01 and jt.converged.all()
    assert np.all(jt.q >= b.lower_limits("left")) and np.all(jt.q <= b.upper_limits("left"))
    v = np.abs(np.diff(jt.q, axis=0)) * 500
    a = np.abs(np.diff(jt.q, 2, axis=0)) * 500**2
    assert np.all(v <= b.velocity_limits("left") * (1 + 1e-9)) and np.all(
        a <= b.acceleration_limits("left") * (1 + 1e-9)
    )


def test_joint_trajectory_slows_down_when_too_fast():
    b = Baxter.load()
    q0 = b.neutral("left")
    ts = np.linspace(0.0, 0.5, 6)
    Q = q0 + np.outer(ts, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 5.0])  # w2 at 5 rad/s > 4 rad/s limit
    pos, ori = b.fk_batch("left", Q)
    tr = generalize(ts, np.column_stack([pos, ori, np.full(6, 100.0)]), rate_hz=500.0, smoothing=0.0)
    jt = joint_trajectory(tr, "left", q0, b)
    # 2.5 rad of w2 from rest to rest at ≤ 4 rad/s and ≤ 8 rad/s² takes 2.5/4 + 4/8 = 1.125 s; the IK may
    # share the turn with w0 (both roll the wrist), so a little less
    assert 0.9 < jt.t[-1] - jt.t[0] < 1.3
    v = np.abs(np.diff(jt.q, axis=0)) * 500
    a = np.abs(np.diff(jt.q, 2, axis=0)) * 500**2
    assert np.all(v <= b.velocity_limits("left") * (1 + 1e-9)) and np.all(
        a <= b.acceleration_limits("left") * (1 + 1e-9)
    )
    assert jt.position_error.max() < 1e-3


def test_pinned_poses_are_met_exactly_and_the_rest_is_untouched():
    from studio.core.generalize import pin_poses, pin_positions

    t = np.linspace(0.0, 2.0, 201)
    pos = np.column_stack([t, np.sin(t), np.zeros_like(t)])
    ori = np.tile([1.0, 0.0, 0.0, 0.0], (t.shape[0], 1))
    turned = np.array([np.cos(0.1), 0.0, 0.0, np.sin(0.1)])
    pins = [(0.0, np.array([0.0, 0.01, 0.0]), ori[0]), (1.0, np.array([1.0, 0.9, 0.0]), turned)]
    p, q = pin_poses(t, pos, ori, pins)
    assert np.array_equal(pin_positions(t, pos, pins), p)  # the positions alone, the same numbers
    assert np.allclose(p[0], pins[0][1]) and np.allclose(p[100], pins[1][1])
    assert abs(abs(float(q[100] @ turned)) - 1.0) < 1e-12
    far = np.abs(t - 1.0) > 0.15
    far &= t > 0.15
    assert np.allclose(p[far], pos[far]) and np.allclose(q[far], ori[far])
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
