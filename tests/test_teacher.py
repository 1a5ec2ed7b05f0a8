"""The scripted teacher: human-like, within the robot's limits, varied, and noisy only when recorded."""

from __future__ import annotations

import numpy as np
import pytest

from studio.core.errors import InvalidInput
from studio.core.kinematics import Baxter, quat_angle
from studio.teacher import GRIP_WIDTH, OPEN_WIDTH, TASKS, recording_from_plan, teach


@pytest.mark.parametrize("task", TASKS)
def test_plans_are_paper_like_and_within_limits(task):
    b = Baxter.load()
    lo = np.concatenate([b.lower_limits("left"), b.lower_limits("right")])
    hi = np.concatenate([b.upper_limits("left"), b.upper_limits("right")])
    vmax = np.concatenate([b.velocity_limits("left"), b.velocity_limits("right")])
    for seed in (0, 1, 2):
        p = teach(task, seed)
        assert 20.0 <= p.duration <= 30.0
        assert np.allclose(np.diff(p.t), 1e-3)
        assert p.q.shape == (len(p.t), 14) and p.gripper.shape == (len(p.t), 2)
        assert np.all(p.q >= lo - 1e-12) and np.all(p.q <= hi + 1e-12)
        v = np.abs(np.diff(p.q, axis=0)) / 1e-3
        assert np.all(v <= vmax), (v / vmax).max()
        assert np.all(p.q[:, 7:] == b.neutral("right"))  # the other arm rests
        # events: closes then opens, at the gripper's pose (FK of q at that time)
        acts = [e.action for e in p.events]
        assert acts == (["close", "open"] if task == "stack-cup" else ["close", "open"] * 2)
        for e in p.events:
            i = round(e.time * 1000)
            pos, ori = b.fk("left", p.q[i, :7])
            assert np.allclose(pos, e.position) and quat_angle(ori, e.wxyz) < 1e-9
            assert abs(np.linalg.norm(p.q[i + 300, :7] - p.q[i, :7])) < 1e-9  # the arm waits while it grips
        levels = np.unique(np.round(p.gripper[:, 0], 6))
        assert levels.min() == pytest.approx(GRIP_WIDTH[task]) and levels.max() == pytest.approx(OPEN_WIDTH[task])


def test_demonstrations_differ_like_a_human_teacher():
    b = Baxter.load()
    ps = [teach("pick-place", s) for s in (0, 1, 2)]
    durations = [p.duration for p in ps]
    assert max(durations) - min(durations) > 1.0  # different speeds and pauses
    # grasp poses a few mm apart, via-points a few cm apart
    grasp = np.array([p.events[0].position for p in ps])
    assert 0.001 < np.max(np.ptp(grasp, axis=0)) < 0.02
    mids = np.array([b.fk("left", p.q[int(len(p.t) * 0.3), :7])[0] for p in ps])
    assert np.max(np.ptp(mids, axis=0)) > 0.01


def test_noise_only_when_recording_and_reproducible():
    p = teach("stack-cup", 4)
    r = recording_from_plan(p)
    clean = recording_from_plan(p, noise=False)
    assert np.array_equal(clean.q, p.q)
    d = r.q - p.q
    assert 1e-4 < d.std() < 1e-3  # encoder noise and quantisation, ~0.3 mrad
    assert np.array_equal(recording_from_plan(p).q, r.q)
    assert r.arms == ("left",) and r.name
    # the smooth plan has no sample-to-sample jitter: second differences are tiny
    assert np.abs(np.diff(p.q[:, :7], 2, axis=0)).max() < 1e-4


def test_plan_follows_the_cartesian_path_closely():
    # joints interpolated between IK knots still give a smooth gripper path: no jumps over 1 mm per ms
    b = Baxter.load()
    p = teach("stack-cup", 0)
    pos, _ = b.fk_batch("left", p.q[::10, :7])
    assert np.linalg.norm(np.diff(pos, axis=0), axis=1).max() < 0.01  # < 1 m/s


def test_right_arm_and_both_arms():
    b = Baxter.load()
    r = teach("stack-cup", 1, arm="right")
    assert r.arms == ("right",) and np.all(r.q[:, :7] == b.neutral("left"))
    assert all(e.arm == "right" and e.position[1] < 0 for e in r.events)
    both = teach("pick-place", 1, arm="both")
    assert both.arms == ("left", "right") and {e.arm for e in both.events} == {"left", "right"}


def test_bad_arguments():
    with pytest.raises(InvalidInput):
        teach("juggle", 0)
    with pytest.raises(InvalidInput):
        teach("stack-cup", 0, arm="middle")
