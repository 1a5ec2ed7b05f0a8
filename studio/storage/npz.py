"""Reading ``.npz`` array files of a session safely: headers first, then the data.

No pickle is ever loaded (``allow_pickle=False``), and the members, dtypes, shapes and declared sizes are
checked from the zip directory and the ``.npy`` headers before any data is read, so a hostile file can
neither run code nor make the studio allocate gigabytes. Every problem is a :class:`SessionFormatError`
naming the file and the problem (see :func:`studio.storage.format.damaged`).
"""

from __future__ import annotations

import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from studio.core.errors import InvalidInput, SessionFormatError, StudioError
from studio.core.types import Recording, Skill
from studio.storage.format import MAX_SAMPLES, MAX_SKILL_ELEMENTS, damaged
from studio.storage.manifest import DemoEntry

#: member name -> (shape with None for "any length", dtype kinds allowed e.g. "f")
Expect = Mapping[str, tuple[tuple[int | None, ...], str]]
_MAX_MEMBERS = 200


def read_npz(path: Path, session: str, rel: str, expect: Expect | None, *, max_elements: int) -> dict[str, np.ndarray]:
    """Read an ``.npz`` safely: members, dtypes, shapes and sizes are checked from the headers first.

    Args:
        expect: the members and their shapes and dtype kinds; None allows any members of numeric, bool or
            text kinds (skill files).
        max_elements: the largest array accepted (elements).
    """
    _check_regular_file(path, session, rel)
    try:
        with zipfile.ZipFile(path) as zf:
            members = _members(zf, session, rel, expect)
            for key, info in members.items():
                _check_member(zf, info, key, session, rel, expect, max_elements)
        with np.load(path, allow_pickle=False) as npz:
            return {key: npz[key] for key in members}
    except SessionFormatError:
        raise
    except (zipfile.BadZipFile, EOFError, zipfile.LargeZipFile, zlib.error, ValueError, OSError, RuntimeError) as exc:
        raise _read_failure(exc, session, rel) from exc


def _read_failure(exc: Exception, session: str, rel: str) -> SessionFormatError:
    if isinstance(exc, zipfile.BadZipFile):
        return damaged(session, rel, "is damaged (it ends early or was cut off)")
    if isinstance(exc, (EOFError, zipfile.LargeZipFile)):
        return damaged(session, rel, "is damaged (it ends early)")
    if isinstance(exc, ValueError):
        if "pickle" in str(exc).lower():
            return damaged(session, rel, "holds Python objects (a pickle), which the studio never opens")
        return damaged(session, rel, f"is damaged ({exc})")
    return damaged(session, rel, "is damaged (its data cannot be decompressed)")  # zlib, OS and runtime errors


def _check_regular_file(path: Path, session: str, rel: str) -> None:
    if not path.exists():
        raise damaged(session, rel, "is missing")
    if not path.is_file() or path.is_symlink():
        raise damaged(session, rel, "is not a regular file")
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except OSError as exc:
        raise damaged(session, rel, f"cannot be read ({exc.strerror})") from exc
    if head[:2] != b"PK":
        if head[:1] == b"\x80":
            raise damaged(session, rel, "holds a Python pickle, which the studio never writes and never opens")
        raise damaged(session, rel, "is not a Teaching Studio array file")


def _members(zf: zipfile.ZipFile, session: str, rel: str, expect: Expect | None) -> dict[str, zipfile.ZipInfo]:
    infos = zf.infolist()
    names = [i.filename for i in infos]
    if len(names) != len(set(names)) or len(names) > _MAX_MEMBERS:
        raise damaged(session, rel, "has a suspicious structure")
    members = {n[:-4]: i for n, i in zip(names, infos, strict=True) if n.endswith(".npy")}
    if len(members) != len(names):
        raise damaged(session, rel, "contains something other than arrays")
    if expect is not None and set(members) != set(expect):
        missing = sorted(set(expect) - set(members))
        extra = sorted(set(members) - set(expect))
        what = f"lacks {', '.join(missing)}" if missing else f"has unexpected parts ({', '.join(extra)})"
        raise damaged(session, rel, f"is not a valid demonstration file (it {what})")
    return members


