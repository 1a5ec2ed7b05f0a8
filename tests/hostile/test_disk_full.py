"""A full disk (a 3 MB tmpfs): adding, creating, importing, recovering and starting the studio say so in plain
words, keep what was saved, and leave no half-made folder. Needs root to mount the tmpfs (CI runs as root);
skipped with the reason otherwise."""

from __future__ import annotations

import os
import shutil
import subprocess
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from studio.core.errors import StudioError
from studio.storage import SessionStore
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


def test_stopping_a_recording_on_a_full_disk_keeps_the_take(disk: Path) -> None:
    import time

    from studio.controller import Controller
    from studio.robot_backend.simulated import SimulatedBaxter
    from tests.conftest import RecordingNotifier

    store = SessionStore(disk / "sessions")
    store.create("s")
    ctl = Controller(store=store, session="s", backend=SimulatedBaxter(), notifier=RecordingNotifier())
    ctl.start()
    try:
        ctl.teaching.start_recording()
        rec = ctl.teaching.recorder
        assert rec is not None
        deadline = time.monotonic() + 20  # a loaded machine (CI) may start the stream late: wait for 1 s of it
        while rec.elapsed < 1.0 and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.6)  # two of the writer's 0.25 s flushes: that second is on disk
        filler = fill(disk)
        time.sleep(0.3)
        with pytest.raises(StudioError, match=r"(?i)no space left.*kept and is added"):
            ctl.teaching.stop_recording()
        assert not ctl.teaching.recording and len(ctl.session.recordings) == 0
    finally:
        ctl.close()
        ctl.shutdown()
    filler.unlink()
    again = store.open("s")
    assert len(again.recordings) == 1 and again.recordings[0].duration > 0.5, again.recovery_message


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
