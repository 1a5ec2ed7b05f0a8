"""Reading ``.npz`` array files of a session safely: headers first, then the data.

No pickle is ever loaded (``allow_pickle=False``), and the members, dtypes, shapes and declared sizes are
checked from the zip directory and the ``.npy`` headers before any data is read, so a hostile file can
neither run code nor make the studio allocate gigabytes. Every problem is a :class:`SessionFormatError`
naming the file and the problem (see :func:`studio.storage.format.damaged`).
"""

from __future__ import annotations

import json
import math
import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from studio.core.errors import InvalidInput, SessionFormatError
from studio.core.text import first_unsendable
from studio.core.types import Recording, Skill
from studio.storage.format import (
    DEMO_BYTES_PER_SAMPLE,
    MAX_DEMO_BYTES,
    MAX_DURATION_S,
    MAX_SAMPLES,
    MAX_SKILL_BYTES,
    damaged,
    implausible,
)
from studio.storage.limits import size_text
from studio.storage.manifest import DemoEntry

#: member name -> (shape with None for "any length", dtype kinds allowed e.g. "f")
Expect = Mapping[str, tuple[tuple[int | None, ...], str]]
_MAX_MEMBERS = 200


def read_npz(path: Path, session: str, rel: str, expect: Expect | None, *, max_bytes: int) -> dict[str, np.ndarray]:
    """Read an ``.npz`` safely: members, dtypes, shapes and sizes are checked from the headers first.

    Args:
        expect: the members and their shapes and dtype kinds; None allows any members of numeric, bool or
            text kinds (skill files).
        max_bytes: the most its arrays may declare together (bytes), checked before any data is read.
    """
    members = _inspect(path, session, rel, expect, max_bytes)[0]
    try:
        with np.load(path, allow_pickle=False) as npz:
            return {key: npz[key] for key in members}
    except (zipfile.BadZipFile, EOFError, zipfile.LargeZipFile, zlib.error, ValueError, OSError, RuntimeError) as exc:
        raise _read_failure(exc, session, rel) from exc


def declared_bytes(path: Path, session: str, rel: str, *, max_bytes: int) -> int:
    """What the arrays of the ``.npz`` at ``path`` declare (bytes), from its headers only (checked as when read)."""
    return _inspect(path, session, rel, None, max_bytes)[1]


def _inspect(
    path: Path, session: str, rel: str, expect: Expect | None, max_bytes: int
) -> tuple[dict[str, zipfile.ZipInfo], int]:
    """The members and the bytes their arrays declare, once every header was found sound and within limits."""
    _check_regular_file(path, session, rel)
    try:
        with zipfile.ZipFile(path) as zf:
            members = _members(zf, session, rel, expect)
            total = 0
            for key, info in members.items():
                total += _check_member(zf, info, key, session, rel, expect)
                if total > max_bytes:
                    raise damaged(
                        session, rel, f"is too large to open ({key} alone takes it past {size_text(max_bytes)})"
                    )
        return members, total
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
    for i in infos:
        if i.flag_bits & 0x1:
            raise damaged(session, rel, "is encrypted")
        if i.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            raise damaged(session, rel, "uses a kind of compression the studio never writes")
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
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError, RuntimeError):
            raise
        except Exception as exc:  # numpy parses the header as Python literals: SyntaxError, TokenError, ...
            raise damaged(session, rel, f"has a damaged array header ({key})") from exc


def _check_member(
    zf: zipfile.ZipFile,
    info: zipfile.ZipInfo,
    key: str,
    session: str,
    rel: str,
    expect: Expect | None,
) -> int:
    """Check one member from its header and directory entry; returns the bytes its array declares."""
    shape, _fortran, dtype = _read_header(zf, info, key, session, rel)
    if not isinstance(dtype, np.dtype) or not isinstance(shape, tuple):
        raise damaged(session, rel, f"has a damaged array header ({key})")
    if dtype.hasobject:
        raise damaged(session, rel, "holds Python objects (a pickle), which the studio never writes and never opens")
    if any(not isinstance(s, int) or s < 0 for s in shape):
        raise damaged(session, rel, f"declares an absurd size ({key}: {shape})")
    n_el = math.prod(shape)
    if expect is not None:
        want_shape, kinds = expect[key]
        if dtype.kind not in kinds or (dtype.kind == "f" and dtype.itemsize not in (4, 8)):
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
    return n_el * dtype.itemsize


def load_demo(path: Path, session: str, entry: DemoEntry) -> Recording:
    """The demonstration in ``path`` as listed by ``entry`` in the manifest, fully validated."""
    rel, n = entry.file, entry.samples
    if n > MAX_SAMPLES or n * DEMO_BYTES_PER_SAMPLE > MAX_DEMO_BYTES:
        raise damaged(
            session,
            rel,
            f"is too large to open ({n:,} samples would take {size_text(n * DEMO_BYTES_PER_SAMPLE)} of memory; "
            f"a demonstration may take {size_text(MAX_DEMO_BYTES)})",
        )
    arrays = read_npz(
        path,
        session,
        rel,
        {"t": ((n,), "f"), "q": ((n, 14), "f"), "gripper": ((n, 2), "f")},
        max_bytes=n * DEMO_BYTES_PER_SAMPLE,
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
    problem = implausible(arrays["t"], arrays["q"])
    if problem is not None:
        raise damaged(session, rel, f"is not a demonstration a robot could make (it {problem})")
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


def _check_texts(arrays: Mapping[str, np.ndarray], session: str, rel: str) -> None:
    """Every text of a skill file (names, and the JSON some of them hold) can be shown on a page
    (docs/decisions/090); else the file is refused, naming the array."""
    for key, a in arrays.items():
        if a.dtype.kind != "U":
            continue
        for text in (str(x) for x in a.reshape(-1)):
            try:
                decoded = json.loads(text) if text.lstrip()[:1] in ("{", "[") else text
            except (ValueError, RecursionError):
                decoded = text
            bad = first_unsendable([text, decoded])
            if bad is not None:
                raise damaged(session, rel, f'has a character that cannot be shown in its "{key}" ({bad[1]})')


def load_skill(path: Path, session: str, rel: str) -> Skill:
    """The learned skill saved in ``path`` (:meth:`Skill.to_arrays`), fully validated."""
    arrays = read_npz(path, session, rel, None, max_bytes=MAX_SKILL_BYTES)
    _check_texts(arrays, session, rel)
    try:
        skill = Skill.from_arrays(arrays)
    except Exception as exc:  # any malformed content: the file is refused, never the studio
        raise damaged(session, rel, f"is not a valid learned skill ({exc})") from exc
    # Preview and the CSV export sample its trajectories over their whole time: a stretched time axis (×10⁶)
    # would make them allocate tens of gigabytes.
    for what, part in (("trajectory", "trajectory"), ("joint trajectory", "joint_trajectory")):
        t = getattr(getattr(skill, part, None), "t", None)
        if t is None:
            continue
        t = np.asarray(t, dtype=np.float64).ravel()
        if len(t) > MAX_SAMPLES or not np.all(np.isfinite(t)) or (len(t) and t[-1] - t[0] > MAX_DURATION_S):
            span = f"{(t[-1] - t[0]) / 3600:,.0f} hours" if len(t) and np.all(np.isfinite(t)) else "no valid time"
            raise damaged(
                session,
                rel,
                f"is not a valid learned skill (its {what} lasts {span}; "
                f"the limit is {MAX_DURATION_S / 3600:.0f} hours)",
            )
    return skill
