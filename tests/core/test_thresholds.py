"""Automatic thresholds that follow the demonstrations, the Detail control, teacher-set values, Suggest (auto-tune)
and the live preview path."""

from __future__ import annotations

import itertools
import math
import multiprocessing
import threading
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import numpy as np
import pytest

from studio.core import autotune
from studio.core.caches import LearningCaches
from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.keypoints import KeypointCache
from studio.core.learn_settings import LearnSettings
from studio.core.pipeline import preview_path
from studio.core.thresholds import DemoStats, ThresholdSettings, auto_params
from studio.core.types import KeypointParams
from studio.shapes import ShapeSpec, shape_demos
from studio.words import tune_summary
from tests.core.teacher_demos import demos as task_demos


def _kps(demos, params):
    cache = KeypointCache()
    return [len(cache.extract(d, params)) for d in demos]


@pytest.mark.parametrize("shape", ["circle", "zigzag", "handwriting"])
def test_a_small_gesture_and_a_large_reach_both_get_enough_keypoints(shape):
    for size, dur in ((0.03, 2.0), (0.6, 20.0)):
        ds = list(shape_demos(ShapeSpec(shape, size, dur), 3))
        n = _kps(ds, auto_params(ds))
        assert all(15 <= k <= 45 for k in n), (size, dur, n)
    # the old fixed values found almost nothing on a 3 cm gesture
    ds = list(shape_demos(ShapeSpec(shape, 0.03, 2.0), 3))
    assert max(_kps(ds, KeypointParams())) <= 6


def test_automatic_values_are_real_units_that_scale_with_the_demos():
    small = DemoStats.of(list(shape_demos(ShapeSpec("circle", 0.03, 2.0), 3)))
    big = DemoStats.of(list(shape_demos(ShapeSpec("circle", 0.6, 2.0), 3)))
    assert big.size / small.size == pytest.approx(20, rel=0.15)
    ps, pb = auto_params(small), auto_params(big)
    assert pb.eps5 / ps.eps5 == pytest.approx(big.path_length / small.path_length, rel=0.01)
    assert ps.eps7 == 2 * ps.eps5 and ps.eps4 == ps.eps5 / 2 and ps.eps3 == ps.eps6
    assert ps.eps1 == KeypointParams().eps1  # an angle needs no scale
    # a slow demo of the same shape waits longer between key-points
    slow = auto_params(list(shape_demos(ShapeSpec("circle", 0.03, 20.0), 3)))
    assert slow.eps6 > ps.eps6


def test_detail_moves_the_coupled_thresholds_together():
    ds = list(shape_demos(ShapeSpec("spiral", 0.15, 2.0), 3))
    counts = [np.mean(_kps(ds, auto_params(ds, d))) for d in (-2, -1, 0, 1, 2)]
    assert all(a < b for a, b in itertools.pairwise(counts))
    lo, hi = auto_params(ds, -1), auto_params(ds, 1)
    assert lo.eps5 > hi.eps5 and lo.eps7 > hi.eps7 and lo.eps4 > hi.eps4
    assert auto_params(ds, 99) == auto_params(ds, 3)  # clipped to the control's range


def test_the_teachers_own_value_is_kept():
    ds = list(shape_demos(ShapeSpec("circle", 0.15, 2.0), 3))
    s = ThresholdSettings().set("eps5", 0.05)
    assert s.resolve(ds).eps5 == 0.05 and not s.is_auto("eps5") and s.is_auto("eps6")
    # Detail moves the automatic ones only
    assert s.with_detail(2).resolve(ds).eps5 == 0.05
    assert s.with_detail(2).resolve(ds).eps6 != s.resolve(ds).eps6
    assert s.auto("eps5").resolve(ds).eps5 == auto_params(ds).eps5
    # saved and read back; and a session saved with fixed values only
    back = ThresholdSettings.from_dict(s.with_detail(1.5).as_dict())
    assert back == s.with_detail(1.5) and back.as_dict() == {"detail": 1.5, "teacher": {"eps5": 0.05}}
    legacy = ThresholdSettings.from_params(KeypointParams(eps2=0.02))
    assert legacy.teacher == {"eps2": 0.02} and legacy.detail == 0.0
    with pytest.raises(InvalidInput):
        ThresholdSettings(teacher={"eps99": 1.0})
    with pytest.raises(InvalidInput):
        ThresholdSettings().set("eps5", -1.0)
    with pytest.raises(InvalidInput):
        ThresholdSettings.from_dict({"detail": "lots"})


