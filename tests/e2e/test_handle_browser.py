"""In real Chromium (issue 30): the block's handle in the Top view moves it the way the mouse goes (arrows in the
room's axes, the ring only behind "Turn with the handle"), its x/y boxes and "Put back to the task's layout";
a hint closes when its control is pressed; status lines keep their place; Shift+key takes 5 cm, a held key 5 cm
steps after a second; after a preview,
Teach shows the live robot and the objects as placed. Screenshots in test-artifacts/handle/."""

from __future__ import annotations

import io
import shutil
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from studio.app import Studio, build_app
from studio.controller import Controller
from studio.world import preset
from tests.conftest import trained_copy, wait_for
from tests.e2e import mouse_flow, ui
from tests.e2e.conftest import ARTIFACTS, free_port

pytestmark = pytest.mark.e2e

OUT = ARTIFACTS / "handle"
OBJECT_HANDLE_SCALE = 0.2


def red(c: np.ndarray) -> np.ndarray:  # the x arrow (pink-red: brighter and bluer than the robot's red)
    return (c[..., 0] > 220) & (c[..., 1] < 110) & (c[..., 2] > 70) & (c[..., 2] < 170)


def green(c: np.ndarray) -> np.ndarray:  # the y arrow (drawn lighter than drei's pure green)
    return (c[..., 1] > 180) & (c[..., 1] - c[..., 0] > 60) & (c[..., 1] - c[..., 2] > 30)


def blue(c: np.ndarray) -> np.ndarray:  # the ring about z (and a z arrow)
    return (c[..., 2] > 180) & (c[..., 2] - c[..., 0] > 80) & (c[..., 2] - c[..., 1] > 40)


RED, GREEN, BLUE = red, green, blue


@pytest.fixture
def studio(sessions: Path) -> Iterator[Studio]:
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    app.controller.sessions.new("handle", scene="pick-place")  # a newcomer's session: no demonstrations yet
    yield app
    app.stop()


def fresh_out() -> Path:
    shutil.rmtree(OUT, ignore_errors=True)
    OUT.mkdir(parents=True)
    return OUT


def colour_near(
    page: Page, centre: tuple[float, float], colour: Callable[[np.ndarray], np.ndarray], radius: float
) -> int:
    """Pixels of a colour (``colour``: RGB array → mask) within ``radius`` pixels of ``centre`` on a screenshot."""
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
    ys, xs = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    near = np.hypot(xs - centre[0], ys - centre[1]) < radius
    return int((near & colour(img)).sum())


def moved_past(ctl: Controller, x0: float, metres: float) -> bool:
    """The gripper's goal is more than ``metres`` past ``x0`` along x."""
    return bool(ctl.guide.pose("left")[0][0] - x0 > metres)


def drag_arrow(page: Page, app: Studio, axis: int, metres: float) -> np.ndarray:
    """Drag the block's arrow along room ``axis`` by ``metres`` on screen (Top view); returns how it moved."""
    o = app.controller.scene.scene.object("block")
    top = np.add(o.position, (0.0, 0.0, o.size[2]))
    start = mouse_flow.arrow_point(page, "Top", top, axis)
    along = mouse_flow.pixels_per_metre("Top", top, axis)
    end = (start[0] + along[0] * metres, start[1] + along[1] * metres)
    m = page.mouse
    m.move(*start)
    m.down()
    m.move(*end, steps=12)
    m.up()
    assert wait_for(lambda: app.controller.scene.scene.object("block").position != o.position)
    moved = np.subtract(app.controller.scene.scene.object("block").position, o.position)
    assert app.controller.scene.scene.object("block").yaw == pytest.approx(o.yaw)  # a drag never turns it
    return moved


