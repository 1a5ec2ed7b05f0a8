"""Issue 21 §3: opening a session never deletes a demonstration it did not create.

A backup of an older ``session.json`` put back, a sync conflict, a duplicated key in a hand-edited manifest, a
damaged demo file, a damaged default session, leftovers of an upload killed half-way: each opens what it can,
says what happened in words, and deletes no demonstration.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from studio.controller import Controller
from studio.core.errors import SessionFormatError
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import Session, SessionStore
from tests.conftest import RecordingNotifier
from tests.hostile.builders import make_rec


@pytest.fixture
def store(tmp_path: Path) -> SessionStore:
    return SessionStore(tmp_path / "sessions")


@pytest.fixture
def three(store: SessionStore) -> Session:
    s = store.create("three")
    for i in range(3):
        s.add_recording(make_rec(seed=i, name=f"demo {i + 1}"))
    return s


def demo_bytes(path: Path) -> dict[str, bytes]:
    """Every demonstration file anywhere in the session folder, by content (what must never be lost)."""
    return {p.read_bytes().hex()[:64] + str(p.stat().st_size): p.read_bytes() for p in path.rglob("d*.npz")}


#: What each controller made by ``ctl_factory`` told the teacher.
TOLD: dict[int, RecordingNotifier] = {}


@pytest.fixture
def ctl_factory(store: SessionStore) -> Iterator:
    made: list[Controller] = []

    def make(session: str) -> Controller:
        told = RecordingNotifier()
        c = Controller(store=store, session=session, backend=SimulatedBaxter(), notifier=told)
        TOLD[id(c)] = told
        made.append(c)
        return c

    yield make
    for c in made:
        c.shutdown()


# -- a backup of an older manifest, a sync conflict -----------------------------------------------------------
def test_an_older_manifest_put_back_keeps_the_newer_demonstration(store: SessionStore, three: Session) -> None:
    """Today's regression: restoring a backup of session.json and opening the session deleted d0004.npz."""
    backup = (three.path / "session.json").read_bytes()
    three.add_recording(make_rec(seed=9, name="the newest"))
    newest = (three.path / "demos" / "d0004.npz").read_bytes()
    (three.path / "session.json").write_bytes(backup)  # the backup is put back

    s = store.open("three")
    assert len(s.recordings) == 3
    kept = three.path / "recovered" / "d0004.npz"
    assert kept.read_bytes() == newest
    assert "1 recording was not in the session list; it is in Recovered" in s.recovery_message
    assert str(three.path / "recovered") in s.recovery_message
    # Opening again (and again) moves nothing more and loses nothing.
    s = store.open("three")
    assert kept.read_bytes() == newest and not s.recovery_message


def test_two_unlisted_recordings_are_told_in_words_by_the_studio(
    store: SessionStore, three: Session, ctl_factory
) -> None:
    backup = (three.path / "session.json").read_bytes()
    three.add_recording(make_rec(seed=8, name="four"))
    three.add_recording(make_rec(seed=9, name="five"))
    before = demo_bytes(three.path)
    (three.path / "session.json").write_bytes(backup)
    ctl = ctl_factory("three")
    notes = ctl.sessions.startup_notes()
    assert any("2 recordings were not in the session list; they are in Recovered" in body for _, body in notes), notes
    assert demo_bytes(three.path) == before  # every file kept, byte for byte
    assert len(ctl.demos.names()) == 3


def test_a_recovered_name_already_taken_keeps_both(store: SessionStore, three: Session) -> None:
    (three.path / "recovered").mkdir()
    (three.path / "recovered" / "d0004.npz").write_bytes(b"an earlier recovered file")
    backup = (three.path / "session.json").read_bytes()
    three.add_recording(make_rec(seed=9, name="the newest"))
    (three.path / "session.json").write_bytes(backup)
    before = demo_bytes(three.path)
    store.open("three")
    assert demo_bytes(three.path) == before
    assert len(list((three.path / "recovered").iterdir())) == 2


