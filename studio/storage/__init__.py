"""Sessions on disk: one folder per session, a versioned human-readable manifest, array files, no pickle.

Layout of ``<root>/<name>/``::

    session.json          the manifest (:class:`Manifest`; format "teaching-studio-session", version 1)
    demos/d0001.npz       one demonstration: t (N,) s float64, q (N, 14) rad, gripper (N, 2) percent
    skills/left.npz       a learned skill, Skill.to_arrays() (one file per arm)
    .recording/           the recorder's crash-safe files while recording (not part of the format)
    recovered/            demo files the manifest did not list when opened, moved aside (never deleted)

Modules, one concern each:

    format.py    names, limits, file patterns, the wording of a damaged file
    atomic.py    atomic writes (temporary file, fsync, rename) and reproducible .npz writing
    npz.py       reading .npz files safely (headers and byte limits first); demo and skill files
    manifest.py  the manifest as frozen dataclasses (how to version and extend it is written there)
    session.py   Session: an open session, every change written at once (all or nothing)
    loading.py   load_session: a folder validated, its memory checked before anything large is read
    fs.py        the folder as someone may have left it: capped reads, links, leftovers of a kill -9
    limits.py    free disk and memory against the limits; a failed write in plain words
    store.py     SessionStore: list, create, open (with crash recovery), save, duplicate, delete
    archive.py   zip export and validated import
    idle.py      idle start/end of a demonstration (for trimming)

Rules: no pickle anywhere; every write is atomic; loading validates everything, raises
:class:`~studio.core.errors.SessionFormatError` with ``file`` and ``problem`` fields and a plain-words message,
and never writes.
"""

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
from studio.storage.session import Session
from studio.storage.store import SessionStore, SessionSummary

__all__ = [
    "DEFAULT_ROOT",
    "FORMAT_VERSION",
    "MAX_CLUSTERS",
    "RECORDING_DIR",
    "DemoEntry",
    "Manifest",
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
