"""Session actions: open, new, save, duplicate, download and upload a session, export the learned trajectory;
and switching the whole controller to another session (never while recording or training)."""

from __future__ import annotations

import logging
import tempfile
from collections.abc import Callable
from pathlib import Path

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.core.errors import InvalidInput, SessionFormatError, StudioError
from studio.storage import ReadOnly, Session, SessionStore, check_session_name
from studio.storage.format import what_went_wrong
from studio.world import preset

log = logging.getLogger(__name__)

#: Title of the note told once after a crash recovery (damaged files are told to every new tab).
RECOVERED = "Recovered recordings"
#: The session the studio opens when the one it should start with cannot be opened.
STAND_IN = "untitled"


def open_or_create(store: SessionStore, name: str) -> Session:
    """The session the studio starts with: ``name`` (damaged demonstrations skipped), created when there is none
    of that name. When it cannot be opened the studio still starts, on the session "untitled", and says why;
    the files of ``name`` are untouched. Temporary folders a killed studio left are removed first."""
    store.clean_temporary()
    try:
        return store.open(name, skip_damaged=True)
    except StudioError as exc:
        failure = exc
    try:
        if not store.path_of(name).exists():
            return store.create(name)
    except StudioError as exc:
        failure = exc
    why = what_went_wrong(failure) if isinstance(failure, SessionFormatError) else str(failure)
    try:
        session = store.open(STAND_IN, skip_damaged=True)
    except StudioError:
        session = store.create(store.free_name(STAND_IN))
    session.opened_instead = (
        f'The session "{name}" could not be opened: {why} The studio opened the session "{session.name}" instead; '
        f'the files of "{name}" are untouched.'
    )
    return session


def session_notes(session: Session) -> list[tuple[str, str]]:
    """(title, body) warnings from opening ``session``: another session opened instead, crash recovery, damaged
    files."""
    notes = [("The session could not be opened", session.opened_instead)] if session.opened_instead else []
    notes += [(RECOVERED, session.recovery_message)] if session.recovery_message else []
    return notes + [("Part of the session could not be read", p) for p in session.problems]


