"""The session store: every session under one folder; create, open (with crash recovery), save, copy, delete.

Crash recovery is orchestrated here: opening a session adds back the recordings a crash interrupted
(read by :mod:`studio.recorder`, which knows nothing of sessions), so the recorder and the storage never
import each other. Zip export and import are in :mod:`studio.storage.archive`.
"""

from __future__ import annotations

import logging
import os
import shutil
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from studio.core.arms import normalize_arms
from studio.core.errors import InvalidInput, SessionFormatError, StorageError, StudioError
from studio.core.thresholds import ThresholdSettings
from studio.core.types import Arm, KeypointParams
from studio.recorder import pending_recordings, recover_recordings
from studio.storage import archive as _archive
from studio.storage.atomic import atomic_write_bytes, atomic_write_npz
from studio.storage.format import (
    DEFAULT_ROOT,
    MANIFEST,
    NAME_RE,
    PRECISIONS,
    RECORDING_DIR,
    RECOVERED_DIR,
    check_session_name,
    now,
    recovered_note,
)
from studio.storage.fs import clean_leftovers, clean_temporary_folders, temporary_folder
from studio.storage.limits import check_disk, reworded, write_failed
from studio.storage.loading import load_session
from studio.storage.manifest import Manifest
from studio.storage.session import Session, new_demo_file

log = logging.getLogger(__name__)
#: The file in the sessions folder that names the session open last (the studio reopens it).
LAST_OPEN = ".last-session"


@dataclass(frozen=True)
class SessionSummary:
    """What the session picker shows, read from the manifest only."""

    name: str
    demos: int
    arms: tuple[Arm, ...]
    created: str
    notes: str
    skills: tuple[str, ...]


