"""A wall-clock ticker that advances a backend's simulated time in batches.

A 1 kHz busy loop keeps one core busy (PLATFORM-FACTS); instead a thread wakes every ``period`` seconds of
wall time and asks the backend to produce every sample that has become due since the last wakeup. Time
stamps come from the sample counter, never from the wall clock, so a late wakeup (a busy CPU, the GIL held
by another thread) makes one batch larger but loses no sample and shifts no time stamp.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from studio.core.errors import StudioError


class BatchClock:
    """Calls ``advance_to(sim_seconds)`` from a daemon thread every ``period`` seconds of wall time.

    Args:
        advance_to: called with the simulated time (s since :meth:`start`, scaled by ``time_scale``) up to
            which samples are due. Runs on the clock's thread.
        period: wall-clock seconds between wakeups (10–20 ms keeps latency low and CPU use tiny).
        time_scale: simulated seconds per wall second (1.0 = real time; >1 runs faster for tests).
        name: thread name, for debugging.
    """

    def __init__(
        self,
        advance_to: Callable[[float], None],
        *,
        period: float = 0.015,
        time_scale: float = 1.0,
        name: str = "clock",
    ) -> None:
        if not period > 0 or not time_scale > 0:
            raise ValueError("period and time_scale must be positive")
        self._advance_to = advance_to
        self.period = float(period)
        self.time_scale = float(time_scale)
        self._name = name
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()  # start and stop from different threads (two tabs: Play and a seek)
        self._stop = threading.Event()
        self._wall0 = 0.0
        self._sim0 = 0.0
        self.error: BaseException | None = None
        #: Wall seconds :meth:`stop` (and a restart) wait for the ticking thread to finish.
        self.join_timeout = 5.0

    @property
    def running(self) -> bool:
        """Ticking (a clock asked to stop whose thread has not finished yet is not running)."""
        return self._thread is not None and self._thread.is_alive() and not self._stop.is_set()

    def start(self, sim_start: float = 0.0) -> None:
        """Start ticking; simulated time ``sim_start`` corresponds to now. Safe beside :meth:`stop` from another
        thread: a thread is published only once it runs.

        Raises:
            StudioError: the previous ticking thread is still busy after :meth:`stop` (never two at once).
        """
        with self._lock:
            if self.running:
                return
            old = self._thread
        if old is not None and old.is_alive() and old is not threading.current_thread():
            old.join(timeout=self.join_timeout)  # stopped, but its last wakeup has not returned yet
        with self._lock:
            if self.running:
                return
            old = self._thread
            if old is not None and old.is_alive():
                raise StudioError(
                    f'The "{self._name}" clock is still finishing its previous work; try again in a moment.'
                )
            self._stop.clear()
            self._wall0 = time.perf_counter()
            self._sim0 = float(sim_start)
            t = threading.Thread(target=self._run, name=self._name, daemon=True)
            t.start()
            self._thread = t

    def rebase(self, sim_now: float) -> None:
        """Declare that simulated time ``sim_now`` corresponds to the wall clock now (after pause/seek)."""
        self._wall0 = time.perf_counter()
        self._sim0 = float(sim_now)

    def now(self) -> float:
        """Simulated time that corresponds to the wall clock now."""
        return self._sim0 + (time.perf_counter() - self._wall0) * self.time_scale

    def stop(self) -> None:
        """Stop ticking and wait (up to :attr:`join_timeout`) for the thread's last wakeup."""
        with self._lock:
            t = self._thread
            if t is None:
                return
            self._stop.set()
        if t is not threading.current_thread():
            t.join(timeout=self.join_timeout)
        with self._lock:
            if self._thread is t and not t.is_alive():  # a thread still busy is kept: start() must not run two
                self._thread = None

    def _run(self) -> None:
        next_wake = time.perf_counter()
        while not self._stop.is_set():
            try:
                self._advance_to(self.now())
            except BaseException as exc:  # keep the error for the owner; a dead clock must not go unnoticed
                self.error = exc
                return
            next_wake += self.period
            delay = next_wake - time.perf_counter()
            if delay < 0:  # fell behind (busy CPU): do not try to catch up wakeups, the next batch is larger
                next_wake = time.perf_counter()
                delay = 0.0
            self._stop.wait(delay)