def test_suggest_reports_progress_and_before_after_figures():
    ds = list(shape_demos(ShapeSpec("zigzag", 0.15, 2.0), 3))
    seen: list[tuple[float, str]] = []
    # start from thresholds that cut the corners in paper mode: Suggest must find better ones
    bad = auto_params(ds, -3.0)
    # no time budget: the search's logic is checked, not the machine's speed (a loaded machine cuts it short)
    r = autotune.suggest(
        ds, current=bad, generalization="paper", progress=lambda f, m: seen.append((f, m)), budget_s=math.inf
    )
    assert r.complete and not r.cancelled and r.evaluated == 10 and r.changed
    assert r.after.g_over_r < 0.5 * r.before.g_over_r
    assert r.params == r.settings.resolve(ds) and r.settings.teacher == {}
    fr = [f for f, _ in seen]
    assert fr == sorted(fr) and fr[-1] == 1.0 and seen[-1][1] == "Done"
    assert "misses it by" in tune_summary(r)


def test_suggest_runs_in_an_executor_the_caller_gives_and_cancels_at_once():
    ds = list(shape_demos(ShapeSpec("circle", 0.15, 2.0), 3))
    a = autotune.suggest(ds, budget_s=math.inf)  # every round, however loaded the machine
    same = (a.settings, a.n_clusters, pytest.approx(a.after.g_over_r))
    with ThreadPoolExecutor(2) as threads:
        b = autotune.suggest(ds, executor=threads, budget_s=math.inf)
    assert (b.settings, b.n_clusters, b.after.g_over_r) == same
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as processes:
        c = autotune.suggest(ds, executor=processes, budget_s=math.inf)  # workers get the demos once, keep them
        assert (c.settings, c.n_clusters, c.after.g_over_r) == same
        cancel = threading.Event()
        cancel.set()
        d = autotune.suggest(ds, executor=processes, cancel=cancel, current=ThresholdSettings(1.0))
    assert d.cancelled and not d.complete and d.settings == ThresholdSettings(1.0)
    autotune.shutdown()


def test_suggest_needs_two_demonstrations():
    with pytest.raises(NotEnoughData, match="at least two"):
        autotune.suggest(list(shape_demos(ShapeSpec("circle", 0.15, 2.0), 1)))


def test_preview_path_follows_the_sliders():
    ds = list(task_demos("stack-cup"))
    cache = KeypointCache()
    p = preview_path(ds, LearnSettings(params=auto_params(ds)), caches=LearningCaches(cache))
    assert p.message == "" and p.position.shape == (p.t.shape[0], 3) and p.t[1] - p.t[0] == pytest.approx(0.02)
    assert 0 < p.g_over_r < 0.6 and p.distance < 0.03
    assert [len(k) for k in p.keypoints] == [len(cache.extract(d, auto_params(ds))) for d in ds]
    # thresholds that find no key-points explain themselves instead of raising
    nothing = KeypointParams(eps5=5.0, eps7=5.0, eps4=5.0, eps12=2.0, eps14=2.0, eps11=1.5)
    none = preview_path(ds, LearnSettings(params=nothing, n_clusters=500))
    assert none.message and none.position.shape == (0, 3) and math.isnan(none.g_over_r)


def test_suggest_leaves_good_defaults_alone_and_says_so():
    from studio.words import tune_summary

    ds = list(shape_demos(ShapeSpec("circle", 0.15, 2.0), 3))
    r = autotune.suggest(ds, budget_s=math.inf)
    assert r.complete and not r.changed and r.settings == ThresholdSettings() and r.n_clusters is None
    assert r.after == r.before and r.params == auto_params(ds)
    assert tune_summary(r).startswith("Your thresholds are already good")