def test_a_manifest_with_a_key_twice_is_refused_and_nothing_is_deleted(store: SessionStore, three: Session) -> None:
    """Today's regression: with "demos" twice (JSON keeps the last), opening deleted two demonstrations."""
    raw = json.loads((three.path / "session.json").read_text())
    one = {**raw, "demos": raw["demos"][:1]}
    text = json.dumps(raw)[:-1] + ', "demos": ' + json.dumps(one["demos"]) + "}"
    (three.path / "session.json").write_text(text)
    before = demo_bytes(three.path)
    with pytest.raises(SessionFormatError, match=r'"demos" twice'):
        store.open("three")
    assert demo_bytes(three.path) == before and not (three.path / "recovered").exists()
    # Nested keys too (a demonstration entry, the scene).
    text = json.dumps(raw).replace('"name": "demo 1"', '"name": "demo 1", "name": "x"', 1)
    (three.path / "session.json").write_text(text)
    with pytest.raises(SessionFormatError, match=r'"name" twice'):
        store.open("three")
    assert demo_bytes(three.path) == before


# -- a damaged demonstration, a damaged default session ----------------------------------------------------------
def test_a_damaged_demonstration_is_skipped_and_the_rest_opens(
    store: SessionStore, three: Session, ctl_factory
) -> None:
    shutil.copytree(three.path, store.root / "other")
    (store.root / "other" / "session.json").write_text(
        (store.root / "other" / "session.json").read_text().replace('"name": "three"', '"name": "other"')
    )
    damaged = three.path / "demos" / "d0002.npz"
    damaged.write_bytes(damaged.read_bytes()[:200])
    ctl = ctl_factory("three")  # the default session: the studio starts
    assert ctl.demos.names() == ["demo 1", "demo 3"]
    notes = ctl.sessions.startup_notes()
    assert any("d0002.npz" in body and "skipped" in body for _, body in notes), notes
    ctl.sessions.open("other")
    ctl.sessions.open("three")  # opened again from the studio: the rest opens, the note is told again
    assert ctl.demos.names() == ["demo 1", "demo 3"]
    assert any("d0002.npz" in body for _, _, body in TOLD[id(ctl)].notes)
    # A later change rewrites the list without the damaged file: it is kept, never deleted.
    ctl.demos.rename(0, "first")
    store.open("three")
    assert (three.path / "recovered" / "d0002.npz").exists() or damaged.exists()


def test_the_studio_starts_when_its_default_session_cannot_be_opened(
    store: SessionStore, three: Session, ctl_factory
) -> None:
    (three.path / "session.json").write_bytes(b'{"format": "teaching-studio-session", "version": 2, "demos": [')
    before = demo_bytes(three.path)
    ctl = ctl_factory("three")
    assert ctl.session.name != "three" and ctl.demos.names() == []
    notes = ctl.sessions.startup_notes()
    assert any('"three"' in body and "could not be opened" in body for _, body in notes), notes
    assert demo_bytes(three.path) == before
    # Started again: the same stand-in opens (no new session each time).
    other = ctl_factory("three")
    assert other.session.name == ctl.session.name


# -- an upload killed half-way ------------------------------------------------------------------------------------
def test_leftover_upload_folders_are_removed_when_the_studio_starts(
    store: SessionStore, three: Session, ctl_factory
) -> None:
    import fcntl

    left = store.root / ".tmp-import-0123abcd" / "big"
    left.mkdir(parents=True)
    (left / "demos").mkdir()
    (left / "demos" / "d0001.npz").write_bytes(np.zeros(1 << 20).tobytes())
    busy = store.root / ".tmp-import-busybusy"
    busy.mkdir()
    fd = os.open(busy, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # an upload being unpacked right now, by another studio
        ctl_factory("three")
        assert not left.parent.exists()
        assert busy.exists()
    finally:
        os.close(fd)
    assert store.list_sessions() == ["three"]


def test_a_session_with_a_damaged_demonstration_can_be_downloaded(
    store: SessionStore, three: Session, ctl_factory
) -> None:
    """Opened with a damaged demonstration skipped, the session downloads as the studio holds it (without
    reading its folder again); the archive uploads as a session."""
    damaged = three.path / "demos" / "d0002.npz"
    damaged.write_bytes(damaged.read_bytes()[:200])
    ctl = ctl_factory("three")
    name, data = ctl.sessions.zip()
    assert name == "three.zip"
    back = store.open(store.import_zip(data, "back"))
    assert back.demo_names == ["demo 1", "demo 3"]
    assert damaged.exists()  # the damaged file itself is left where it is
