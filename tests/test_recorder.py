"""Recorder: what is recorded, crash safety (kill -9), recovery, bad samples from the stream."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from studio.core.arms import arm_columns
from studio.core.errors import InvalidInput, RecordingError
from studio.core.kinematics import Baxter
from studio.core.types import ARMS, Recording
from studio.recorder import Recorder, pending_recordings, read_recording_file, recover_recordings
from studio.robot_backend.base import JointStateBatch, RobotBackend, RobotState
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore
from tests.conftest import wait_for

REPO = Path(__file__).resolve().parent.parent


class FakeBackend(RobotBackend):
    """Delivers hand-made batches (NaN, repeated time stamps...)."""

    def __init__(self) -> None:
        self.listeners: list[Callable[[JointStateBatch], None]] = []

    def start(self) -> None: ...
    def stop(self) -> None: ...

    def subscribe(self, listener):
        self.listeners.append(listener)
        return lambda: self.listeners.remove(listener)

    def command_joints(self, arm, q) -> None: ...
    def command_gripper(self, arm, width) -> None: ...

    def state(self) -> RobotState:
        return RobotState(0.0, np.zeros(14), np.zeros(2))

    def push(self, t: np.ndarray, q: np.ndarray | None = None, g: np.ndarray | None = None) -> None:
        n = len(t)
        q = np.tile(Baxter.load().neutral("left").tolist() * 2, (n, 1)) if q is None else q
        g = np.full((n, 2), 50.0) if g is None else g
        for fn in list(self.listeners):
            fn(JointStateBatch(np.asarray(t, float), np.asarray(q, float), np.asarray(g, float)))


def test_records_time_joints_grippers_and_fk_pose_of_taught_arms(tmp_path: Path) -> None:
    sim = SimulatedBaxter(sensor_noise=1e-4, seed=1)
    rec = Recorder(sim, tmp_path, arms="both", name="take 1")
    sim.step(7)  # before start: not recorded
    rec.start()
    sim.command_joints("left", np.zeros(7))
    sim.command_gripper("right", 10)
    sim.step(1500)
    assert rec.n_samples == 1500
    assert rec.elapsed == pytest.approx(1.499)
    demo = rec.stop_demo()
    r = demo.recording
    assert r.name == "take 1" and r.arms == ("left", "right") and len(r) == 1500
    assert np.allclose(np.diff(r.t), 1e-3) and r.t[0] == 0.0
    b = Baxter.load()
    for arm in ARMS:
        cols = arm_columns(arm)
        pos, wxyz = b.fk_batch(arm, r.q[:, cols])
        assert np.allclose(demo.poses[arm][:, :3], pos) and np.allclose(demo.poses[arm][:, 3:], wxyz)
    assert r.gripper[-1, 1] == pytest.approx(10.0)
    assert rec.path is not None and rec.path.exists()  # kept until saved
    rec.discard()
    assert not rec.path.exists()


def test_flushes_to_disk_while_recording(tmp_path: Path) -> None:
    sim = SimulatedBaxter()
    rec = Recorder(sim, tmp_path, arms="left", flush_interval=0.5)
    rec.start()
    sim.start()
    try:
        assert wait_for(lambda: sim.sim_time >= 1.6)
        now = sim.sim_time
        # Read the file as a crash would leave it, without asking the recorder to flush.
        on_disk = read_recording_file(rec.path)  # type: ignore[arg-type]
        assert on_disk is not None
        assert len(on_disk.recording) >= (now - 1.0) * 1000  # at most the last second is not yet on disk
    finally:
        sim.stop()
        rec.discard()


def test_a_full_disk_at_stop_keeps_what_was_written(tmp_path: Path) -> None:
    """Closing the file flushes its buffer; on a full disk that raises (CI, 2026-11-23). Stopping still
    returns the samples on disk, and says in words that the disk was full."""
    sim = SimulatedBaxter()
    rec = Recorder(sim, tmp_path, arms="left")
    rec.start()
    sim.step(500)
    rec.flush()
    real = rec._file
    assert real is not None
    fd, close = real.fileno(), real.close

    class FullDisk:
        def fileno(self) -> int:
            return fd

        def close(self) -> None:
            close()  # a buffered file is closed even when its last flush fails
            raise OSError(28, "No space left on device")

    rec._file = FullDisk()  # type: ignore[assignment]
    r = rec.stop()
    assert len(r) == 500 and real.closed
    assert rec.error is not None and "disk could not take more data" in rec.error
    rec.discard()


def test_nan_and_out_of_order_samples_are_skipped_with_a_message(tmp_path: Path) -> None:
    fb = FakeBackend()
    rec = Recorder(fb, tmp_path, arms="left")
    rec.start()
    q = np.tile(Baxter.load().neutral("left").tolist() * 2, (10, 1))
    q[3, 2] = np.nan
    fb.push(np.arange(10) / 1000.0, q)
    fb.push(np.array([0.005, 0.009, 0.010, 0.011]))  # two stale, two new
    r = rec.stop()
    assert len(r) == 9 + 2
    text = " ".join(rec.messages)
    assert "1 samples" in text and "invalid joint values" in text and "the rest of the demonstration is kept" in text
    assert "2 samples arrived out of order" in text


def test_stops_by_itself_at_the_length_limit(tmp_path: Path) -> None:
    sim = SimulatedBaxter()
    rec = Recorder(sim, tmp_path, arms="left", max_seconds=1.0)
    rec.start()
    sim.step(3000)
    rec.flush()
    sim.step(1000)
    r = rec.stop()
    assert len(r) == 1001 and r.duration == pytest.approx(1.0)
    assert any("longest allowed length" in m for m in rec.messages)


def test_empty_recording_is_an_error_in_plain_words(tmp_path: Path) -> None:
    rec = Recorder(SimulatedBaxter(), tmp_path, arms="left")
    rec.start()
    with pytest.raises(RecordingError, match="no joint states"):
        rec.stop()
    with pytest.raises(RecordingError, match="already been used"):
        rec.start()


def test_unwritable_folder_is_reported(tmp_path: Path) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(RecordingError, match="cannot be written"):
        Recorder(SimulatedBaxter(), f / "sub", arms="left").start()


def test_torn_last_row_is_dropped_on_recovery(tmp_path: Path) -> None:
    sim = SimulatedBaxter()
    rec = Recorder(sim, tmp_path, arms="left")
    rec.start()
    sim.step(500)
    rec.flush()
    assert rec.path is not None
    with open(rec.path, "ab") as f:
        f.write(b"\x00" * 8 * 30)  # a crash in the middle of a row, zero-filled (30 of 24 columns)
    rec._finish()  # stop without reading (as if the process had died)
    recs, msg = recover_recordings(tmp_path)
    assert len(recs) == 1 and len(recs[0]) == 500
    assert "recovered" in msg and "500 samples" in msg


def test_live_recording_is_not_recovered_by_another_reader(tmp_path: Path) -> None:
    sim = SimulatedBaxter()
    rec = Recorder(sim, tmp_path, arms="left")
    rec.start()
    sim.step(100)
    rec.flush()
    assert pending_recordings(tmp_path) == []  # locked: still being written
    assert recover_recordings(tmp_path) == ([], "")
    rec.stop()
    assert pending_recordings(tmp_path) == [rec.path]


CHILD = textwrap.dedent(
    """
    import sys, time
    from studio.robot_backend.simulated import SimulatedBaxter
    from studio.recorder import Recorder
    import numpy as np
    sim = SimulatedBaxter(time_scale=2.0)
    rec = Recorder(sim, sys.argv[1], arms="left", name="interrupted take", flush_interval=0.2)
    rec.start()
    sim.command_joints("left", np.zeros(7))
    sim.start()
    while rec.elapsed < 2.5:  # the stream runs late on a loaded machine: wait for the samples, not the clock
        time.sleep(0.05)
    seconds = rec.elapsed  # every sample counted here is on disk once flush() returns
    rec.flush()
    print("recording", seconds, flush=True)
    time.sleep(60)
    """
)


def test_kill_dash_nine_mid_recording_then_recover_on_next_open(tmp_path: Path) -> None:
    store = SessionStore(tmp_path / "sessions")
    session = store.create("crash test")
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(session.recording_dir)],
        stdout=subprocess.PIPE,
        cwd=REPO,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    try:
        assert proc.stdout is not None
        said, written = proc.stdout.readline().split()
        assert said == b"recording"
        time.sleep(0.5)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        if proc.stdout is not None:
            proc.stdout.close()
    assert proc.returncode == -signal.SIGKILL
    assert store.pending_recoveries() == ["crash test"]
    reopened = store.open("crash test")
    assert "stopped while recording" in reopened.recovery_message
    assert reopened.demo_names == ["interrupted take (recovered)"]
    r = reopened.recordings[0]
    # everything written before the kill is back (what came after it may be lost)
    assert r.duration >= float(written) - 1e-6 > 2.0
    assert np.allclose(np.diff(r.t), 1e-3)
    assert list(session.recording_dir.glob("*.rec")) == []  # saved into the session, file removed
    assert store.open("crash test").recovery_message == ""  # recovered once, not again
    assert store.pending_recoveries() == []


def test_memory_stays_bounded_when_the_producer_outruns_the_writer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import studio.recorder.writer as recorder_mod

    monkeypatch.setattr(recorder_mod, "MAX_PENDING", 500)
    sim = SimulatedBaxter()
    rec = Recorder(sim, tmp_path, arms="left", flush_interval=1.0)
    rec.start()
    worst = 0
    for _ in range(60):
        sim.step(100)  # far faster than real time
        worst = max(worst, rec._pending_n)
    assert worst <= 600  # the producer waited for the writer instead of piling up samples
    assert rec.n_samples == 6000
    assert len(rec.stop()) == 6000


def test_a_one_sample_take_left_by_a_crash_does_not_block_the_session(tmp_path: Path) -> None:
    store = SessionStore(tmp_path / "sessions")
    session = store.create("s1")
    sim = SimulatedBaxter()
    rec = Recorder(sim, session.recording_dir, ("left",), name="demo 1")
    rec.start()
    sim.step(1)
    rec.flush()
    rec._finish()  # the process died: the file stays, unlocked, with a single sample
    assert rec.path is not None
    first = store.open("s1")
    assert first.recordings == [] and f'"{rec.path.name}"' in first.recovery_message
    assert "not a demonstration" in first.recovery_message
    assert not rec.path.exists() and pending_recordings(session.recording_dir) == []
    assert store.open("s1").recovery_message == ""


def test_one_sample_recovery_message_names_the_file(tmp_path: Path) -> None:
    sim = SimulatedBaxter()
    rec = Recorder(sim, tmp_path, ("left",), name="demo 1")
    rec.start()
    sim.step(1)
    rec.flush()
    rec._finish()
    assert rec.path is not None
    recs, msg = recover_recordings(tmp_path)
    assert recs == [] and f'"{rec.path.name}"' in msg and "single sample" in msg
    assert not rec.path.exists()


def test_a_recording_the_session_refuses_is_kept_aside_and_reported(tmp_path: Path) -> None:
    store = SessionStore(tmp_path / "sessions")
    session = store.create("s1")
    sim = SimulatedBaxter()
    rec = Recorder(sim, session.recording_dir, ("left",), name="demo 1")
    rec.start()
    sim.step(50)
    rec.flush()
    rec._finish()
    assert rec.path is not None

    def refuse(r: Recording) -> int:
        raise InvalidInput("A session holds at most 1000 demonstrations.")

    recs, msg = recover_recordings(session.recording_dir, add=refuse)
    assert recs == []
    assert f'"{rec.path.name}"' in msg and "at most 1000" in msg and f'"{rec.path.name}.damaged"' in msg
    assert not rec.path.exists() and rec.path.with_name(rec.path.name + ".damaged").exists()
    assert store.open("s1").recovery_message == ""  # set aside: the next open is clean


def test_stopping_a_take_the_session_refuses_leaves_nothing_for_the_next_open(tmp_path: Path) -> None:
    from studio.controller import Controller

    store = SessionStore(tmp_path / "sessions")
    store.create("s1")
    sim = SimulatedBaxter()
    ctl = Controller(store=store, session="s1", backend=sim)
    try:
        ctl.teaching.start_recording()
        sim.step(1)
        with pytest.raises(InvalidInput, match="at least two"):
            ctl.teaching.stop_recording()
        assert pending_recordings(ctl.session.recording_dir) == []
        assert store.open("s1").recovery_message == ""
    finally:
        ctl.shutdown()