class SessionStore:
    """All sessions under ``root`` (default: :data:`~studio.storage.format.DEFAULT_ROOT`)."""

    def __init__(self, root: str | os.PathLike[str] | None = None, *, examples: Iterable[str] = ()) -> None:
        self.root = Path(root) if root is not None else DEFAULT_ROOT
        #: Sessions opened read-only (:attr:`Session.read_only`): the bundled examples, kept as they are.
        self.examples = frozenset(examples)

    def path_of(self, name: str) -> Path:
        return self.root / check_session_name(name)

    def exists(self, name: str) -> bool:
        return (self.path_of(name) / MANIFEST).is_file()

    def list_sessions(self) -> list[str]:
        """Names of the sessions (folders with a manifest), sorted."""
        if not self.root.is_dir():
            return []
        return [
            p.name
            for p in sorted(self.root.iterdir())
            if p.is_dir() and not p.is_symlink() and NAME_RE.fullmatch(p.name) and (p / MANIFEST).is_file()
        ]

    def remember_open(self, name: str) -> None:
        """Note ``name`` as the session open last (:meth:`last_open`); a failed write is only logged."""
        try:
            atomic_write_bytes(self.root / LAST_OPEN, (check_session_name(name) + "\n").encode())
        except (OSError, StudioError):
            log.warning("could not note the open session in %s", self.root, exc_info=True)

    def last_open(self) -> str | None:
        """The session open when the studio last ran here, if it still exists (None otherwise)."""
        try:
            name = (self.root / LAST_OPEN).read_text(encoding="utf-8")[:200].strip()
            return name if self.exists(name) else None
        except (OSError, UnicodeDecodeError, StudioError):
            return None

    def summaries(self) -> list[SessionSummary]:
        """One summary per session whose manifest is valid (damaged ones are left out)."""
        out = []
        for n in self.list_sessions():
            try:
                m = Manifest.read(self.root / n / MANIFEST, n)
            except SessionFormatError:
                continue
            out.append(SessionSummary(n, len(m.demos), m.arms, m.created, m.notes, tuple(m.skills)))
        return out

    def pending_recoveries(self) -> list[str]:
        """Sessions that hold recordings interrupted by a crash (recovered when the session is opened)."""
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
        if precision not in PRECISIONS:
            raise InvalidInput(f"Precision must be one of {', '.join(PRECISIONS)}.")
        a = normalize_arms(tuple(arms))
        try:
            path.mkdir(parents=True)
        except OSError as exc:
            raise write_failed(path, exc, doing="created") from exc
        s = Session(
            name=name,
            path=path,
            arms=a,
            notes=notes,
            params=params or KeypointParams(),
            thresholds=ThresholdSettings.from_params(params) if params is not None else ThresholdSettings(),
            precision=precision,
        )
        try:
            s._write_manifest()
        except BaseException as exc:
            shutil.rmtree(path, ignore_errors=True)  # no half-made session folder
            if isinstance(exc, StorageError):
                raise reworded(exc, path, f'The session "{name}"', "created") from exc.__cause__
            raise
        return s

    def open(self, name: str, *, recover: bool = True, skip_damaged: bool = False) -> Session:
        """Load a session; with ``recover``, recordings interrupted by a crash are added back first.

        The recovery message (if any) is in ``session.recovery_message``.
        """
        path = self.path_of(name)
        if not path.is_dir() and not path.is_symlink():
            raise SessionFormatError(f'There is no session called "{name}" in {self.root}.')
        s = load_session(path, skip_damaged=skip_damaged)
        # What a kill -9 during a save, or a manifest put back from a backup, left: temporary files are removed,
        # demo files the manifest does not list are moved to recovered/ (never deleted).
        _, moved = clean_leftovers(path, Manifest.read(path / MANIFEST, name).files())
        notes = [recovered_note(len(moved), path / RECOVERED_DIR)] if moved else []
        if recover and (path / RECORDING_DIR).is_dir():
            _, message = recover_recordings(path / RECORDING_DIR, add=s.add_recording)
            notes.insert(0, message)
        s.recovery_message = " ".join(n for n in notes if n)
        s.read_only = name in self.examples
        return s

    def clean_temporary(self) -> list[str]:
        """Remove the temporary folders of uploads and copies a killed studio left (none in use elsewhere)."""
        return clean_temporary_folders(self.root)

    def save(self, session: Session) -> None:
        """Write the whole session (manifest and any missing demo files) to its folder atomically."""
        try:
            session.path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise write_failed(session.path, exc) from exc
        with session.change():
            dt = PRECISIONS[session.precision]
            for i, r in enumerate(session.recordings):
                if i < len(session._files) and (session.path / session._files[i]).exists():
                    continue
                rel = new_demo_file(session)
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

    def free_name(self, name: str) -> str:
        """``name``, or ``name (2)``, ``name (3)``… whichever no session uses yet."""
        if not self.path_of(name).exists():
            return name
        i = 2
        while True:
            cand = f"{name[:58]} ({i})"
            if not self.path_of(cand).exists():
                return cand
            i += 1

    def duplicate(self, name: str, new_name: str) -> Session:
        """Copy a session under a new name; returns the copy. Only its own files are copied (manifest, demos,
        skills), as regular files: not its in-progress recordings, nor anything else in its folder or behind a link."""
        src = self.path_of(name)
        dst = self.path_of(new_name)
        if dst.exists():
            raise InvalidInput(f'A session called "{new_name}" already exists; choose another name.')
        original = load_session(src)  # only valid sessions are copied
        # Only the session's own files, as regular files: never a link, nor what a link points to.
        files = [*original.demo_files, *(i.file for i in original.skill_info.values())]
        check_disk(self.root, sum((src / f).stat().st_size for f in files), f'The copy of "{name}"')
        try:
            with temporary_folder(self.root, "copy") as tmp:
                for rel in files:
                    (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(src / rel, tmp / rel, follow_symlinks=False)
                original.path = tmp
                original.name = new_name
                original.created = now()
                original._write_manifest()
                os.rename(tmp, dst)
        except OSError as exc:
            raise write_failed(dst, exc, doing="copied") from exc
        return load_session(dst)

    def export_zip(self, name: str, *, opened: Session | None = None) -> bytes:
        """The session as a zip archive (manifest, demos, skills) for download or sharing: what loads from its
        folder, or ``opened``, the session as the studio holds it (damaged demonstrations it skipped are left
        out, and its list says so; nothing is written)."""
        if opened is not None:
            return _archive.export_zip(opened, manifest=opened.manifest().to_bytes())
        return _archive.export_zip(load_session(self.path_of(name)))  # only export what loads

    def import_zip(self, data: bytes, name: str | None = None, *, archive: str | None = None) -> str:
        """Add a session from a zip made by :meth:`export_zip`; returns its (possibly renamed) name.

        The archive is checked (safe member names, sizes), unpacked into a temporary folder, loaded with full
        validation, and only then moved into place; on any problem nothing is added. ``archive`` is the
        uploaded file's name, used in messages.
        """

        def final_name(top: str) -> str:
            return self.free_name(check_session_name(name or top))

        return _archive.import_zip(self.root, data, final_name, archive=archive)
