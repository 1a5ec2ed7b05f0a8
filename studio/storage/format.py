"""The session format's fixed points: file names, limits, name rules, and how a damaged file is worded.

Everything else in :mod:`studio.storage` reads these; change a limit here and it holds everywhere.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import numbers
import re
import unicodedata
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.errors import InvalidInput, SessionFormatError
from studio.core.sampling import MAX_SECONDS
from studio.core.text import first_unsendable

FORMAT = "teaching-studio-session"
#: Version of the manifest written today; see :mod:`studio.storage.manifest` for how it is extended.
#: 2: the task scene and each demonstration's object events (a studio of version 1 would drop them).
FORMAT_VERSION = 3
MANIFEST = "session.json"
DEMO_DIR = "demos"
SKILL_DIR = "skills"
#: The recorder's crash-safe files while recording (inside the session folder, not part of the format).
RECORDING_DIR = ".recording"
#: Demonstration files found in the session folder but not in its list, moved aside on opening (never deleted).
RECOVERED_DIR = "recovered"
#: The one place that knows where sessions live by default: the repository's ``sessions/`` folder.
DEFAULT_ROOT = Path(__file__).resolve().parent.parent.parent / "sessions"
#: The examples bundled in :data:`DEFAULT_ROOT` (``studio make-examples``): the studio opens them read-only there.
EXAMPLE_SESSIONS: tuple[str, ...] = ("stack-cup", "pick-place")

# -- limits: bytes, counted from what a file declares, checked before anything is read or unpacked ------------
#: Longest demonstration accepted: 1 hour at 1 kHz (the recorder stops by itself at 1 hour). The limits below
#: keep the studio within 2 GB of memory whatever it is given (docs/decisions/051-memory-budget.md).
MAX_SAMPLES = 3600 * 1000
#: Most samples a manifest may list for one demonstration (earlier studios kept 6 hours): a longer one listed
#: is a damaged manifest; one between this and MAX_SAMPLES is refused (or skipped) when it is opened.
MAX_LISTED_SAMPLES = 6 * 3600 * 1000
#: Longest demonstration or learned trajectory, seconds (whatever the sampling rate; Preview and export too).
MAX_DURATION_S = MAX_SECONDS
#: Shortest mean (and median) sampling interval, seconds (a 100 kHz stream; robots stream at 1 kHz at most).
MIN_TIME_STEP_S = 1e-5
#: Largest joint angle accepted, radians (Baxter's joints turn less than ±3.1 rad; a full turn either way).
MAX_JOINT_RAD = 2 * math.pi
#: Bytes a demonstration takes in memory per sample: t, 14 joints, 2 grippers as float64.
DEMO_BYTES_PER_SAMPLE = 17 * 8
#: Largest demonstration in memory (≈ 66 minutes at 1 kHz), and largest session (demonstrations and skills).
MAX_DEMO_BYTES = 512 * 1024**2
MAX_SESSION_BYTES = 768 * 1024**2
#: Samples of all shown demonstrations together that the studio derives poses, key-points and skills from;
#: beyond it every n-th sample is used (the recordings themselves stay whole).
WORK_SAMPLES = 1_000_000
#: Largest learned skill file's arrays (bytes, as declared by its headers).
MAX_SKILL_BYTES = 2 * 1024**3
MAX_MANIFEST_BYTES = 4 * 1024 * 1024
MAX_DEMOS = 1000
#: Largest number of clusters (k) kept with a session.
MAX_CLUSTERS = 10_000
#: Largest number of a demo file (``demos/d<id>.npz`` has 4 to 9 digits).
MAX_FILE_ID = 999_999_999
MAX_NOTES_CHARS = 100_000
#: Uploaded archives (someone else's files): what unpacking may write to disk, and what loading may take in
#: memory, for each byte uploaded, beyond a floor that any ordinary session stays under.
ARCHIVE_DISK_PER_BYTE = 4
ARCHIVE_DISK_FLOOR = 16 * 1024**2
ARCHIVE_MEMORY_PER_BYTE = 32
ARCHIVE_MEMORY_FLOOR = 64 * 1024**2
#: Disk space left free after any write the studio plans (bytes).
DISK_RESERVE = 8 * 1024**2

#: Longest demonstration name (characters).
MAX_NAME_CHARS = 100
#: Unicode categories a typed name may not hold (see :func:`invisible`).
_INVISIBLE = frozenset({"Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp"})

# Names and files. Every pattern is matched whole (``fullmatch``): "$" would accept a trailing newline.
NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9 _\-.()]{0,63}")
DEMO_FILE_RE = re.compile(r"demos/d(\d{4,9})\.npz")
SKILL_FILE_RE = re.compile(r"skills/(left|right)\.npz")
PRECISIONS: dict[str, type[np.floating]] = {"float64": np.float64, "float32": np.float32}

_NOT_LOADED = "It was not loaded; your other files are untouched."


def now() -> str:
    """The current time as the manifest stores it (UTC, ISO 8601, seconds)."""
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def check_session_name(name: str) -> str:
    """Return ``name`` if it is a safe folder name for a session, else raise :class:`InvalidInput`."""
    if not isinstance(name, str) or not NAME_RE.fullmatch(name) or ".." in name or name.endswith((" ", ".")):
        raise InvalidInput(
            f"{shown(name)} cannot be a session name: use up to 64 letters, digits, spaces, '-', '_', '.' or "
            "brackets, starting with a letter or digit (no '/' and no '..')."
        )
    return name


def check_demo_name(name: object, *, typed: bool = True) -> str:
    """A demo name is a label (never a file name): 1–100 printable characters; a name given now (``typed``,
    not one read from an existing session) also holds no invisible ones (:func:`invisible`)."""
    if not isinstance(name, str):
        raise InvalidInput("A demonstration name must be text.")
    name = name.strip()
    if not name or len(name) > MAX_NAME_CHARS or any(ord(c) < 32 or ord(c) == 127 for c in name):
        raise InvalidInput(f"A demonstration name must be 1 to {MAX_NAME_CHARS} printable characters.")
    if typed and invisible(name):
        raise InvalidInput(
            "A demonstration name may not hold invisible characters (such as right-to-left marks or zero-width "
            "spaces), which make it look like another name. Type it again with letters, digits and punctuation."
        )
    return name


def invisible(text: str) -> bool:
    """Whether ``text`` holds a character that is not shown as itself: controls, format characters (bidi
    overrides and isolates, zero-width ones), line and paragraph separators, private-use or unassigned ones."""
    return any(unicodedata.category(c) in _INVISIBLE for c in text)


def shown(text: object, limit: int = 60) -> str:
    """``text`` quoted for a message or a log line: at most ``limit`` characters, invisible ones escaped."""
    s = str(text)
    cut = s[:limit]
    out = "".join(c if unicodedata.category(c) not in _INVISIBLE else f"\\u{ord(c):04x}" for c in cut)
    return f'"{out}{"…" if len(s) > limit else ""}"'


def check_n_clusters(k: object) -> int | None:
    """``k`` if it is a valid hand-chosen number of clusters (or None: automatic), else :class:`InvalidInput`."""
    if k is None:
        return None
    if not isinstance(k, (int, np.integer)) or isinstance(k, bool) or not 1 <= int(k) <= MAX_CLUSTERS:
        raise InvalidInput(f"The number of clusters must be a whole number from 1 to {MAX_CLUSTERS}, or automatic.")
    return int(k)


def sanitize_name(name: str) -> str:
    """A safe session name made from any text (an archive's folder name)."""
    out = re.sub(r"[^A-Za-z0-9 _\-.()]", "_", name).strip(" .")
    out = out.replace("..", "_")
    if not out or not out[0].isalnum():
        out = "imported" + (f"-{out}" if out else "")
    return out[:64]


# -- wording of a damaged file ------------------------------------------------------------------------------
def describe(session: str, file: str, problem: str) -> str:
    """'The session file "<file>" of session "<session>" <problem>.' — the sentence every message starts with."""
    return f'The session file "{file}" of session "{session}" {problem}.'


def damaged(session: str, file: str, problem: str) -> SessionFormatError:
    """The error for one damaged file of a session, with ``file`` and ``problem`` as fields."""
    return SessionFormatError(
        f"{describe(session, file, problem)} {_NOT_LOADED}", session=session, file=file, problem=problem
    )


def what_went_wrong(exc: SessionFormatError) -> str:
    """The problem of ``exc`` without the closing "It was not loaded…" (to wrap it in another message)."""
    if exc.file is not None and exc.session is not None and exc.problem is not None:
        return describe(exc.session, exc.file, exc.problem)
    return str(exc)


def skipped_note(exc: SessionFormatError) -> str:
    """The message of a damaged file that loading with ``skip_damaged`` passed over, told as skipped."""
    return f"{what_went_wrong(exc)} It was skipped."


def implausible(t: np.ndarray, q: np.ndarray) -> str | None:
    """What makes a demonstration's times ``t`` (N,) s or joints ``q`` (N, 14) rad impossible for a robot, in plain
    words ("lasts 9.3 hours; …"), or None. Such values pass as numbers but make learning overflow or never end.

    The sampling interval is judged by its mean and median (what learning divides by), not by the closest two
    samples: a real stream has jitter, and one pair of samples a microsecond apart harms nothing.
    """
    if len(t) >= 2:
        duration = float(t[-1] - t[0])
        if duration > MAX_DURATION_S:
            return f"lasts {duration / 3600:,.1f} hours; the limit is {MAX_DURATION_S / 3600:.0f} hours"
        step = min(duration / (len(t) - 1), float(np.median(np.diff(t))))
        if step < MIN_TIME_STEP_S:
            return (
                f"has its samples {step:.3g} s apart; a robot streams at most {1 / MIN_TIME_STEP_S:,.0f} samples "
                "a second (times are in seconds)"
            )
    if q.size:
        worst = max(abs(float(np.max(q))), abs(float(np.min(q))))  # no |q| temporary: q may be 2 GB
        if worst > MAX_JOINT_RAD:
            return f"has a joint angle of {worst:.3g} rad, more than a full turn (joint angles are in radians)"
    return None


def recovered_note(n: int, folder: Path) -> str:
    """What the teacher is told when opening moved ``n`` unlisted demonstration files into ``folder``."""
    were, they = ("was", "it is") if n == 1 else ("were", "they are")
    s = "" if n == 1 else "s"
    return (
        f'{n} recording{s} {were} not in the session list; {they} in Recovered (the folder "{folder}"). '
        "Nothing was deleted."
    )


def unique_name(name: str, taken: set[str]) -> str:
    """``name``, or ``name (2)``, ``name (3)``… whichever is not ``taken``, within the 100-character limit."""
    if name not in taken:
        return name
    i = 2
    while True:
        suffix = f" ({i})"
        # Cut the base so that name and suffix stay within the 100-character limit reload enforces.
        candidate = f"{name[: 100 - len(suffix)].rstrip()}{suffix}"
        if candidate not in taken:
            return check_demo_name(candidate, typed=False)
        i += 1


class _KeyTwice(ValueError):
    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _once(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object whose keys are all different (JSON itself would silently keep the last of two)."""
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise _KeyTwice(k)
        out[k] = v
    return out


def decode_manifest(raw: bytes, session: str) -> dict[str, Any]:
    """The manifest's JSON object, or a plain-words :class:`SessionFormatError` for each way it can be damaged
    (a key written twice included: which of the two is right cannot be told)."""
    try:
        m = json.loads(raw.decode("utf-8"), object_pairs_hook=_once)
    except _KeyTwice as exc:
        shown = exc.key if len(exc.key) <= 40 else exc.key[:37] + "..."
        raise damaged(
            session, MANIFEST, f'has the entry "{shown}" twice (a hand edit or a copy that went wrong?)'
        ) from exc
    except UnicodeDecodeError as exc:
        raise damaged(session, MANIFEST, "is not readable text") from exc
    except RecursionError as exc:
        raise damaged(session, MANIFEST, "is damaged (it is nested too deeply to be a session description)") from exc
    except json.JSONDecodeError as exc:
        cut = not raw.rstrip().endswith(b"}") or exc.pos >= len(raw.rstrip()) - 1
        problem = "it ends early" if cut else f"unreadable near line {exc.lineno}"
        raise damaged(session, MANIFEST, f"is damaged ({problem})") from exc
    except ValueError as exc:  # e.g. a number of more than 4300 digits
        raise damaged(session, MANIFEST, "is damaged (it holds an impossible number)") from exc
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        raise damaged(session, MANIFEST, "is not a Teaching Studio session description")
    bad = first_unsendable(m)
    if bad is not None:  # a page could not show it (docs/decisions/090): refused here, never half shown
        raise damaged(session, MANIFEST, f"has a character that cannot be shown in {field_words(bad[0])} ({bad[1]})")
    return m


def field_words(path: tuple[str | int, ...]) -> str:
    """Where in a manifest the JSON ``path`` (keys and indices) is, in words: "the name of demonstration 3"."""
    if len(path) >= 3 and path[0] == "demos" and isinstance(path[1], int):
        entry = f"demonstration {path[1] + 1}"
        return f"the name of {entry}" if path[2:] == ("name",) else f"the entry {_dotted(path[2:])} of {entry}"
    words: dict[tuple[str | int, ...], str] = {("notes",): "the session's notes", ("name",): "the session's name"}
    return words.get(path, f"the entry {_dotted(path)}")


def _dotted(path: tuple[str | int, ...]) -> str:
    return shown("".join(f"[{k}]" if isinstance(k, int) else f".{k}" for k in path).lstrip("."))


def finite_number(v: object) -> float | None:
    """``v`` as a finite float, or None (not a number, a bool, or too large for a float)."""
    if not isinstance(v, numbers.Real) or isinstance(v, bool):
        return None
    try:
        f = float(v)
    except (OverflowError, ValueError):
        return None
    return f if math.isfinite(f) else None
