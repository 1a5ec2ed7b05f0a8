"""Sessions on disk: one folder per session, a versioned human-readable manifest, array files, no pickle.

Layout of ``<root>/<name>/``::

    session.json          manifest (format "teaching-studio-session", version 1): name, robot, arms,
                          creation time, notes, the ε parameters last used, the number of clusters
                          chosen by hand ("n_clusters": null = automatic; optional), the demos (file, name, arms,
                          samples, duration) and the learned skills (file, when, with which parameters)
    demos/d0001.npz       one demonstration: t (N,) s float64, q (N, 14) rad, gripper (N, 2) percent
    skills/left.npz       a learned skill, Skill.to_arrays() (one file per arm)
    .recording/           the recorder's crash-safe files while recording (not part of the format)

Rules:

* No pickle anywhere: arrays are ``.npz`` read with ``np.load(allow_pickle=False)`` after their headers
  (dtype, shape, sizes) were checked, so a hostile file cannot run code or make the studio allocate
  gigabytes.
* Every write is atomic (temporary file in the same folder, fsync, rename). A demo whose content changes
  (trim) gets a new file; the manifest is switched to it atomically, then the old file is removed, so a crash
  at any moment leaves a loadable session.
* Loading validates everything and raises :class:`SessionFormatError` naming the file and the problem in
  plain words; loading never writes.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import functools
import io
import json
import os
import re
import shutil
import tempfile
import threading
import uuid
import zipfile
import zlib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from studio.core.errors import InvalidInput, SessionFormatError, StudioError
from studio.core.types import ARMS, KeypointParams, Recording

FORMAT = "teaching-studio-session"
FORMAT_VERSION = 1
MANIFEST = "session.json"
DEMO_DIR = "demos"
SKILL_DIR = "skills"
RECORDING_DIR = ".recording"
#: Default folder of the session store: the repository's ``sessions/``.
DEFAULT_ROOT = Path(__file__).resolve().parent.parent / "sessions"

#: Largest demonstration accepted: 6 hours at 1 kHz. Anything larger is treated as a damaged/hostile file.
MAX_SAMPLES = 6 * 3600 * 1000
MAX_MANIFEST_BYTES = 4 * 1024 * 1024
MAX_DEMOS = 1000
#: Largest number of clusters (k) kept with a session.
MAX_CLUSTERS = 10_000
#: Largest uncompressed array accepted inside a skill file (elements).
MAX_SKILL_ELEMENTS = 50_000_000
MAX_ZIP_BYTES = 8 * 1024**3

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9 _\-.()]{0,63}$")
_DEMO_FILE_RE = re.compile(r"^demos/d(\d{4,9})\.npz$")
_SKILL_FILE_RE = re.compile(r"^skills/(left|right)\.npz$")
_PRECISIONS = {"float64": np.float64, "float32": np.float32}


# -- names and messages ------------------------------------------------------------------------------------
def check_session_name(name: str) -> str:
    """Return ``name`` if it is a safe folder name for a session, else raise :class:`InvalidInput`."""
    if not isinstance(name, str) or not _NAME_RE.match(name) or ".." in name or name.endswith((" ", ".")):
        raise InvalidInput(
            f"{name!r} cannot be a session name: use up to 64 letters, digits, spaces, '-', '_', '.' or "
            "brackets, starting with a letter or digit (no '/' and no '..')."
        )
    return name


def check_demo_name(name: str) -> str:
    """A demo name is a label (never a file name): 1–100 printable characters."""
    if not isinstance(name, str):
        raise InvalidInput("A demonstration name must be text.")
    name = name.strip()
    if not name or len(name) > 100 or any(ord(c) < 32 or ord(c) == 127 for c in name):
        raise InvalidInput("A demonstration name must be 1 to 100 printable characters.")
    return name


def _damaged(session: str, rel: str, problem: str) -> SessionFormatError:
    err = SessionFormatError(
        f'The session file "{rel}" of session "{session}" {problem}. It was not loaded; your other files are untouched.'
    )
    err.file = rel  # type: ignore[attr-defined]
    err.problem = problem  # type: ignore[attr-defined]
    return err


def _now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


# -- atomic writes -----------------------------------------------------------------------------------------
def _fsync_dir(d: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(d, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _atomic_write(path: Path, write: Callable[[BinaryIO], object]) -> None:
    """Call ``write`` on a temporary file in ``path``'s folder, fsync it, then rename it onto ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".tmp-{path.name}-", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            os.fchmod(f.fileno(), 0o644)  # mkstemp makes 0600; session files are ordinary documents
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _fsync_dir(path.parent)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: temporary file in the same folder, fsync, rename."""
    _atomic_write(path, lambda f: f.write(data))


def atomic_write_npz(path: Path, arrays: Mapping[str, np.ndarray], *, compress: bool = True) -> None:
    """Save ``arrays`` as an ``.npz`` atomically (never pickled: object arrays are refused)."""
    for k, a in arrays.items():
        if np.asarray(a).dtype.hasobject:
            raise InvalidInput(f"Cannot save {k!r}: it is not a plain numeric array.")
    # streamed into the file: no second copy of the data in memory
    _atomic_write(path, lambda f: _write_npz(f, arrays, compress=compress))


def npz_bytes(arrays: Mapping[str, np.ndarray], *, compress: bool = True) -> bytes:
    """An ``.npz`` (zip of ``.npy``) readable by ``np.load``, byte-for-byte reproducible (see :func:`_write_npz`)."""
    buf = io.BytesIO()
    _write_npz(buf, arrays, compress=compress)
    return buf.getvalue()


def _write_npz(fileobj: Any, arrays: Mapping[str, np.ndarray], *, compress: bool = True) -> None:
    """Write an ``.npz`` readable by ``np.load(allow_pickle=False)`` to ``fileobj``.

    Unlike ``np.savez`` it stamps a fixed date into the zip entries, so regenerating the same arrays gives
    the same file (the example sessions do not churn in version control).
    """
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(fileobj, "w", compression=method, allowZip64=True) as zf:
        for k, v in arrays.items():
            a = np.asarray(v)
            if a.dtype.hasobject:
                raise InvalidInput(f"Cannot save {k!r}: it is not a plain numeric array.")
            info = zipfile.ZipInfo(f"{k}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = method
            info.external_attr = 0o644 << 16
            with zf.open(info, "w", force_zip64=True) as f:
                np.lib.format.write_array(f, a if a.flags.c_contiguous else a.copy(order="C"), allow_pickle=False)


# -- validated npz reading ----------------------------------------------------------------------------------
def _read_npz(
    path: Path,
    session: str,
    rel: str,
    expect: Mapping[str, tuple[tuple[int | None, ...], str]] | None,
    *,
    max_elements: int,
) -> dict[str, np.ndarray]:
    """Read an ``.npz`` safely: members, dtypes, shapes and sizes are checked from the headers first.

    Args:
        expect: member name -> (shape with None for "any length", dtype kinds allowed e.g. "f"); None
            allows any members of numeric/bool/text kinds (skill files).
    """
    if not path.exists():
        raise _damaged(session, rel, "is missing")
    if not path.is_file() or path.is_symlink():
        raise _damaged(session, rel, "is not a regular file")
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except OSError as exc:
        raise _damaged(session, rel, f"cannot be read ({exc.strerror})") from exc
    if head[:2] != b"PK":
        if head[:1] == b"\x80":
            raise _damaged(session, rel, "holds a Python pickle, which the studio never writes and never opens")
        raise _damaged(session, rel, "is not a Teaching Studio array file")
    out: dict[str, np.ndarray] = {}
    try:
        with zipfile.ZipFile(path) as zf:
            infos = zf.infolist()
            names = [i.filename for i in infos]
            if len(names) != len(set(names)) or len(names) > 200:
                raise _damaged(session, rel, "has a suspicious structure")
            members = {n[:-4]: i for n, i in zip(names, infos, strict=True) if n.endswith(".npy")}
            if len(members) != len(names):
                raise _damaged(session, rel, "contains something other than arrays")
            if expect is not None and set(members) != set(expect):
                missing = sorted(set(expect) - set(members))
                extra = sorted(set(members) - set(expect))
                what = f"lacks {', '.join(missing)}" if missing else f"has unexpected parts ({', '.join(extra)})"
                raise _damaged(session, rel, f"is not a valid demonstration file (it {what})")
            for key, info in members.items():
                with zf.open(info) as mf:
                    try:
                        version = np.lib.format.read_magic(mf)
                        if version == (1, 0):
                            shape, _fortran, dtype = np.lib.format.read_array_header_1_0(mf)
                        elif version in ((2, 0), (3, 0)):
                            shape, _fortran, dtype = np.lib.format.read_array_header_2_0(mf)
                        else:
                            raise ValueError("unknown npy version")
                    except ValueError as exc:
                        raise _damaged(session, rel, f"has a damaged array header ({key})") from exc
                if dtype.hasobject:
                    raise _damaged(
                        session, rel, "holds Python objects (a pickle), which the studio never writes and never opens"
                    )
                n_el = int(np.prod(shape, dtype=np.int64)) if shape else 1
                if any(s < 0 for s in shape) or n_el > max_elements:
                    raise _damaged(session, rel, f"declares an absurd size ({key}: {shape})")
                if expect is not None:
                    want_shape, kinds = expect[key]
                    if dtype.kind not in kinds:
                        raise _damaged(session, rel, f"has the wrong kind of numbers in {key} ({dtype})")
                    if len(shape) != len(want_shape) or any(
                        w is not None and w != s for w, s in zip(want_shape, shape, strict=True)
                    ):
                        want = "(" + ", ".join("N" if w is None else str(w) for w in want_shape) + ")"
                        raise _damaged(session, rel, f"has {key} of the wrong shape {tuple(shape)}, expected {want}")
                elif dtype.kind not in "fiubU":
                    raise _damaged(session, rel, f"has an unsupported kind of data in {key} ({dtype})")
                # The declared sizes must agree (guards against zip bombs and against cut-off data).
                if info.file_size > n_el * dtype.itemsize + 65536:
                    raise _damaged(session, rel, f"declares an absurd size ({key})")
                if info.file_size < n_el * dtype.itemsize:
                    raise _damaged(session, rel, f"is damaged (it ends early: {key} is incomplete)")
            with np.load(path, allow_pickle=False) as npz:
                for key in members:
                    out[key] = npz[key]
    except SessionFormatError:
        raise
    except zipfile.BadZipFile as exc:
        raise _damaged(session, rel, "is damaged (it ends early or was cut off)") from exc
    except (EOFError, zipfile.LargeZipFile) as exc:
        raise _damaged(session, rel, "is damaged (it ends early)") from exc
    except zlib.error as exc:
        raise _damaged(session, rel, "is damaged (its data cannot be decompressed)") from exc
    except ValueError as exc:
        if "pickle" in str(exc).lower():
            raise _damaged(session, rel, "holds Python objects (a pickle), which the studio never opens") from exc
        raise _damaged(session, rel, f"is damaged ({exc})") from exc
    except (OSError, RuntimeError) as exc:
        raise _damaged(session, rel, "is damaged (its data cannot be decompressed)") from exc
    return out


def _load_demo(path: Path, session: str, rel: str, entry: Mapping[str, Any]) -> Recording:
    arrays = _read_npz(
        path,
        session,
        rel,
        {"t": ((entry["samples"],), "f"), "q": ((entry["samples"], 14), "f"), "gripper": ((entry["samples"], 2), "f")},
        max_elements=MAX_SAMPLES * 14,
    )
    n = arrays["t"].shape[0]
    if arrays["q"].shape[0] != n or arrays["gripper"].shape[0] != n:
        raise _damaged(session, rel, "has times, joints and grippers of different lengths")
    if n > MAX_SAMPLES:
        raise _damaged(session, rel, f"declares an absurd size ({n} samples)")
    for key, a in arrays.items():
        if not np.all(np.isfinite(a)):
            bad = int(np.count_nonzero(~np.isfinite(a)))
            raise _damaged(session, rel, f"contains {bad} invalid values (NaN or infinity) in {key}")
    if n >= 2 and np.any(np.diff(arrays["t"]) <= 0):
        raise _damaged(session, rel, "has time stamps that do not increase")
    g = arrays["gripper"]
    if np.any(g < -1e-6) or np.any(g > 100 + 1e-6):
        raise _damaged(session, rel, "has gripper openings outside 0–100 %")
    try:
        return Recording(
            t=arrays["t"].astype(np.float64, copy=False),
            q=arrays["q"].astype(np.float64, copy=False),
            gripper=g.astype(np.float64, copy=False),
            arms=tuple(entry["arms"]),
            name=entry["name"],
        )
    except InvalidInput as exc:
        raise _damaged(session, rel, f"is not a valid demonstration ({exc})") from exc


# -- manifest validation ------------------------------------------------------------------------------------
def _parse_manifest(path: Path, session: str) -> dict[str, Any]:
    rel = MANIFEST
    if not path.exists():
        raise _damaged(session, rel, "is missing (this folder is not a Teaching Studio session)")
    try:
        size = path.stat().st_size
        if size > MAX_MANIFEST_BYTES:
            raise _damaged(session, rel, f"is absurdly large ({size} bytes)")
        raw = path.read_bytes()
    except OSError as exc:
        raise _damaged(session, rel, f"cannot be read ({exc.strerror})") from exc
    try:
        m = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise _damaged(session, rel, "is not readable text") from exc
    except json.JSONDecodeError as exc:
        cut = not raw.rstrip().endswith(b"}") or exc.pos >= len(raw.rstrip()) - 1
        problem = "it ends early" if cut else f"unreadable near line {exc.lineno}"
        raise _damaged(session, rel, f"is damaged ({problem})") from exc
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        raise _damaged(session, rel, "is not a Teaching Studio session description")
    v = m.get("version")
    if not isinstance(v, int) or isinstance(v, bool):
        raise _damaged(session, rel, "has no valid format version")
    if v > FORMAT_VERSION:
        raise _damaged(
            session, rel, f"was written by a newer Teaching Studio (format {v}; this one reads format {FORMAT_VERSION})"
        )
    if v < 1:
        raise _damaged(session, rel, f"has an unknown format version {v}")

    def need(key: str, typ: type | tuple[type, ...]) -> Any:
        val = m.get(key)
        if not isinstance(val, typ) or (isinstance(val, bool) and typ is not bool):
            raise _damaged(session, rel, f'has a missing or invalid "{key}"')
        return val

    arms = need("arms", list)
    if not arms or any(a not in ARMS for a in arms) or len(set(arms)) != len(arms):
        raise _damaged(session, rel, 'has invalid "arms" (must be "left" and/or "right")')
    need("name", str)
    need("created", str)
    need("notes", str)
    if need("robot", str) != "baxter":
        raise _damaged(session, rel, f'is for a robot this studio does not know ("{m["robot"]}")')
    try:
        m["_params"] = KeypointParams.from_dict(need("params", dict))
    except (InvalidInput, TypeError, ValueError) as exc:
        raise _damaged(session, rel, f"has invalid key-point thresholds ({exc})") from exc
    try:
        m["_n_clusters"] = _check_n_clusters(m.get("n_clusters"))
    except InvalidInput as exc:
        raise _damaged(session, rel, f'has an invalid "n_clusters" ({exc})') from exc
    prec = m.get("precision", "float64")
    if prec not in _PRECISIONS:
        raise _damaged(session, rel, f'has an unknown "precision" {prec!r}')
    demos = need("demos", list)
    if len(demos) > MAX_DEMOS:
        raise _damaged(session, rel, f"lists an absurd number of demonstrations ({len(demos)})")
    seen: set[str] = set()
    max_id = 0
    for i, d in enumerate(demos):
        if not isinstance(d, dict):
            raise _damaged(session, rel, f"has an invalid entry for demonstration {i + 1}")
        f = d.get("file")
        if not isinstance(f, str) or not _DEMO_FILE_RE.match(f):
            raise _damaged(session, rel, f"names an unsafe or invalid file for demonstration {i + 1}: {f!r}")
        if f in seen:
            raise _damaged(session, rel, f"lists the file {f} twice")
        seen.add(f)
        max_id = max(max_id, int(_DEMO_FILE_RE.match(f).group(1)))  # type: ignore[union-attr]
        try:
            d["name"] = check_demo_name(d.get("name"))  # type: ignore[arg-type]
        except InvalidInput as exc:
            raise _damaged(session, rel, f"has an invalid name for demonstration {i + 1}") from exc
        da = d.get("arms")
        if not isinstance(da, list) or not da or any(a not in ARMS for a in da):
            raise _damaged(session, rel, f"has invalid taught arms for demonstration {i + 1}")
        s = d.get("samples")
        if not isinstance(s, int) or isinstance(s, bool) or not 0 < s <= MAX_SAMPLES:
            raise _damaged(session, rel, f"has an invalid sample count for demonstration {i + 1}")
        if not isinstance(d.get("hidden", False), bool):
            raise _damaged(session, rel, f'has an invalid "hidden" mark for demonstration {i + 1}')
    nid = m.get("next_id", max_id + 1)
    if not isinstance(nid, int) or isinstance(nid, bool) or nid < 1:
        raise _damaged(session, rel, 'has an invalid "next_id"')
    m["next_id"] = max(nid, max_id + 1)
    skills = m.get("skills", {})
    if not isinstance(skills, dict):
        raise _damaged(session, rel, 'has invalid "skills"')
    for arm, s in skills.items():
        if arm not in ARMS or not isinstance(s, dict) or not isinstance(s.get("file"), str):
            raise _damaged(session, rel, f"has an invalid skill entry {arm!r}")
        if not _SKILL_FILE_RE.match(s["file"]) or s["file"] != f"skills/{arm}.npz":
            raise _damaged(session, rel, f"names an unsafe or invalid skill file: {s['file']!r}")
    return m


def _locked(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Serialise a Session mutator (GUI callbacks and the recorder may call from different threads)."""

    @functools.wraps(fn)
    def wrapper(self: Session, *args: Any, **kwargs: Any) -> Any:
        with self._lock:
            return fn(self, *args, **kwargs)

    return wrapper


