"""What the computer can hold: free disk space and free memory, checked before a write or a load is started,
and a failed write told in plain words.

The limits themselves (bytes per demonstration, per session, per uploaded byte) are in
:mod:`studio.storage.format`; this module measures the machine against them.
"""

from __future__ import annotations

import errno
import shutil
from pathlib import Path

from studio.core.errors import InvalidInput, StorageError
from studio.core.types import Recording
from studio.storage.format import (
    DEMO_BYTES_PER_SAMPLE,
    DISK_RESERVE,
    MAX_DEMO_BYTES,
    MAX_SESSION_BYTES,
    implausible,
)


def size_text(n: float) -> str:
    """Bytes as a person reads them: "340 MB", "2.9 GB", "12 KB"."""
    if n >= 1e9:
        return f"{n / 1e9:.1f} GB"
    if n >= 1e6:
        return f"{n / 1e6:,.0f} MB"
    return f"{max(n, 0) / 1e3:,.0f} KB"


def available_memory() -> int | None:
    """Bytes of memory the system can give without swapping (``MemAvailable``), or None when unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def free_disk(path: Path) -> int:
    """Free bytes on the disk that holds ``path`` (or its nearest existing parent)."""
    p = Path(path)
    while not p.exists() and p != p.parent:
        p = p.parent
    return int(shutil.disk_usage(p).free)


def check_disk(path: Path, need: int, what: str) -> None:
    """Raise :class:`StorageError` unless ``need`` bytes (and a reserve) fit on the disk of ``path``.

    Args:
        what: what would be written, for the message ("The archive "x.zip"", "The copy of "s"").
    """
    free = free_disk(path)
    if need + DISK_RESERVE > free:
        raise StorageError(
            f"{what} needs {size_text(need)} of disk space, and the disk holding {path} has {size_text(free)} free. "
            "Free some space and try again; nothing was changed."
        )


def check_memory(need: int, what: str) -> None:
    """Raise :class:`StorageError` when ``need`` bytes exceed the session limit or the memory free right now."""
    if need > MAX_SESSION_BYTES:
        raise StorageError(
            f"{what} would take {size_text(need)} of memory; a session may take at most "
            f"{size_text(MAX_SESSION_BYTES)}. Nothing was loaded."
        )
    avail = available_memory()
    if avail is not None and need > 0.8 * avail:
        raise StorageError(
            f"{what} needs about {size_text(need)} of memory, and this computer has {size_text(avail)} free. "
            "Close other programs and try again; nothing was loaded."
        )


def write_failed(
    path: Path, exc: OSError, *, doing: str = "saved", subject: str | None = None, after: str = "Nothing was changed."
) -> StorageError:
    """A failed write (disk full, read-only, no permission) as plain words: '"<file>" could not be <doing>: <why>.
    <what to do> <after>' (``subject`` replaces the quoted file name)."""
    name = path.name if not path.name.startswith(".tmp-") else path.parent.name
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        why = "there is no space left on the disk"
        try:
            why += f" ({size_text(free_disk(path.parent))} free)"
        except OSError:
            pass
        fix = "Free some space and try again."
    elif exc.errno == errno.EROFS:
        why, fix = "the disk is read-only", "Use a sessions folder on a disk you can write to."
    elif exc.errno in (errno.EACCES, errno.EPERM):
        why, fix = "you may not write there", f"Check the permissions of {path.parent}."
    else:
        why, fix = exc.strerror or str(exc), "Try again."
    return StorageError(f"{subject or chr(34) + name + chr(34)} could not be {doing}: {why}. {fix} {after}")


def reworded(exc: StorageError, path: Path, subject: str, doing: str) -> StorageError:
    """``exc`` (a failed write of one file) told about what the person did: 'The demonstration "demo 4" could
    not be saved: …' instead of the file's name; ``exc`` itself when it did not come from the disk."""
    cause = exc.__cause__
    return write_failed(path, cause, doing=doing, subject=subject) if isinstance(cause, OSError) else exc


def check_keepable(rec: Recording, recordings: list[Recording]) -> None:
    """Refuse (:class:`InvalidInput`) a demonstration no robot could make, or one the session cannot hold."""
    problem = implausible(rec.t, rec.q)
    if problem is not None:
        raise InvalidInput(f'"{rec.name}" cannot be kept: it {problem}.')
    size = len(rec) * DEMO_BYTES_PER_SAMPLE
    held = sum(len(r) for r in recordings) * DEMO_BYTES_PER_SAMPLE
    if size > MAX_DEMO_BYTES or held + size > MAX_SESSION_BYTES:
        raise InvalidInput(
            f'"{rec.name}" is too large to keep in this session ({size_text(size)}; the session holds '
            f"{size_text(held)} and may hold {size_text(MAX_SESSION_BYTES)}, one demonstration "
            f"{size_text(MAX_DEMO_BYTES)}). Trim it, or start a new session."
        )
