"""Sessions on disk: one folder per session, a versioned human-readable manifest, array files, no pickle.

``<root>/<name>/`` holds ``session.json`` (:class:`Manifest`), ``demos/d0001.npz`` (t, q, gripper),
``skills/<arm>.npz``, ``recovered/`` (unlisted demo files, never deleted) and, while
recording, ``.recording/``. Every write is atomic; loading validates
everything, raises :class:`~studio.core.errors.SessionFormatError` in plain words and never writes. One module
per concern: see ARCHITECTURE.md."""

from studio.storage.atomic import atomic_write_bytes, atomic_write_npz
from studio.storage.format import (
    DEFAULT_ROOT,
    FORMAT_VERSION,
    MAX_CLUSTERS,
    RECORDING_DIR,
    check_demo_name,
    check_session_name,
)
from studio.storage.idle import idle_bounds
from studio.storage.loading import load_session
from studio.storage.manifest import DemoEntry, Manifest, SkillEntry
from studio.storage.session import ReadOnly, Session
from studio.storage.store import SessionStore, SessionSummary

__all__ = [
    "DEFAULT_ROOT",
    "FORMAT_VERSION",
    "MAX_CLUSTERS",
    "RECORDING_DIR",
    "DemoEntry",
    "Manifest",
    "ReadOnly",
    "Session",
    "SessionStore",
    "SessionSummary",
    "SkillEntry",
    "atomic_write_bytes",
    "atomic_write_npz",
    "check_demo_name",
    "check_session_name",
    "idle_bounds",
    "load_session",
]
