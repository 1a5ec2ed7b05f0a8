"""The browser studio: builds the viser server, the robot backend, the controller and the panels.

Everything a user sees is shared by all browser tabs (viser's server-level GUI and scene are broadcast), so two
tabs show the same robot and session and a reloaded page gets the current state replayed. :class:`Studio`
has a :class:`~studio.controller.Controller` (no viser) and adds the server and its scene, the panels,
notifications in the tabs, and the pose pump (one thread pushing the latest robot pose at up to 60 Hz)."""

from __future__ import annotations

import logging
import math
import sys
import threading
import time
from pathlib import Path
from typing import Any, Literal, Protocol, runtime_checkable

import viser

from studio.controller import Controller, Kind, LogNotifier, Topic
from studio.core.errors import StudioError
from studio.core.kinematics import baxter_urdf_path
from studio.core.text import sendable
from studio.panels import Panels, build_panels
from studio.panels._page import install as install_page
from studio.panels.steps import HOME_CAMERA_FOV_DEG, HOME_CAMERA_LOOK_AT, HOME_CAMERA_POSITION
from studio.robot_backend.base import RobotBackend
from studio.storage import DEFAULT_ROOT, SessionStore
from studio.storage.format import EXAMPLE_SESSIONS

log = logging.getLogger(__name__)

ROOT = Path(__file__).resolve().parent.parent
LIGHT_URDF = ROOT / "urdf" / "baxter_light.urdf"
DEFAULT_SESSION = "stack-cup"
#: Seconds within which a stopped studio (SIGTERM, Ctrl+C) has ended, whatever is still running.
STOP_S = 2.5
#: Initial view for every tab (and "Reset view"): in front of Baxter, to its right, framing the robot and table.
CAMERA_POSITION = HOME_CAMERA_POSITION
CAMERA_LOOK_AT = HOME_CAMERA_LOOK_AT
CAMERA_FOV_DEG = HOME_CAMERA_FOV_DEG
_COLORS: dict[Kind, Literal["red", "blue", "green", "yellow"]] = {
    "error": "red",
    "info": "blue",
    "success": "green",
    "warning": "yellow",
}


def robot_urdf_path(meshes: str = "auto") -> Path:
    """The URDF the scene draws: the light one (decimated meshes, fast without a GPU) unless ``full``."""
    if meshes not in ("auto", "light", "full"):
        raise StudioError(f'Unknown mesh choice "{meshes}": use auto, light or full.')
    if meshes == "full":
        try:
            return baxter_urdf_path()
        except FileNotFoundError:
            raise StudioError(
                "The original robot meshes come with the example-robot-data package, which the first start does "
                "not install. Install it (.venv/bin/pip install example-robot-data), or use the light meshes."
            ) from None
    if LIGHT_URDF.is_file():
        return LIGHT_URDF
    if meshes == "light":
        raise StudioError(
            "The light robot meshes are missing (urdf/baxter_light.urdf). Run: python scripts/decimate_meshes.py"
        )
    return baxter_urdf_path()


def configure_scene(server: viser.ViserServer) -> None:
    """Theme, initial camera, lights and ground of the shared scene."""
    s = server
    # No share button: it would offer to open the studio to the internet through a public relay.
    s.gui.configure_theme(
        control_width="large", dark_mode=False, show_logo=False, show_share_button=False, brand_color=(196, 30, 58)
    )
    s.initial_camera.position = CAMERA_POSITION
    s.initial_camera.look_at = CAMERA_LOOK_AT
    s.initial_camera.fov = math.radians(CAMERA_FOV_DEG)
    s.scene.set_up_direction("+z")
    # Software WebGL (no GPU) spends most of each frame on image-based lighting and shadow maps; with plain
    # lights Baxter still looks like Baxter (frame rates: bench/README.md, "Browser studio").
    s.scene.configure_environment_map(hdri=None)
    s.scene.configure_default_lights(enabled=True, cast_shadow=False)
    s.scene.add_light_hemisphere("/lights/sky", sky_color=(255, 255, 255), ground_color=(90, 90, 100), intensity=1.6)
    s.scene.add_light_directional("/lights/key", color=(255, 255, 255), intensity=1.2, position=(2.0, -1.5, 3.0))
    s.scene.add_grid("/ground", width=3.0, height=3.0, position=(0.5, 0.0, -0.93), cell_size=0.25, shadow_opacity=0.0)


@runtime_checkable
class _Tab(Protocol):
    """A browser tab that can show a notification (viser's ClientHandle)."""

    def add_notification(self, title: str, body: str, **kwargs: Any) -> object: ...


