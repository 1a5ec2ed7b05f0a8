"""The live learned path: while the thresholds move, the path the robot would learn is recomputed after each
new key-point view (on the key-point thread, skipped when a newer request already waits) and drawn thin and
dashed with its fidelity figure."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.controller.learning import Follower, KeypointView, ShownDemos
from studio.core.learn_settings import LearnSettings
from studio.core.types import Arm, Demo, SkillRoute


@dataclass(frozen=True)
class LivePath:
    """The path learned with one view's thresholds for one arm.

    Attributes:
        arm: the arm; version: the key-point view it belongs to.
        position: (M, 3) metres (empty when no path could be made).
        distance: root-mean-square distance to the shown demonstrations, m.
        g_over_r: G/R against them (≤ 0.6 is close; NaN with one demonstration).
        k: the number of clusters used.
        message: why there is no path, in plain words ("" when there is one).
        routes, route: the ways the demonstrations go when more than one, and the one the path follows.
    """

    arm: Arm
    version: int
    position: np.ndarray
    distance: float
    g_over_r: float
    k: int
    message: str = ""
    routes: tuple[SkillRoute, ...] = ()
    route: int = 0

    @property
    def words(self) -> str:
        """The fidelity figure in plain words."""
        from studio.words import length_words, routes_words

        if self.message:
            return self.message
        if self.routes:
            near = (
                f", within {length_words(self.distance)} of those demonstrations on average"
                if math.isfinite(self.distance)
                else ""
            )
            return f"{routes_words(self.routes, self.route)}: the learned path would follow that way{near}."
        if not math.isfinite(self.distance):
            return "The learned path would follow your demonstration."
        return f"The learned path would stay within {length_words(self.distance)} of your demonstrations on average."


class KeypointSource(Protocol):
    """The key-point view and its settings (:class:`~studio.controller.learning.KeypointTuning`)."""

    view: KeypointView | None

    @property
    def k(self) -> int | None: ...
    def request(self) -> None: ...
    def add_follower(self, follower: Follower) -> None: ...
    def in_frames(self, arm: Arm, demos: Sequence[tuple[int, Demo]]) -> list[Demo] | None: ...


class LivePaths:
    """Follows the key-point view (a :data:`~studio.controller.learning.Follower`) and keeps one live path per
    taught arm in :attr:`paths`; emits :attr:`Topic.LIVE_PATH` when they are new.

    ``wanted()`` says whether anybody looks at them (the Key-points step): otherwise nothing is computed; when
    the view changes (:attr:`Topic.VIEW`) and they are wanted, they are brought up to date.
    """

    def __init__(
        self,
        ctx: Context,
        demos: ShownDemos,
        tuning: KeypointSource,
        wanted: Callable[[], bool],
        route: Callable[[Arm], int | None] = lambda arm: None,
    ) -> None:
        self.ctx = ctx
        self.demos = demos
        self.tuning = tuning
        self.wanted = wanted
        self.route = route  #: the way the teacher chose for an arm (None: the way most demonstrations go)
        self.paths: dict[Arm, LivePath] = {}
        self.computed_ms: float = math.nan  # how long the last set of paths took (for the bench)
        tuning.add_follower(self.follow)
        ctx.events.on(Topic.VIEW, self.refresh_if_wanted)

    def follow(self, view: KeypointView, stale: Callable[[], bool]) -> None:
        """Compute the live path of every arm of ``view`` unless a newer view is coming; :attr:`Topic.LIVE_PATH`
        is emitted for every view it does not skip, also when no path could be made (the key-points panel
        draws the view's markers with it)."""
        import time

        from studio.core.pipeline import preview_path

        if not self.wanted():
            return
        t0 = time.perf_counter()
        mode = self.ctx.session.generalization
        out: dict[Arm, LivePath] = {}
        try:
            for arm, params in view.params.items():
                shown = self.demos.for_arm(arm)
                moved = self.tuning.in_frames(arm, shown) if arm in view.in_frames else None
                demos = moved if moved is not None else [d for _, d in shown]  # as the key-points are drawn
                idx = view.indices.get(arm)
                if stale():
                    return
                if not demos or idx is None or len(idx) != len(demos):
                    continue
                settings = LearnSettings(
                    params=params,
                    n_clusters=view.k.get(arm) if self.tuning.k is not None else None,
                    generalization=mode,
                    route=self.route(arm),
                )
                pp = preview_path(demos, settings, caches=self.ctx.caches, keypoints=idx)
                out[arm] = LivePath(
                    arm,
                    view.version,
                    pp.position,
                    pp.distance,
                    pp.g_over_r,
                    pp.n_clusters,
                    pp.message,
                    pp.routes,
                    pp.route,
                )
        except Exception:
            out = {}
            raise
        finally:
            if not stale():
                self.paths = out
                self.computed_ms = 1e3 * (time.perf_counter() - t0)
                self.ctx.emit(Topic.LIVE_PATH)

    def refresh_if_wanted(self) -> None:
        """The Key-points step opened: bring the paths up to date (a new view is computed first)."""
        view = self.tuning.view
        if self.wanted() and (
            view is None or any(p.version != view.version for p in self.paths.values()) or not self.paths
        ):
            self.tuning.request()
