"""The browser studio: builds the viser server, the robot backend, the controller and the panels.

Everything a user sees is shared by all browser tabs (viser's server-level GUI and scene are broadcast),
so two tabs show the same robot and session and a reloaded page gets the current state replayed.

The GUI state and every action live in :class:`studio.controller.Controller`; :class:`Studio` adds the
viser parts on top of it: the server and its scene, the panels, notifications in the tabs, and the pose pump.

Threads:
    * viser's thread pool runs GUI callbacks; each is wrapped by :meth:`Studio.guarded` so a failure is a
      notification in plain words and never stops the studio;
    * one *pose pump* thread pushes the latest robot pose to the scene at ~60 Hz (never per 1 kHz sample);
    * one *work* thread runs heavy jobs (training, IK along a trajectory, session files) one at a time;
    * one *key-point* thread recomputes key-points for the latest ε values (older slider positions are
      skipped, so dragging a slider never queues work).
"""

from __future__ import annotations

import logging
import math
import sys
import threading
import time
from pathlib import Path
from typing import Any

import viser

from studio.controller import (
    PALETTE,
    Controller,
    Events,
    KeypointItem,
    KeypointView,
    Playback,
    PoseSource,
)
from studio.core.errors import StudioError
from studio.core.kinematics import baxter_urdf_path
from studio.core.types import ALL_ARM_JOINTS
from studio.robot_backend.base import RobotBackend

log = logging.getLogger("studio")

ROOT = Path(__file__).resolve().parent.parent
LIGHT_URDF = ROOT / "urdf" / "baxter_light.urdf"
DEFAULT_SESSION = "stack-cup"
#: Initial view for every tab: in front of Baxter, to its right, looking at the workspace of the grippers.
CAMERA_POSITION = (2.5, -0.95, 1.05)
CAMERA_LOOK_AT = (0.3, 0.12, 0.12)
CAMERA_FOV_DEG = 55.0


def robot_urdf_path(meshes: str = "auto") -> Path:
    """The URDF the scene draws: the light one (decimated meshes, fast without a GPU) unless ``full``."""
    if meshes not in ("auto", "light", "full"):
        raise StudioError(f'Unknown mesh choice "{meshes}": use auto, light or full.')
    if meshes == "full":
        return baxter_urdf_path()
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
    s.gui.configure_theme(control_width="large", dark_mode=False, show_logo=False, brand_color=(196, 30, 58))
    s.initial_camera.position = CAMERA_POSITION
    s.initial_camera.look_at = CAMERA_LOOK_AT
    s.initial_camera.fov = math.radians(CAMERA_FOV_DEG)
    s.scene.set_up_direction("+z")
    # Software WebGL (no GPU) spends most of each frame on image-based lighting and shadow maps: without
    # them the studio draws ~20x faster and, with plain lights, Baxter still looks like Baxter.
    s.scene.configure_environment_map(hdri=None)
    s.scene.configure_default_lights(enabled=True, cast_shadow=False)
    s.scene.add_light_hemisphere("/lights/sky", sky_color=(255, 255, 255), ground_color=(90, 90, 100), intensity=1.6)
    s.scene.add_light_directional("/lights/key", color=(255, 255, 255), intensity=1.2, position=(2.0, -1.5, 3.0))
    s.scene.add_grid("/ground", width=3.0, height=3.0, position=(0.5, 0.0, -0.93), cell_size=0.25, shadow_opacity=0.0)