def test_the_blocks_handle_in_top_view_goes_the_way_the_mouse_goes(browser, studio: Studio, monkeypatch) -> None:
    out = fresh_out()
    app, ctl = studio, studio.controller
    monkeypatch.setattr(mouse_flow, "HANDLE_SCALE", OBJECT_HANDLE_SCALE)
    page = ui.open_studio(browser, app.url())
    try:
        ui.choose(page, "Object", "block")
        ui.click_in_row(page, "View", "Top")
        page.mouse.move(20, ui.VIEWPORT["height"] - 20)  # the pointer leaves the button
        ui.settle(page, path=str(out / "block-handle-top.png"))
        block = ctl.scene.scene.object("block")
        centre = mouse_flow.project("Top", np.add(block.position, (0.0, 0.0, block.size[2])))
        assert abs(block.yaw) > 0.1  # the block stands turned; its handle does not
        assert colour_near(page, centre, RED, 80) > 20 and colour_near(page, centre, GREEN, 80) > 20
        assert colour_near(page, centre, BLUE, 80) < 5  # no ring, no z arrow to catch a drag by mistake
        for axis, metres in ((0, 0.05), (1, 0.05), (0, -0.05), (1, -0.05)):
            moved = drag_arrow(page, app, axis, metres)
            assert moved[axis] == pytest.approx(metres, abs=0.01), (axis, metres, moved)
            assert abs(moved[1 - axis]) < 0.005 and moved[2] == pytest.approx(0.0), (axis, metres, moved)
        # the turn is behind the toggle: then a ring only
        ui.row(page, "Turn with the handle").locator("input[type=checkbox]").first.click()
        assert wait_for(lambda: ctl.guide.turning)
        ui.settle(page, path=str(out / "block-handle-top-turning.png"))
        block = ctl.scene.scene.object("block")
        centre = mouse_flow.project("Top", np.add(block.position, (0.0, 0.0, block.size[2])))
        assert colour_near(page, centre, BLUE, 80) > 20
        assert colour_near(page, centre, RED, 80) < 5 and colour_near(page, centre, GREEN, 80) < 5
        ui.row(page, "Turn with the handle").locator("input[type=checkbox]").first.click()
        assert wait_for(lambda: not ctl.guide.turning)
        # typed in centimetres, then back to the task's layout
        ui.set_number(page, "Object x (cm)", 70)
        assert wait_for(lambda: ctl.scene.scene.object("block").position[0] == pytest.approx(0.70))
        page.get_by_role("button", name="Put back to the task's layout").click()
        layout = preset("pick-place", ctl.ctx.arms).object("block")
        assert wait_for(lambda: ctl.scene.scene.object("block").position == pytest.approx(layout.position))
        box = ui.row(page, "Object x (cm)").locator("input")
        assert wait_for(lambda: float(box.input_value()) == pytest.approx(100 * layout.position[0], abs=0.05))
    finally:
        page.close()


