"""Shared test helpers: one free port, one wait, the example session copied per test, a notifier that
records, and one headless Chromium for the browser tests (Debian's, never ``playwright install``)."""

from __future__ import annotations

import fcntl
import os
import shutil
import socket
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np
import pytest

from studio.controller import Kind, Notifier
from studio.robot_backend.base import JointStateBatch

if TYPE_CHECKING:
    from playwright.sync_api import Browser, BrowserContext, Page

    from studio.app import Studio
    from studio.controller import Controller
    from studio.robot_backend.simulated import SimulatedBaxter

ROOT = Path(__file__).resolve().parent.parent
CHROMIUM = os.environ.get("STUDIO_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


#: Test pages run at most one frame every FRAME_MS while something moves (but freely while the mouse acts on the
#: page) and viser's once-a-second safety-net frame every HEARTBEAT_MS (docs/decisions/093); they paint the 3D view
#: only when a test looks at it, which makes a frame cheap enough to run four a second (decision 099). ``drawn()``
#: asks for a painted frame and waits until it is painted, so a screenshot shows what the page holds.
#: ``STUDIO_TEST_FRAMES=native`` leaves pages as they are (to measure the difference: bench/README.md).
FRAME_MS, HEARTBEAT_MS = 250, 10_000
NATIVE_FRAMES = os.environ.get("STUDIO_TEST_FRAMES") == "native"


def page_js(frame_ms: int = FRAME_MS, heartbeat_ms: int = HEARTBEAT_MS) -> str:
    """A page script (run before the page's own): a callback asking for the next animation frame again (the
    render loop) waits until ``frame_ms`` after the last such frame, a one-off (a transition) does not, nor does
    any while the mouse acts on the 3D view (a drag draws as it does for a person; a click on the panel does not);
    WebGL without multisampling; the 3D view painted only in a frame asked for (``window.__studioDrawNow()``, which
    counts ``window.__studioLooks`` once painted): the other frames run as they do for a person, their draws on the
    page's canvas skipped; viser's heartbeat every ``heartbeat_ms``; frames counted (``window.__studioFrames``)."""
    return _PAGE_JS.replace("FRAME_MS_", str(int(frame_ms))).replace("HEARTBEAT_MS_", str(int(heartbeat_ms)))


_PAGE_JS = """(() => {
    const FRAME_MS = FRAME_MS_, HEARTBEAT_MS = HEARTBEAT_MS_, POINTER_MS = 500;
    const raf = window.requestAnimationFrame.bind(window), caf = window.cancelAnimationFrame.bind(window);
    const interval = window.setInterval.bind(window);
    const ran = new WeakSet(), native = new Map();
    let last = -Infinity, waiting = false, next = 1, due = new Map(), timer = null;
    window.__studioFrames = 0;
    const run = (now) => {
        waiting = false;
        last = now;
        window.__studioFrames += 1;
        const cbs = [...due.values()];
        due = new Map();
        for (const cb of cbs) cb(now);
    };
    window.requestAnimationFrame = (cb) => {
        const id = next++;
        if (!ran.has(cb)) {
            ran.add(cb);
            native.set(id, raf((now) => { native.delete(id); window.__studioFrames += 1; cb(now); }));
            return id;
        }
        due.set(id, cb);
        if (!waiting) {
            waiting = true;
            const now = performance.now(), wait = now < handled ? 0 : last + FRAME_MS - now;
            if (wait > 0) timer = setTimeout(() => { timer = null; raf(run); }, wait);
            else raf(run);
        }
        return id;
    };
    // The 3D view is painted only when a test looks at it: software WebGL spends nearly all of a frame's CPU in the
    // draws on the page's canvas (decision 099). Every frame still runs (the render loop, the handles, viser's
    // messages); between looks its draws on the canvas are skipped and the canvas keeps the last painted picture
    // (viser asks for preserveDrawingBuffer). Draws into off-screen targets (the renderer's own passes) always run.
    let look = false, ending = false;
    window.__studioLooks = 0;
    for (const P of [WebGLRenderingContext.prototype, WebGL2RenderingContext.prototype]) {
        const bind = P.bindFramebuffer;
        P.bindFramebuffer = function (target, fb) {
            if (target !== 0x8CA8) this.__studioTarget = fb;  // not READ_FRAMEBUFFER: where draws go
            return bind.call(this, target, fb);
        };
        for (const name of ["clear", "drawArrays", "drawElements", "drawArraysInstanced", "drawElementsInstanced",
                            "drawRangeElements", "blitFramebuffer"]) {
            const draw = P[name];
            if (!draw) continue;
            P[name] = function (...args) {
                if (!this.__studioTarget) {  // the page's canvas
                    if (!look) return undefined;
                    if (!ending) {  // the whole frame is painted: it ends when the frame's task has run
                        ending = true;
                        queueMicrotask(() => { ending = false; look = false; window.__studioLooks += 1; });
                    }
                }
                return draw.apply(this, args);
            };
        }
    }
    // a painted frame now (for a screenshot): the render loop asked for one, and one that waits is not kept waiting
    window.__studioDrawNow = () => {
        look = true;
        if (window.__studioDraw) window.__studioDraw();
        if (timer !== null) { clearTimeout(timer); timer = null; raf(run); }
    };
    // the mouse on the page (a drag of a handle, an orbit): frames as a person sees them, until POINTER_MS after
    let handled = -Infinity;
    const pointer = (e) => {
        if (!(e.target instanceof HTMLCanvasElement)) return;  // a click on the panel draws nothing new
        handled = performance.now() + POINTER_MS;
        if (timer !== null) { clearTimeout(timer); timer = null; raf(run); }
    };
    for (const type of ["pointerdown", "pointermove", "pointerup", "wheel"])
        window.addEventListener(type, pointer, { capture: true, passive: true });
    window.cancelAnimationFrame = (id) => {
        due.delete(id);
        if (native.has(id)) { caf(native.get(id)); native.delete(id); }
    };
    // software WebGL spends about a third of a frame on multisampling: test pages draw without it
    const getContext = HTMLCanvasElement.prototype.getContext;
    HTMLCanvasElement.prototype.getContext = function (type, attrs) {
        if (type === "webgl2" || type === "webgl") attrs = Object.assign({}, attrs || {}, { antialias: false });
        return getContext.call(this, type, attrs);
    };
    // viser's render heartbeat is its only one-second interval: slowed, and kept as the way to ask for a frame
    window.setInterval = (fn, ms, ...args) => {
        if (ms === 1000 && !window.__studioDraw) {
            window.__studioDraw = fn;
            ms = HEARTBEAT_MS;
        }
        return interval(fn, ms, ...args);
    };
})();"""


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def reap(proc: subprocess.Popen) -> None:
    """Kill ``proc`` if it still runs, wait for it, and close its output."""
    if proc.poll() is None:
        proc.kill()
        proc.wait()
    if proc.stdout is not None:
        proc.stdout.close()


def cpu_seconds(pid: int) -> tuple[str, float]:
    """The state letter of process ``pid`` ("Z": ended, not yet reaped) and the CPU seconds it used (all threads)."""
    f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return f[0], (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def end_with_signal(proc: subprocess.Popen, sig: int, timeout: float = 60.0) -> float:
    """Send ``sig`` to ``proc`` (a child of this test), wait until it has ended (``timeout``: wall seconds, only
    against a hang) and reap it; returns the CPU seconds it used after the signal (how long it kept working,
    whatever else loads the machine)."""
    _, before = cpu_seconds(proc.pid)
    proc.send_signal(sig)
    assert wait_for(lambda: cpu_seconds(proc.pid)[0] == "Z", timeout), f"still running {timeout} s after {sig}"
    _, after = cpu_seconds(proc.pid)
    proc.wait(timeout=10)
    return after - before


def wait_for(pred: Callable[[], bool], timeout: float = 30.0) -> bool:
    """Poll ``pred`` until it holds (True) or ``timeout`` seconds passed (its last value)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(0.05)
    return bool(pred())


def quiet_for(count: Callable[[], object], seconds: float, timeout: float = 30.0) -> bool:
    """Poll until ``count()`` has stayed the same for ``seconds`` (True), or ``timeout`` passed (False)."""
    deadline = time.monotonic() + timeout
    last, since = count(), time.monotonic()
    while time.monotonic() < deadline:
        time.sleep(0.05)
        now = count()
        if now != last:
            last, since = now, time.monotonic()
        elif time.monotonic() - since >= seconds:
            return True
    return False


class RecordingNotifier:
    """A notifier that keeps every notification as (kind, title, body), then passes it on (if given one)."""

    def __init__(self, then: Notifier | None = None) -> None:
        self.notes: list[tuple[str, str, str]] = []
        self.then = then

    def notify(self, title: str, body: str, *, kind: Kind = "error", client: object | None = None) -> None:
        self.notes.append((kind, title, body))
        if self.then is not None:
            self.then.notify(title, body, kind=kind, client=client)

    def titles(self) -> list[str]:
        return [title for _, title, _ in self.notes]


@pytest.fixture
def sessions(tmp_path: Path) -> Path:
    """A sessions folder holding a copy of the "stack-cup" example."""
    d = tmp_path / "sessions"
    d.mkdir()
    shutil.copytree(ROOT / "sessions" / "stack-cup", d / "stack-cup")
    return d


def run_once(tmp_path_factory: pytest.TempPathFactory, name: str, fill: Callable[[Path], None]) -> Path:
    """A sessions folder that the whole run shares (every worker of ``-n``), filled by ``fill(folder)`` once: the
    first worker to come fills it under a file lock, the others wait and find it filled."""
    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base  # the run's own folder either way
    shared = root / name
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file is closed
        if not (shared / "done").exists():
            shutil.rmtree(shared, ignore_errors=True)  # a worker's filling that failed
            (shared / "sessions").mkdir(parents=True)
            fill(shared / "sessions")
            (shared / "done").touch()
    return shared / "sessions"


@pytest.fixture(scope="session")
def trained_examples(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder holding the "pick-place" and "stack-cup" examples, each trained once in the run as the Train
    button trains (``studio learn``) and saved: copied by the tests whose subject comes after training."""
    from studio.cli import main

    def fill(d: Path) -> None:
        for name in ("pick-place", "stack-cup"):
            shutil.copytree(ROOT / "sessions" / name, d / name)
            assert main(["learn", name, "--sessions-dir", str(d)]) == 0

    return run_once(tmp_path_factory, "trained", fill)


def trained_copy(trained: Path, name: str, sessions: Path) -> Path:
    """Copy the trained example ``name`` from ``trained`` (:func:`trained_examples`) into ``sessions``."""
    sessions.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(sessions / name, ignore_errors=True)
    shutil.copytree(trained / name, sessions / name)
    return sessions


def _started(sessions: Path) -> tuple[Controller, SimulatedBaxter]:
    """A started controller on the "stack-cup" example, and its simulated robot (streaming in real time)."""
    from studio.controller import Controller
    from studio.robot_backend.simulated import SimulatedBaxter
    from studio.storage import SessionStore

    sim = SimulatedBaxter()
    c = Controller(store=SessionStore(sessions), session="stack-cup", backend=sim, notifier=RecordingNotifier())
    c.start()
    return c, sim


@pytest.fixture
def ctl(sessions: Path) -> Iterator[Controller]:
    """A started controller on the "stack-cup" example with a simulated robot streaming in real time."""
    c, _ = _started(sessions)
    yield c
    c.close()
    c.shutdown()


@pytest.fixture
def app(sessions: Path) -> Iterator[Studio]:
    """The studio in-process on the "stack-cup" example; its notifications are also kept
    (``app.controller.notifier.notes``)."""
    from studio.app import build_app

    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    a.controller.notifier = RecordingNotifier(then=a.notifier)
    yield a
    a.stop()


@pytest.fixture
def rig(sessions: Path) -> Iterator[tuple[Controller, SimulatedBaxter]]:
    """A controller on the example session whose simulated robot is stepped by hand (fast, deterministic)."""
    c, sim = _started(sessions)
    sim.stop()  # manual steps from here on
    yield c, sim
    c.close()
    c.shutdown()


#: Background threads of a controller (its work thread and helpers): a job still running when a test shut its
#: controller down (a judge after Train) must end before the next test, or it runs under that test's patches.
WORK_THREADS = ("studio-work", "studio-helper")


@pytest.fixture(autouse=True)
def _work_threads_end_with_their_test() -> Iterator[None]:
    before = set(threading.enumerate())
    yield
    deadline = time.monotonic() + 30.0
    for t in threading.enumerate():
        if t not in before and t.name.startswith(WORK_THREADS):
            t.join(timeout=max(0.0, deadline - time.monotonic()))


@pytest.fixture(scope="session")
def browser() -> Iterator[Browser]:
    """One headless Debian Chromium for the whole run (pages are opened and closed by each test); its pages run
    :func:`page_js` and take screenshots of a freshly drawn frame (:func:`drawn`)."""
    if not Path(CHROMIUM).exists():
        pytest.skip(f"Debian chromium not found at {CHROMIUM} (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        yield cast("Browser", _Drawn(b))
        b.close()


def drawn(page: Page, timeout: float = 30.0) -> None:
    """Ask ``page`` for a frame with the 3D view painted and wait until it is: what the page holds is then on
    screen (a page that draws no scene, e.g. a refusal, after its next paint)."""
    done = page.evaluate(
        """(timeout) => new Promise((resolve) => {
            if (window.__studioFrames === undefined) return resolve(true);  // a page without page_js()
            // a page without a render loop (not the studio's: a refusal, another site): its next paint will do
            if (!window.__studioDraw) return requestAnimationFrame(() => resolve(true));
            const n = window.__studioLooks, until = performance.now() + timeout;
            window.__studioDrawNow();
            const check = () => {
                if (window.__studioLooks > n) resolve(true);
                else if (performance.now() > until) resolve(false);
                else setTimeout(check, 20);
            };
            check();
        })""",
        timeout * 1000,
    )
    assert done, f"the page drew no frame within {timeout} s"


class _Drawn:
    """A browser (or context) whose new pages run :func:`page_js` and draw a frame before each screenshot."""

    def __init__(self, inner: Browser | BrowserContext) -> None:
        self._inner = inner

    def __getattr__(self, name: str) -> object:
        return getattr(self._inner, name)

    def new_context(self, **kwargs: object) -> BrowserContext:
        return cast("BrowserContext", _Drawn(self._inner.new_context(**kwargs)))  # type: ignore[union-attr,arg-type]

    def new_page(self, **kwargs: object) -> Page:
        page = self._inner.new_page(**kwargs)  # type: ignore[arg-type]
        if not NATIVE_FRAMES:
            page.add_init_script(page_js())
        shot = page.screenshot

        def screenshot(**kw: object) -> bytes:
            drawn(page)
            return shot(**kw)  # type: ignore[arg-type]

        setattr(page, "screenshot", screenshot)  # noqa: B010
        return page


#: The browser walks, slowest first (bench/README.md, "Issue 28 — a faster suite"); the other browser tests follow
#: them, then every other test as collected.
SLOWEST_FIRST = (
    "test_scene_walk.py::test_teach_with_objects_to_the_task_result",
    "test_teach_skill.py::test_teach_a_skill_like_a_user",
    "test_first_skill.py::test_first_skill_from_the_sessions_step",
    "test_teach_mouse.py::test_teach_stack_cup_with_mouse_and_keys",
    "test_drawing_browser.py::test_drawn_grippers_cover_their_fk_points",
    "test_execution_browser.py::test_run_on_robot_follows_the_plan_and_does_the_task",
    "test_handle_browser.py::test_the_blocks_handle_in_top_view_goes_the_way_the_mouse_goes",
    "test_failures_and_tabs.py::test_two_tabs_see_the_same_robot_and_session",
    "test_quality_browser.py::test_live_path_suggest_and_verdict",
    "test_words_browser.py::test_words_for_a_newcomer",
    "test_objects_browser.py::test_move_the_cup_and_the_skill_follows_it",
)


def _rank(item: pytest.Item) -> int:
    """Where ``item`` runs in the order handed out: a listed walk by its place, then other browser tests, then the
    rest."""
    nodeid = item.nodeid.replace("\\", "/")
    name = nodeid.rsplit("/", 1)[-1]
    if name in SLOWEST_FIRST:
        return SLOWEST_FIRST.index(name)
    return len(SLOWEST_FIRST) + (0 if "tests/e2e/" in nodeid or nodeid.startswith("e2e/") else 1)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """With ``-n 3`` (scripts/run-tests.sh) each worker is handed the next test when it is free: the slowest
    browser walks go first, so that the many short tests fill in at the end and the workers end together."""
    items.sort(key=_rank)


class Collector:
    """A robot backend listener keeping every joint-state batch (thread-safe); ``arrays()``: t, q, gripper."""

    def __init__(self) -> None:
        self.batches: list[JointStateBatch] = []
        self.lock = threading.Lock()

    def __call__(self, b: JointStateBatch) -> None:
        with self.lock:
            self.batches.append(b)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        with self.lock:
            bs = list(self.batches)
        return (
            np.concatenate([b.t for b in bs]),
            np.concatenate([b.q for b in bs]),
            np.concatenate([b.gripper for b in bs]),
        )
