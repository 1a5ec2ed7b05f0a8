"""Browser-test helpers: a real `studio serve` subprocess, headless Debian Chromium via Playwright, screenshots.

Servers listen on 127.0.0.1 on a free port and are stopped by the test that started them; screenshots go
to ``test-artifacts/<test name>/`` (gitignored) so a person can look at each step.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import expect

from tests.conftest import free_port

# Every page assertion waits up to 30 s (Playwright's default is 5 s): CI runs the other tests beside the browser
# on a slower machine, where a frame of the software renderer alone can take a second. A passing check returns
# as soon as it holds, so this only changes how long a real failure takes to report.
expect.set_options(timeout=30_000)

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = ROOT / "test-artifacts"

#: Simulated seconds per wall second of the robot in the walks (studios in a subprocess) that are not about
#: timing (docs/decisions/093): the arm gets where it is sent sooner; takes are in the robot's own time.
FAST = 3.0


class StudioProcess:
    """`python -m studio serve` in a subprocess (so "restart the server" is a real restart)."""

    def __init__(
        self,
        sessions_dir: Path,
        session: str,
        port: int | None = None,
        log: Path | None = None,
        time_scale: float = 1.0,
    ) -> None:
        self.sessions_dir = sessions_dir
        self.time_scale = time_scale
        self.session = session
        self.port = port or free_port()
        self.log = log
        self.proc: subprocess.Popen[str] | None = None
        self.output: list[str] = []
        self._reader: threading.Thread | None = None
        self.printed_url = ""

    @property
    def base(self) -> str:
        """The studio's origin, without the key."""
        return f"http://127.0.0.1:{self.port}"

    @property
    def url(self) -> str:
        """The address the studio printed (with its key): what a person opens."""
        return self.printed_url

    def start(self, timeout: float = 180.0) -> StudioProcess:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.output = []
        studio = ["-m", "studio"] if self.time_scale == 1.0 else ["-m", "tests.e2e.fast_robot", str(self.time_scale)]
        self.proc = subprocess.Popen(
            [
                sys.executable,
                *studio,
                "serve",
                "--port",
                str(self.port),
                "--session",
                self.session,
                "--sessions-dir",
                str(self.sessions_dir),
                "--meshes",
                "light",
            ],
            cwd=ROOT,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        proc = self.proc

        def pump() -> None:
            assert proc.stdout is not None
            for line in proc.stdout:
                self.output.append(line)

        self._reader = threading.Thread(target=pump, daemon=True)
        self._reader.start()
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            text = "".join(self.output)
            m = re.search(r"open (http://\S+) in your browser", text)
            if m:
                self.printed_url = m.group(1)
                assert re.fullmatch(re.escape(self.base) + r"/\?key=[A-Za-z0-9_-]{16,}", self.printed_url), text
                return self
            if proc.poll() is not None:
                time.sleep(0.2)
                raise RuntimeError("studio exited early:\n" + "".join(self.output))
            time.sleep(0.1)
        self.stop()
        raise RuntimeError(f"studio did not start within {timeout} s:\n" + "".join(self.output))

    def read_output(self) -> str:
        return "".join(self.output)

    def stop(self) -> None:
        if self.proc is None:
            return
        if self.proc.poll() is None:
            self.proc.terminate()  # SIGTERM to our own child only
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5)
        if self._reader is not None:
            self._reader.join(timeout=5)
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        text = self.read_output()
        if self.log is not None:
            self.log.parent.mkdir(parents=True, exist_ok=True)
            self.log.write_text(text)
        self.proc = None


class Shots:
    """Numbered screenshots of a test's steps under test-artifacts/<test>/."""

    def __init__(self, name: str) -> None:
        self.dir = ARTIFACTS / re.sub(r"[^A-Za-z0-9_.-]+", "_", name)
        shutil.rmtree(self.dir, ignore_errors=True)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.n = 0
        self.t0 = self.t_last = time.monotonic()

    def __call__(self, page, step: str) -> Path:
        from tests.e2e.ui import dismiss_notifications

        dismiss_notifications(page)
        self.n += 1
        path = self.dir / f"{self.n:02d}-{re.sub(r'[^A-Za-z0-9_-]+', '-', step)}.png"
        page.screenshot(path=str(path))
        now = time.monotonic()
        with open(self.dir / "timings.txt", "a") as f:
            f.write(f"{path.name}: {now - self.t_last:6.1f} s (total {now - self.t0:6.1f} s)\n")
        self.t_last = now
        return path


@pytest.fixture
def shots(request) -> Shots:
    return Shots(request.node.name)


@pytest.fixture
def studio_factory(tmp_path: Path, request) -> Iterator:
    """Start studios on fresh ports; every one started is stopped at the end of the test."""
    started: list[StudioProcess] = []

    def make(
        session: str = "fresh", sessions_dir: Path | None = None, port: int | None = None, time_scale: float = 1.0
    ) -> StudioProcess:
        d = sessions_dir or (tmp_path / "sessions")
        d.mkdir(parents=True, exist_ok=True)
        log = ARTIFACTS / re.sub(r"[^A-Za-z0-9_.-]+", "_", request.node.name) / f"server-{len(started)}.log"
        s = StudioProcess(d, session, port=port, log=log, time_scale=time_scale)
        started.append(s)
        return s.start()

    yield make
    for s in started:
        s.stop()
