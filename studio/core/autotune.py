"""Search the key-point thresholds and k for the best held-out fidelity (GUI-free): :func:`suggest`.

Searched: ``detail`` (:mod:`studio.core.thresholds`) and k (a factor on the paper's default). Scored held out
(learned without one demo, measured on it, at most :data:`MAX_FOLDS` folds) on what the teacher sees: the path
(G/R) and the task (where the gripper closes and opens). A candidate wins only when no figure is worse and one is
better; the current thresholds stay (``changed`` False) otherwise. Candidates run here or in the caller's
``executor`` (docs/decisions/030, 062)."""

from __future__ import annotations

import hashlib
import math
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from dataclasses import dataclass

import numpy as np

from studio.core.errors import NotEnoughData, StudioError
from studio.core.thresholds import DemoStats, ThresholdSettings, auto_params
from studio.core.types import Demo, KeypointParams

#: At most this many demos are left out in turn.
MAX_FOLDS = 3
#: Coarse ``detail`` values tried first.
COARSE_DETAIL = (-2.0, -1.0, 0.0, 1.0, 2.0)
#: k factors tried at the best ``detail``.
K_FACTORS = (0.75, 1.3)
#: Relative improvement needed to prefer more detail or a different k, or to leave the default thresholds.
MARGIN = 0.02
#: Relative improvement needed to leave the teacher's own thresholds (beyond the held-out measure's resolution).
OWN_MARGIN = 0.005
#: No round of the search starts after this many seconds.
BUDGET_S = 2.0
#: A held-out task figure must also improve by this much, m (less is within a demonstration's own noise).
TASK_FLOOR_M = 0.0005
#: Held-out task figures this close are the same, m (the precision the poses are pinned to).
TASK_TIE_M = 0.0001


@dataclass(frozen=True)
class Candidate:
    """One point of the search: ``detail``, a factor on the default k (1 = the paper's k), or fixed values.

    ``fixed`` holds thresholds to use as they are (the teacher's current ones for "before"); ``k`` a fixed k.
    """

    detail: float
    k_factor: float = 1.0
    fixed: tuple[tuple[str, float], ...] = ()
    k: int | None = None


@dataclass(frozen=True)
class Score:
    """Held-out figures of one candidate.

    Attributes:
        g_over_r: held-out G/R (lower is better; inf when learning failed).
        distance: root-mean-square distance to the left-out demos, m.
        keypoints: mean key-points per demo with these thresholds.
        k: clusters used (mean over folds).
        task: root-mean-square distance from where the learned path closes and opens the gripper to where the
            left-out demos did, m (0 without gripper actions; inf when the path closes and opens it differently).
    """

    g_over_r: float
    distance: float
    keypoints: float
    k: float
    task: float = 0.0

    def no_worse(self, other: Score) -> bool:
        """Neither held-out figure is worse than ``other``'s (G/R by no more than the measure's resolution,
        :data:`OWN_MARGIN`; the task by no more than :data:`TASK_TIE_M`)."""
        path = self.g_over_r <= other.g_over_r * (1.0 + OWN_MARGIN) or self.g_over_r == other.g_over_r
        return path and (self.task <= other.task + TASK_TIE_M or self.task == other.task)

    def gains(self, other: Score, margin: float) -> bool:
        """At least one held-out figure is better than ``other``'s by ``margin`` (relative; the task also by
        :data:`TASK_FLOOR_M`)."""
        path = self.g_over_r < other.g_over_r * (1.0 - margin)
        task = self.task < other.task * (1.0 - margin) and other.task - self.task > TASK_FLOOR_M
        return path or task

    def same(self, other: Score) -> bool:
        """The same figures to five digits (the same path and grasps)."""
        return math.isclose(self.g_over_r, other.g_over_r, rel_tol=1e-5) and (
            self.task == other.task or math.isclose(self.task, other.task, rel_tol=1e-5)
        )

    def near(self, other: Score) -> bool:
        """Both figures within :data:`MARGIN` of ``other``'s (the task also within :data:`TASK_FLOOR_M`): the
        thresholds changed nothing the teacher would see."""
        if not (math.isfinite(self.g_over_r) and math.isfinite(other.g_over_r)):
            return False
        path = abs(self.g_over_r - other.g_over_r) <= MARGIN * other.g_over_r
        if math.isinf(self.task) or math.isinf(other.task):
            return path and self.task == other.task
        return path and abs(self.task - other.task) <= max(MARGIN * other.task, TASK_FLOOR_M)


