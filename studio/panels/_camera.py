"""Camera views for each tab: Front, Top, Side and the home view, and a camera that stays above the floor.

Each view looks along a room axis at the task area, framed for the part of the window the side panel leaves
visible (its left two thirds), so the gripper's arrows lie in the picture's plane except the one that points
at the viewer."""

from __future__ import annotations

import logging
import math

import numpy as np
import viser

from studio.controller import FLOOR_Z

log = logging.getLogger(__name__)

#: The camera every tab starts with and "Reset" returns to: in front of Baxter and to its right, above the
#: table, framing the robot and the task area (metres, robot base frame; z up).
HOME_CAMERA_POSITION = (2.65, -0.63, 1.2)
HOME_CAMERA_LOOK_AT = (0.74, 0.71, 0.05)
HOME_CAMERA_FOV_DEG = 55.0
#: View name → (camera position, look-at point), m. Front: from the table's far side towards the robot; Top:
#: from above, the robot at the top of the picture; Side: from the robot's left.
VIEWS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "Front": ((2.5, 0.62, 0.6), (0.7, 0.62, -0.05)),
    "Top": ((0.88, 0.62, 2.3), (0.75, 0.62, -0.07)),
    "Side": ((0.1, 2.7, 0.3), (0.1, 0.2, 0.0)),
}
#: The camera stays at least this high above the floor, m.
CAMERA_ABOVE_FLOOR_M = 0.15


def set_view(client: viser.ClientHandle, name: str) -> None:
    """Put one tab's camera at a named view ("Front", "Top", "Side") or back home ("Reset")."""
    position, look_at = VIEWS.get(name, (HOME_CAMERA_POSITION, HOME_CAMERA_LOOK_AT))
    with client.atomic():
        client.camera.up_direction = (0.0, 0.0, 1.0)
        client.camera.position = position
        client.camera.look_at = look_at
        client.camera.fov = math.radians(HOME_CAMERA_FOV_DEG)


def keep_above_floor(server: viser.ViserServer) -> None:
    """Every tab's camera (and the point it orbits) is lifted back above the floor whenever it goes below."""

    def watch(client: viser.ClientHandle) -> None:
        def lift(camera: viser.CameraHandle) -> None:
            up = lifted(camera.position, camera.look_at)
            if up is None:
                return
            try:
                with client.atomic():
                    camera.position = up[0]
                    camera.look_at = up[1]
            except Exception:  # the tab closed meanwhile
                log.debug("camera of a closed tab", exc_info=True)

        client.camera.on_update(lift)

    server.on_client_connect(watch)


def lifted(
    position: np.ndarray | tuple[float, float, float], look_at: np.ndarray | tuple[float, float, float]
) -> tuple[tuple[float, float, float], tuple[float, float, float]] | None:
    """The camera's position and look-at point raised above the floor, or None when both are above it already."""
    p, at = np.array(position, dtype=float), np.array(look_at, dtype=float)
    low = FLOOR_Z + CAMERA_ABOVE_FLOOR_M
    if p[2] >= low and at[2] >= FLOOR_Z:
        return None
    p[2], at[2] = max(p[2], low), max(at[2], FLOOR_Z)
    return (float(p[0]), float(p[1]), float(p[2])), (float(at[0]), float(at[1]), float(at[2]))