def test_hints_close_status_lines_keep_their_place_and_shift_takes_big_steps(browser, studio: Studio) -> None:
    app, ctl = studio, studio.controller
    OUT.mkdir(parents=True, exist_ok=True)
    page = ui.open_studio(browser, app.url())
    try:
        top = ui.row(page, "View").get_by_role("button", name="Top", exact=True)
        top.hover()
        expect(page.locator("[role=tooltip]").first).to_be_visible()  # the View buttons' hint …
        top.click()
        expect(page.locator("[role=tooltip]").first).to_be_hidden()  # … closes when a button is pressed
        ui.row(page, "Step").locator("input").first.click()  # the Step chooser is not covered
        page.keyboard.press("Escape")
        page.mouse.click(20, ui.VIEWPORT["height"] - 20)  # out of the chooser, on the scene: the keys work again

        def y(locator) -> float:
            box = locator.bounding_box()
            assert box is not None
            return float(box["y"])

        record, step = page.get_by_role("button", name="Record"), ui.row(page, "Step")
        before = (y(record), y(step))
        page.keyboard.press("KeyC")  # closing far from the block: the grasp feedback fills its slot
        expect(page.locator(".grasp-feedback")).to_contain_text("Missed the block by")
        pos, wxyz = ctl.baxter.fk("left", ctl.teaching.arm_q("left"))
        ctl.teaching.move_gripper("left", np.asarray(pos) + np.array([1.5, 0.0, 0.0]), np.asarray(wxyz))
        expect(page.get_by_text("cannot reach the handle's position")).to_be_visible()
        page.screenshot(path=str(OUT / "status-lines-filled.png"))
        assert (y(record), y(step)) == pytest.approx(before, abs=1.0)  # nothing below them moved
        page.keyboard.press("KeyH")
        expect(page.get_by_text("cannot reach the handle's position")).to_be_hidden(timeout=60_000)
        assert (y(record), y(step)) == pytest.approx(before, abs=1.0)
        # Shift + a key: 5 cm (its button shows "⇧S")
        ui.wait_arm_settled(page)
        x0 = ctl.guide.pose("left")[0][0]
        page.keyboard.press("Shift+KeyS")
        assert wait_for(lambda: ctl.guide.pose("left")[0][0] - x0 > 0.04)
        assert ctl.guide.pose("left")[0][0] - x0 == pytest.approx(0.05, abs=0.002)
        # a held key: 1 cm at first, 5 cm steps once held a second (the page times the hold, not the repeats)
        ui.wait_arm_settled(page)
        x0 = ctl.guide.pose("left")[0][0]
        kb = page.keyboard
        kb.down("KeyS")
        assert wait_for(lambda: ctl.guide.pose("left")[0][0] - x0 > 0.009)
        assert ctl.guide.pose("left")[0][0] - x0 == pytest.approx(0.01, abs=0.002)  # a tap's step
        page.wait_for_timeout(1100)
        for k in range(3):  # the keyboard's repeats, each once the last step is seen (as a person watches)
            kb.down("KeyS")
            assert wait_for(partial(moved_past, ctl, x0, 0.01 + 0.05 * (k + 1) - 0.005))
            page.wait_for_timeout(300)
        kb.up("KeyS")
        assert ctl.guide.pose("left")[0][0] - x0 == pytest.approx(0.16, abs=0.005)  # 1 cm, then 3 steps of 5 cm
    finally:
        page.close()


def test_after_a_preview_teach_shows_the_live_robot_and_the_objects_as_placed(
    browser, tmp_path: Path, trained_examples: Path
) -> None:
    out = OUT
    out.mkdir(parents=True, exist_ok=True)
    sessions = trained_copy(trained_examples, "stack-cup", tmp_path / "sessions")  # trained as Train does
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    page = ui.open_studio(browser, app.url())
    ctl = app.controller
    try:
        ui.tab(page, "Preview")
        ui.choose(page, "Watch at", "4×")
        ui.click_in_row(page, "Playback", "Play")
        source = page.locator(".robot-source").first
        expect(source).to_contain_text("(preview), playing")
        expect(source).to_contain_text("(preview), at its end", timeout=120_000)  # "playing" ends with it
        ui.settle(page, path=str(out / "preview-at-its-end.png"))
        ended = {p.name: p.position for p in ctl.scene.shown()[1]}
        placed = ctl.scene.scene.object("cup").position  # held out for the robot
        assert np.hypot(*np.subtract(ended["cup"], placed)[:2]) > 0.05  # the preview put the cup elsewhere
        ui.tab(page, "Teach")
        expect(source).to_have_text("Showing the robot live.")
        assert {p.name: p.position for p in ctl.scene.shown()[1]}["cup"] == pytest.approx(placed)
        live, _ = ctl.baxter.fk("left", ctl.teaching.arm_q("left"))  # the robot itself, not the preview's pose
        ui.wait_status(page, f"Math.hypot(s.x - {live[0]:.4f}, s.y - {live[1]:.4f}, s.z - {live[2]:.4f}) < 0.005")
        ui.settle(page, path=str(out / "teach-after-preview.png"))
        ui.tab(page, "Preview")  # back: the preview where it ended
        expect(source).to_contain_text("(preview), at its end")
        assert {p.name: p.position for p in ctl.scene.shown()[1]}["cup"] == pytest.approx(ended["cup"])
    finally:
        page.close()
        app.stop()
