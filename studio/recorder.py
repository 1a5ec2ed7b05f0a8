"""Records the robot's joint-state stream into a demonstration, crash-safe.

What is recorded (paper § Data Collection): every streamed sample's time stamp, all 14 joint angles, both
gripper openings, and the forward-kinematics pose (position + w,x,y,z quaternion) of each taught arm.

Crash safety: samples go to an append-only file as they arrive (a writer thread drains the stream every
``flush_interval`` ≤ 1 s, computes FK, appends, flushes to the operating system, and fsyncs about once a
second). The file is a short JSON header followed by fixed-size float64 rows, so whatever prefix survives a
crash (kill -9, power cut) is readable: :func:`recover_recordings` keeps every complete row and drops a
half-written last one. Memory stays bounded while recording (only the not-yet-written samples are held).

File layout (``*.rec``)::

    b"TSREC\\n" | uint32 little-endian header length | header JSON (utf-8) | rows of float64 × ncols
    columns: t, q[14], gripper[2], then for each taught arm x, y, z, qw, qx, qy, qz
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import fcntl
import json
import logging
import os
import struct
import threading
import time
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.errors import InvalidInput, RecordingError, StudioError
from studio.core.types import ARMS, Recording
from studio.robot_backend.base import JointStateBatch, RobotBackend

log = logging.getLogger(__name__)

MAGIC = b"TSREC\n"
FORMAT_VERSION = 1
SUFFIX = ".rec"
#: Longest recording accepted (simulated seconds); past it the recorder stops by itself and says so.
MAX_SECONDS = 4 * 3600.0
#: Samples the writer turns into rows at once (FK temporaries stay a few MB).
DRAIN_CHUNK = 32_768
#: Samples allowed to wait for the writer before the producer is made to wait (~100 s at 1 kHz).
MAX_PENDING = 100_000


def _columns(arms: tuple[str, ...]) -> list[str]:
    from studio.core.types import ALL_ARM_JOINTS

    cols = ["t", *ALL_ARM_JOINTS, "left_gripper", "right_gripper"]
    for a in arms:
        cols += [f"{a}_{c}" for c in ("x", "y", "z", "qw", "qx", "qy", "qz")]
    return cols


@dataclass(frozen=True)
class RecordedDemo:
    """A finished or recovered recording together with the FK poses computed while recording.

    Attributes:
        recording: the raw demonstration (times from 0, joints, grippers, taught arms, name).
        poses: for each taught arm, (N, 7) x, y, z (m), qw, qx, qy, qz of the gripper frame.
        path: the append-only file it was read from.
    """

    recording: Recording
    poses: dict[str, np.ndarray]
    path: Path


class Recorder:
    """Records ``backend``'s stream into ``directory`` while started.

    Typical use (the app)::

        rec = Recorder(backend, session.recording_dir, arms=("left",), name="demo 4")
        rec.start()            # ... the teacher moves the arm ...
        recording = rec.stop() # a Recording; the file stays on disk until saved
        session.add_recording(recording); rec.discard()   # or rec.save_to(session)

    Args:
        backend: any :class:`RobotBackend`; the recorder subscribes on :meth:`start`.
        directory: folder for the append-only file (created if missing).
        arms: taught arm(s), whose FK pose is recorded.
        name: demonstration name.
        flush_interval: seconds between writes to disk (≤ 1 s).
        max_seconds: stop by itself after this much recorded time.
        baxter: kinematics model (default: the shared :meth:`Baxter.load`).
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
        baxter: Any = None,
    ) -> None:
        if isinstance(arms, str):
            arms = ("left", "right") if arms == "both" else (arms,)
        arms = tuple(a for a in ARMS if a in set(arms))
        if not arms or len(arms) != len(set(arms)):
            raise InvalidInput('Choose the taught arm(s): "left", "right" or both.')
        self.backend = backend
        self.directory = Path(directory)
        self.arms: tuple[str, ...] = arms
        self.name = str(name)
        self.flush_interval = min(max(float(flush_interval), 0.01), 1.0)
        self.max_seconds = float(max_seconds)
        self._baxter = baxter
        self._cols = _columns(arms)
        self._ncols = len(self._cols)
        self._lock = threading.Lock()
        self._write_lock = threading.Lock()
        self._pending: list[JointStateBatch] = []
        self._pending_n = 0
        self._in_flight = 0
        self._wake = threading.Event()
        self._stop_writer = threading.Event()
        self._writer: threading.Thread | None = None
        self._unsubscribe: Any = None
        self._file: Any = None
        self.path: Path | None = None
        self._t0: float | None = None
        self._first_seen: float | None = None
        self._last_t: float | None = None
        self._n = 0
        self._dropped_invalid = 0
        self._dropped_order = 0
        self._last_sync = 0.0
        self.error: str | None = None
        self.state = "idle"  # idle -> recording -> stopped | discarded
        self.limit_reached = False

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
            last = self._pending[-1].t[-1] if self._pending and len(self._pending[-1]) else self._last_t
            t0 = self._t0 if self._t0 is not None else self._first_seen
            if last is None or t0 is None or not np.isfinite(last):
                return 0.0
            return max(0.0, float(last - t0))

    @property
    def recording(self) -> bool:
        return self.state == "recording"

    @property
    def messages(self) -> list[str]:
        """Plain-words notes about the recording (skipped samples, limits, disk problems)."""
        out = []
        if self._dropped_invalid:
            out.append(
                f"{self._dropped_invalid} samples from the robot had invalid joint values (NaN or infinity) and "
                "were skipped; the rest of the demonstration is kept."
            )
        if self._dropped_order:
            out.append(f"{self._dropped_order} samples arrived out of order or twice and were skipped.")
        if self.limit_reached:
            out.append(
                f"The recording reached the longest allowed length ({self.max_seconds / 60:.0f} minutes) and "
                "stopped by itself; everything up to then is kept."
            )
        if self.error:
            out.append(self.error)
        return out

    def start(self) -> None:
        """Open the append-only file and start recording the stream."""
        if self.state != "idle":
            raise RecordingError("This recorder has already been used; make a new one for the next demonstration.")
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%S")
            self.path = self.directory / f"{stamp}-{uuid.uuid4().hex[:8]}{SUFFIX}"
            header = {
                "format": "teaching-studio-recording",
                "version": FORMAT_VERSION,
                "name": self.name,
                "arms": list(self.arms),
                "columns": self._cols,
                "rate_hz": float(getattr(self.backend, "rate_hz", 1000.0)),
                "started": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
                "pid": os.getpid(),
            }
            hb = json.dumps(header).encode()
            f = open(self.path, "xb")
            # An exclusive lock marks the file as "being written": recovery skips locked files, and the
            # operating system releases the lock when this process dies, however it dies.
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            f.write(MAGIC + struct.pack("<I", len(hb)) + hb)
            f.flush()
            os.fsync(f.fileno())
            self._file = f
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
        if demo is None or len(demo.recording) == 0:
            raise RecordingError(
                "The recording is empty: the robot sent no joint states while recording. "
                "Check that the robot is streaming and record again."
            )
        return demo

    def discard(self) -> None:
        """Stop (if needed) and delete the recording file (after saving it, or to throw the take away)."""
        if self.state == "recording":
            self._finish()
        if self.path is not None:
            with contextlib.suppress(FileNotFoundError):
                self.path.unlink()
        self.state = "discarded"

    def save_to(self, session: Any) -> int:
        """Stop, add the demonstration to ``session`` (written atomically), then delete the file.

        Returns the new demo's index in the session.
        """
        rec = self.stop()
        index = session.add_recording(rec)
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
        # state check before the unsubscribe) then finds no file instead of writing into a closed one.
        with self._write_lock:
            if self._file is not None:
                with contextlib.suppress(OSError):
                    fcntl.flock(self._file.fileno(), fcntl.LOCK_UN)
                self._file.close()
                self._file = None
        self.state = "stopped"

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
            if self._file is not None:
                # Bounded chunks: FK temporaries stay small however far the writer fell behind.
                group: list[JointStateBatch] = []
                size = 0
                for b in batches:
                    group.append(b)
                    size += len(b)
                    if size >= DRAIN_CHUNK:
                        if not self._write_group(group):
                            return
                        group, size = [], 0
                if group and not self._write_group(group):
                    return
                if sync:
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
        if rows is not None:
            try:
                self._file.write(rows.tobytes())
                self._file.flush()
                if time.monotonic() - self._last_sync >= 0.9:
                    self._sync()
            except OSError as exc:
                self.error = (
                    f"Recording stopped: the disk could not take more data ({exc.strerror}). "
                    "Everything recorded until then is kept."
                )
                log.error("recorder write failed: %s", exc)
                self._halt()
                return False
        with self._lock:
            self._n += 0 if rows is None else rows.shape[0]
            self._in_flight -= n_in
        if self.limit_reached:
            self._halt()
            return False
        return True

    def _sync(self) -> None:
        with contextlib.suppress(OSError):
            os.fsync(self._file.fileno())
        self._last_sync = time.monotonic()

    def _halt(self) -> None:
        """Stop listening (limit reached or disk error) without closing: stop() still returns the data."""
        unsub, self._unsubscribe = self._unsubscribe, None
        if unsub is not None:
            unsub()

    def _rows(self, t: np.ndarray, q: np.ndarray, g: np.ndarray) -> np.ndarray | None:
        ok = np.isfinite(t) & np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(g), axis=1)
        if not np.all(ok):
            self._dropped_invalid += int(np.count_nonzero(~ok))
            t, q, g = t[ok], q[ok], g[ok]
        if t.size == 0:
            return None
        # Strictly increasing time: keep a sample only if it is later than every sample before it.
        prev = -np.inf if self._last_t is None else self._last_t
        run_max = np.maximum.accumulate(np.concatenate([[prev], t]))
        keep = t > run_max[:-1]
        if not np.all(keep):
            self._dropped_order += int(np.count_nonzero(~keep))
            t, q, g = t[keep], q[keep], g[keep]
        if t.size == 0:
            return None
        if self._t0 is None:
            self._t0 = float(t[0])
        over = t - self._t0 > self.max_seconds
        if np.any(over):
            self.limit_reached = True
            t, q, g = t[~over], q[~over], g[~over]
            if t.size == 0:
                return None
        self._last_t = float(t[-1])
        g = np.clip(g, 0.0, 100.0)
        parts = [t[:, None], q, g]
        for arm in self.arms:
            pos, wxyz = self._kin().fk_batch(arm, q[:, :7] if arm == "left" else q[:, 7:])
            parts += [pos, wxyz]
        return np.ascontiguousarray(np.hstack(parts), dtype="<f8")

    def _kin(self) -> Any:
        if self._baxter is None:
            from studio.core.kinematics import Baxter

            self._baxter = Baxter.load()
        return self._baxter


