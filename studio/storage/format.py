"""The session format's fixed points: file names, limits, name rules, and how a damaged file is worded.

Everything else in :mod:`studio.storage` reads these; change a limit here and it holds everywhere.
"""

from __future__ import annotations

import datetime as _dt
import re
from pathlib import Path

import numpy as np

from studio.core.errors import InvalidInput, SessionFormatError

FORMAT = "teaching-studio-session"
#: Version of the manifest written today; see :mod:`studio.storage.manifest` for how it is extended.
#: 2: the task scene and each demonstration's object events (a studio of version 1 would drop them).
FORMAT_VERSION = 2
MANIFEST = "session.json"
DEMO_DIR = "demos"
SKILL_DIR = "skills"
#: The recorder's crash-safe files while recording (inside the session folder, not part of the format).
RECORDING_DIR = ".recording"
#: The one place that knows where sessions live by default: the repository's ``sessions/`` folder.
DEFAULT_ROOT = Path(__file__).resolve().parent.parent.parent / "sessions"

#: Largest demonstration accepted: 6 hours at 1 kHz. Anything larger is treated as a damaged/hostile file.
MAX_SAMPLES = 6 * 3600 * 1000
MAX_MANIFEST_BYTES = 4 * 1024 * 1024
MAX_DEMOS = 1000
#: Largest number of clusters (k) kept with a session.
MAX_CLUSTERS = 10_000
#: Largest uncompressed array accepted inside a skill file (elements).
MAX_SKILL_ELEMENTS = 50_000_000
MAX_ZIP_BYTES = 8 * 1024**3
MAX_NOTES_CHARS = 100_000

NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9 _\-.()]{0,63}$")
DEMO_FILE_RE = re.compile(r"^demos/d(\d{4,9})\.npz$")
SKILL_FILE_RE = re.compile(r"^skills/(left|right)\.npz$")
PRECISIONS: dict[str, type[np.floating]] = {"float64": np.float64, "float32": np.float32}

_NOT_LOADED = "It was not loaded; your other files are untouched."


def now() -> str:
    """The current time as the manifest stores it (UTC, ISO 8601, seconds)."""
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def check_session_name(name: str) -> str:
    """Return ``name`` if it is a safe folder name for a session, else raise :class:`InvalidInput`."""
    if not isinstance(name, str) or not NAME_RE.match(name) or ".." in name or name.endswith((" ", ".")):
        raise InvalidInput(
            f"{name!r} cannot be a session name: use up to 64 letters, digits, spaces, '-', '_', '.' or "
            "brackets, starting with a letter or digit (no '/' and no '..')."
        )
    return name


def check_demo_name(name: object) -> str:
    """A demo name is a label (never a file name): 1–100 printable characters."""
    if not isinstance(name, str):
        raise InvalidInput("A demonstration name must be text.")
    name = name.strip()
    if not name or len(name) > 100 or any(ord(c) < 32 or ord(c) == 127 for c in name):
        raise InvalidInput("A demonstration name must be 1 to 100 printable characters.")
    return name


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
