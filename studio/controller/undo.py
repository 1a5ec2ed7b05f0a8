"""Undo for a thrown-away take or a deleted demonstration: the last one is kept in memory for a while
(:data:`KEEP_S`) and brought back into the session it came from with its objects, instead of asking first."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.core.errors import StudioError
from studio.core.types import Recording
from studio.storage import Session
from studio.world import WorldEvent

#: Seconds a discarded take or a deleted demonstration can be brought back.
KEEP_S = 600.0


@dataclass(frozen=True)
class Kept:
    """What Undo brings back: a take or demonstration, its object events, whether it was hidden, the words."""

    session: Session
    recording: Recording
    events: tuple[WorldEvent, ...]
    hidden: bool
    what: str
    at: float


class Undo:
    """One thing at a time can be undone (the newest discard or delete), within :data:`KEEP_S` seconds and as
    long as its session is open."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self._kept: Kept | None = None
        ctx.events.on(Topic.SESSION, self.forget)

    def keep(
        self, recording: Recording, events: Sequence[WorldEvent] = (), *, hidden: bool = False, what: str = ""
    ) -> None:
        """Keep ``recording`` (just thrown away from the open session) so that :meth:`undo` can bring it back."""
        words = what or f'"{recording.name}" ({recording.duration:.0f} s)'
        with self.ctx.lock:
            self._kept = Kept(self.ctx.session, recording, tuple(events), hidden, words, time.monotonic())
        self.ctx.emit(Topic.UNDO)

    @property
    def what(self) -> str:
        """What Undo would bring back, in words ("" when nothing)."""
        k = self._kept
        if k is None or k.session is not self.ctx.session or time.monotonic() - k.at > KEEP_S:
            return ""
        return k.what

    def undo(self) -> None:
        """Put the kept demonstration back into the session, as its last demonstration."""
        with self.ctx.lock:
            k, self._kept = self._kept, None
            if k is None or k.session is not self.ctx.session or time.monotonic() - k.at > KEEP_S:
                raise StudioError("There is nothing to bring back any more.")
            i = k.session.add_recording(k.recording, name=k.recording.name, events=k.events)
            if k.hidden:
                k.session.set_demo_hidden(i, True)
        self.ctx.emit(Topic.UNDO)
        self.ctx.emit(Topic.DEMOS)
        self.ctx.notify("Brought back", f"{k.what} is a demonstration again.", kind="success")

    def forget(self) -> None:
        with self.ctx.lock:
            had, self._kept = self._kept is not None, None
        if had:
            self.ctx.emit(Topic.UNDO)
