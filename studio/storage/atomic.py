"""Atomic file writes: a temporary file in the same folder, fsync, rename — a crash leaves the old file or
the new one, never half of either. Arrays are written as ``.npz`` without pickle, byte-for-byte reproducible."""

from __future__ import annotations

import contextlib
import os
import tempfile
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import BinaryIO

import numpy as np

from studio.core.errors import InvalidInput
from studio.storage.limits import write_failed


def _fsync_dir(d: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(d, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def atomic_write(path: Path, write: Callable[[BinaryIO], object]) -> None:
    """Call ``write`` on a temporary file in ``path``'s folder, fsync it, then rename it onto ``path``.

    Raises:
        StorageError: the disk is full, read-only or not writable (plain words naming the file); the old file,
            if any, is untouched and no temporary file is left.
    """
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".tmp-{path.name}-", dir=path.parent)
    except OSError as exc:
        raise write_failed(path, exc) from exc
    try:
        with os.fdopen(fd, "wb") as f:
            os.fchmod(f.fileno(), 0o644)  # mkstemp makes 0600; session files are ordinary documents
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise write_failed(path, exc) from exc
        raise
    _fsync_dir(path.parent)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: temporary file in the same folder, fsync, rename."""
    atomic_write(path, lambda f: f.write(data))


def atomic_write_npz(path: Path, arrays: Mapping[str, np.ndarray], *, compress: bool = True) -> None:
    """Save ``arrays`` as an ``.npz`` atomically (never pickled: object arrays are refused)."""
    _check_plain(arrays)
    # streamed into the file: no second copy of the data in memory
    atomic_write(path, lambda f: write_npz(f, arrays, compress=compress))


def _check_plain(arrays: Mapping[str, np.ndarray]) -> None:
    for k, a in arrays.items():
        if np.asarray(a).dtype.hasobject:
            raise InvalidInput(f"Cannot save {k!r}: it is not a plain numeric array.")


def write_npz(fileobj: BinaryIO, arrays: Mapping[str, np.ndarray], *, compress: bool = True) -> None:
    """Write an ``.npz`` readable by ``np.load(allow_pickle=False)`` to ``fileobj``.

    Unlike ``np.savez`` it stamps a fixed date into the zip entries, so regenerating the same arrays gives
    the same file (the example sessions do not churn in version control).
    """
    _check_plain(arrays)
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(fileobj, "w", compression=method, allowZip64=True) as zf:
        for k, v in arrays.items():
            a = np.asarray(v)
            info = zipfile.ZipInfo(f"{k}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = method
            info.external_attr = 0o644 << 16
            with zf.open(info, "w", force_zip64=True) as f:
                np.lib.format.write_array(f, a if a.flags.c_contiguous else a.copy(order="C"), allow_pickle=False)
