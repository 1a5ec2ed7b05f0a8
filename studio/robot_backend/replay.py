"""A backend that streams a saved demonstration as if it came live from the robot (for replaying sessions).

Same interface as the simulator: :meth:`start` plays in (scaled) real time in batches, :meth:`pause`,
:meth:`seek`, and :meth:`step` for manual stepping. Joint and gripper commands are ignored: a replay is
read-only. Streamed time stamps are the recording's own, shifted so they keep increasing across loops and
seeks (a listener such as the recorder may rely on increasing time).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np

from studio.core.errors import InvalidInput, StudioError
from studio.core.types import Arm, Recording
from studio.robot_backend._clock import BatchClock
from studio.robot_backend.base import JointStateBatch, ListenerHub, RobotBackend, RobotState, StateListener

MAX_BATCH = 1000


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


class ReplayBackend(RobotBackend):
    """Streams ``recording`` sample by sample at its own time stamps.

    Args:
        recording: the demonstration to replay (at least two samples).
        speed: playback speed (1.0 = as recorded).
        loop: start over at the end instead of stopping there.
        period: wall seconds between batches.
    """

    def __init__(self, recording: Recording, *, speed: float = 1.0, loop: bool = False, period: float = 0.015) -> None:
        if len(recording) == 0:
            raise InvalidInput(f'The demonstration "{recording.name}" has no samples to replay.')
        if len(recording) < 2:
            raise InvalidInput(
                f'The demonstration "{recording.name}" has a single sample: there is no motion to replay.'
            )
        self.recording = recording
        self.loop = bool(loop)
        n = len(recording)
        self.rate_hz = float((n - 1) / recording.duration) if n > 1 and recording.duration > 0 else 1000.0
        self._dt = 1.0 / self.rate_hz
        self._lock = threading.RLock()
        self._deliver_lock = threading.RLock()
        self._hub = ListenerHub()
        self._idx = 0  # next sample to stream
        self._offset = 0.0  # streamed t = recording t + offset
        self._last_t: float | None = None
        self._cur = 0  # index of the latest streamed sample (state())
        self._clock = BatchClock(self._advance_to, period=period, time_scale=speed, name="replay")

    # -- RobotBackend -------------------------------------------------------------------------------------
    def start(self) -> None:
        """Play from the current position (idempotent)."""
        with self._lock:
            if self._clock.running:
                return
            if self._idx >= len(self.recording):
                if not self.loop:
                    return
                self._wrap()
            self._clock.start(sim_start=float(self.recording.t[self._idx]))

    play = start

    def stop(self) -> None:
        """Stop playing (the position is kept; :meth:`start` resumes)."""
        self._clock.stop()

    pause = stop

    def subscribe(self, listener: StateListener) -> Callable[[], None]:
        return self._hub.subscribe(listener)

    def command_joints(self, arm: Arm, q: np.ndarray) -> None:
        """Ignored: a replay cannot be steered."""

    def command_gripper(self, arm: Arm, width: float) -> None:
        """Ignored: a replay cannot be steered."""

    def execute(self, plan: object) -> None:
        """Refused: a replay only plays back a recording."""
        raise StudioError("A demonstration is being replayed: go back to the live robot to run the skill.")

    def emergency_stop(self) -> str:
        """Pause the replay (it moves nothing, but an emergency stop must stop what is on screen too)."""
        self.stop()
        return "halted"

    def state(self) -> RobotState:
        with self._lock:
            i = self._cur
            rec = self.recording
            return RobotState(
                t=float(rec.t[i] + self._offset),
                q=_ro(rec.q[i].copy()),
                gripper=_ro(rec.gripper[i].copy()),
                moving=self._clock.running and not self.finished,
            )

    # -- playback controls --------------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        return self._clock.running

    @property
    def speed(self) -> float:
        return self._clock.time_scale

    @speed.setter
    def speed(self, value: float) -> None:
        if not value > 0:
            raise InvalidInput(f"The replay speed must be positive, got {value}.")
        with self._lock:
            now = self._clock.now() if self._clock.running else None
            self._clock.time_scale = float(value)
            if now is not None:
                self._clock.rebase(now)

    @property
    def position(self) -> float:
        """Recording time (s) of the latest streamed sample."""
        with self._lock:
            return float(self.recording.t[self._cur])

    @property
    def finished(self) -> bool:
        """True when every sample has been streamed and looping is off."""
        return self._idx >= len(self.recording) and not self.loop

    def seek(self, t: float) -> None:
        """Continue streaming from recording time ``t`` seconds (clipped into the recording)."""
        with self._lock:
            rec = self.recording
            i = int(np.searchsorted(rec.t, float(t), side="left"))
            i = min(max(i, 0), len(rec) - 1)
            self._set_index(i)
            if self._clock.running:
                self._clock.rebase(float(rec.t[i]))

    def step(self, n: int = 1) -> JointStateBatch:
        """Manual mode: stream the next ``n`` samples now (fewer at the end); returns them."""
        if self._clock.running:
            raise InvalidInput("The replay is playing; pause it before stepping by hand.")
        with self._deliver_lock:
            with self._lock:
                batch = self._take(int(n))
            self._deliver(batch)
        return batch

    # -- internals ----------------------------------------------------------------------------------------
    def _set_index(self, i: int) -> None:
        rec = self.recording
        self._idx = i
        if self._last_t is not None:
            # Keep streamed time increasing: the next sample comes one sample period after the last one.
            self._offset = self._last_t + self._dt - float(rec.t[i])
        self._cur = max(0, i - 1) if self._last_t is not None else i

    def _wrap(self) -> None:
        self._set_index(0)

    def _take(self, n: int) -> JointStateBatch:
        rec = self.recording
        n = max(0, min(n, len(rec) - self._idx))
        s, e = self._idx, self._idx + n
        t = rec.t[s:e] + self._offset
        batch = JointStateBatch(t=_ro(t), q=_ro(rec.q[s:e].copy()), gripper=_ro(rec.gripper[s:e].copy()))
        if n:
            self._idx = e
            self._cur = e - 1
            self._last_t = float(t[-1])
        return batch

    def _advance_to(self, pos: float) -> None:
        with self._deliver_lock:
            while True:
                with self._lock:
                    rec = self.recording
                    due = int(np.searchsorted(rec.t, pos + 1e-9, side="right"))
                    n = min(due - self._idx, MAX_BATCH)
                    batch = self._take(n) if n > 0 else None
                    at_end = self._idx >= len(rec)
                    if batch is None and at_end and self.loop:
                        self._wrap()
                        self._clock.rebase(float(rec.t[0]))
                        pos = float(rec.t[0])
                        continue
                if batch is None:
                    return
                self._deliver(batch)

    def _deliver(self, batch: JointStateBatch) -> None:
        self._hub.deliver(batch)

    @property
    def listener_errors(self) -> int:
        """How many times a listener raised (each one logged; the stream went on)."""
        return self._hub.errors


__all__ = ["ReplayBackend"]
