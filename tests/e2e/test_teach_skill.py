"""End to end, the way a user teaches a skill: move, grip, record three demos, tune ε, train, preview, save,
restart the server, open the session and find everything back. Screenshots of each step in test-artifacts/."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from playwright.sync_api import Page, expect
from playwright.sync_api import TimeoutError as PlaywrightTimeout

from studio.app import CAMERA_FOV_DEG, CAMERA_LOOK_AT, CAMERA_POSITION
from studio.core.kinematics import Baxter
from tests.e2e import ui
from tests.e2e.conftest import FAST

pytestmark = pytest.mark.e2e

SESSION = "my-first-skill"
VIEW_POS = np.array(CAMERA_POSITION)
VIEW_AT = np.array(CAMERA_LOOK_AT)
VIEW_FOV = math.radians(CAMERA_FOV_DEG)


def gripper_status(page: Page, arm: str = "left") -> dict[str, float]:
    el = page.locator(f'.gripper-status[data-arm="{arm}"]').first
    return {k: float(el.get_attribute(f"data-{k}") or "nan") for k in ("x", "y", "z", "open")}


def moved_from(before: dict[str, float], keys: str = "xyz", by: float = 0.02) -> str:
    """A status expression (see ui.wait_status): the gripper moved more than ``by`` m from ``before``."""
    return " || ".join(f"Math.abs(s.{k} - {before[k]}) > {by}" for k in keys)


def project(p: np.ndarray, width: int = 1280, height: int = 800) -> tuple[float, float]:
    """Screen pixel of world point ``p`` for the studio's initial camera (+z up, vertical fov)."""
    f = VIEW_AT - VIEW_POS
    f /= np.linalg.norm(f)
    r = np.cross(f, [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    d = p - VIEW_POS
    x, y, z = d @ r, d @ u, d @ f
    s = (height / 2) / math.tan(VIEW_FOV / 2)
    return width / 2 + s * x / z, height / 2 - s * y / z


AXIS_RGB = ((255, 32, 96), (32, 223, 128), (32, 128, 255))  # the handle's x, y, z arrows (drei's colours)


def find_arrow(page: Page, center: tuple[float, float], tip: tuple[float, float], axis: int) -> tuple[float, float]:
    """Pixel on the drawn arrow of ``axis``: the projected tip, refined by the arrow's colour on screen."""
    import io

    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
    c = np.array(center)
    d = np.array(tip) - c
    length = max(float(np.linalg.norm(d)), 1.0)
    u = d / length
    ys, xs = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    near = np.hypot(xs - c[0], ys - c[1]) < 1.6 * length + 20
    colour = np.abs(img - np.array(AXIS_RGB[axis])).sum(axis=2) < 90
    m = near & colour
    if m.sum() < 5:
        return float(tip[0]), float(tip[1])
    px = np.stack([xs[m], ys[m]], axis=1).astype(float)
    along = (px - c) @ u
    pick = px[np.argsort(along)[int(0.8 * (len(along) - 1))]]
    return float(pick[0]), float(pick[1])


def drag_gizmo(page: Page, q_left: np.ndarray, axis: int = 2, pixels: float = -70.0) -> None:
    """Drag the left gripper handle's arrow along one of its axes (the room's) with the mouse."""
    b = Baxter.load()
    pos, _ = b.fk("left", q_left)
    R = np.eye(3)  # the handle's arrows are the room's axes
    center = project(pos)
    x1, y1 = find_arrow(page, center, project(pos + R[:, axis] * 0.22 * 0.9), axis)
    direction = np.array([x1 - center[0], y1 - center[1]])
    direction /= np.linalg.norm(direction)
    page.mouse.move(x1, y1)
    page.mouse.down()
    page.mouse.move(x1 + direction[0] * pixels, y1 + direction[1] * pixels, steps=10)  # a hand, not a jump
    page.mouse.up()


def teach_one_demo(page: Page, variant: int) -> None:
    """Record one demonstration: reach, close the gripper, carry, open — with the joint sliders."""
    ui.tab(page, "Teach")
    page.get_by_role("button", name="Record").click()
    ui.wait_text(page, "Recording")
    dv = 4.0 * variant
    # Each step waits until the arm (or gripper) moved, arrived and held still, as a teacher does.
    before = ui.arm_status(page)
    for label, value in (
        ("Left shoulder lift (s1) °", -40 + dv),
        ("Left elbow bend (e1) °", 100 - dv),
    ):
        ui.set_number(page, label, value)
    ui.wait_arm_settled(page, moved_from=before)
    ui.click_in_row(page, "Left gripper", "Close")
    ui.wait_status(page, "s.open < 1")
    before = ui.arm_status(page)
    ui.set_number(page, "Left shoulder turn (s0) °", 30 + dv)
    ui.wait_arm_settled(page, moved_from=before)
    ui.click_in_row(page, "Left gripper", "Open")
    ui.wait_status(page, "s.open > 99")
    before = ui.arm_status(page)
    ui.set_number(page, "Left shoulder turn (s0) °", 0 - dv)
    ui.set_number(page, "Left shoulder lift (s1) °", -55)
    ui.wait_arm_settled(page, moved_from=before)
    page.get_by_role("button", name="Stop", exact=True).click()
    ui.wait_text(page, "Not recording")


def test_teach_a_skill_like_a_user(browser, studio_factory, shots, tmp_path) -> None:
    sessions = tmp_path / "sessions"
    server = studio_factory(SESSION, sessions_dir=sessions, time_scale=FAST)  # the walk is not about timing
    page = ui.open_studio(browser, server.url)
    shots(page, "fresh session")
    expect(page.get_by_text("No demonstrations yet")).to_be_visible()

    # Move the arm with the joint sliders.
    ui.open_folder(page, "Joints")
    before = gripper_status(page)
    ui.set_number(page, "Left elbow bend (e1) °", 70)
    ui.wait_status(page, f"Math.abs(s.x - {before['x']}) + Math.abs(s.z - {before['z']}) > 0.05")
    shots(page, "moved with a joint slider")

    # Move it with the gripper handle (gizmo): mouse drag on the handle's arrow.
    q = np.array([0.08, -1.0, -1.19, math.radians(70), 0.67, 1.03, -0.50])
    ui.wait_arm_settled(page)  # the arm arrived, so the handle is where we aim
    settled = gripper_status(page)
    moved = False
    for axis in (2, 0, 1):  # the handle's arrows; a miss would orbit the camera instead, so try another
        drag_gizmo(page, q, axis=axis, pixels=-80)
        try:
            ui.wait_status(page, moved_from(settled), timeout=30.0)
            moved = True
            break
        except PlaywrightTimeout:
            continue
    assert moved, "dragging the gripper handle did not move the arm"
    shots(page, "moved with the gripper handle")

    # Close and open the gripper.
    ui.click_in_row(page, "Left gripper", "Close")
    ui.wait_status(page, "s.open < 1")
    shots(page, "gripper closed")
    ui.click_in_row(page, "Left gripper", "Open")
    ui.wait_status(page, "s.open > 99")

    # Record three demonstrations.
    for v in range(3):
        teach_one_demo(page, v)
    expect(page.locator(".demo-row")).to_have_count(3)
    shots(page, "three demonstrations")

    # Key-points: counts per demo change when an ε slider moves.
    ui.tab(page, "Key-points")
    expect(page.locator(".kp-count")).to_have_count(3, timeout=30_000)
    counts0 = ui.keypoint_counts(page)
    shots(page, "key-points default")
    ui.open_folder(page, "All thresholds")
    eps5 = round(ui.threshold_value(page, "Travel distance, cm (ε5)") / 3, 1)  # a third of the automatic value
    ui.set_threshold(page, "Travel distance, cm (ε5)", eps5)
    counts1 = ui.wait_keypoint_counts_change(page, counts0)
    assert counts1 != counts0, f"key-point counts did not change: {counts0}"
    assert sum(counts1.values()) > sum(counts0.values())
    shots(page, "key-points after moving eps5")

    # Train.
    ui.tab(page, "Train")
    page.get_by_role("button", name="Train").click()
    ui.wait_text(page, r"^Trained\.", timeout=120)
    expect(page.locator("svg.heatmap")).to_have_count(1)
    expect(page.locator("svg.position-plot")).to_have_count(4)  # 3 demos + learned path
    expect(page.locator("tr.fit-row")).to_have_count(3)
    verdict = page.locator(".verdict[data-level]").first
    expect(verdict).to_contain_text(re.compile("^(Good|Fair|Poor): "), timeout=60_000)
    shots(page, "trained")

    # Preview: play and see the robot move along the learned path.
    ui.tab(page, "Preview")
    start = gripper_status(page)
    ui.click_in_row(page, "Playback", "Play")
    ui.wait_text(page, "learned skill \\(preview\\), playing")
    ui.wait_status(page, f"Math.abs(s.x - {start['x']}) + Math.abs(s.y - {start['y']}) > 0.01")
    time_box = ui.row(page, "Time (s)").locator("input.mantine-NumberInput-input")
    expect(time_box).not_to_have_value(re.compile(r"^0(\.0*)?$"))
    shots(page, "preview playing")
    assert ui.number_value(page, "Time (s)") > 0

    # Save, restart the server, open the session and find everything back.
    ui.tab(page, "Sessions")
    ui.click_in_row(page, "Session action", "Save")
    ui.wait_text(page, "is saved")
    shots(page, "saved")

    # Replay a recorded demonstration on the robot; download the session and the Baxter SDK CSV.
    ui.choose(page, "Demonstration", "demo 2")
    ui.click_in_row(page, "Replay", "Play")
    ui.wait_text(page, 'Showing demonstration "demo 2", playing')
    shots(page, "replaying demo 2")
    ui.click_in_row(page, "Replay", "Stop")
    ui.wait_text(page, "Showing the robot live")
    with page.expect_download(timeout=30_000) as dl:
        page.get_by_role("button", name="Export joint trajectory (Baxter SDK CSV)").click()
    csv_path = tmp_path / "trajectory.csv"
    dl.value.save_as(csv_path)
    assert csv_path.read_text().startswith("time,left_s0")
    with page.expect_download(timeout=30_000) as dl:
        page.get_by_role("button", name="Download session (.zip)").click()
    zip_path = tmp_path / "session.zip"
    dl.value.save_as(zip_path)
    assert zip_path.read_bytes()[:2] == b"PK"
    page.close()
    server.stop()

    server2 = studio_factory("stack-cup", sessions_dir=sessions, time_scale=FAST)
    page = ui.open_studio(browser, server2.url)
    ui.tab(page, "Sessions")
    ui.choose(page, "Open session", SESSION)
    ui.click_in_row(page, "Session action", "Open")
    ui.wait_text(page, f"Open session: {SESSION}")
    ui.tab(page, "Teach")
    expect(page.locator(".demo-row")).to_have_count(3)
    ui.tab(page, "Key-points")
    ui.open_folder(page, "All thresholds")
    assert ui.threshold_value(page, "Travel distance, cm (ε5)") == pytest.approx(eps5)
    expect(page.locator(".kp-count")).to_have_count(3, timeout=30_000)
    assert ui.keypoint_counts(page) == counts1
    ui.tab(page, "Train")
    expect(page.locator("svg.heatmap")).to_have_count(1)
    expect(page.locator("tr.fit-row")).to_have_count(3)
    shots(page, "after restart: trained skill back")
    ui.tab(page, "Preview")
    shots(page, "after restart: learned path")
    page.close()
