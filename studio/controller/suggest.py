"""Suggest thresholds: search Detail and k for the best held-out fidelity on the work thread, with progress and
cancel, applied as one change the teacher can undo; the before/after figures in plain words."""

from __future__ import annotations

import threading
import time
from concurrent.futures import Future
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.controller.learning import ShownDemos
from studio.core.errors import NotEnoughData, StudioError
from studio.core.thresholds import ThresholdSettings
from studio.core.types import Arm
from studio.words import tune_summary

if TYPE_CHECKING:
    from studio.core.autotune import TuneResult

#: Progress is told to the views at most this often (s).
PROGRESS_EVERY_S = 0.1


@dataclass(frozen=True)
class SuggestState:
    """What the Suggest controls show.

    Attributes:
        running: a search is under way; fraction (0…1) and step say how far.
        summary: the last outcome in plain words (before/after figures, or stopped, or undone).
        can_undo: Undo would put back the settings from before the last applied suggestion.
        seconds: how long the last search took.
        result: the last finished search's outcome (settings, k, figures; ``changed`` says if it was applied).
        replaced: the thresholds the teacher had set that the applied suggestion made automatic again (names).
    """

    running: bool = False
    fraction: float = 0.0
    step: str = ""
    summary: str = ""
    can_undo: bool = False
    seconds: float = 0.0
    result: TuneResult | None = None
    replaced: tuple[str, ...] = ()


class Thresholds(Protocol):
    """The threshold settings Suggest starts from and changes (:class:`~studio.controller.learning.KeypointTuning`)."""

    @property
    def k(self) -> int | None: ...
    def settings(self) -> ThresholdSettings: ...
    def shown_arm(self) -> Arm | None: ...
    def restore(self, settings: ThresholdSettings, k: int | None) -> None: ...


class Suggesting:
    """Runs :func:`studio.core.autotune.suggest` on the shown demonstrations of the arm the sliders show."""

    def __init__(self, ctx: Context, demos: ShownDemos, tuning: Thresholds) -> None:
        self.ctx = ctx
        self.demos = demos
        self.tuning = tuning
        self.state = SuggestState()
        #: Where the search runs: None, the work thread and the helper threads (``ctx.helpers``); 1, the work
        #: thread alone.
        self.workers: int | None = None
        self._cancel = threading.Event()
        self._undo: tuple[ThresholdSettings, int | None] | None = None
        self._told = 0.0
        ctx.events.on(Topic.SESSION, self._forget)

    def _set(self, **changes: object) -> None:
        with self.ctx.lock:
            self.state = replace(self.state, **changes)  # type: ignore[arg-type]
        self.ctx.emit(Topic.SUGGEST)

    def start(self, arm: Arm | None = None) -> Future[None]:
        """Start a search on the demonstrations of ``arm`` (default: the arm the sliders show) on the work
        thread; the result is applied as one change when it completes."""
        from studio.core import autotune

        with self.ctx.lock:
            if self.state.running:
                raise StudioError("Suggest is already running.")
            arm = arm or self.tuning.shown_arm()
            demos = [d for _, d in self.demos.for_arm(arm)] if arm else []
            if len(demos) < 2:
                raise NotEnoughData(
                    "Suggest learns the skill without each demonstration in turn and checks it on the one left "
                    "out: record at least two demonstrations (or show hidden ones)."
                )
            settings, k, session = self.tuning.settings(), self.tuning.k, self.ctx.session
            mode = session.generalization
            self._cancel.clear()
        self._set(running=True, fraction=0.0, step="Starting", summary="", result=None, replaced=())

        def progress(fraction: float, step: str) -> None:
            now = time.monotonic()
            if now - self._told >= PROGRESS_EVERY_S or fraction >= 1.0:
                self._told = now
                self._set(fraction=float(fraction), step=step)

        def job() -> None:
            executor = self.ctx.helpers if self.workers != 1 else None
            res = autotune.suggest(
                demos,
                current=settings,
                n_clusters=k,
                generalization=mode,
                progress=progress,
                cancel=self._cancel,
                executor=executor,
            )
            if res.cancelled:
                self._set(running=False, summary="Suggest was stopped: your thresholds are unchanged.")
                return
            if session is not self.ctx.session:
                self._set(running=False, summary="")
                return
            if not res.changed:
                self._set(
                    running=False, fraction=1.0, step="Done", summary=tune_summary(res), seconds=res.seconds, result=res
                )
                return
            with self.ctx.lock:
                self._undo = (settings, k)
            self.tuning.restore(res.settings, res.n_clusters)
            words = "" if arm is None or len(self.ctx.arms) < 2 else f" (for the {arm} arm's demonstrations)"
            self._set(
                running=False,
                fraction=1.0,
                step="Done",
                summary=f"Suggested{words}: {_detail_words(res.settings.detail)}. {tune_summary(res)}",
                can_undo=True,
                seconds=res.seconds,
                result=res,
                replaced=tuple(n for n in settings.teacher if res.settings.teacher.get(n) != settings.teacher[n]),
            )

        def failed(f: Future[None]) -> None:
            if self.state.running:  # the job raised: the context told the teacher
                self._set(running=False, summary="")

        fut = self.ctx.submit(job, title="Suggest did not work")
        fut.add_done_callback(failed)
        return fut

    def cancel(self) -> None:
        """Stop a running search (nothing is changed)."""
        self._cancel.set()

    def undo(self) -> None:
        """Put back the settings from before the last applied suggestion."""
        with self.ctx.lock:
            undo, self._undo = self._undo, None
        if undo is None:
            raise StudioError("There is no suggestion to undo.")
        self.tuning.restore(*undo)
        self._set(can_undo=False, replaced=(), summary="Undone: your thresholds are back as they were before Suggest.")

    def _forget(self) -> None:
        self._cancel.set()
        with self.ctx.lock:
            self._undo = None
        self._set(can_undo=False, summary="")


def _detail_words(detail: float) -> str:
    if abs(detail) < 0.05:
        return "automatic thresholds at the usual detail"
    more = "more" if detail > 0 else "fewer"
    return f"automatic thresholds with {more} key-points (Detail {detail:+.1f})"