@dataclass(frozen=True)
class TuneResult:
    """What the search found.

    Attributes:
        settings: the suggested :class:`ThresholdSettings` (``detail``; every threshold automatic).
        params: the same as the fourteen values in real units for these demos.
        n_clusters: the suggested k, or None for the paper's default (mean key-points per demo).
        before, after: held-out figures of the current settings and of the suggestion.
        evaluated: candidates scored.
        seconds: wall time.
        cancelled: the search was cancelled (``settings`` is then the best found so far, or the current one).
        complete: every planned candidate was scored (False when cancelled or out of time).
        changed: the suggestion differs from the current thresholds (False: they are already good — nothing
            did better by :data:`MARGIN` than the defaults, or by :data:`OWN_MARGIN` than the teacher's own
            values (automatic ones with the same figures to five digits replace those), without a held-out
            figure worse).
    """

    settings: ThresholdSettings
    params: KeypointParams
    n_clusters: int | None
    before: Score
    after: Score
    evaluated: int
    seconds: float
    cancelled: bool
    complete: bool
    changed: bool = True


# -- the work (in the calling thread, or a task of the caller's executor) -----------------------------------------

#: The last search's demos and derived data in this process, by search token (a worker keeps them between its
#: tasks; a second search on the same demos reuses them).
_STATE: dict[str, tuple] = {}


def _state(token: str, demos: list[Demo], generalization: str) -> tuple:
    from studio.core import quality
    from studio.core.caches import LearningCaches

    st = _STATE.get(token)
    if st is None:
        _STATE.clear()  # one search at a time per worker: drop the previous search's demos
        curves = [quality.curve(d, 300) for d in demos]
        r = quality.spread(curves)[0]
        actions = [quality.demo_actions(d) for d in demos]
        st = _STATE[token] = (
            demos,
            LearningCaches(),
            curves,
            r,
            DemoStats.of(demos),
            generalization,
            actions,
        )
    return st


def _params(c: Candidate, stats: DemoStats) -> KeypointParams:
    if c.fixed:
        return KeypointParams(**dict(c.fixed))
    return auto_params(stats, c.detail)


def _score(c: Candidate, st: tuple, folds: Sequence[int]) -> Score:
    from studio.core import quality
    from studio.core.clustering import default_n_clusters
    from studio.core.learn_settings import LearnSettings
    from studio.core.pipeline import learn_path

    demos, caches, curves, r, stats, generalization, actions = st
    params = _params(c, stats)
    kps_all = [caches.keypoints.extract(d, params) for d in demos]
    msd, ks, task = [], [], []
    for i in folds:
        train = [d for j, d in enumerate(demos) if j != i]
        kps = [k for j, k in enumerate(kps_all) if j != i]
        if c.k is not None:
            k = min(c.k, sum(len(x) for x in kps))
        else:
            k = max(2, round(c.k_factor * default_n_clusters(kps)))
        try:
            settings = LearnSettings(params=params, n_clusters=k, generalization=generalization)
            tr = learn_path(train, settings, caches=caches)
        except StudioError:
            return Score(math.inf, math.inf, float(np.mean([len(x) for x in kps_all])), float(k), math.inf)
        msd.append(quality.ndtw(quality.curve(tr, 300), curves[i]))
        task.append(quality.task_error(tr, actions[i]) ** 2)
        ks.append(k)
    g = float(np.mean(msd))
    return Score(
        g / r if r > 0 else math.inf,
        math.sqrt(g),
        float(np.mean([len(x) for x in kps_all])),
        float(np.mean(ks)),
        math.sqrt(float(np.mean(task))),
    )