class BrowserNotifier:
    """Notifications in the browser tabs (one tab, or all); logged until the server is attached.

    The same message again within 5 s to the same tabs (e.g. from a slider or a handle being dragged while the
    robot runs a skill) is shown once.
    """

    def __init__(self) -> None:
        self.server: viser.ViserServer | None = None
        self._recent: dict[tuple[str, str, int | None], float] = {}

    def notify(self, title: str, body: str, *, kind: Kind = "error", client: object | None = None) -> None:
        if self.server is None:
            LogNotifier().notify(title, body, kind=kind)
            return
        title, body = sendable(title, line=True), sendable(body)  # words built from a file or the robot's text
        key = (title, body, id(client) if client is not None else None)
        now = time.monotonic()
        if now - self._recent.get(key, -1e9) < 5.0:
            return
        self._recent[key] = now
        if kind == "error":
            log.warning("%s: %s", title, body)
        tabs: list[_Tab] = [client] if isinstance(client, _Tab) else list(self.server.get_clients().values())
        close_after = None if kind == "error" else 6.0  # errors stay until closed
        for c in tabs:
            try:
                c.add_notification(title, body, color=_COLORS[kind], auto_close_seconds=close_after)
            except Exception:  # a tab that just closed
                log.debug("notification to a closed tab", exc_info=True)


class PosePump:
    """Pushes the pose the scene should show (``controller.display``) to the drawn robot at ~60 Hz, and ticks
    the panels (timers, handles following the robot, playback positions)."""

    hz = 60.0

    def __init__(self, controller: Controller, panels: Panels) -> None:
        self.controller = controller
        self.panels = panels
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="studio-pose-pump", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)

    def _loop(self) -> None:
        period = 1.0 / self.hz
        last_version = -1
        next_t = time.perf_counter()
        while not self._stop.is_set():
            now = time.perf_counter()
            try:
                version, _t, q, grip = self.controller.display.get()
                if version != last_version:
                    last_version = version
                    self.panels.robot.show_pose(q, grip)
                self.panels.tick(now)
            except Exception:
                log.exception("pose pump")
            next_t += period
            delay = next_t - time.perf_counter()
            if delay < -period:  # fell behind (busy CPU): skip, never burst
                next_t = time.perf_counter()
                delay = 0.0
            self._stop.wait(max(delay, 0.0))


class Studio:
    """The running studio: a :class:`Controller` plus its viser server, panels and pose pump.

    Build with :func:`build_app`; stop with :meth:`stop`.

    Attributes:
        controller: the studio's state and actions (what the panels drive).
        server: the viser server (``server.gui`` / ``server.scene`` are shared by every tab).
        port: the port it listens on.
        panels: the side-bar panels (:class:`studio.panels.Panels`).
    """

    def __init__(
        self,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        session: str | None = DEFAULT_SESSION,
        sessions_dir: Path | str = DEFAULT_ROOT,
        meshes: str = "auto",
        backend: RobotBackend | None = None,
        verbose: bool = False,
        key: str | Literal[False] | None = None,
    ) -> None:
        from studio.security import Access

        self.access = Access(host, key)  # who may connect (checked first: a refused --host starts nothing)
        if backend is None:
            from studio.robot_backend.simulated import SimulatedBaxter

            backend = SimulatedBaxter()
        self.notifier = BrowserNotifier()
        bundled = Path(sessions_dir).resolve() == DEFAULT_ROOT.resolve()  # the examples stay as they are there
        store = SessionStore(Path(sessions_dir), examples=EXAMPLE_SESSIONS if bundled else ())
        self.controller = Controller(
            store=store,
            session=session or store.last_open() or DEFAULT_SESSION,  # no choice: the session open last time
            backend=backend,
            notifier=self.notifier,
        )
        remember = lambda: store.remember_open(self.controller.session.name)  # noqa: E731
        remember()
        self.controller.events.on(Topic.SESSION, remember)
        self.urdf_path = robot_urdf_path(meshes)
        self.server = self.access.start_viser(host=host, port=port, label="Teaching Studio", verbose=verbose)
        self.notifier.server = self.server
        self.port = int(self.server.get_port())
        self.host = host
        configure_scene(self.server)
        self._stopped = False
        self.controller.start()
        self.panels = build_panels(self.controller, self.server, self.urdf_path)
        install_page(self.server)  # arrow keys stay in the focused control; hints on labels too
        self._pump = PosePump(self.controller, self.panels)
        self._pump.start()
        self.server.on_client_connect(self._greet)

    def _greet(self, client: viser.ClientHandle) -> None:
        """Show what happened while opening the session to a new tab (a crash recovery only to the first)."""
        sessions = self.controller.sessions
        for title, body in sessions.startup_notes():
            self.notifier.notify(title, body, kind="warning", client=client)
        sessions.startup_notes_shown()

    def url(self) -> str:
        """The address to open in the browser, with the key (see :mod:`studio.security`)."""
        return self.access.url(self.port)

    def stop(self, kept: threading.Event | None = None) -> None:
        """Keep a running take and unsaved thresholds (then ``kept`` is set), then stop the pump, the panels, the
        robot and the server (idempotent)."""
        if self._stopped:
            return
        self._stopped = True
        if self.access.presses is not None:
            self.access.presses.close()  # presses still waiting are dropped: the studio is stopping
        self.controller.close()
        if kept is not None:
            kept.set()
        self._pump.stop()
        try:
            self.panels.close()
        except Exception:
            log.exception("closing panels")
        self.controller.events.clear()  # a job still running must not draw into a stopped server
        self.controller.shutdown()
        self.server.stop()


