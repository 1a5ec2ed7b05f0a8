"""Key-point criteria (paper § Key-point Extraction): each test on a constructed path, the fast path against
the literal reference, noise robustness, sampling-rate independence, q ≡ −q, counts on scripted demos."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from studio.core.errors import NotEnoughData, StudioError
from studio.core.keypoints import (
    KeypointCache,
    corner_candidates,
    extract_keypoints,
    gripper_events,
    precompute,
)
from studio.core.types import Demo, KeypointParams
from tests.core.oracles import extract_keypoints_reference
from tests.core.teacher_demos import demos, plans

DOWN = np.array([0.0, 0.0, 1.0, 0.0])
#: Only one test active at a time: the others are switched off by impossible thresholds.
OFF = dict(eps1=2 * math.pi, eps2=0.0, eps5=1e9, eps7=1e9, eps8=2 * math.pi, eps9=0.0, eps12=10.0, eps14=10.0)


def make_demo(t, pos, ori=None, grip=None, name="constructed"):
    n = len(t)
    ori = np.tile(DOWN, (n, 1)) if ori is None else ori
    grip = np.full(n, 100.0) if grip is None else grip
    return Demo(t, pos, ori, grip, name=name)


def min_jerk(u):
    u = np.clip(u, 0, 1)
    return u**3 * (10 - 15 * u + 6 * u * u)


def corner_path(rate=1000.0, noise=0.0, seed=0):
    """0.3 m along x in 2 s, then 0.3 m along y in 2 s, with a constant-speed right-angle corner at t = 2 s."""
    t = np.arange(int(4 * rate) + 1) / rate
    x = np.minimum(t, 2.0) * 0.15
    y = np.maximum(t - 2.0, 0.0) * 0.15
    pos = np.column_stack([x, y, np.zeros_like(t)])
    if noise:
        pos = pos + np.random.default_rng(seed).normal(0, noise, pos.shape)
    return make_demo(t, pos)


def test_corner_test_finds_a_right_angle_corner():
    d = corner_path()
    p = KeypointParams(**{**OFF, "eps1": 2 * math.pi - 2.2})  # corner: angle < 2.2 rad; 90° qualifies
    kp = extract_keypoints(d, p)
    inner = kp[1:-1]
    assert len(inner) == 1
    assert abs(d.t[inner[0]] - 2.0) < 0.02


def test_corner_test_ignores_a_straight_line_and_a_gentle_bend():
    d = corner_path()
    # 90° corner = angle π/2 at the sample; a threshold below it (sharper corners only) finds nothing
    p = KeypointParams(**{**OFF, "eps1": 2 * math.pi - 1.2})
    assert extract_keypoints(d, p).tolist() == [0, len(d) - 1]


def test_corner_test_is_robust_to_1khz_sensor_noise():
    d = corner_path(noise=0.0005)  # 0.5 mm white noise per sample: per-sample angles are random
    p = KeypointParams(**{**OFF, "eps1": 2 * math.pi - 2.2})
    kp = extract_keypoints(d, p)[1:-1]
    assert len(kp) == 1 and abs(d.t[kp[0]] - 2.0) < 0.05


def test_pause_test_marks_the_start_of_a_pause_far_from_the_last_keypoint():
    # move 0.2 m in 2 s (min-jerk), rest 2 s, move on 0.2 m: one pause key-point when speed drops below ε2
    rate = 1000.0
    t = np.arange(int(6 * rate) + 1) / rate
    s = 0.2 * min_jerk(t / 2.0) + 0.2 * min_jerk((t - 4.0) / 2.0)
    pos = np.column_stack([s, np.zeros_like(s), np.zeros_like(s)])
    d = make_demo(t, pos)
    p = KeypointParams(**{**OFF, "eps2": 0.01, "eps3": 0.5, "eps4": 0.02})
    kp = extract_keypoints(d, p)[1:-1]
    assert len(kp) == 2  # the pause, and the slow end of the second move
    u = np.clip(t / 2.0, 0, 1)
    v = 0.2 * 30 * u**2 * (1 - u) ** 2 / 2.0  # min-jerk speed of the first move
    first_slow = np.flatnonzero((t > 1.0) & (v < 0.01))[0]
    assert abs(d.t[kp[0]] - d.t[first_slow]) < 0.03
    assert 5.5 < d.t[kp[1]] < 6.0
    # far from the last key-point is required: with ε4 larger than the move there is no pause key-point
    assert extract_keypoints(d, KeypointParams(**{**OFF, "eps2": 0.01, "eps4": 0.45}))[1:-1].size == 0
    # and it must come ε3 after the last key-point
    assert extract_keypoints(d, KeypointParams(**{**OFF, "eps2": 0.01, "eps3": 6.5}))[1:-1].size == 0


def test_distance_test_cuts_a_long_straight_line_every_eps5():
    rate = 1000.0
    t = np.arange(int(10 * rate) + 1) / rate
    pos = np.column_stack([0.1 * t, np.zeros_like(t), np.zeros_like(t)])  # 1 m at 0.1 m/s
    d = make_demo(t, pos)
    p = KeypointParams(**{**OFF, "eps5": 0.12, "eps6": 0.5, "eps7": 0.12})
    kp = extract_keypoints(d, p)
    gaps = np.diff(d.position[kp[:-1], 0])
    assert len(kp) == 2 + 8  # 1 m / 0.12 m
    assert np.allclose(gaps, 0.12, atol=0.001)
    # ε6: nothing before that many seconds even if the ball is left earlier
    kp = extract_keypoints(d, KeypointParams(**{**OFF, "eps5": 0.05, "eps6": 2.0, "eps7": 0.5}))
    assert np.all(np.diff(d.t[kp[:-1]]) > 2.0)
    # ε7: if the path left the ε7 ball before the time limit, the test never fires for that key-point
    assert extract_keypoints(d, KeypointParams(**{**OFF, "eps5": 0.05, "eps6": 2.0, "eps7": 0.1})).tolist() == [
        0,
        len(d) - 1,
    ]


def test_orientation_tests_use_rotation_angles():
    # rotate 1.2 rad about z in 4 s at constant speed, position fixed: distance test every ε12
    rate = 500.0
    t = np.arange(int(4 * rate) + 1) / rate
    ang = 0.3 * t
    ori = np.column_stack([np.cos(ang / 2), np.zeros_like(t), np.zeros_like(t), np.sin(ang / 2)])
    d = make_demo(t, np.zeros((len(t), 3)), ori)
    kp = extract_keypoints(d, KeypointParams(**{**OFF, "eps12": 0.4, "eps13": 0.2, "eps14": 0.5}))
    assert np.allclose(np.diff(ang[kp[:-1]]), 0.4, atol=0.01)


def test_q_and_minus_q_are_the_same_orientation():
    d = demos("pick-place")[0]
    flip = np.where(np.random.default_rng(3).random(len(d)) < 0.5, -1.0, 1.0)
    d2 = Demo(d.t, d.position, d.orientation * flip[:, None], d.gripper, name="flipped")
    assert np.array_equal(extract_keypoints(d), extract_keypoints(d2))


def test_gripper_events_and_ends_are_always_keypoints():
    d = demos("stack-cup")[0]
    plan = plans("stack-cup")[0]
    ev = gripper_events(d.t, d.gripper)
    assert len(ev) == 2 * len(plan.events)
    kp = extract_keypoints(d, KeypointParams(**OFF))
    assert set(ev.tolist()) | {0, len(d) - 1} == set(kp.tolist())
    for e, a, b in zip(plan.events, ev[::2], ev[1::2], strict=True):
        assert d.t[a] <= e.time + 0.1 and d.t[b] >= e.time
        assert abs(d.gripper[b] - d.gripper[a]) > 20


@pytest.mark.parametrize("task", ["stack-cup", "pick-place"])
def test_defaults_give_paper_like_counts_and_fast_path_matches_reference(task):
    for d in demos(task):
        s = precompute(d)
        kp = extract_keypoints(d, series=s)
        assert 15 <= len(kp) <= 30, len(kp)  # the paper: 18–24 key-points on 18k–31k samples
        assert np.array_equal(kp, extract_keypoints_reference(d, series=s))
        assert np.all(np.diff(kp) > 0) and kp[0] == 0 and kp[-1] == len(d) - 1


def _f(lo, hi):
    return st.one_of(st.sampled_from([lo, hi, (lo + hi) / 2]), st.floats(lo, hi))


_eps = st.fixed_dictionaries(
    {
        "eps1": _f(math.pi, 2 * math.pi),
        "eps2": _f(0.0, 0.1),
        "eps3": _f(0.0, 2.0),
        "eps4": _f(0.0, 0.2),
        "eps5": _f(0.0, 0.5),
        "eps6": _f(0.0, 2.0),
        "eps7": _f(0.0, 0.6),
        "eps8": _f(math.pi, 2 * math.pi),
        "eps9": _f(0.0, 0.3),
        "eps10": _f(0.0, 2.0),
        "eps11": _f(0.0, 0.5),
        "eps12": _f(0.0, 1.5),
        "eps13": _f(0.0, 2.0),
        "eps14": _f(0.0, 1.5),
    }
)


@functools.lru_cache(maxsize=1)
def _short():
    """The first 8 s of a pick-place demo (grasp included): keeps the literal oracle quick."""
    d = demos("pick-place")[1]
    n = 8000
    short = Demo(d.t[:n], d.position[:n], d.orientation[:n], d.gripper[:n], name="short")
    return short, precompute(short)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_eps)
def test_fast_path_equals_literal_reference_for_any_thresholds(eps):
    d, s = _short()
    p = KeypointParams(**eps)
    assert np.array_equal(extract_keypoints(d, p, series=s), extract_keypoints_reference(d, p, series=s))


def test_keypoints_do_not_depend_on_the_sampling_rate():
    fine = corner_path(rate=1000.0)
    coarse = corner_path(rate=250.0)
    p = KeypointParams(eps1=2 * math.pi - 2.2, eps5=0.1, eps6=0.3, eps7=0.1)
    a, b = fine.t[extract_keypoints(fine, p)], coarse.t[extract_keypoints(coarse, p)]
    assert len(a) == len(b) and np.allclose(a, b, atol=0.02)


def test_corner_candidates_one_per_run_at_its_minimum():
    a = np.array([3.0, 1.0, 0.5, 1.0, 3.0, 3.0, 2.0, 0.2, 0.2, 3.0, 1.5])
    assert corner_candidates(a, 2.5).tolist() == [2, 7, 10]
    assert corner_candidates(a, 0.1).tolist() == []


def test_cache_reuses_series_and_gives_same_result():
    cache = KeypointCache()
    d = demos("stack-cup")[2]
    s1 = cache.series(d)
    assert cache.series(d) is s1
    p = KeypointParams(eps2=0.02)
    assert np.array_equal(cache.extract(d, p), extract_keypoints(d, p))


def test_too_short_demo_is_refused_in_plain_words():
    d = Demo(np.array([0.0]), np.zeros((1, 3)), np.array([DOWN]), np.array([100.0]), name="Demo 4")
    with pytest.raises(NotEnoughData, match="Demo 4"):
        extract_keypoints(d)
    assert issubclass(NotEnoughData, StudioError)


def test_corner_cache_is_safe_across_threads() -> None:
    """The slider thread and the training thread share one series; evicting the cache must never raise."""
    import sys
    import threading

    from studio.core.keypoints import precompute
    from studio.core.types import Demo

    n = 200  # short, so each call is quick and the threads interleave inside the cache update
    t = np.arange(n) / 1000.0
    pos = np.column_stack([np.sin(t * 30), np.cos(t * 30), t])
    series = precompute(Demo(t, pos, np.tile([1.0, 0, 0, 0], (n, 1)), np.full(n, 50.0)))
    errors: list[BaseException] = []

    def hammer(seed: int) -> None:
        rng = np.random.default_rng(seed)
        try:
            for _ in range(20_000):
                series.corner_mask("position", float(rng.uniform(0.0, 3.0)))
                if errors:
                    return
        except Exception as exc:  # the test reports any failure
            errors.append(exc)

    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    try:
        threads = [threading.Thread(target=hammer, args=(k,)) for k in range(3)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
    finally:
        sys.setswitchinterval(old)
    assert not errors, errors


def test_thresholds_accept_numpy_numbers() -> None:
    from studio.core.types import KeypointParams

    p = KeypointParams(eps5=np.float32(0.2), eps2=np.float64(0.01))  # type: ignore[arg-type]  # on purpose
    assert isinstance(p.eps5, float) and abs(p.eps5 - 0.2) < 1e-6
    assert p.as_dict()["eps2"] == 0.01
