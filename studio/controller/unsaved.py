"""Takes the disk could not take when they were stopped: each is tried again every few seconds and saved into its
session once there is space, and told; what is still in memory when the studio stops goes to a spill folder and is
added when its session next opens (docs/decisions/090)."""

from __future__ import annotations

import logging
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.core.errors import StorageError, StudioError
from studio.core.types import Recording
from studio.recorder import Recorder
from studio.world import WorldEvent

log = logging.getLogger(__name__)

#: Seconds between two tries to save a take the disk did not take.
RETRY_S = 2.0


@dataclass
class _Take:
    recorder: Recorder
    folder: Path  # the session folder it was recorded into
    recording: Recording
    events: Sequence[WorldEvent]


def take_length(recording: Recording) -> str:
    """A take's length in words: "demo 3" (8.0 s, 8,012 samples)."""
    return f'"{recording.name}" ({recording.duration:.1f} s, {len(recording):,} samples)'


class UnsavedTakes:
    """The takes that wait for disk space (see the module); ``ctl.unsaved``."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self._takes: list[_Take] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def keep(self, recorder: Recorder, folder: Path, recording: Recording, events: Sequence[WorldEvent]) -> None:
        """Keep trying to save a stopped take its session refused for want of space."""
        with self._lock:
            self._takes.append(_Take(recorder, folder, recording, tuple(events)))
            if self._thread is None or not self._thread.is_alive():
                self._stop.clear()
                self._thread = threading.Thread(target=self._loop, name="studio-unsaved", daemon=True)
                self._thread.start()

    def waiting(self) -> list[str]:
        """Each take still waiting for space, in words."""
        with self._lock:
            return [take_length(t.recording) for t in self._takes]

    def _loop(self) -> None:
        while not self._stop.wait(RETRY_S):
            self.retry()
            with self._lock:
                if not self._takes:
                    self._thread = None
                    return

    def retry(self) -> None:
        """Try each take once: its rows to its file, then the take into its session if that is open (else its file
        waits, unlocked, for the session's next open)."""
        with self._lock:
            takes = list(self._takes)
        for take in takes:
            if not take.recorder.save_pending():
                continue  # the disk still takes no rows: the rest waits in memory
            with self.ctx.lock:
                session = self.ctx.session
                if session.path.resolve() != take.folder.resolve():
                    take.recorder.release()  # whole in its file: added when its session opens
                    self._drop(take)
                    continue
                try:
                    session.add_recording(take.recording, events=take.events)
                except StorageError:
                    continue  # no space for the session's copy yet
                except StudioError as exc:
                    log.warning("a take waiting for space was refused by its session: %s", exc)
                    take.recorder.release()  # left in its file: the next open sets it aside by name, never lost
                    self._drop(take)
                    continue
            take.recorder.discard()
            self._drop(take)
            self.ctx.emit(Topic.DEMOS)
            self.ctx.notify(
                "Demonstration saved",
                f"{take_length(take.recording)} was saved: the disk had space again.",
                kind="success",
            )

    def _drop(self, take: _Take) -> None:
        with self._lock:
            if take in self._takes:
                self._takes.remove(take)

    def close(self) -> None:
        """The studio stops: a last try; rows still only in memory go to a spill folder (logged either way)."""
        self._stop.set()
        self.retry()
        with self._lock:
            takes, self._takes = list(self._takes), []
        for take in takes:
            where = take.recorder.spill() or take.recorder.release()
            if where is not None:
                log.warning(
                    "%s waits for disk space in %s; it is added when its session next opens",
                    take_length(take.recording),
                    where,
                )
            else:
                log.error(
                    "%s could not be written anywhere (the disk is full); what its file holds is recovered when "
                    "its session next opens",
                    take_length(take.recording),
                )


__all__ = ["RETRY_S", "UnsavedTakes", "take_length"]