def _check_n_clusters(k: Any) -> int | None:
    """``k`` if it is a valid hand-chosen number of clusters (or None: automatic), else :class:`InvalidInput`."""
    if k is None:
        return None
    if not isinstance(k, (int, np.integer)) or isinstance(k, bool) or not 1 <= int(k) <= MAX_CLUSTERS:
        raise InvalidInput(f"The number of clusters must be a whole number from 1 to {MAX_CLUSTERS}, or automatic.")
    return int(k)


# -- the session --------------------------------------------------------------------------------------------
@dataclass
class Session:
    """An open session: its demonstrations, parameters and learned skills, bound to its folder.

    Every mutating method writes to disk at once (atomically) and leaves the other files untouched.
    Attributes are for reading; change them through the methods.
    """

    name: str
    path: Path
    arms: tuple[str, ...] = ("left",)
    created: str = field(default_factory=_now)
    notes: str = ""
    params: KeypointParams = field(default_factory=KeypointParams)
    #: k, the number of clusters chosen by hand (None: automatic, the pipeline's default).
    n_clusters: int | None = None
    recordings: list[Recording] = field(default_factory=list)
    #: Names of the demonstrations the teacher hid: they are drawn faintly and left out of learning.
    hidden_demos: set[str] = field(default_factory=set)
    skills: dict[str, Any] = field(default_factory=dict)
    precision: str = "float64"
    skills_stale: bool = False
    skill_info: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: Plain-words notes from loading (skipped damaged files, recovered recordings).
    problems: list[str] = field(default_factory=list)
    recovery_message: str = ""
    _files: list[str] = field(default_factory=list, repr=False)
    _next_id: int = field(default=1, repr=False)
    _lock: threading.RLock = field(default_factory=threading.RLock, repr=False, compare=False)

    # -- reading ------------------------------------------------------------------------------------------
    @property
    def demo_names(self) -> list[str]:
        return [r.name for r in self.recordings]

    @property
    def demo_files(self) -> list[str]:
        """Relative paths of the demo files, in demo order."""
        return list(self._files)

    @property
    def recording_dir(self) -> Path:
        """Folder for the recorder's crash-safe files of this session."""
        return self.path / RECORDING_DIR

    def __len__(self) -> int:
        return len(self.recordings)

    # -- demos --------------------------------------------------------------------------------------------
    def _unique_name(self, name: str) -> str:
        names = set(self.demo_names)
        if name not in names:
            return name
        i = 2
        while True:
            suffix = f" ({i})"
            # Cut the base so that name and suffix stay within the 100-character limit reload enforces.
            candidate = f"{name[: 100 - len(suffix)].rstrip()}{suffix}"
            if candidate not in names:
                return check_demo_name(candidate)
            i += 1

    def _check_index(self, i: int) -> int:
        if not isinstance(i, (int, np.integer)) or not 0 <= int(i) < len(self.recordings):
            raise InvalidInput(f"There is no demonstration number {i}; the session has {len(self.recordings)}.")
        return int(i)

    def _write_demo(self, rec: Recording) -> str:
        rel = f"{DEMO_DIR}/d{self._next_id:04d}.npz"
        self._next_id += 1
        dt = _PRECISIONS[self.precision]
        atomic_write_npz(
            self.path / rel,
            {"t": rec.t, "q": rec.q.astype(dt, copy=False), "gripper": rec.gripper.astype(dt, copy=False)},
        )
        return rel

    def _reload_stored(self, rec: Recording) -> Recording:
        """The recording as it will load back (float32 precision rounds the joints)."""
        if self.precision == "float64":
            return rec
        dt = _PRECISIONS[self.precision]
        return Recording(
            t=rec.t,
            q=rec.q.astype(dt).astype(np.float64),
            gripper=rec.gripper.astype(dt).astype(np.float64),
            arms=rec.arms,
            name=rec.name,
        )

    @_locked
    def add_recording(self, rec: Recording, name: str | None = None) -> int:
        """Add a demonstration (saved at once); returns its index. Names are made unique ("demo (2)")."""
        if not isinstance(rec, Recording):
            raise InvalidInput("Only recordings can be added to a session.")
        if len(rec) < 2:
            raise InvalidInput("A demonstration needs at least two samples.")
        if len(rec) > MAX_SAMPLES:
            raise InvalidInput(
                f"This demonstration is too long to keep ({rec.duration / 3600:.1f} hours); "
                f"the limit is {MAX_SAMPLES // 3_600_000} hours. Trim it first."
            )
        if len(self.recordings) >= MAX_DEMOS:
            raise InvalidInput(f"A session holds at most {MAX_DEMOS} demonstrations.")
        nm = self._unique_name(check_demo_name(name if name is not None else rec.name))
        rec = Recording(t=rec.t, q=rec.q, gripper=rec.gripper, arms=rec.arms, name=nm)
        rel = self._write_demo(rec)
        self.recordings.append(self._reload_stored(rec))
        self._files.append(rel)
        self.skills_stale = bool(self.skills) or self.skills_stale
        self._write_manifest()
        return len(self.recordings) - 1

    @_locked
    def rename_demo(self, i: int, name: str) -> None:
        """Rename demonstration ``i`` (only the manifest changes)."""
        i = self._check_index(i)
        nm = check_demo_name(name)
        if nm != self.recordings[i].name and nm in self.demo_names:
            raise InvalidInput(f'Another demonstration is already called "{nm}".')
        r = self.recordings[i]
        self.recordings[i] = Recording(t=r.t, q=r.q, gripper=r.gripper, arms=r.arms, name=nm)
        if r.name in self.hidden_demos:
            self.hidden_demos = (self.hidden_demos - {r.name}) | {nm}
        self._write_manifest()

    @_locked
    def set_demo_hidden(self, i: int, hidden: bool) -> None:
        """Hide demonstration ``i`` from learning (kept on disk and in the list), or show it again."""
        name = self.recordings[self._check_index(i)].name
        self.hidden_demos = (self.hidden_demos | {name}) if hidden else (self.hidden_demos - {name})
        self._write_manifest()

    @_locked
    def delete_demo(self, i: int) -> None:
        """Delete demonstration ``i``: the manifest stops listing it first, then its file is removed."""
        i = self._check_index(i)
        rel = self._files.pop(i)
        self.hidden_demos = self.hidden_demos - {self.recordings.pop(i).name}
        self.skills_stale = bool(self.skills) or self.skills_stale
        self._write_manifest()
        with contextlib.suppress(FileNotFoundError):
            (self.path / rel).unlink()

    @_locked
    def trim_demo(self, i: int, t0: float, t1: float) -> None:
        """Keep only the samples of demonstration ``i`` with t0 ≤ t ≤ t1 (seconds); times restart at 0."""
        i = self._check_index(i)
        r = self.recordings[i]
        if not (np.isfinite(t0) and np.isfinite(t1)) or t1 <= t0:
            raise InvalidInput("To trim, choose a start time before the end time.")
        keep = (r.t >= t0 - 1e-9) & (r.t <= t1 + 1e-9)
        if np.count_nonzero(keep) < 2:
            raise InvalidInput("Trimming would leave fewer than two samples; choose a wider range.")
        new = Recording(t=r.t[keep] - r.t[keep][0], q=r.q[keep], gripper=r.gripper[keep], arms=r.arms, name=r.name)
        rel = self._write_demo(new)
        old = self._files[i]
        self._files[i] = rel
        self.recordings[i] = self._reload_stored(new)
        self.skills_stale = bool(self.skills) or self.skills_stale
        self._write_manifest()
        with contextlib.suppress(FileNotFoundError):
            (self.path / old).unlink()

    @_locked
    def trim_idle(self, i: int, **kwargs: Any) -> tuple[float, float]:
        """Cut the idle start and end of demonstration ``i`` (see :func:`idle_bounds`); returns (t0, t1) used."""
        i = self._check_index(i)
        t0, t1 = idle_bounds(self.recordings[i], **kwargs)
        r = self.recordings[i]
        if t0 > r.t[0] + 1e-9 or t1 < r.t[-1] - 1e-9:
            self.trim_demo(i, t0, t1)
        return t0, t1

    # -- parameters, notes, skills ------------------------------------------------------------------------
    @_locked
    def set_params(self, params: KeypointParams) -> None:
        if not isinstance(params, KeypointParams):
            raise InvalidInput("Key-point thresholds must be a KeypointParams.")
        self.params = params
        self._write_manifest()

    @_locked
    def set_n_clusters(self, k: int | None) -> None:
        """Remember k, the number of clusters chosen by hand (None: choose it automatically)."""
        self.n_clusters = _check_n_clusters(k)
        self._write_manifest()

    @_locked
    def set_notes(self, notes: str) -> None:
        if not isinstance(notes, str) or len(notes) > 100_000:
            raise InvalidInput("Notes must be text of at most 100,000 characters.")
        self.notes = notes
        self._write_manifest()

    @_locked
    def set_arms(self, arms: Iterable[str]) -> None:
        a = tuple(x for x in ARMS if x in set(arms))
        if not a:
            raise InvalidInput('Choose the taught arm(s): "left", "right" or both.')
        self.arms = a
        self._write_manifest()

    @_locked
    def set_skills(
        self,
        skills: Mapping[str, Any],
        params: KeypointParams | None = None,
        demos: Iterable[str] | Mapping[str, Iterable[str]] | None = None,
    ) -> None:
        """Save learned skills (arm -> Skill, each with ``to_arrays()``), replacing the previous ones.

        Args:
            params: the thresholds they were learned with (also become the session's parameters).
            demos: names of the demonstrations they were learned from: one list for every arm, or a mapping
                arm -> names (default: all of the session's).
        """
        for arm in skills:
            if arm not in ARMS:
                raise InvalidInput(f'Unknown arm "{arm}" for a skill.')
        if isinstance(demos, Mapping):
            per_arm = {arm: list(demos.get(arm, self.demo_names)) for arm in skills}
        else:
            names = list(demos) if demos is not None else self.demo_names
            per_arm = {arm: list(names) for arm in skills}
        for arm, sk in skills.items():
            atomic_write_npz(self.path / SKILL_DIR / f"{arm}.npz", dict(sk.to_arrays()))
        old = set(self.skills) - set(skills)
        if params is not None:
            self.params = params
        self.skills = dict(skills)
        self.skill_info = {
            arm: {
                "file": f"{SKILL_DIR}/{arm}.npz",
                "learned": _now(),
                "params": self.params.as_dict(),
                "demos": per_arm[arm],
            }
            for arm in skills
        }
        self.skills_stale = False
        self._write_manifest()
        for arm in old:
            with contextlib.suppress(FileNotFoundError):
                (self.path / SKILL_DIR / f"{arm}.npz").unlink()

    # -- manifest -----------------------------------------------------------------------------------------
    def manifest(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "name": self.name,
            "robot": "baxter",
            "arms": list(self.arms),
            "created": self.created,
            "modified": _now(),
            "notes": self.notes,
            "params": self.params.as_dict(),
            "n_clusters": self.n_clusters,
            "precision": self.precision,
            "next_id": self._next_id,
            "demos": [
                {
                    "file": f,
                    "name": r.name,
                    "arms": list(r.arms),
                    "samples": len(r),
                    "duration": round(r.duration, 6),
                    "hidden": r.name in self.hidden_demos,
                }
                for f, r in zip(self._files, self.recordings, strict=True)
            ],
            "skills": self.skill_info,
            "skills_stale": self.skills_stale,
        }

    def _write_manifest(self) -> None:
        data = json.dumps(self.manifest(), indent=2, ensure_ascii=False).encode("utf-8") + b"\n"
        atomic_write_bytes(self.path / MANIFEST, data)


