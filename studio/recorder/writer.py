"""Records the robot's joint-state stream into a demonstration, crash-safe.

Every sample's time, joints, grippers and the FK pose of each taught arm go to an append-only file as they arrive
(:mod:`studio.recorder.files`; a writer thread appends and fsyncs about once a second), so what survives a crash
is readable (docs/decisions/025). When the disk is full, rows wait in memory (bounded) and are written when space
returns (docs/decisions/090). Use: ``rec = Recorder(backend, folder, arms=...); rec.start(); recording =
rec.stop(); session.add_recording(recording); rec.discard()``."""

from __future__ import annotations

import contextlib
import datetime as _dt
import fcntl
import logging
import os
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, TYPE_CHECKING, Protocol

import numpy as np

from studio.core.arms import arm_columns, normalize_arms
from studio.core.errors import RecordingError
from studio.core.types import Arm, Recording
from studio.recorder.files import (
    FINISHED,
    FORMAT_VERSION,
    SUFFIX,
    RecordedDemo,
    columns,
    demo_from_rows,
    open_locked,
    read_recording_file,
    write_spill,
)
from studio.robot_backend.base import JointStateBatch, RobotBackend

if TYPE_CHECKING:
    from studio.core.kinematics import Baxter

log = logging.getLogger(__name__)

#: Longest recording accepted (simulated seconds); past it the recorder stops by itself and says so (a session
#: keeps demonstrations up to 1 hour at 1 kHz: studio.storage.format.MAX_SAMPLES).
MAX_SECONDS = 3600.0
#: Samples the writer turns into rows at once (FK temporaries stay a few MB).
DRAIN_CHUNK = 32_768
#: Samples allowed to wait for the writer before the producer is made to wait (100 s of the stream at 1 kHz).
MAX_PENDING = 100_000
#: Bytes of rows a take may hold in memory while the disk takes none (docs/decisions/090 says how long that lasts).
MAX_UNSAVED_BYTES = 256 * 1024**2


class DemoSink(Protocol):
    """Where a finished take goes (a :class:`studio.storage.Session`): the recorder knows nothing more of it."""

    def add_recording(self, rec: Recording, name: str | None = None) -> int: ...


