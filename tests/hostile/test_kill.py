"""kill -9 at any moment: while saving (add, trim, rename, hide, delete, learn) and while recording.

After a kill the session opens with every demonstration whose save had finished, the take being recorded is
recovered up to its last flush, and opening cleans what the kill left (temporary files, demo files the
manifest never listed). ``bench/bench_hostile.py`` runs the same loops 40 times each.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from studio.recorder.files import read_recording_file
from studio.storage import SessionStore
from tests.conftest import wait_for
from tests.hostile.builders import ROOT, make_rec

SAVER = """
import sys, itertools
sys.path.insert(0, {root!r})
from studio.storage import SessionStore
from tests.hostile.builders import make_rec
s = SessionStore({sessions!r}).open("victim")
print("ready", flush=True)
for i in itertools.count():
    k = i % 5
    if k == 0:
        s.add_recording(make_rec(n=3000, seed=i, name=f"take {{i}}"))
    elif k == 1 and len(s.recordings) > 1:
        s.trim_demo(len(s.recordings) - 1, 0.1, 2.5)
    elif k == 2 and s.recordings:
        s.rename_demo(0, f"first {{i}}")
    elif k == 3 and s.recordings:
        s.set_demo_hidden(0, i % 2 == 0)
    elif k == 4 and len(s.recordings) > 3:
        s.delete_demo(1)
"""

RECORDER = """
import sys, time
sys.path.insert(0, {root!r})
from studio.storage import SessionStore
from studio.recorder import Recorder
from studio.robot_backend.simulated import SimulatedBaxter
s = SessionStore({sessions!r}).open("victim")
sim = SimulatedBaxter()
sim.start()
rec = Recorder(sim, s.recording_dir, ("left",), name="interrupted", flush_interval=0.25)
rec.start()
print("recording", flush=True)
while True:
    time.sleep(1)
"""


def leftovers(path: Path) -> list[str]:
    """Temporary files and demo files the manifest does not list."""
    s = SessionStore(path.parent).open(path.name, recover=False)
    listed = set(s.demo_files) | {i.file for i in s.skill_info.values()}
    out = [str(p.relative_to(path)) for p in path.rglob(".tmp-*")]
    out += [f"demos/{p.name}" for p in (path / "demos").glob("*.npz") if f"demos/{p.name}" not in listed]
    return sorted(out)


def start(code: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(code)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def kill_after(proc: subprocess.Popen[str], seconds: float, ready: str) -> float:
    """Wait for ``ready``, then ``seconds``, then kill -9; returns the seconds from ``ready`` to the kill."""
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert ready in line, (line, proc.stderr.read() if proc.stderr else "")
    t0 = time.monotonic()
    time.sleep(seconds)
    os.kill(proc.pid, signal.SIGKILL)
    alive = time.monotonic() - t0
    proc.communicate(timeout=10)  # reaps it and closes its pipes
    return alive


@pytest.mark.slow
def test_kill_9_during_saves_loses_nothing_saved_and_opening_cleans_up(tmp_path: Path) -> None:
    rng = random.Random(7)
    store = SessionStore(tmp_path / "sessions")
    s = store.create("victim")
    s.add_recording(make_rec(seed=1))
    for run in range(8):
        proc = start(SAVER.format(root=str(ROOT), sessions=str(store.root)))
        kill_after(proc, rng.uniform(0.2, 1.2), "ready")
        opened = store.open("victim")  # must open: every save is atomic
        assert opened.recordings, f"run {run}: the session lost its demonstrations"
        assert not opened.problems, opened.problems
        assert leftovers(opened.path) == [], f"run {run}: opening left {leftovers(opened.path)}"


def kill_when_flushed(proc: subprocess.Popen[str], folder: Path, seconds: float) -> float:
    """Wait until the take being recorded holds ``seconds`` on disk (the recorder flushes as it goes), then
    kill -9; returns the seconds the file held just before the kill."""
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert "recording" in line, (line, proc.stderr.read() if proc.stderr else "")

    def held() -> float:
        files = list(folder.rglob("*.rec"))
        demo = read_recording_file(files[0], poses=False) if len(files) == 1 else None
        return demo.recording.duration if demo is not None else 0.0

    assert wait_for(lambda: held() >= seconds), f"the take never held {seconds} s on disk"
    on_disk = held()
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=10)  # reaps it and closes its pipes
    return on_disk


@pytest.mark.slow
def test_kill_9_while_recording_loses_at_most_the_last_flush(tmp_path: Path) -> None:
    """Whatever the take held on disk when the recorder was killed is recovered (only what was not flushed yet
    is lost)."""
    store = SessionStore(tmp_path / "sessions")
    store.create("victim")
    for run in range(2):
        proc = start(RECORDER.format(root=str(ROOT), sessions=str(store.root)))
        on_disk = kill_when_flushed(proc, store.root / "victim", 1.5 + run)
        s = store.open("victim")
        assert "recovered" in s.recovery_message, s.recovery_message
        got = s.recordings[-1]
        assert got.name.startswith("interrupted") and got.duration >= on_disk, (got.duration, on_disk)
        assert leftovers(s.path) == []
    assert len(store.open("victim").recordings) == 2