# -- reading and recovery -----------------------------------------------------------------------------------
def _read_header(f: Any, path: Path) -> dict[str, Any]:
    head = f.read(len(MAGIC) + 4)
    if len(head) < len(MAGIC) + 4 or head[: len(MAGIC)] != MAGIC:
        raise RecordingError(f'"{path.name}" is not a Teaching Studio recording.')
    (hlen,) = struct.unpack("<I", head[len(MAGIC) :])
    if hlen > 1_000_000:
        raise RecordingError(f'"{path.name}" is damaged (its header is implausibly large).')
    hb = f.read(hlen)
    if len(hb) != hlen:
        raise RecordingError(f'"{path.name}" is damaged (it ends inside its header).')
    try:
        header = json.loads(hb.decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RecordingError(f'"{path.name}" is damaged (its header cannot be read).') from exc
    if not isinstance(header, dict) or header.get("format") != "teaching-studio-recording":
        raise RecordingError(f'"{path.name}" is not a Teaching Studio recording.')
    if header.get("version") != FORMAT_VERSION:
        raise RecordingError(f'"{path.name}" was written by another version of Teaching Studio.')
    arms = header.get("arms")
    if not isinstance(arms, list) or not arms or any(a not in ARMS for a in arms):
        raise RecordingError(f'"{path.name}" is damaged (unknown taught arms).')
    if header.get("columns") != _columns(tuple(arms)):
        raise RecordingError(f'"{path.name}" is damaged (unexpected columns).')
    header["_data_offset"] = len(MAGIC) + 4 + hlen
    return header


def read_recording_file(
    path: str | os.PathLike[str], *, name: str | None = None, poses: bool = True
) -> RecordedDemo | None:
    """Read an append-only recording file; a half-written last row is dropped. None if it holds no sample.

    The file is memory-mapped and checked in chunks, so reading a 2-hour recording needs little more memory
    than the returned arrays themselves.

    Args:
        poses: also return the recorded FK poses (skip them to save memory when only the Recording is needed).

    Raises:
        RecordingError: the file is not a recording or its header is damaged.
    """
    path = Path(path)
    try:
        with open(path, "rb") as f:
            header = _read_header(f, path)
            size = os.fstat(f.fileno()).st_size
    except OSError as exc:
        raise RecordingError(f'The recording "{path.name}" cannot be read ({exc.strerror}).') from exc
    arms = tuple(header["arms"])
    ncols = len(header["columns"])
    nrows = (size - header["_data_offset"]) // (8 * ncols)
    if nrows <= 0:
        return None
    data: np.ndarray = np.memmap(path, dtype="<f8", mode="r", offset=header["_data_offset"], shape=(nrows, ncols))
    # A crash can leave a torn last row (e.g. zero-filled); keep only the clean, increasing prefix.
    n_ok = nrows
    prev = -np.inf
    chunk = 1 << 18
    for s in range(0, nrows, chunk):
        block = np.asarray(data[s : s + chunk])
        good = np.all(np.isfinite(block), axis=1) & (block[:, 0] > np.concatenate([[prev], block[:-1, 0]]))
        if not np.all(good):
            n_ok = s + int(np.argmin(good))
            break
        prev = float(block[-1, 0])
    if n_ok == 0:
        return None
    data = data[:n_ok]
    t = np.asarray(data[:, 0]) - float(data[0, 0])
    rec = Recording(
        t=t,
        q=data[:, 1:15],
        gripper=np.clip(data[:, 15:17], 0.0, 100.0),
        arms=arms,
        name=name or str(header.get("name") or "demo"),
    )
    out_poses = {a: np.array(data[:, 17 + 7 * i : 24 + 7 * i]) for i, a in enumerate(arms)} if poses else {}
    del data
    return RecordedDemo(recording=rec, poses=out_poses, path=path)


def _is_locked(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            try:
                fcntl.flock(f.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
            except BlockingIOError:
                return True
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)
            return False
    except OSError:
        return True


def pending_recordings(directory: str | os.PathLike[str]) -> list[Path]:
    """Recording files left in ``directory`` by a process that is no longer writing them."""
    d = Path(directory)
    if not d.is_dir():
        return []
    return sorted(p for p in d.glob(f"*{SUFFIX}") if p.is_file() and not _is_locked(p))


def recover_recordings(directory: str | os.PathLike[str], session: Any = None) -> tuple[list[Recording], str]:
    """Recover recordings interrupted by a crash.

    Reads every unlocked ``*.rec`` file in ``directory`` (a file still being written by a live recorder is
    locked and left alone), keeping all samples up to the last flush.

    Args:
        directory: the recorder's folder.
        session: if given, each recovered demonstration is added to it (saved atomically) and its file is
            deleted afterwards; otherwise the files stay (delete them with :func:`discard_pending`).

    Returns:
        The recovered recordings and a plain-words message for the user ("" if there was nothing).
    """
    recs: list[Recording] = []
    notes: list[str] = []
    damaged: list[str] = []
    for p in pending_recordings(directory):
        try:
            demo = read_recording_file(p, poses=False)
        except RecordingError as exc:
            damaged.append(str(exc))
            continue
        if demo is None:
            with contextlib.suppress(OSError):
                p.unlink()
            continue
        rec = demo.recording
        if len(rec) < 2:
            # One sample is not a demonstration (a session refuses it): say so and remove the file.
            with contextlib.suppress(OSError):
                p.unlink()
            damaged.append(
                f'The recording file "{p.name}" held a single sample, which is not a demonstration; it was removed.'
            )
            continue
        suffix = " (recovered)"
        rec = Recording(
            t=rec.t, q=rec.q, gripper=rec.gripper, arms=rec.arms, name=f"{rec.name[: 100 - len(suffix)]}{suffix}"
        )
        if session is not None:
            try:
                session.add_recording(rec)
            except StudioError as exc:
                # Keep the file aside (no longer a pending "*.rec") so the session still opens next time.
                aside = p.with_name(p.name + ".damaged")
                with contextlib.suppress(OSError):
                    p.rename(aside)
                damaged.append(
                    f'The recording file "{p.name}" could not be added to the session ({exc}); '
                    f'it was kept as "{aside.name}" in the folder "{p.parent}".'
                )
                continue
            with contextlib.suppress(OSError):
                p.unlink()
        recs.append(rec)
        notes.append(f'"{rec.name}" ({rec.duration:.1f} s, {len(rec)} samples)')
    msg = ""
    if recs:
        where = " and added to the session" if session is not None else ""
        msg = (
            f"The studio stopped while recording last time. {len(recs)} demonstration"
            f"{'s were' if len(recs) > 1 else ' was'} recovered{where}, up to the last second before it "
            f"stopped: {', '.join(notes)}."
        )
    if damaged:
        msg = (msg + " " if msg else "") + "Some recording files could not be recovered: " + " ".join(damaged)
    return recs, msg


def discard_pending(directory: str | os.PathLike[str]) -> int:
    """Delete leftover recording files in ``directory`` (not those still being written); returns how many."""
    n = 0
    for p in pending_recordings(directory):
        with contextlib.suppress(OSError):
            p.unlink()
            n += 1
    return n


__all__ = [
    "MAX_SECONDS",
    "RecordedDemo",
    "Recorder",
    "discard_pending",
    "pending_recordings",
    "read_recording_file",
    "recover_recordings",
]