class SessionActions:
    """The Sessions panel's actions; each refuses in plain words while a recording, training or a run on the
    robot goes on (the parts' own checks, :meth:`Context.on_leave`).

    Args:
        persist: writes the threshold settings not yet saved into the open session (before a save or a zip).
    """

    def __init__(self, ctx: Context, persist: Callable[[], None] = lambda: None) -> None:
        self.ctx = ctx
        self.persist = persist
        self._startup_notes = session_notes(ctx.session)

    @property
    def current(self) -> Session:
        return self.ctx.session

    def names(self) -> list[str]:
        return self.ctx.store.list_sessions()

    # -- notes from opening --------------------------------------------------------------------------------
    def startup_notes(self) -> list[tuple[str, str]]:
        """(title, body) warnings from opening the session (crash recovery, damaged files), for a new tab."""
        return list(self._startup_notes)

    def startup_notes_shown(self) -> None:
        """A tab got the notes: a recovery is told once, damaged files to every new tab."""
        self._startup_notes = [n for n in self._startup_notes if n[0] != RECOVERED]

    # -- actions -------------------------------------------------------------------------------------------
    def _check_can_switch(self, doing: str) -> None:
        """Refuse, in plain words, to change the open session while recording, training or running."""
        with self.ctx.lock:
            self.ctx.leave(doing)

    def open(self, name: str) -> None:
        """Open session ``name``: its damaged demonstrations are skipped and told, the rest opens."""
        self._check_can_switch("opening another session")
        session = self.ctx.store.open(name, skip_damaged=True)
        self.switch(session)
        self._startup_notes = session_notes(session)
        for title, body in self._startup_notes:
            self.ctx.notify(title, body, kind="warning")
        self.startup_notes_shown()  # told to every open tab

    def new(self, name: str, scene: str = "empty table") -> None:
        """Start a new session on the task scene ``scene`` (a preset: "empty table", "stack-cup", "pick-place")."""
        self._check_can_switch("starting a new session")
        name = check_session_name(_typed_name(name))
        objects = preset(scene, self.ctx.arms)  # checked before anything is created
        session = self.ctx.store.create(name, arms=self.ctx.arms)
        session.set_scene(objects)
        self.switch(session)
        self.ctx.emit(Topic.SESSIONS)

    def save(self, *, quiet: bool = False) -> None:
        self.persist()
        if self.ctx.session.read_only:  # an example is saved as it is already
            if not quiet:
                raise ReadOnly(self.ctx.session.name)
            return
        self.ctx.store.save(self.ctx.session)
        if not quiet:
            self.ctx.notify("Saved", f'Session "{self.ctx.session.name}" is saved.', kind="success")

    def duplicate(self, new_name: str) -> None:
        self._check_can_switch("copying the session")
        new_name = check_session_name(_typed_name(new_name))
        if self.ctx.store.path_of(new_name).exists():  # checked before "Saved" is shown
            raise InvalidInput(f'A session called "{new_name}" already exists; choose another name.')
        original = self.ctx.session.name
        self.save(quiet=True)  # the copy is what the person asked for: say that, not "… is saved"
        copy = self.ctx.store.duplicate(original, new_name)
        self.switch(copy)
        self.ctx.emit(Topic.SESSIONS)
        self.ctx.notify(
            "Copied", f'Session "{original}" was copied as "{new_name}"; the copy is open now.', kind="success"
        )

    def zip(self) -> tuple[str, bytes]:
        """(file name, bytes) of the open session as a zip archive, as the studio holds it (a damaged demonstration
        it skipped is left out). Every edit is on disk already; threshold settings not yet written are written
        first when the disk allows it (on a read-only disk the download holds them as last saved, and the
        teacher is told)."""
        try:
            self.persist()
        except (StudioError, OSError) as exc:
            log.warning("zip: the newest threshold settings could not be written first: %s", exc)
            self.ctx.notify(
                "Downloaded as last saved",
                "Your newest threshold settings could not be written to disk (is it read-only or full?), so the "
                "download holds the session as it was last saved.",
                kind="warning",
            )
        session = self.ctx.session
        return f"{session.name}.zip", self.ctx.store.export_zip(session.name, opened=session)

    def import_zip(self, filename: str, data: bytes) -> str:
        """Add an uploaded session archive (validated first: a bad file changes nothing) and open it."""
        self._check_can_switch("uploading a session")  # checked first so that a refused upload adds nothing
        name = self.ctx.store.import_zip(data, archive=filename)
        self.ctx.emit(Topic.SESSIONS)
        self.open(name)
        self.ctx.notify("Session uploaded", f'"{filename}" was added as session "{name}" and opened.', kind="success")
        return name

    def trajectory_csv(self) -> tuple[str, bytes]:
        """(file name, bytes) of the learned joint trajectory as a Baxter SDK CSV."""
        from studio.csv_io import export_joint_trajectory_csv

        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / f"{self.ctx.session.name}-trajectory.csv"
            export_joint_trajectory_csv(self.ctx.session.skills, path)
            return path.name, path.read_bytes()

    def switch(self, session: Session) -> None:
        """Make ``session`` the open one and tell every part and view (:attr:`Topic.SESSION`). The parts' checks
        decide first, under ``ctx.lock`` (a recording starts under it too: never a take in between)."""
        with self.ctx.lock:
            if session is not self.ctx.session:
                self.ctx.leave("changing the session")
            self.ctx.session = session
        self.ctx.emit(Topic.SESSION)


def _typed_name(name: str | None) -> str:
    """A name typed in "New name", stripped; empty gets plain words instead of a format message."""
    name = (name or "").strip()
    if not name:
        raise InvalidInput("Type a name in 'New name' first.")
    return name