def evaluate(
    token: str, demos: list[Demo] | None, generalization: str, folds: list[int], cands: list[Candidate]
) -> list[Score] | None:
    """One task: score ``cands`` for the search ``token`` (picklable, for an executor of processes). ``demos`` may
    be None when this process already holds the search's data; then None is returned if it does not."""
    if demos is None and token not in _STATE:
        return None
    st = _state(token, demos or [], generalization)
    return [_score(c, st, folds) for c in cands]


def warm_up() -> None:
    """Load the learning pipeline (a worker process's first task, ahead of the first search)."""
    from studio.core import pipeline, quality  # noqa: F401


def shutdown() -> None:
    """Forget the last search's demos and derived data in this process."""
    _STATE.clear()


# -- the search --------------------------------------------------------------------------------------------------


def _fingerprint(demos: Sequence[Demo]) -> str:
    """A cheap content key of the demos: a worker that already holds them (a second search on the same demos)
    keeps their derived series and DTW maps."""
    h = hashlib.blake2b(digest_size=12)
    for d in demos:
        h.update(np.asarray([len(d), d.t[0], d.t[-1]], dtype=np.float64).tobytes())
        h.update(np.ascontiguousarray(d.position[:: max(1, len(d) // 512)]).tobytes())
        h.update(d.name.encode())
    return h.hexdigest()


def _folds(n: int) -> list[int]:
    if n <= MAX_FOLDS:
        return list(range(n))
    return sorted({round(x) for x in np.linspace(0, n - 1, MAX_FOLDS)})


def _better(a: Score, ca: Candidate, b: Score, cb: Candidate) -> bool:
    """Is (a, ca) better than the incumbent (b, cb)? No held-out figure worse and one better; more detail or
    another k must be better by MARGIN."""
    if not math.isfinite(b.g_over_r):
        return math.isfinite(a.g_over_r)
    simpler = ca.detail < cb.detail or (ca.detail == cb.detail and ca.k_factor == 1.0 and cb.k_factor != 1.0)
    return a.no_worse(b) and a.gains(b, 0.0 if simpler else MARGIN)


class _Search:
    """One search's scoring: "before" here (it derives the demos' series and DTW maps), the other candidates here
    or as tasks of ``executor``; counts progress, honours cancel."""

    def __init__(
        self,
        demos: list[Demo],
        generalization: str,
        executor: Executor | None,
        progress: Callable[[float, str], None] | None,
        cancel: threading.Event | None,
    ) -> None:
        self.demos = demos
        self.generalization = generalization
        self.folds = _folds(len(demos))
        self.token = f"{_fingerprint(demos)}-{generalization}"
        self.st = _state(self.token, demos, generalization)
        self.executor = executor
        self.progress = progress
        self.cancel = cancel
        self.done = 0
        self.planned = 1 + len(COARSE_DETAIL) + 2 + len(K_FACTORS)
        self.cancelled = False
        self.memo: dict[tuple, Score] = {}
        self.evaluated = 0

    def report(self, msg: str) -> None:
        if self.progress is not None:
            self.progress(min(1.0, self.done / self.planned), msg)

    def stopped(self) -> bool:
        if self.cancel is not None and self.cancel.is_set():
            self.cancelled = True
        return self.cancelled

    def first(self, before_c: Candidate) -> Score | None:
        """Score "before" in this thread (it derives the demos' series and DTW maps)."""
        self.report("Measuring the current thresholds")
        if self.stopped():
            return None
        score = _score(before_c, self.st, self.folds)
        self.memo[self.key(before_c)] = score
        self.done += 1
        self.evaluated += 1
        return score

    def key(self, c: Candidate) -> tuple:
        """What decides a candidate's figures: its thresholds in real units and its k (or k factor)."""
        k = ("k", c.k) if c.k is not None else ("factor", c.k_factor)
        return (tuple(_params(c, self.st[4]).as_dict().items()), k)

    def run(self, cands: list[Candidate], msg: str) -> list[Score] | None:
        """Score candidates, each set of thresholds once per search (:meth:`key`); None if cancelled."""
        keys = [self.key(c) for c in cands]
        todo: dict[tuple, Candidate] = {}
        for c, k in zip(cands, keys, strict=True):
            if k not in self.memo and k not in todo:
                todo[k] = c
        self.done += len(cands) - len(todo)
        scores = self._score_all(list(todo.values()), msg)
        if scores is None:
            return None
        self.memo.update(zip(todo, scores, strict=True))
        self.evaluated += len(scores)
        return [self.memo[k] for k in keys]

    def _score_all(self, cands: list[Candidate], msg: str) -> list[Score] | None:
        """Score candidates (one per task of the executor); None if cancelled."""
        if self.executor is None:
            out = []
            for c in cands:
                if self.stopped():
                    return None
                out.append(_score(c, self.st, self.folds))
                self.done += 1
                self.report(msg)
            return out
        futs = {self._submit(c): i for i, c in enumerate(cands)}
        res: list[Score | None] = [None] * len(cands)
        pending: set[Future] = set(futs)
        while pending:
            done, pending = wait(pending, timeout=0.05, return_when=FIRST_COMPLETED)
            for f in done:
                scores = f.result()
                if scores is None:  # a worker without the search's data: send it the demos
                    again = self._submit(cands[futs[f]], with_demos=True)
                    futs[again] = futs[f]
                    pending.add(again)
                    continue
                res[futs[f]] = scores[0]
                self.done += 1
                self.report(msg)
            if self.stopped():
                for f in pending:
                    f.cancel()
                return None
        return [r for r in res if r is not None]

    def _submit(self, c: Candidate, *, with_demos: bool = False) -> Future[list[Score] | None]:
        assert self.executor is not None
        demos = self.demos if with_demos else None
        return self.executor.submit(evaluate, self.token, demos, self.generalization, self.folds, [c])


def _before(current: ThresholdSettings | KeypointParams | None, stats: DemoStats, k: int | None) -> Candidate:
    """The candidate for the thresholds and k in use (scored as "before")."""
    if isinstance(current, KeypointParams):
        return Candidate(0.0, fixed=tuple(current.as_dict().items()), k=k)
    settings = current or ThresholdSettings()
    return Candidate(settings.detail, fixed=tuple(settings.resolve(stats).as_dict().items()), k=k)


def _challenge(cands: list[Candidate], scores: list[Score], best_c: Candidate, best: Score) -> tuple[Candidate, Score]:
    """The incumbent after each candidate challenged it in turn (:func:`_better`)."""
    for c, sc in zip(cands, scores, strict=True):
        if _better(sc, c, best, best_c):
            best_c, best = c, sc
    return best_c, best


def _rounds(search: _Search, before_c: Candidate, t0: float, budget_s: float) -> tuple[Candidate, Score, Score, bool]:
    """The search itself: (best candidate, its score, "before", every round done).

    Round 1: "before" and the coarse ``detail`` values (0 is the incumbent the others challenge); round 2:
    ±0.5 around the best; round 3: other k at the best. When every coarse value is near the best
    (:meth:`Score.near`), the thresholds change nothing the teacher sees and the search ends there. A round
    starts only within the time budget.
    """
    nothing = Score(math.inf, math.inf, math.nan, math.nan, math.inf)
    before0 = search.first(before_c)
    coarse_c = [Candidate(d) for d in COARSE_DETAIL]
    coarse = None if before0 is None else search.run(coarse_c, "Trying fewer and more key-points")
    if before0 is None or coarse is None:
        return before_c, nothing, nothing, False
    best_c, best = _challenge(coarse_c, coarse, Candidate(0.0), coarse[COARSE_DETAIL.index(0.0)])
    if all(sc.near(best) for sc in coarse):
        search.done = search.planned
        return best_c, best, before0, True
    for step in ("fine", "k"):
        if time.perf_counter() - t0 >= budget_s:
            return best_c, best, before0, False
        if step == "fine":
            cands, msg = [Candidate(best_c.detail - 0.5), Candidate(best_c.detail + 0.5)], "Refining"
        else:
            cands, msg = [Candidate(best_c.detail, f) for f in K_FACTORS], "Trying other numbers of clusters"
        scores = search.run(cands, msg)
        if scores is None:
            return best_c, best, before0, False
        best_c, best = _challenge(cands, scores, best_c, best)
    return best_c, best, before0, True


def suggest(
    demos: Sequence[Demo],
    *,
    current: ThresholdSettings | KeypointParams | None = None,
    n_clusters: int | None = None,
    generalization: str | None = None,
    progress: Callable[[float, str], None] | None = None,
    cancel: threading.Event | None = None,
    executor: Executor | None = None,
    budget_s: float = BUDGET_S,
) -> TuneResult:
    """Search ``detail`` and k for the best held-out fidelity (module docstring; docs/decisions/011).

    Args:
        demos: the shown demonstrations (at least two).
        current: the thresholds in use (settings or plain values), scored as "before"; default automatic.
        n_clusters: the k in use (None = the paper's default).
        generalization: the mode to tune for (default: the pipeline's default).
        progress: called with (fraction 0…1, plain-words step) as candidates finish, from this thread.
        cancel: set it to stop; :func:`suggest` then returns early with ``cancelled=True``.
        executor: runs the candidates after "before" (threads, or processes the caller started); None: here.
        budget_s: start no round after this many seconds (the result says ``complete=False``).

    Raises:
        NotEnoughData: fewer than two demonstrations.
    """
    from studio.core.pipeline import _validate
    from studio.core.types import DEFAULT_GENERALIZATION

    t0 = time.perf_counter()
    demos = _validate(demos)
    if len(demos) < 2:
        raise NotEnoughData(
            "Searching for thresholds compares the skill with a demonstration it did not learn from: record at least "
            "two."
        )
    generalization = generalization or DEFAULT_GENERALIZATION
    stats = DemoStats.of(demos)
    before_c = _before(current, stats, n_clusters)
    search = _Search(demos, generalization, executor, progress, cancel)
    best_c, best, before, complete = _rounds(search, before_c, t0, budget_s)
    evaluated = search.evaluated
    defaults = n_clusters is None and (current is None or current == ThresholdSettings())
    # never a held-out figure worse; the defaults stay unless one is better by MARGIN, the teacher's own values
    # unless one is better by OWN_MARGIN or automatic thresholds give the same figures (they follow the demos)
    gains = best.gains(before, MARGIN) if defaults else best.gains(before, OWN_MARGIN) or best.same(before)
    better = best.no_worse(before) and gains
    keep = math.isfinite(before.g_over_r) and not better
    if search.cancelled or keep:  # keep what the teacher has
        settings = current if isinstance(current, ThresholdSettings) else ThresholdSettings()
        params, k = _params(before_c, stats), n_clusters
        if keep and not search.cancelled:
            best = before
            if progress is not None:
                progress(1.0, "Done")
    else:
        settings = ThresholdSettings(detail=best_c.detail)
        params = auto_params(stats, best_c.detail)
        k = _suggested_k(demos, params, best_c.k_factor)
        if progress is not None:
            progress(1.0, "Done")
    return TuneResult(
        settings=settings,
        params=params,
        n_clusters=k,
        before=before,
        after=best,
        evaluated=evaluated,
        seconds=time.perf_counter() - t0,
        cancelled=search.cancelled,
        complete=complete and not search.cancelled,
        changed=not keep and not search.cancelled,
    )


def _suggested_k(demos: list[Demo], params: KeypointParams, k_factor: float) -> int | None:
    """None for the paper's default k, else the default times ``k_factor``."""
    if k_factor == 1.0:
        return None
    from studio.core.clustering import default_n_clusters
    from studio.core.keypoints import KeypointCache

    kc = KeypointCache()
    return max(2, round(k_factor * default_n_clusters([kc.extract(d, params) for d in demos])))


__all__ = [
    "BUDGET_S",
    "COARSE_DETAIL",
    "K_FACTORS",
    "Candidate",
    "Score",
    "TuneResult",
    "evaluate",
    "shutdown",
    "suggest",
    "warm_up",
]