def build_app(
    host: str = "127.0.0.1",
    port: int = 8080,
    session: str | None = DEFAULT_SESSION,
    sessions_dir: Path | str = DEFAULT_ROOT,
    meshes: str = "auto",
    *,
    backend: RobotBackend | None = None,
    verbose: bool = False,
    key: str | Literal[False] | None = None,
) -> Studio:
    """Build and start the studio (server listening, robot streaming); returns the :class:`Studio`.

    ``key``: None for a new random key in :meth:`Studio.url`, a chosen key, or False for none (this computer only).
    """
    return Studio(
        host=host,
        port=port,
        session=session,
        sessions_dir=sessions_dir,
        meshes=meshes,
        backend=backend,
        verbose=verbose,
        key=key,
    )


def exposure_warning(host: str, port: int) -> str | None:
    """The warning printed when the studio listens beyond this computer (None for localhost)."""
    if host in ("127.0.0.1", "localhost", "::1"):
        return None
    return (
        f"WARNING: listening on {host}: anyone who can reach this computer on port {port} and learns the address "
        "with its key (it travels unencrypted) can move the robot and read or change your sessions. "
        "Use --host 127.0.0.1 to keep it to this computer."
    )


def robot_backend(address: str | None) -> RobotBackend | None:
    """The robot ``studio serve --robot ADDRESS`` drives: a real Baxter through rosbridge at ``address``, or
    None (the simulated robot, the default) without one.

    Raises:
        InvalidInput: ``address`` is not a rosbridge websocket address (``ws://HOST:9090``).
    """
    if not address:
        return None
    import importlib.util

    if importlib.util.find_spec("roslibpy") is None:
        raise StudioError(
            "Driving a real Baxter needs the roslibpy package, which the first start does not install. Start the "
            "studio with: bash scripts/run-studio.sh --robot " + address + " (it installs it first)."
        )
    from studio.robot_backend.rosbridge import RosbridgeBaxter

    return RosbridgeBaxter(address)


def serve(
    host: str,
    port: int,
    session: str | None,
    sessions_dir: Path | str,
    meshes: str = "auto",
    key: str | Literal[False] | None = None,
    backend: RobotBackend | None = None,
) -> None:
    """Start the studio and block until Ctrl+C or SIGTERM (the ``studio serve`` command)."""
    import signal

    app = build_app(host, port, session, sessions_dir, meshes, key=key, backend=backend)
    warning = exposure_warning(host, port)
    if warning:
        print(warning, file=sys.stderr, flush=True)
    for title, body in app.controller.sessions.startup_notes():
        if title == "The session could not be opened":
            print(f"studio: {body}", file=sys.stderr, flush=True)
    stop = threading.Event()
    stopped = threading.Event()

    def on_term(*_: object) -> None:
        stop.set()
        end_after(STOP_S, stopped)

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, on_term)
    print(f"Teaching Studio is running: open {app.url()} in your browser (Ctrl+C stops it).", flush=True)
    try:
        while not stop.wait(0.5):
            pass
    except KeyboardInterrupt:
        end_after(STOP_S, stopped)
    finally:
        app.stop(kept=stopped)


def end_after(seconds: float, stopped: threading.Event) -> None:
    """End the process ``seconds`` from now if it is still running then (a callback or thread that does not
    finish must not keep a stopping studio alive; its saves are atomic, a take being saved is recovered at the
    next open). Exit status 0 when ``stopped`` is set (the studio kept the take and settings), 1 otherwise."""
    import os

    deadline = time.monotonic() + seconds

    def watch() -> None:
        while (left := deadline - time.monotonic()) > 0:
            time.sleep(min(left, 0.1))
        os._exit(0 if stopped.is_set() else 1)  # nothing else first: a log handler could be what hangs

    threading.Thread(target=watch, name="studio-stop-watch", daemon=True).start()


__all__ = [
    "BrowserNotifier",
    "PosePump",
    "Studio",
    "build_app",
    "configure_scene",
    "end_after",
    "exposure_warning",
    "robot_backend",
    "robot_urdf_path",
    "serve",
]