class Recorder:
    """Records ``backend``'s stream into ``directory`` while started (one take per recorder).

    Args:
        backend: any :class:`RobotBackend`; the recorder subscribes on :meth:`start`.
        directory: folder for the append-only file (created if missing).
        arms: taught arm(s), whose FK pose is recorded.
        name: demonstration name.
        flush_interval: seconds between writes to disk (≤ 1 s).
        max_seconds: stop by itself after this much recorded time.
        baxter: kinematics model (default: the shared :meth:`Baxter.load`).
        on_full: told (in words, from the writer thread) when the disk first takes no more rows.
    """

    def __init__(
        self,
        backend: RobotBackend,
        directory: str | os.PathLike[str],
        arms: tuple[str, ...] | list[str] | str = ("left",),
        *,
        name: str = "demo",
        flush_interval: float = 0.25,
        max_seconds: float = MAX_SECONDS,
        baxter: Baxter | None = None,
        on_full: Callable[[str], None] | None = None,
    ) -> None:
        arms = normalize_arms(arms)
        self.backend = backend
        self.directory = Path(directory)
        self.arms: tuple[Arm, ...] = arms
        self.name = str(name)
        self.flush_interval = min(max(float(flush_interval), 0.01), 1.0)
        self.max_seconds = float(max_seconds)
        self._rows = _Rows(arms, self.max_seconds, baxter)
        self._lock = threading.Lock()
        self._write_lock = threading.Lock()
        self._pending: list[JointStateBatch] = []
        self._pending_n = 0
        self._in_flight = 0
        self._wake = threading.Event()
        self._stop_writer = threading.Event()
        self._writer: threading.Thread | None = None
        self._unsubscribe: Callable[[], None] | None = None
        self._file: IO[bytes] | None = None
        self._header: dict[str, object] = {}
        self._offset = 0  # where the rows start in the file (after its header)
        self._end = 0  # bytes of the file that hold whole rows (the header and every row written)
        #: rows not on disk yet (the disk took no more), oldest first, and how many bytes they hold
        self._unsaved: list[np.ndarray] = []
        self._unsaved_bytes = 0
        self._on_full = on_full
        self.path: Path | None = None
        self._first_seen: float | None = None
        self._n = 0
        self._last_sync = 0.0
        self.error: str | None = None
        self.state = "idle"  # idle -> recording -> stopped | discarded

    # -- public -------------------------------------------------------------------------------------------
    @property
    def n_samples(self) -> int:
        """Samples recorded so far (written or waiting to be written)."""
        with self._lock:
            return self._n + self._pending_n + self._in_flight

    @property
    def elapsed(self) -> float:
        """Recorded time so far, seconds."""
        with self._lock:
            last = self._pending[-1].t[-1] if self._pending and len(self._pending[-1]) else self._rows.last_t
            t0 = self._rows.t0 if self._rows.t0 is not None else self._first_seen
            if last is None or t0 is None or not np.isfinite(last):
                return 0.0
            return max(0.0, float(last - t0))

    #: Stream time (s, the backend's clock) of the first sample written, the recording's ``t = 0`` (None before).
    first_time = property(lambda self: self._rows.t0)

    @property
    def recording(self) -> bool:
        return self.state == "recording"

    @property
    def limit_reached(self) -> bool:
        """The recording reached :attr:`max_seconds` and stopped by itself."""
        return self._rows.limit_reached

    @property
    def unsaved(self) -> int:
        """Samples recorded but not on disk yet (the disk is full): they wait in memory."""
        with self._lock:
            return sum(len(a) for a in self._unsaved)

    @property
    def messages(self) -> list[str]:
        """Plain-words notes about the recording (skipped samples, limits, disk problems)."""
        error = self.error
        if error and error.startswith(_FULL) and self.state != "recording":
            error = None  # after the take the studio tells whether it is saved (the rows wait in memory)
        return self._rows.messages() + ([error] if error else [])

    def start(self) -> None:
        """Open the append-only file and start recording the stream."""
        if self.state != "idle":
            raise RecordingError("This recorder has already been used; make a new one for the next demonstration.")
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%S")
            self.path = self.directory / f"{stamp}-{uuid.uuid4().hex[:8]}{SUFFIX}"
            header: dict[str, object] = {
                "format": "teaching-studio-recording",
                "version": FORMAT_VERSION,
                "name": self.name,
                "arms": list(self.arms),
                "columns": columns(self.arms),
                "rate_hz": float(getattr(self.backend, "rate_hz", 1000.0)),  # a backend may not say
                "started": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
                "pid": os.getpid(),
            }
            self._file = open_locked(self.path, header)
            self._header = header
            self._offset = self._end = self._file.tell()
        except OSError as exc:
            raise RecordingError(
                f"Recording could not start: the folder {self.directory} cannot be written ({exc.strerror})."
            ) from exc
        self.state = "recording"
        self._last_sync = time.monotonic()
        self._writer = threading.Thread(target=self._write_loop, name="recorder-writer", daemon=True)
        self._writer.start()
        self._unsubscribe = self.backend.subscribe(self._on_batch)

    def flush(self) -> None:
        """Write everything received so far to disk now (tests; the writer does this on its own)."""
        self._drain(sync=True)

    def stop(self) -> Recording:
        """Stop recording and return the demonstration (the file stays until :meth:`discard`)."""
        return self.stop_demo(poses=False).recording

    def stop_demo(self, *, poses: bool = True) -> RecordedDemo:
        """Like :meth:`stop`, also returning the FK poses recorded for the taught arms."""
        if self.state not in ("recording", "stopped"):
            raise RecordingError("Nothing is being recorded.")
        if self.state == "recording":
            self._finish()
        assert self.path is not None
        demo = read_recording_file(self.path, name=self.name, poses=poses)
        with self._lock:
            unsaved = list(self._unsaved)
        if unsaved:  # what the disk did not take yet belongs to the take as much as what it did
            on_disk = demo.recording if demo is not None else None
            head = [] if on_disk is None else [self._file_rows()]
            demo = demo_from_rows(np.concatenate([*head, *unsaved]), self.arms, self.name, self.path, poses=poses)
        if demo is None or len(demo.recording) == 0:
            raise RecordingError(
                "The recording is empty: the robot sent no joint states while recording. "
                "Check that the robot is streaming and record again."
            )
        return demo

    def save_pending(self) -> bool:
        """Try again to write the rows the disk did not take; True once the whole take is in its file (which is
        then closed and unlocked: a session opening recovers it from there)."""
        self._drain(sync=True)
        with self._write_lock:
            if self._unsaved:
                return False
            if self.state != "recording":
                self._close_file()
        return True

    def spill(self) -> Path | None:
        """The studio stops with rows the disk did not take: write the whole take to a spill folder
        (:func:`~studio.recorder.files.write_spill`, recovered with its session) and remove the partial file;
        the spilled file, or None when nothing needed it or no folder took it."""
        if self.save_pending() or self.path is None:
            return None
        with self._write_lock, self._lock:
            parts = [self._file_rows(), *self._unsaved]
        spilled = write_spill(self.path.parent, self.path.name[: -len(SUFFIX)] + FINISHED, self._header, parts)
        if spilled is not None:
            with self._write_lock:
                self._unsaved, self._unsaved_bytes = [], 0
                self._close_file()
            with contextlib.suppress(OSError):
                self.path.unlink()
        return spilled

    def release(self) -> Path | None:
        """Leave a stopped take that is whole in its file for its session's next open: closed, unlocked and
        named as a finished take (:data:`~studio.recorder.files.FINISHED`); its path (None while rows wait)."""
        if self.state == "recording" or not self.save_pending() or self.path is None or not self.path.exists():
            return None
        finished = self.path.with_name(self.path.name[: -len(SUFFIX)] + FINISHED)
        try:
            os.rename(self.path, finished)
        except OSError:
            return self.path  # recovered all the same, as a take the studio stopped during
        self.path = finished
        return finished

    def discard(self) -> None:
        """Stop (if needed) and delete the recording file (after saving it, or to throw the take away)."""
        if self.state == "recording":
            self._finish()
        with self._write_lock:
            self._unsaved, self._unsaved_bytes = [], 0
            self._close_file()
        if self.path is not None:
            with contextlib.suppress(FileNotFoundError):
                self.path.unlink()
        self.state = "discarded"

    def save_to(self, sink: DemoSink) -> int:
        """Stop, add the demonstration to ``sink`` (a session: written atomically), then delete the file.

        Returns the new demo's index in the session.
        """
        rec = self.stop()
        index = sink.add_recording(rec)
        self.discard()
        return int(index)

    # -- internals ----------------------------------------------------------------------------------------
    def _finish(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None
        self._stop_writer.set()
        self._wake.set()
        if self._writer is not None and self._writer is not threading.current_thread():
            self._writer.join(timeout=30.0)
        self._drain(sync=True)
        # Under the write lock: a back-pressure drain already under way on the backend thread (it passed the
        # state check before the unsubscribe) then finds no file instead of writing into a closed one. A take with
        # rows the disk did not take keeps its file open and locked (:meth:`save_pending`).
        with self._write_lock:
            self.state = "stopped"
            if not self._unsaved:
                self._close_file()

    def _close_file(self) -> None:
        """Close and unlock the recording file (under the write lock)."""
        if self._file is not None:
            why, self._file = _close(self._file), None  # closed first: `or` would skip it after an error
            self.error = self.error or why

    def _file_rows(self) -> np.ndarray:
        """The whole rows written to the file so far (read back from it)."""
        assert self.path is not None
        ncols = len(columns(self.arms))
        n = (self._end - self._offset) // (8 * ncols)
        if n <= 0:
            return np.empty((0, ncols))
        return np.array(np.memmap(self.path, dtype="<f8", mode="r", offset=self._offset, shape=(n, ncols)))

    def _on_batch(self, batch: JointStateBatch) -> None:
        # Runs on the backend's streaming thread: only queue the batch, the writer does the work.
        if self.state != "recording":
            return
        with self._lock:
            if self._first_seen is None and len(batch) and np.isfinite(batch.t[0]):
                self._first_seen = float(batch.t[0])
            self._pending.append(batch)
            self._pending_n += len(batch)
            behind = self._pending_n > MAX_PENDING
        if behind:
            # Back-pressure: the producer (e.g. manual stepping far faster than real time) waits while the
            # writer catches up, so memory stays bounded. At 1 kHz real time this never triggers.
            self._drain(sync=False)

    def _write_loop(self) -> None:
        while not self._stop_writer.is_set():
            self._wake.wait(self.flush_interval)
            self._wake.clear()
            self._drain(sync=False)

    def _drain(self, *, sync: bool) -> None:
        with self._write_lock:
            self._drain_locked(sync=sync)

    def _drain_locked(self, *, sync: bool) -> None:
        with self._lock:
            batches, self._pending = self._pending, []
            self._pending_n = 0
            self._in_flight = sum(len(b) for b in batches)
        try:
            # Bounded chunks: FK temporaries stay small however far the writer fell behind; a group that
            # halts the recording (limit, disk error) ends the drain.
            ok = self._file is not None and all(self._write_group(g) for g in _chunks(batches))
            self._write_unsaved()  # rows the disk did not take before: tried again each drain
            if ok and sync:
                self._sync()
        finally:
            with self._lock:
                self._in_flight = 0

    def _write_group(self, batches: list[JointStateBatch]) -> bool:
        """FK + append + flush one group of batches; False when recording had to halt."""
        n_in = sum(len(b) for b in batches)
        t = np.concatenate([b.t for b in batches]).astype(np.float64, copy=False)
        q = np.concatenate([b.q for b in batches]).astype(np.float64, copy=False)
        g = np.concatenate([b.gripper for b in batches]).astype(np.float64, copy=False)
        rows = self._rows(t, q, g)
        if rows is not None and self._file is not None:
            with self._lock:
                self._unsaved.append(rows)
                self._unsaved_bytes += rows.nbytes
        self._write_unsaved()
        with self._lock:
            self._n += 0 if rows is None else rows.shape[0]
            self._in_flight -= n_in
        if self._unsaved_bytes > MAX_UNSAVED_BYTES:
            self.error = (
                f"Recording stopped at {self.elapsed:.1f} s: the disk is full, and the studio holds at most "
                f"{MAX_UNSAVED_BYTES // 1024**2} MB of a take in memory. Everything recorded until then is kept."
            )
            self._halt()
            return False
        if self.limit_reached:
            self._halt()
            return False
        return True

    def _write_unsaved(self) -> None:
        """Append the rows waiting in memory to the file, as many as the disk takes; a row the disk cut is cut
        from the file again, so it always holds whole rows (the rest waits for the next try)."""
        f = self._file
        if f is None or not self._unsaved:
            return
        fd = f.fileno()
        while self._unsaved:
            rows = self._unsaved[0]
            data = rows.data.cast("B")
            done, why = 0, None
            try:
                while done < len(data):
                    done += os.write(fd, data[done:])
            except OSError as exc:
                why = exc
            whole = done // (rows.shape[1] * 8)
            self._end += whole * rows.shape[1] * 8
            with self._lock:
                if whole == len(rows):
                    self._unsaved.pop(0)
                else:
                    self._unsaved[0] = rows[whole:]
                self._unsaved_bytes -= whole * rows.shape[1] * 8
            if why is not None or whole < len(rows):
                self._full(why)
                return
        if self.error and self.error.startswith(_FULL):
            self.error = None  # the disk took everything again
        if time.monotonic() - self._last_sync >= 0.9:
            self._sync()

    def _full(self, exc: OSError | None) -> None:
        """The disk took no more: the file is cut back to whole rows; the take goes on in memory."""
        f = self._file
        if f is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(f.fileno(), self._end)
                os.lseek(f.fileno(), self._end, os.SEEK_SET)
        first = not (self.error and self.error.startswith(_FULL))
        self.error = _FULL + (f" ({exc.strerror})." if exc is not None and exc.strerror else ".") + _KEPT
        if first:
            log.error("recorder: the disk takes no more rows (%s); they wait in memory", exc)
            if self._on_full is not None:
                self._on_full(self.error)

    def _sync(self) -> None:
        f = self._file
        if f is not None:
            with contextlib.suppress(OSError):
                os.fsync(f.fileno())
        self._last_sync = time.monotonic()

    def _halt(self) -> None:
        """Stop listening (limit reached or disk error) without closing: stop() still returns the data."""
        unsub, self._unsubscribe = self._unsubscribe, None
        if unsub is not None:
            unsub()


_FULL = "The disk is full"
_KEPT = (
    " The take goes on: what the disk cannot take waits in the studio's memory and is written as soon as there "
    "is space. Free some space on the disk."
)


def _disk_full(exc: OSError) -> str:
    return (
        f"Recording stopped: the disk could not take more data ({exc.strerror}). "
        "Everything recorded until then is kept."
    )


def _close(f: IO[bytes]) -> str | None:
    """Unlock and close a recording file; None, or why its last buffered rows could not be written (in words)."""
    with contextlib.suppress(OSError):
        fcntl.flock(f.fileno(), fcntl.LOCK_UN)
    try:
        f.close()
    except OSError as exc:
        log.error("recorder close failed: %s", exc)
        return _disk_full(exc)
    return None


def _chunks(batches: list[JointStateBatch], size: int = DRAIN_CHUNK) -> Iterator[list[JointStateBatch]]:
    """Consecutive groups of ``batches`` of about ``size`` samples each."""
    group: list[JointStateBatch] = []
    n = 0
    for b in batches:
        group.append(b)
        n += len(b)
        if n >= size:
            yield group
            group, n = [], 0
    if group:
        yield group


class _Rows:
    """Turns streamed samples into file rows: skips invalid and out-of-order samples (and counts them), stops
    at the length limit, clips the grippers, and appends the FK pose of each taught arm."""

    def __init__(self, arms: tuple[Arm, ...], max_seconds: float, baxter: Baxter | None) -> None:
        self.arms = arms
        self.max_seconds = max_seconds
        self._baxter = baxter
        self.t0: float | None = None
        self.last_t: float | None = None
        self.dropped_invalid = 0
        self.dropped_order = 0
        self.limit_reached = False

    def __call__(self, t: np.ndarray, q: np.ndarray, g: np.ndarray) -> np.ndarray | None:
        ok = np.isfinite(t) & np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(g), axis=1)
        if not np.all(ok):
            self.dropped_invalid += int(np.count_nonzero(~ok))
            t, q, g = t[ok], q[ok], g[ok]
        if t.size == 0:
            return None
        # Strictly increasing time: keep a sample only if it is later than every sample before it.
        prev = -np.inf if self.last_t is None else self.last_t
        run_max = np.maximum.accumulate(np.concatenate([[prev], t]))
        keep = t > run_max[:-1]
        if not np.all(keep):
            self.dropped_order += int(np.count_nonzero(~keep))
            t, q, g = t[keep], q[keep], g[keep]
        if t.size == 0:
            return None
        if self.t0 is None:
            self.t0 = float(t[0])
        over = t - self.t0 > self.max_seconds
        if np.any(over):
            self.limit_reached = True
            t, q, g = t[~over], q[~over], g[~over]
            if t.size == 0:
                return None
        self.last_t = float(t[-1])
        parts = [t[:, None], q, np.clip(g, 0.0, 100.0)]
        for arm in self.arms:
            parts += list(self._kin().fk_batch(arm, q[:, arm_columns(arm)]))
        return np.ascontiguousarray(np.hstack(parts), dtype="<f8")

    def _kin(self) -> Baxter:
        if self._baxter is None:
            from studio.core.kinematics import Baxter  # pinocchio: loaded when the first samples arrive

            self._baxter = Baxter.load()
        return self._baxter

    def messages(self) -> list[str]:
        out = []
        if self.dropped_invalid:
            out.append(
                f"{self.dropped_invalid} samples from the robot had invalid joint values (NaN or infinity) and "
                "were skipped; the rest of the demonstration is kept."
            )
        if self.dropped_order:
            out.append(f"{self.dropped_order} samples arrived out of order or twice and were skipped.")
        if self.limit_reached:
            out.append(
                f"The recording reached the longest allowed length ({self.max_seconds / 60:.0f} minutes) and "
                "stopped by itself; everything up to then is kept."
            )
        return out
