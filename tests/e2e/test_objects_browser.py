"""In real Chromium, a skill that follows the objects: open the stack-cup example, train, choose the bottom cup and
move it with its handle (the drag messages a page sends, from a second tab), read in
Preview that the cup now stands where no demonstration put it and the adapted task result ("ended on the bottom
cup"), preview it; screenshots from the front and the top before and after the move. The verdict speaks per
stretch and the key-points are drawn in the objects' frames."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from studio.app import Studio, build_app
from tests.conftest import wait_for
from tests.e2e import ui
from tests.e2e.conftest import ARTIFACTS, free_port
from tests.viser_client import ViserClient

pytestmark = pytest.mark.e2e

VIEWS = {
    "front": ((2.7, 0.25, 0.45), (0.4, 0.25, -0.1)),
    "top": ((0.6, 0.25, 2.4), (0.72, 0.25, -0.07)),
}


def views(app: Studio, page: Page, out: Path, step: str) -> None:
    """Screenshots of ``step`` from the front and from the top, once the drawing has come to rest."""
    ui.views(app.server, page, out, step, VIEWS)


def test_move_the_cup_and_the_skill_follows_it(browser, sessions) -> None:
    out = ARTIFACTS / "objects"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    page, tab = None, None
    try:
        page = ui.open_studio(browser, app.url())
        ui.tab(page, "Train")
        page.get_by_role("button", name="Train", exact=True).click()
        ui.wait_text(page, "Trained", timeout=120)
        # The verdict says each stretch relative to its object; the key-points are drawn in those frames.
        stretch = page.locator(".verdict-segment").first
        expect(stretch).to_contain_text("Reaching for the cup (relative to the cup): within", timeout=120_000)
        expect(page.locator(".verdict-segment")).to_have_count(3)
        ui.tab(page, "Key-points")
        expect(page.locator(".kp-frames").first).to_contain_text("relative to the object it acts on", timeout=30_000)
        ui.tab(page, "Preview")
        task = page.locator(".task-result").first
        expect(task).to_have_attribute("data-ok", "true", timeout=60_000)
        expect(task).to_contain_text("ended in the bottom cup")
        expect(page.locator('.reach-warning[data-outside="false"]')).to_contain_text("one place only")
        views(app, page, out, "1-trained")
        # Choose the bottom cup and drag its handle 6 cm to the robot's right.
        ui.tab(page, "Teach")
        ui.choose(page, "Object", "bottom cup")
        tab = ViserClient.tab_of(app)  # a second tab drags the handle
        handle = lambda: tab.scene().get("/objects_handle", {})  # noqa: E731
        assert tab.wait_for(lambda _m: handle().get("visible") and handle().get("position") is not None, 30)
        before = np.array(handle()["position"], dtype=float)
        target = (float(before[0]), float(before[1] - 0.06), float(before[2]))
        tab.drag("/objects_handle", target, tuple(float(v) for v in handle()["wxyz"] or (1.0, 0.0, 0.0, 0.0)))
        moved = lambda: app.controller.scene.scene.object("bottom cup")  # noqa: E731
        assert wait_for(lambda: abs(moved().position[1] - (before[1] - 0.06)) < 1e-6)
        bottom = moved()

        def bottom_cup_drawn_there() -> bool:
            p = tab.drawn_position("/objects/bottom_cup")
            return p is not None and abs(p[1] - bottom.position[1]) < 1e-6

        assert wait_for(bottom_cup_drawn_there)
        # Preview: said before the run, and the adapted task result.
        ui.tab(page, "Preview")
        warn = page.locator('.reach-warning[data-outside="true"]').first
        expect(warn).to_contain_text("You never showed me the bottom cup this far to the robot's right", timeout=60_000)
        expect(task).to_have_attribute("data-ok", "true", timeout=60_000)
        expect(task).to_contain_text("ended in the bottom cup")
        text = task.inner_text()
        (out / "task-result.txt").write_text(text + "\n" + warn.inner_text() + "\n")
        # The preview plays the adapted skill: at its end the cup sits on the moved bottom cup.
        ui.click_in_row(page, "Playback", "Play")
        placed = app.controller.placed.get()["left"]
        assert placed.joint_trajectory is not None and bool(np.all(placed.joint_trajectory.converged))
        end = float(placed.joint_trajectory.t[-1] - placed.joint_trajectory.t[0])
        app.controller.playback.seek_preview(end)

        def on_bottom() -> bool:
            cup = tab.drawn_position("/objects/cup")
            return cup is not None and bool(np.hypot(cup[0] - bottom.position[0], cup[1] - bottom.position[1]) < 0.01)

        assert wait_for(on_bottom), (tab.drawn_position("/objects/cup"), bottom.position)
        views(app, page, out, "2-cup-moved")
    finally:
        if tab is not None:
            tab.close()
        if page is not None:
            page.close()
        app.stop()
