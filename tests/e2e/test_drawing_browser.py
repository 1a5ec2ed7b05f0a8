"""In real Chromium: the gripper the page draws covers the pixel where pinocchio's FK puts it.

The studio runs in-process (so the test can set the page's camera and read it back as the browser reports
it). At two configurations of both arms, seen from the top and from the front, the test takes a screenshot,
hides only each gripper's drawing (the ``<arm>_gripper_base_link`` subtree: gripper base and fingers) and
takes another: the pixels that changed are the drawn gripper. Two FK points on the closed fingers (6 cm and
1.5 cm back from the fingertip point ``<arm>_gripper``), projected with the page's own camera, must lie on
the outline of those pixels (within 1 px); the other configuration's FK points must not (so the check can
fail). Screenshots (plain, and with the gripper tinted and the points marked) go to test-artifacts/drawing/.
"""

from __future__ import annotations

import io
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import FloatRect

from studio.app import build_app
from studio.core.kinematics import matrix_from_quat_wxyz
from studio.robot_backend.simulated import SimulatedBaxter
from tests.conftest import wait_for
from tests.e2e import ui
from tests.e2e.conftest import ARTIFACTS, free_port

pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parents[2]

#: Two configurations of both arms (left s0..w2, right s0..w2), found with Baxter.ik, with the grippers in
#: front of the robot pointing forward and down (so the top and the front camera both see them).
CONFIGS = {
    # left gripper at (0.85, 0.45, 0.05), right at (0.70, -0.25, 0.25)
    "reach": np.array([-0.38, -0.69, -0.24, 2.06, -0.14, -0.93, 0.37, -1.04, -2.14, 2.29, 2.44, -2.39, 0.78, 0.06]),
    # left gripper at (0.60, 0.20, -0.10), right at (0.85, -0.55, 0.0)
    "low": np.array([0.09, -0.1, -0.36, 2.27, 0.8, -1.06, 0.55, -0.39, -0.32, 0.75, 1.41, 0.54, 0.4, 1.54]),
}
#: Cameras (position, look-at, up) for the two views.
VIEWS = {
    "top": ((0.25, 0.0, 3.2), (0.55, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "front": ((3.2, 0.3, 0.45), (0.3, 0.3, 0.1), (0.0, 0.0, 1.0)),  # shifted: the panel covers the right
}


def _screenshot(page) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)


def _settle(page, seconds: float = 1.0) -> np.ndarray:
    """Screenshots until three in a row agree (camera and drawing have come to rest); returns the last."""
    time.sleep(seconds)
    shots = [_screenshot(page)]
    for _ in range(20):
        time.sleep(0.3)
        shots.append(_screenshot(page))
        if len(shots) >= 3 and all(np.abs(a - shots[-1]).max() <= 8 for a in shots[-3:-1]):
            return shots[-1]
    raise AssertionError("the page never came to rest")


def _project(client, box: FloatRect, p: np.ndarray) -> tuple[float, float]:
    """Page pixel of world point ``p`` through the page's camera (OpenCV convention, vertical fov)."""
    cam = client.camera
    R = matrix_from_quat_wxyz(np.asarray(cam.wxyz, dtype=float))
    pc = R.T @ (np.asarray(p, dtype=float) - np.asarray(cam.position, dtype=float))
    h, w = float(cam.image_height), float(cam.image_width)
    f = (h / 2.0) / np.tan(float(cam.fov) / 2.0)
    u, v = w / 2.0 + f * pc[0] / pc[2], h / 2.0 + f * pc[1] / pc[2]
    return box["x"] + u * box["width"] / w, box["y"] + v * box["height"] / h


def _inside_points(baxter, arm: str, q7: np.ndarray) -> list[np.ndarray]:
    pos, wxyz = baxter.fk(arm, q7)
    z = matrix_from_quat_wxyz(wxyz)[:, 2]  # the gripper's axis, pointing out past the fingertips
    # Two points along the closed fingers (they run from 0.045 m to 0.1577 m past the hand).
    return [pos - 0.06 * z, pos - 0.015 * z]


def _outline(mask: np.ndarray) -> np.ndarray:
    """The drawn gripper's outline: the convex hull of its pixels (isolated specks of < 8 pixels dropped), so
    the narrow gap between the two fingers, where the FK points lie, counts as covered."""
    from scipy.ndimage import binary_dilation, label
    from scipy.spatial import Delaunay

    lab, n = label(binary_dilation(mask, iterations=2))  # thin finger pieces count as one piece
    sizes = np.bincount(lab[mask], minlength=n + 1)
    keep = mask & np.isin(lab, [i for i in range(1, n + 1) if sizes[i] >= 8])
    ys, xs = np.nonzero(keep)
    if len(xs) < 3:
        return keep
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    tri = Delaunay(np.column_stack([xs, ys]).astype(float))
    gy, gx = np.mgrid[y0:y1, x0:x1]
    inside = tri.find_simplex(np.column_stack([gx.ravel(), gy.ravel()]).astype(float)) >= 0
    out = keep.copy()
    out[y0:y1, x0:x1] |= inside.reshape(gy.shape)
    return out


def _distance_to_mask(mask: np.ndarray, xy: tuple[float, float]) -> float:
    ys, xs = np.nonzero(mask)
    if len(xs) == 0:
        return float("inf")
    return float(np.min(np.hypot(xs - xy[0], ys - xy[1])))


def _gripper_masks(page, grip_nodes: dict, shown: np.ndarray) -> dict[str, np.ndarray]:
    """Each gripper's drawn pixels: hidden one at a time (left, then right), then both shown again; a pixel
    belongs to a gripper when it changed as that gripper was hidden and came back when it was shown."""
    hidden = {}
    grip_nodes["left"].visible = False
    hidden["left"] = _settle(page, 0.5)
    grip_nodes["right"].visible = False
    grip_nodes["left"].visible = True
    hidden["right"] = _settle(page, 0.5)
    grip_nodes["right"].visible = True
    again = _settle(page, 0.5)
    out = {}
    for arm in ("left", "right"):
        mask = (np.abs(shown - hidden[arm]).sum(axis=2) > 40) & (np.abs(again - hidden[arm]).sum(axis=2) > 40)
        mask &= np.abs(shown - again).sum(axis=2) <= 24
        out[arm] = _outline(mask)
    return out


def test_drawn_grippers_cover_their_fk_points(browser, tmp_path) -> None:
    from PIL import Image

    sessions = tmp_path / "sessions"
    sessions.mkdir()
    out = ARTIFACTS / "drawing"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    app = build_app(port=free_port(), session="drawing", sessions_dir=sessions, meshes="light")
    page = None
    try:
        for arm in ("left", "right"):  # the handles draw over the gripper (no depth test): out of the way
            app.panels.teach.handles[arm].visible = False
        for name, node in app.server.scene._handle_from_node_name.items():  # "low" reaches under the table top
            if name.startswith("/table/"):
                node.visible = False
        page = ui.open_studio(browser, app.url())
        assert wait_for(lambda: bool(app.server.get_clients()))
        client = next(iter(app.server.get_clients().values()))
        box = page.locator("canvas").first.bounding_box()
        assert box is not None
        grip_nodes = {
            arm: next(
                h
                for name, h in app.server.scene._handle_from_node_name.items()
                if name.startswith("/robot/visual/") and name.endswith(f"/{arm}_gripper_base_link")
            )
            for arm in ("left", "right")
        }
        baxter = app.controller.baxter
        backend = app.controller.backend
        assert isinstance(backend, SimulatedBaxter)
        points = {
            (c, arm): _inside_points(baxter, arm, q[:7] if arm == "left" else q[7:])
            for c, q in CONFIGS.items()
            for arm in ("left", "right")
        }
        report: list[str] = []
        failures: list[str] = []
        for c, q in CONFIGS.items():
            backend.teleport(q, np.array([0.0, 0.0]))  # grippers closed (fingertips ~3 cm apart)
            for view in VIEWS:
                pos, at, up = VIEWS[view]
                ui.look(client, pos, at, up)
                ui.dismiss_notifications(page)
                shown = _settle(page, 1.5)
                Image.fromarray(shown.astype(np.uint8)).save(out / f"{c}-{view}.png")
                masks = _gripper_masks(page, grip_nodes, shown)
                for arm in ("left", "right"):
                    mask = masks[arm]
                    if mask.sum() < 30:
                        failures.append(f"{c}/{view}: the {arm} gripper is not drawn in view (hidden, or elsewhere)")
                        continue
                    own = [_project(client, box, p) for p in points[(c, arm)]]
                    other = "low" if c == "reach" else "reach"
                    wrong = [_project(client, box, p) for p in points[(other, arm)]]
                    _mark(out / f"{c}-{view}-{arm}-gripper.png", shown, mask, own, wrong)
                    for xy in own:
                        d = _distance_to_mask(mask, xy)
                        report.append(f"{c} {view} {arm}: FK point at px ({xy[0]:.0f}, {xy[1]:.0f}), {d:.1f} px")
                        if d > 1.0:
                            failures.append(f"{c}/{view}: the drawn {arm} gripper is {d:.0f} px from its FK point")
                    for xy in wrong:  # the other configuration's points: the check can tell them apart
                        if _distance_to_mask(mask, xy) <= 15.0:
                            failures.append(f"{c}/{view}/{arm}: the check would pass for a wrong pose")
        (out / "report.txt").write_text("\n".join(report + failures) + "\n")
        assert not failures, failures
    finally:
        if page is not None:
            page.close()
        app.stop()


def _mark(
    path: Path, img: np.ndarray, mask: np.ndarray, pts: list[tuple[float, float]], wrong: list[tuple[float, float]]
) -> None:
    """The screenshot with the gripper's pixels tinted, the projected FK points as green crosses and the other
    configuration's points as orange ones."""
    from PIL import Image

    a = img.copy()
    a[mask] = (a[mask] * 0.4 + np.array([255, 0, 200]) * 0.6).astype(int)
    h, w = a.shape[:2]
    for colour, group in (((0, 200, 0), pts), ((255, 140, 0), wrong)):
        for x, y in group:
            xi, yi = round(x), round(y)
            if 0 <= xi < w and 0 <= yi < h:
                a[max(yi - 6, 0) : yi + 7, xi] = colour
                a[yi, max(xi - 6, 0) : xi + 7] = colour
    Image.fromarray(a.astype(np.uint8)).save(path)