# -- loading ------------------------------------------------------------------------------------------------
def _skill_class() -> Any:
    from studio.core import types

    return getattr(types, "Skill", None)


def _skipped_note(exc: SessionFormatError) -> str:
    """The message of a damaged file that ``skip_damaged`` passed over, told as skipped."""
    return str(exc).replace(" It was not loaded; your other files are untouched.", " It was skipped.")


def load_session(path: Path, *, skip_damaged: bool = False) -> Session:
    """Load and validate the session in folder ``path`` (never writes).

    Args:
        skip_damaged: load what is valid and list the damaged demo/skill files in ``session.problems``
            instead of raising (the manifest itself must be valid).

    Raises:
        SessionFormatError: a file is missing, damaged, of another version, or hostile.
    """
    path = Path(path)
    name = path.name
    m = _parse_manifest(path / MANIFEST, name)
    s = Session(
        name=name,
        path=path,
        arms=tuple(m["arms"]),
        created=m["created"],
        notes=m["notes"],
        params=m["_params"],
        n_clusters=m["_n_clusters"],
        precision=m.get("precision", "float64"),
        skills_stale=bool(m.get("skills_stale", False)),
    )
    s._next_id = m["next_id"]
    for entry in m["demos"]:
        rel = entry["file"]
        try:
            rec = _load_demo(path / rel, name, rel, entry)
        except SessionFormatError as exc:
            if not skip_damaged:
                raise
            s.problems.append(_skipped_note(exc))
            continue
        s.recordings.append(rec)
        s._files.append(rel)
        if entry.get("hidden", False):
            s.hidden_demos.add(rec.name)
    Skill = _skill_class()
    for arm, info in m.get("skills", {}).items():
        rel = info["file"]
        try:
            arrays = _read_npz(path / rel, name, rel, None, max_elements=MAX_SKILL_ELEMENTS)
            if Skill is None:
                raise _damaged(name, rel, "cannot be read by this version of the studio (no skill support)")
            try:
                skill = Skill.from_arrays(arrays)
            except (StudioError, ValueError, KeyError, TypeError, IndexError) as exc:
                raise _damaged(name, rel, f"is not a valid learned skill ({exc})") from exc
        except SessionFormatError as exc:
            if not skip_damaged:
                raise
            s.problems.append(_skipped_note(exc))
            continue
        s.skills[arm] = skill
        s.skill_info[arm] = info
    if len(s.recordings) != len(m["demos"]):
        s.skills_stale = bool(s.skills) or s.skills_stale
    return s