def _read_header(zf: zipfile.ZipFile, info: zipfile.ZipInfo, key: str, session: str, rel: str) -> tuple:
    with zf.open(info) as mf:
        try:
            version = np.lib.format.read_magic(mf)
            if version == (1, 0):
                return tuple(np.lib.format.read_array_header_1_0(mf))
            if version in ((2, 0), (3, 0)):
                return tuple(np.lib.format.read_array_header_2_0(mf))
            raise ValueError("unknown npy version")
        except ValueError as exc:
            raise damaged(session, rel, f"has a damaged array header ({key})") from exc


def _check_member(
    zf: zipfile.ZipFile,
    info: zipfile.ZipInfo,
    key: str,
    session: str,
    rel: str,
    expect: Expect | None,
    max_elements: int,
) -> None:
    shape, _fortran, dtype = _read_header(zf, info, key, session, rel)
    if dtype.hasobject:
        raise damaged(session, rel, "holds Python objects (a pickle), which the studio never writes and never opens")
    n_el = int(np.prod(shape, dtype=np.int64)) if shape else 1
    if any(s < 0 for s in shape) or n_el > max_elements:
        raise damaged(session, rel, f"declares an absurd size ({key}: {shape})")
    if expect is not None:
        want_shape, kinds = expect[key]
        if dtype.kind not in kinds:
            raise damaged(session, rel, f"has the wrong kind of numbers in {key} ({dtype})")
        if len(shape) != len(want_shape) or any(
            w is not None and w != s for w, s in zip(want_shape, shape, strict=True)
        ):
            want = "(" + ", ".join("N" if w is None else str(w) for w in want_shape) + ")"
            raise damaged(session, rel, f"has {key} of the wrong shape {tuple(shape)}, expected {want}")
    elif dtype.kind not in "fiubU":
        raise damaged(session, rel, f"has an unsupported kind of data in {key} ({dtype})")
    # The declared sizes must agree (guards against zip bombs and against cut-off data).
    if info.file_size > n_el * dtype.itemsize + 65536:
        raise damaged(session, rel, f"declares an absurd size ({key})")
    if info.file_size < n_el * dtype.itemsize:
        raise damaged(session, rel, f"is damaged (it ends early: {key} is incomplete)")


def load_demo(path: Path, session: str, entry: DemoEntry) -> Recording:
    """The demonstration in ``path`` as listed by ``entry`` in the manifest, fully validated."""
    rel, n = entry.file, entry.samples
    arrays = read_npz(
        path,
        session,
        rel,
        {"t": ((n,), "f"), "q": ((n, 14), "f"), "gripper": ((n, 2), "f")},
        max_elements=MAX_SAMPLES * 14,
    )
    for key, a in arrays.items():
        if not np.all(np.isfinite(a)):
            bad = int(np.count_nonzero(~np.isfinite(a)))
            raise damaged(session, rel, f"contains {bad} invalid values (NaN or infinity) in {key}")
    if n >= 2 and np.any(np.diff(arrays["t"]) <= 0):
        raise damaged(session, rel, "has time stamps that do not increase")
    g = arrays["gripper"]
    if np.any(g < -1e-6) or np.any(g > 100 + 1e-6):
        raise damaged(session, rel, "has gripper openings outside 0–100 %")
    try:
        return Recording(
            t=arrays["t"].astype(np.float64, copy=False),
            q=arrays["q"].astype(np.float64, copy=False),
            gripper=g.astype(np.float64, copy=False),
            arms=entry.arms,
            name=entry.name,
        )
    except InvalidInput as exc:
        raise damaged(session, rel, f"is not a valid demonstration ({exc})") from exc


def load_skill(path: Path, session: str, rel: str) -> Skill:
    """The learned skill saved in ``path`` (:meth:`Skill.to_arrays`), fully validated."""
    arrays = read_npz(path, session, rel, None, max_elements=MAX_SKILL_ELEMENTS)
    try:
        return Skill.from_arrays(arrays)
    except (StudioError, ValueError, KeyError, TypeError, IndexError) as exc:
        raise damaged(session, rel, f"is not a valid learned skill ({exc})") from exc