def _held_out(ds, params, k, mode):
    """The held-out figures the teacher sees, measured outside Suggest: path (G/R on 600-point curves) and task
    (root-mean-square distance of the grasps and releases to the left-out demo's), every demo left out."""
    from studio.core import quality
    from studio.core.pipeline import learn_path

    def learn(train):
        return learn_path(train, LearnSettings(params=params, n_clusters=k, generalization=mode))

    path = quality.held_out(ds, learn).g_over_r
    task = [
        quality.task_error(learn([d for j, d in enumerate(ds) if j != i]), quality.demo_actions(ds[i])) ** 2
        for i in range(len(ds))
    ]
    return path, math.sqrt(float(np.mean(task)))


@pytest.mark.parametrize(
    ("demos", "mode", "current"),
    [
        ("zigzag", "paper", -3.0),  # thresholds that cut the corners: Suggest changes them
        ("stack-cup", "paper", None),  # a task: the grasp and release count too
        ("pick-place", "paper", -3.0),
        ("pick-place", "paper", None),  # the path-only search chose thresholds that grasped 0.14 mm further off
        ("pick-place", "aligned-mean", None),  # the default: already good
    ],
)
def test_suggest_never_makes_a_held_out_figure_worse(demos, mode, current):
    ds = (
        list(task_demos(demos))
        if demos in ("stack-cup", "pick-place")
        else list(shape_demos(ShapeSpec(demos, 0.15, 2.0), 3))
    )
    settings = ThresholdSettings() if current is None else ThresholdSettings(current)
    r = autotune.suggest(ds, current=settings, generalization=mode, budget_s=math.inf)
    assert r.complete
    before = _held_out(ds, settings.resolve(ds), None, mode)
    after = _held_out(ds, r.params, r.n_clusters, mode)
    assert after[0] <= before[0] * (1 + 1e-9), (r.changed, before, after)
    assert after[1] <= before[1] + autotune.TASK_TIE_M, (r.changed, before, after)
    assert r.after.no_worse(r.before)
    if r.changed:
        assert r.after.gains(r.before, autotune.OWN_MARGIN if current is not None else autotune.MARGIN)
    if current == -3.0 and demos == "zigzag":
        assert r.changed and after[0] < 0.8 * before[0]


def test_a_candidate_wins_only_when_no_held_out_figure_is_worse():
    base = autotune.Score(g_over_r=1.0, distance=0.01, keypoints=20, k=20, task=0.006)
    better_path_worse_task = autotune.Score(0.7, 0.008, 20, 20, task=0.008)
    assert not better_path_worse_task.no_worse(base)
    better_task = autotune.Score(1.0, 0.01, 20, 20, task=0.004)
    assert better_task.no_worse(base) and better_task.gains(base, autotune.MARGIN)
    tiny = autotune.Score(1.0, 0.01, 20, 20, task=0.0058)  # 0.2 mm: within a demonstration's noise
    assert tiny.no_worse(base) and not tiny.gains(base, autotune.MARGIN) and tiny.near(base)
    assert not autotune.Score(0.9, 0.01, 20, 20, task=0.006).near(base)


def test_suggest_ends_early_when_the_thresholds_change_nothing_the_teacher_sees():
    ds = list(shape_demos(ShapeSpec("circle", 0.15, 2.0), 3))
    seen: list[tuple[float, str]] = []
    r = autotune.suggest(ds, progress=lambda f, m: seen.append((f, m)), budget_s=math.inf)
    # "before" is the default thresholds, scored once; every coarse Detail near it: no refining, no other k
    assert r.complete and not r.changed and r.evaluated == len(autotune.COARSE_DETAIL)
    assert seen[-1] == (1.0, "Done")


def test_my_own_values_give_way_to_automatic_ones_that_do_exactly_as_well():
    ds = list(task_demos("stack-cup"))
    mine = ThresholdSettings().set("eps5", 0.30)  # far too long: a few key-points, the same learned path
    r = autotune.suggest(ds, current=mine, budget_s=math.inf)
    assert r.changed and r.settings.teacher == {} and r.after.same(r.before)
    assert tune_summary(r).startswith("Automatic thresholds, which follow your demonstrations, do exactly as well")
    assert "misses it by" in tune_summary(r) and "either way" in tune_summary(r)