# -- the store ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SessionSummary:
    """What the session picker shows, read from the manifest only."""

    name: str
    demos: int
    arms: tuple[str, ...]
    created: str
    notes: str
    skills: tuple[str, ...]


class SessionStore:
    """All sessions under ``root`` (default: the repository's ``sessions/`` folder)."""

    def __init__(self, root: str | os.PathLike[str] | None = None) -> None:
        self.root = Path(root) if root is not None else DEFAULT_ROOT

    def path_of(self, name: str) -> Path:
        return self.root / check_session_name(name)

    def exists(self, name: str) -> bool:
        return (self.path_of(name) / MANIFEST).is_file()

    def list_sessions(self) -> list[str]:
        """Names of the sessions (folders with a manifest), sorted."""
        if not self.root.is_dir():
            return []
        out = []
        for p in sorted(self.root.iterdir()):
            if p.is_dir() and not p.is_symlink() and _NAME_RE.match(p.name) and (p / MANIFEST).is_file():
                out.append(p.name)
        return out

    def summaries(self) -> list[SessionSummary]:
        """One summary per session whose manifest is valid (damaged ones are left out)."""
        out = []
        for n in self.list_sessions():
            try:
                m = _parse_manifest(self.root / n / MANIFEST, n)
            except SessionFormatError:
                continue
            out.append(
                SessionSummary(n, len(m["demos"]), tuple(m["arms"]), m["created"], m["notes"], tuple(m["skills"]))
            )
        return out

    def pending_recoveries(self) -> list[str]:
        """Sessions that hold recordings interrupted by a crash (recovered when the session is opened)."""
        from studio.recorder import pending_recordings

        return [n for n in self.list_sessions() if pending_recordings(self.root / n / RECORDING_DIR)]

    def create(
        self,
        name: str,
        *,
        arms: Iterable[str] = ("left",),
        notes: str = "",
        params: KeypointParams | None = None,
        precision: str = "float64",
    ) -> Session:
        """Create an empty session (error if one of that name exists)."""
        path = self.path_of(name)
        if path.exists():
            raise InvalidInput(f'A session called "{name}" already exists; choose another name.')
        if precision not in _PRECISIONS:
            raise InvalidInput(f"Precision must be one of {', '.join(_PRECISIONS)}.")
        a = tuple(x for x in ARMS if x in set(arms))
        if not a:
            raise InvalidInput('Choose the taught arm(s): "left", "right" or both.')
        path.mkdir(parents=True)
        s = Session(name=name, path=path, arms=a, notes=notes, params=params or KeypointParams(), precision=precision)
        s._write_manifest()
        return s

    def open(self, name: str, *, recover: bool = True, skip_damaged: bool = False) -> Session:
        """Load a session; with ``recover``, recordings interrupted by a crash are added back first.

        The recovery message (if any) is in ``session.recovery_message``.
        """
        path = self.path_of(name)
        if not path.is_dir():
            raise SessionFormatError(f'There is no session called "{name}" in {self.root}.')
        s = load_session(path, skip_damaged=skip_damaged)
        if recover and (path / RECORDING_DIR).is_dir():
            from studio.recorder import recover_recordings

            _, msg = recover_recordings(path / RECORDING_DIR, session=s)
            s.recovery_message = msg
        return s

    def save(self, session: Session) -> None:
        """Write the whole session (manifest and any missing demo files) to its folder atomically."""
        with session._lock:
            self._save(session)

    def _save(self, session: Session) -> None:
        session.path.mkdir(parents=True, exist_ok=True)
        dt = _PRECISIONS[session.precision]
        for i, r in enumerate(session.recordings):
            if i >= len(session._files) or not (session.path / session._files[i]).exists():
                rel = f"{DEMO_DIR}/d{session._next_id:04d}.npz"
                session._next_id += 1
                atomic_write_npz(session.path / rel, {"t": r.t, "q": r.q.astype(dt), "gripper": r.gripper.astype(dt)})
                if i < len(session._files):
                    session._files[i] = rel
                else:
                    session._files.append(rel)
        session._write_manifest()

    def delete(self, name: str) -> None:
        """Delete a session folder and everything in it."""
        path = self.path_of(name)
        if not (path / MANIFEST).is_file():
            raise InvalidInput(f'There is no session called "{name}".')
        shutil.rmtree(path)

    def _free_name(self, name: str) -> str:
        if not self.path_of(name).exists():
            return name
        i = 2
        while True:
            cand = f"{name[:58]} ({i})"
            if not self.path_of(cand).exists():
                return cand
            i += 1

    def duplicate(self, name: str, new_name: str) -> Session:
        """Copy a session (not its in-progress recordings) under a new name; returns the copy."""
        src = self.path_of(name)
        dst = self.path_of(new_name)
        if dst.exists():
            raise InvalidInput(f'A session called "{new_name}" already exists; choose another name.')
        load_session(src)  # only valid sessions are copied
        tmp = self.root / f".tmp-copy-{uuid.uuid4().hex[:8]}"
        try:
            shutil.copytree(src, tmp, ignore=shutil.ignore_patterns(RECORDING_DIR, ".tmp-*"))
            s = load_session(tmp)
            s.name = new_name
            s.created = _now()
            s._write_manifest()
            os.rename(tmp, dst)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
        return load_session(dst)

    def export_zip(self, name: str) -> bytes:
        """The session as a zip archive (manifest, demos, skills) for download or sharing."""
        s = load_session(self.path_of(name))  # only export what loads
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
            zf.write(s.path / MANIFEST, f"{name}/{MANIFEST}")
            for rel in s._files:
                zf.write(s.path / rel, f"{name}/{rel}")
            for info in s.skill_info.values():
                zf.write(s.path / info["file"], f"{name}/{info['file']}")
        return buf.getvalue()

    def import_zip(self, data: bytes, name: str | None = None, *, archive: str | None = None) -> str:
        """Add a session from a zip made by :meth:`export_zip`; returns its (possibly renamed) name.

        The archive is checked (safe member names, sizes), unpacked into a temporary folder, loaded with full
        validation, and only then moved into place; on any problem nothing is added. ``archive`` is the
        uploaded file's name, used in messages.
        """
        try:
            zf = zipfile.ZipFile(io.BytesIO(data))
        except zipfile.BadZipFile as exc:
            raise SessionFormatError(
                "The uploaded file is not a session archive (.zip). Nothing was imported."
            ) from exc
        with zf:
            infos = zf.infolist()
            if not infos or len(infos) > MAX_DEMOS + 10:
                raise SessionFormatError(
                    "The archive does not look like a Teaching Studio session. Nothing was imported."
                )
            tops = {i.filename.split("/", 1)[0] for i in infos}
            if len(tops) != 1:
                raise SessionFormatError("The archive must hold exactly one session folder. Nothing was imported.")
            top = tops.pop()
            total = 0
            for i in infos:
                fn = i.filename
                rel = fn[len(top) + 1 :]
                mode = (i.external_attr >> 16) & 0o170000
                if (
                    fn.startswith("/")
                    or "\\" in fn
                    or ".." in fn.split("/")
                    or mode == 0o120000
                    or not (rel == MANIFEST or _DEMO_FILE_RE.match(rel) or _SKILL_FILE_RE.match(rel) or i.is_dir())
                ):
                    raise SessionFormatError(
                        f'The archive contains an unexpected or unsafe entry "{fn}". Nothing was imported.'
                    )
                total += i.file_size
            if total > MAX_ZIP_BYTES:
                raise SessionFormatError("The archive is absurdly large once unpacked. Nothing was imported.")
            label = f'The archive "{archive}"' if archive else f'The archive of session "{top}"'
            self.root.mkdir(parents=True, exist_ok=True)
            tmp_root = self.root / f".tmp-import-{uuid.uuid4().hex[:8]}"
            tmp = tmp_root / _sanitize(top)  # messages from loading name the session, not the temporary folder
            tmp.mkdir(parents=True)
            try:
                for i in infos:
                    if i.is_dir():
                        continue
                    rel = i.filename[len(top) + 1 :]
                    dest = tmp / rel
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    try:
                        with zf.open(i) as src, open(dest, "wb") as out:
                            shutil.copyfileobj(src, out)
                    except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError) as exc:
                        raise SessionFormatError(
                            f'{label} is damaged (the file "{i.filename}" inside it cannot be read). '
                            "Nothing was imported."
                        ) from exc
                try:
                    s = load_session(tmp)
                except SessionFormatError as exc:
                    problem = str(exc).replace(" It was not loaded; your other files are untouched.", "")
                    raise SessionFormatError(f"{label} cannot be imported. {problem} Nothing was imported.") from exc
                final = self._free_name(check_session_name(name or _sanitize(top)))
                s.name = final
                s._write_manifest()
                os.rename(tmp, self.path_of(final))
            finally:
                if tmp_root.exists():
                    shutil.rmtree(tmp_root, ignore_errors=True)
        return final


