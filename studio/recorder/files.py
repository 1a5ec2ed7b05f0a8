"""The recorder's append-only files: their format, reading them back (a torn last row is dropped), and
recovering the takes a crash interrupted.

File layout (``*.rec``)::

    b"TSREC\\n" | uint32 little-endian header length | header JSON (utf-8) | rows of float64 × ncols
    columns: t, q[14], gripper[2], then for each taught arm x, y, z, qw, qx, qy, qz

Whatever prefix survives a crash (kill -9, power cut) is readable: :func:`recover_recordings` keeps every
complete row. A file still being written is locked (``flock``) by its recorder, and left alone.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import struct
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from studio.core.errors import RecordingError, StorageError, StudioError
from studio.core.types import ALL_ARM_JOINTS, ARMS, Arm, Recording

MAGIC = b"TSREC\n"
FORMAT_VERSION = 1
SUFFIX = ".rec"
#: The ending of a take that was stopped, whole, but waited for disk space (not one a crash interrupted).
FINISHED = ".stopped" + SUFFIX


def columns(arms: tuple[str, ...]) -> list[str]:
    """The column names of a recording file for the taught ``arms``."""
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


def write_header(f: IO[bytes], header: dict[str, object]) -> None:
    """Start a recording file: magic, header length, header JSON."""
    hb = json.dumps(header).encode()
    f.write(MAGIC + struct.pack("<I", len(hb)) + hb)


def open_locked(path: Path, header: dict[str, object]) -> IO[bytes]:
    """Create the recording file, lock it, write its header, and fsync it."""
    f = open(path, "xb")
    try:
        # An exclusive lock marks the file as "being written": recovery skips locked files, and the
        # operating system releases the lock when this process dies, however it dies.
        fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        write_header(f, header)
        f.flush()
        os.fsync(f.fileno())
    except OSError:
        f.close()
        raise
    return f


def _read_header(f: IO[bytes], path: Path) -> dict[str, Any]:
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
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:  # JSONDecodeError is a ValueError
        raise RecordingError(f'"{path.name}" is damaged (its header cannot be read).') from exc
    if not isinstance(header, dict) or header.get("format") != "teaching-studio-recording":
        raise RecordingError(f'"{path.name}" is not a Teaching Studio recording.')
    if header.get("version") != FORMAT_VERSION:
        raise RecordingError(f'"{path.name}" was written by another version of Teaching Studio.')
    arms = header.get("arms")
    if not isinstance(arms, list) or not arms or any(a not in ARMS for a in arms):
        raise RecordingError(f'"{path.name}" is damaged (unknown taught arms).')
    if header.get("columns") != columns(tuple(arms)):
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
    demo = demo_from_rows(data[:n_ok], arms, name or str(header.get("name") or "demo"), path, poses=poses)
    del data
    return demo


def demo_from_rows(
    data: np.ndarray, arms: tuple[Arm, ...], name: str, path: Path, *, poses: bool = True
) -> RecordedDemo:
    """A take from its file rows ``data`` (n, columns(arms)), times made to start at 0."""
    t = np.asarray(data[:, 0]) - float(data[0, 0])
    rec = Recording(t=t, q=data[:, 1:15], gripper=np.clip(data[:, 15:17], 0.0, 100.0), arms=arms, name=name)
    out_poses: dict[str, np.ndarray] = (
        {a: np.array(data[:, 17 + 7 * i : 24 + 7 * i]) for i, a in enumerate(arms)} if poses else {}
    )
    return RecordedDemo(recording=rec, poses=out_poses, path=path)


def spill_dirs(directory: str | os.PathLike[str]) -> list[Path]:
    """Where a take goes whose own disk is still full when the studio stops (the user's state folder, else the
    temporary one), one folder per recording folder: the next open of its session adds it from there."""
    key = hashlib.sha1(str(Path(directory).resolve()).encode()).hexdigest()[:16]
    state = Path(os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state")
    return [state / "teaching-studio" / "takes" / key, Path(tempfile.gettempdir()) / "teaching-studio-takes" / key]


def write_spill(
    directory: str | os.PathLike[str], name: str, header: dict[str, object], parts: list[np.ndarray]
) -> Path | None:
    """Write a whole take (``header`` and the rows of ``parts``) to the first of :func:`spill_dirs` that takes it;
    its path, or None when none could."""
    for folder in spill_dirs(directory):
        part = folder / f"{name}.part"
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with open(part, "xb") as f:
                write_header(f, header)
                for rows in parts:
                    f.write(np.ascontiguousarray(rows, dtype="<f8").data.cast("B"))
                f.flush()
                os.fsync(f.fileno())
            final = folder / name
            os.rename(part, final)
            return final
        except OSError:
            with contextlib.suppress(OSError):
                part.unlink()
    return None


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
    """Recording files left in ``directory`` (or, for it, in :func:`spill_dirs`) by a process that is no longer
    writing them."""
    found: list[Path] = []
    for d in [Path(directory), *spill_dirs(directory)]:
        if d.is_dir() and not d.is_symlink():
            found += sorted(p for p in d.glob(f"*{SUFFIX}") if p.is_file() and not p.is_symlink() and not _is_locked(p))
    return found


def recover_recordings(
    directory: str | os.PathLike[str], add: Callable[[Recording], object] | None = None
) -> tuple[list[Recording], str]:
    """Recover recordings interrupted by a crash.

    Reads every unlocked ``*.rec`` file in ``directory`` (a file still being written by a live recorder is
    locked and left alone), keeping all samples up to the last flush. The session store calls this when it
    opens a session (:meth:`studio.storage.SessionStore.open`), with ``add=session.add_recording``.

    Args:
        directory: the recorder's folder.
        add: if given, called with each recovered demonstration (to save it into a session); its file is
            deleted afterwards, or set aside as ``*.damaged`` when ``add`` refuses it with a
            :class:`StudioError`. Without ``add`` the files stay (delete them with :func:`discard_pending`).

    Returns:
        The recovered recordings and a plain-words message for the user ("" if there was nothing).
    """
    recs: list[Recording] = []
    notes: list[str] = []
    waited: list[str] = []
    damaged: list[str] = []
    kept: list[str] = []
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
        finished = p.name.endswith(FINISHED)  # stopped whole; it only waited for disk space
        suffix = "" if finished else " (recovered)"
        rec = Recording(
            t=rec.t, q=rec.q, gripper=rec.gripper, arms=rec.arms, name=f"{rec.name[: 100 - len(suffix)]}{suffix}"
        )
        if add is not None:
            try:
                add(rec)
            except StorageError as exc:
                # The disk is full (or read-only) now: the take stays as it is and is added next time.
                kept.append(
                    f'The recording "{rec.name}" ({rec.duration:.1f} s) could not be added to the session yet: '
                    f"{exc} It is kept, and will be added the next time the session opens."
                )
                continue
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
        (waited if finished else notes).append(f'"{rec.name}" ({rec.duration:.1f} s, {len(rec):,} samples)')
    msg = ""
    if notes:
        where = " and added to the session" if add is not None else ""
        msg = (
            f"The studio stopped while recording last time. {len(notes)} demonstration"
            f"{'s were' if len(notes) > 1 else ' was'} recovered{where}, up to the last second before it "
            f"stopped: {', '.join(notes)}."
        )
    if waited:
        msg = (msg + " " if msg else "") + (
            f"{'These takes' if len(waited) > 1 else 'This take'} could not be saved when recorded (the disk was "
            f"full) and {'were' if len(waited) > 1 else 'was'} added now, whole: {', '.join(waited)}."
        )
    if damaged:
        msg = (msg + " " if msg else "") + "Some recording files could not be recovered: " + " ".join(damaged)
    if kept:
        msg = (msg + " " if msg else "") + " ".join(kept)
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
    "FINISHED",
    "FORMAT_VERSION",
    "MAGIC",
    "SUFFIX",
    "RecordedDemo",
    "columns",
    "demo_from_rows",
    "discard_pending",
    "open_locked",
    "pending_recordings",
    "read_recording_file",
    "recover_recordings",
    "spill_dirs",
    "write_header",
    "write_spill",
]
