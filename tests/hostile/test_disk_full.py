"""A full disk (a 3 MB tmpfs): adding, creating, importing, recovering and starting the studio say so in plain
words, keep what was saved, and leave no half-made folder. Needs root to mount the tmpfs (CI runs as root);
skipped with the reason otherwise."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from studio.controller import Controller
from studio.core.errors import StudioError
from studio.storage import SessionStore
from tests.conftest import RecordingNotifier, wait_for
from tests.hostile.builders import assert_plain, make_rec, studio_cli


@pytest.fixture
def disk(tmp_path: Path) -> Iterator[Path]:
    """A 3 MB tmpfs mounted for this test."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root (CI runs as root)")
    mnt = tmp_path / f"disk-{uuid.uuid4().hex[:6]}"
    mnt.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(mnt)], capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {proc.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def fill(disk: Path, leave: int = 0) -> Path:
    """Fill ``disk`` up to ``leave`` free bytes; returns the filler (delete it to free the space)."""
    filler = disk / "filler"
    with open(filler, "wb", buffering=0) as f:
        try:
            while True:
                f.write(b"\0" * 4096)
        except OSError:
            pass
    if leave:
        os.truncate(filler, max(0, filler.stat().st_size - leave))
    return filler


def no_temporaries(root: Path) -> bool:
    return not [p for p in root.rglob(".tmp-*")]


def test_adding_demos_until_the_disk_is_full(disk: Path) -> None:
    store = SessionStore(disk / "sessions")
    s = store.create("s")
    saved = 0
    with pytest.raises(StudioError, match=r"(?i)no space left|disk is full") as ei:
        for i in range(200):
            s.add_recording(make_rec(n=5000, seed=i, name=f"d{i}"))
            saved += 1
    assert "Traceback" not in str(ei.value) and "Errno" not in str(ei.value)
    assert len(s.recordings) == saved  # the refused one is not shown as if it were kept
    again = store.open("s")
    assert len(again.recordings) == saved and not again.problems
    assert no_temporaries(store.root)


def test_creating_a_session_on_a_full_disk_leaves_no_folder(disk: Path) -> None:
    store = SessionStore(disk / "sessions")
    store.root.mkdir()
    fill(disk)
    with pytest.raises(StudioError, match=r"(?i)no space left|disk is full"):
        store.create("new one")
    assert list(store.root.iterdir()) == []


def test_importing_onto_a_full_disk(disk: Path, tmp_path: Path) -> None:
    elsewhere = SessionStore(tmp_path / "elsewhere")
    s = elsewhere.create("big")
    for i in range(4):
        s.add_recording(make_rec(n=20_000, seed=i, name=f"d{i}"))
    data = elsewhere.export_zip("big")
    store = SessionStore(disk / "sessions")
    store.create("home")
    fill(disk, leave=len(data) // 2)
    with pytest.raises(StudioError, match=r"(?i)space"):
        store.import_zip(data, archive="big.zip")
    assert sorted(p.name for p in store.root.iterdir()) == ["home"]


def test_recovery_on_a_full_disk_keeps_the_take_for_later(disk: Path, tmp_path: Path) -> None:
    from studio.recorder import Recorder
    from studio.robot_backend.simulated import SimulatedBaxter

    store = SessionStore(disk / "sessions")
    s = store.create("s")
    sim = SimulatedBaxter()
    rec = Recorder(sim, tmp_path / "rec", ("left",), name="take")
    sim.start()
    rec.start()
    import time

    time.sleep(0.6)
    rec.stop()
    sim.stop()
    assert rec.path is not None
    s.recording_dir.mkdir()
    shutil.copy(rec.path, s.recording_dir / rec.path.name)
    filler = fill(disk)
    opened = store.open("s")  # opens although the take cannot be added now
    assert len(opened.recordings) == 0
    assert "space" in opened.recovery_message and "next time" in opened.recovery_message
    assert [p.suffix for p in s.recording_dir.iterdir()] == [".rec"]  # kept as it is, not set aside as damaged
    filler.unlink()
    again = store.open("s")
    assert len(again.recordings) == 1 and "recovered" in again.recovery_message


def test_the_cli_on_a_full_disk_speaks_plain_words(disk: Path, tmp_path: Path) -> None:
    from studio.csv_io import export_recording_csv

    for i in range(3):
        export_recording_csv(make_rec(n=20_000, seed=i), tmp_path / f"c{i}.csv")
    fill(disk, leave=64 * 1024)
    files = [str(tmp_path / f"c{i}.csv") for i in range(3)]
    proc = studio_cli("import-csv", *files, "--session", "x", "--sessions-dir", str(disk / "sessions"))
    assert_plain(proc)
    assert "space" in proc.stdout + proc.stderr
    root = disk / "sessions"
    assert not root.exists() or all((p / "session.json").is_file() for p in root.iterdir())


def test_the_studio_starts_on_a_full_disk(disk: Path, tmp_path: Path) -> None:
    """A take waiting for recovery and no space to add it: the studio still starts and says so."""
    from studio.app import build_app
    from tests.conftest import ROOT, free_port

    shutil.copytree(ROOT / "sessions" / "stack-cup", disk / "stack-cup")
    rec_dir = disk / "stack-cup" / ".recording"
    rec_dir.mkdir()
    from studio.recorder import Recorder
    from studio.robot_backend.simulated import SimulatedBaxter

    sim = SimulatedBaxter()
    rec = Recorder(sim, tmp_path / "rec", ("left",), name="take")
    sim.start()
    rec.start()
    import time

    time.sleep(0.6)
    rec.stop()
    sim.stop()
    assert rec.path is not None
    shutil.copy(rec.path, rec_dir / rec.path.name)
    fill(disk)
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=disk)
    try:
        notes = app.controller.sessions.startup_notes()
        assert any("space" in body for _, body in notes), notes
        assert len(app.controller.demos.names()) == 3
    finally:
        app.stop()


def _recording(store: SessionStore) -> tuple[Controller, RecordingNotifier]:
    from studio.robot_backend.simulated import SimulatedBaxter

    store.create("s")
    told = RecordingNotifier()
    # the robot streams 4 simulated seconds a wall second: the subject is what a take holds, not its timing
    ctl = Controller(store=store, session="s", backend=SimulatedBaxter(time_scale=4.0), notifier=told)
    ctl.start()
    ctl.teaching.start_recording()
    return ctl, told


def _record_until(ctl: Controller, seconds: float) -> None:
    rec = ctl.teaching.recorder
    assert rec is not None
    assert wait_for(lambda: rec.elapsed >= seconds, 120), rec.elapsed  # a loaded machine may start the stream late


def _samples(words: str) -> int:
    found = re.search(r"([\d,]+) samples", words)
    assert found, words
    return int(found.group(1).replace(",", ""))


def test_an_8_s_take_survives_a_full_disk_whole_and_is_saved_when_space_returns(
    disk: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 31 §2, today: the disk filled 0.8 s into an 8 s take; the recorder stopped writing (and listening),
    said "The take itself is kept", and the session got back a 0.785 s demo of 786 samples, "recovered"."""
    monkeypatch.setenv("XDG_STATE_HOME", str(disk.parent / "state"))
    store = SessionStore(disk / "sessions")
    ctl, told = _recording(store)
    try:
        _record_until(ctl, 1.0)
        filler = fill(disk)
        _record_until(ctl, 8.0)  # seven seconds recorded with no space on the disk
        assert any(title == "The disk is full" for title in told.titles()), told.notes  # said during the take
        with pytest.raises(StudioError) as err:
            ctl.teaching.stop_recording()
        words = str(err.value)
        assert "is not saved yet" in words and "in the studio's memory" in words, words
        assert re.search(r"\((8|9|\d\d)\.\d s, [\d,]+ samples\)", words), words  # its length
        n = _samples(words)
        assert n >= 7_000 and len(ctl.session.recordings) == 0
        filler.unlink()  # space again: saved without anything pressed
        assert wait_for(lambda: len(ctl.session.recordings) == 1, 60), told.notes
        saved = ctl.session.recordings[0]
        assert len(saved) == n, (len(saved), n)  # every sample, not the 786 on disk when it filled
        assert "Demonstration saved" in told.titles() and "recovered" not in saved.name
    finally:
        ctl.close()
        ctl.shutdown()
    again = store.open("s")
    assert [len(r) for r in again.recordings] == [n] and not again.recovery_message
    assert not list((disk / "sessions" / "s" / ".recording").glob("*.rec"))


def test_a_take_still_in_memory_when_the_studio_stops_is_added_at_the_next_start(
    disk: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The disk stays full until the studio stops: the take goes whole to a spill folder on another disk (the user's
    state folder), and opening the session adds it, with every sample."""
    state = disk.parent / "state"
    monkeypatch.setenv("XDG_STATE_HOME", str(state))
    store = SessionStore(disk / "sessions")
    ctl, _ = _recording(store)
    try:
        _record_until(ctl, 0.5)
        filler = fill(disk)
        _record_until(ctl, 3.0)
        with pytest.raises(StudioError, match="not saved yet") as err:
            ctl.teaching.stop_recording()
        n = _samples(str(err.value))
    finally:
        ctl.close()  # the disk is still full
        ctl.shutdown()
    assert list(state.rglob("*.rec"))  # spilled, whole
    filler.unlink()
    again = store.open("s")
    assert [len(r) for r in again.recordings] == [n], again.recovery_message
    words = again.recovery_message
    assert "could not be saved when recorded" in words and "stopped while" not in words, words
    assert not list(state.rglob("*.rec"))


def test_download_works_on_a_read_only_disk(disk: Path) -> None:
    """Issue 21 §7, today: Download saved the session first, which failed on a read-only disk."""
    import io
    import zipfile

    from studio.controller import Controller
    from studio.robot_backend.simulated import SimulatedBaxter
    from tests.conftest import ROOT, RecordingNotifier

    shutil.copytree(ROOT / "sessions" / "stack-cup", disk / "stack-cup")
    told = RecordingNotifier()
    ctl = Controller(store=SessionStore(disk), session="stack-cup", backend=SimulatedBaxter(), notifier=told)
    try:
        ctl.keypoints.set_detail(0.4)  # a setting not written yet
        subprocess.run(["mount", "-o", "remount,ro", str(disk)], check=True)
        name, data = ctl.sessions.zip()
        assert name == "stack-cup.zip"
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            entries = z.namelist()
        assert "stack-cup/session.json" in entries and sum("/demos/" in e for e in entries) == 3, entries
        assert "Downloaded as last saved" in told.titles()
    finally:
        subprocess.run(["mount", "-o", "remount,rw", str(disk)], check=False)
        ctl.shutdown()