def _sanitize(name: str) -> str:
    out = re.sub(r"[^A-Za-z0-9 _\-.()]", "_", name).strip(" .")
    out = out.replace("..", "_")
    if not out or not out[0].isalnum():
        out = "imported" + (f"-{out}" if out else "")
    return out[:64]


# -- idle detection ------------------------------------------------------------------------------------------
def idle_bounds(
    rec: Recording, *, threshold: float = 0.01, gripper_threshold: float = 1.0, margin: float = 0.2
) -> tuple[float, float]:
    """Times (t0, t1) between which the taught arm(s) move: the idle start and end are outside.

    The arm is idle while every joint of the taught arms stays within ``threshold`` rad of its pose at the
    start (or at the end) and the gripper within ``gripper_threshold`` percent. Robust to sensor noise of a
    few milliradians (displacement, not speed, is tested). ``margin`` seconds of idle are kept on each side.
    """
    cols = np.concatenate([np.arange(7) if a == "left" else np.arange(7, 14) for a in rec.arms])
    gcols = [0 if a == "left" else 1 for a in rec.arms]
    q = rec.q[:, cols]
    g = rec.gripper[:, gcols]
    n = len(rec)
    if n < 2:
        return float(rec.t[0]), float(rec.t[-1])
    w = max(1, min(n, int(0.1 * n / max(rec.duration, 1e-9))))  # ~100 ms reference window

    def first_move(qq: np.ndarray, gg: np.ndarray) -> int:
        ref_q = np.median(qq[:w], axis=0)
        ref_g = np.median(gg[:w], axis=0)
        moved = np.any(np.abs(qq - ref_q) > threshold, axis=1) | np.any(np.abs(gg - ref_g) > gripper_threshold, axis=1)
        return int(np.argmax(moved)) if moved.any() else n

    i0 = first_move(q, g)
    if i0 >= n:  # never moves: nothing to cut
        return float(rec.t[0]), float(rec.t[-1])
    i1 = n - 1 - first_move(q[::-1], g[::-1])
    t0 = max(float(rec.t[0]), float(rec.t[i0]) - margin)
    t1 = min(float(rec.t[-1]), float(rec.t[i1]) + margin)
    return t0, t1


__all__ = [
    "DEFAULT_ROOT",
    "FORMAT_VERSION",
    "Session",
    "SessionStore",
    "SessionSummary",
    "atomic_write_bytes",
    "atomic_write_npz",
    "check_demo_name",
    "check_session_name",
    "idle_bounds",
    "load_session",
    "npz_bytes",
]