class Studio(Controller):
    """The running studio: the :class:`Controller` plus its viser server, panels and pose pump.

    Build with :func:`build_app`; stop with :meth:`stop`.

    Attributes:
        server: the viser server (``server.gui`` / ``server.scene`` are shared by every tab).
        port: the port it listens on.
        panels: the side-bar panels (:class:`studio.panels.Panels`).
        (and the controller's: ``baxter``, ``backend``, ``store``, ``session``, ...)
    """

    pump_hz = 60.0

    def __init__(
        self,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        session: str | None = DEFAULT_SESSION,
        sessions_dir: Path | str = ROOT / "sessions",
        meshes: str = "auto",
        backend: RobotBackend | None = None,
        verbose: bool = False,
    ) -> None:
        from studio.sessions import SessionStore

        self._recent_notes: dict[tuple[str, str], float] = {}
        if backend is None:
            from studio.robot_backend.simulated import SimulatedBaxter

            backend = SimulatedBaxter()
        super().__init__(store=SessionStore(Path(sessions_dir)), session=session or DEFAULT_SESSION, backend=backend)
        self.urdf_path = robot_urdf_path(meshes)

        self.server = viser.ViserServer(host=host, port=port, label="Teaching Studio", verbose=verbose)
        self.port = int(self.server.get_port())
        self.host = host
        configure_scene(self.server)

        self._stop = threading.Event()
        self.start_robot()

        from studio.panels import build_panels

        self.panels = build_panels(self)
        self._pump = threading.Thread(target=self._pump_loop, name="studio-pose-pump", daemon=True)
        self._pump.start()
        self.server.on_client_connect(self._greet)

    def _greet(self, client: viser.ClientHandle) -> None:
        """Show what happened while opening the session to a new tab (a crash recovery only to the first)."""
        for title, body in self.startup_notes():
            self.notify(title, body, kind="warning", client=client)
        self.startup_notes_shown()

    # -- the scene follows the robot -------------------------------------------------------------------
    def _pump_loop(self) -> None:
        period = 1.0 / self.pump_hz
        last_version = -1
        next_t = time.perf_counter()
        while not self._stop.is_set():
            now = time.perf_counter()
            try:
                version, _t, q, grip = self.display.get()
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

    # -- notifications in the browser tabs -------------------------------------------------------------
    def notify(self, title: str, body: str, *, kind: str = "error", client: viser.ClientHandle | None = None) -> None:
        """Show a notification in plain words (to one tab, or to every tab when ``client`` is None)."""
        key = (title, body)
        now = time.monotonic()
        if client is None and now - self._recent_notes.get(key, -1e9) < 5.0:
            return  # the same message again within seconds (e.g. from a slider being dragged): once is enough
        self._recent_notes[key] = now
        color: Any = {"error": "red", "info": "blue", "success": "green", "warning": "yellow"}.get(kind, "blue")
        clients = [client] if client is not None else list(self.server.get_clients().values())
        for c in clients:
            try:
                c.add_notification(title, body, color=color, auto_close_seconds=None if kind == "error" else 6.0)
            except Exception:  # a tab that just closed
                log.debug("notification to a closed tab", exc_info=True)
        if kind == "error":
            log.warning("%s: %s", title, body)

    # -- lifecycle ---------------------------------------------------------------------------------------
    def url(self) -> str:
        host = "127.0.0.1" if self.host in ("0.0.0.0", "") else self.host
        return f"http://{host}:{self.port}"

    def stop(self) -> None:
        """Stop the pump, the backend and the server (idempotent)."""
        if self._stop.is_set():
            return
        self.save_running_recording()  # keep a take that was running when the studio was stopped
        try:
            self.persist_params()  # and ε values not yet written by the key-point thread
        except Exception:
            log.exception("saving the key-point settings at shutdown")
        self._stop.set()
        try:
            self.panels.close()
        except Exception:
            log.exception("closing panels")
        self._pump.join(timeout=2.0)
        self.shutdown()
        self.server.stop()


def build_app(
    host: str = "127.0.0.1",
    port: int = 8080,
    session: str | None = DEFAULT_SESSION,
    sessions_dir: Path | str = ROOT / "sessions",
    meshes: str = "auto",
    *,
    backend: RobotBackend | None = None,
    verbose: bool = False,
) -> Studio:
    """Build and start the studio (server listening, robot streaming); returns the :class:`Studio`."""
    return Studio(
        host=host,
        port=port,
        session=session,
        sessions_dir=sessions_dir,
        meshes=meshes,
        backend=backend,
        verbose=verbose,
    )


def exposure_warning(host: str, port: int) -> str | None:
    """The warning printed when the studio listens beyond this computer (None for localhost)."""
    if host in ("127.0.0.1", "localhost", "::1"):
        return None
    return (
        f"WARNING: listening on {host}: anyone who can reach this computer on port {port} can move the "
        "robot and read or change your sessions. Use --host 127.0.0.1 to keep it to this computer."
    )


def serve(
    host: str, port: int, session: str | None, sessions_dir: Path | str, meshes: str = "auto", backend=None
) -> None:
    """Start the studio and block until Ctrl+C or SIGTERM (the ``studio serve`` command)."""
    import signal

    warning = exposure_warning(host, port)
    if warning:
        print(warning, file=sys.stderr, flush=True)
    app = build_app(host, port, session, sessions_dir, meshes, backend=backend)
    stop = threading.Event()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: stop.set())
    print(f"Teaching Studio is running: open {app.url()} in your browser (Ctrl+C stops it).", flush=True)
    try:
        while not stop.wait(1.0):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        app.stop()


__all__ = [
    "ALL_ARM_JOINTS",
    "PALETTE",
    "Controller",
    "Events",
    "KeypointItem",
    "KeypointView",
    "Playback",
    "PoseSource",
    "Studio",
    "build_app",
    "exposure_warning",
    "robot_urdf_path",
    "serve",
]
