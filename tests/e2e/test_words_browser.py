"""In real Chromium, the studio's words for a newcomer: the tab title, no developer settings button, the task of
the set-up, what closing the gripper did ("Holding the cup" / "Missed the …"), the stand under the cup held out,
a double-click on Record without a warning, Undo after Discard, the x/y/z of the chosen object, the skill
speed control, the model's terms behind a fold, an empty "New name" after New, and no text
wider than the panel. Screenshots of each step go to test-artifacts/words/ (looked at by a person)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from studio.app import build_app
from studio.teacher import teach
from tests.conftest import free_port, wait_for
from tests.e2e import ui
from tests.e2e.conftest import ARTIFACTS

pytestmark = pytest.mark.e2e

#: Elements of the side panel wider than the panel (text running past its edge), as the page lays them out.
OVERFLOW_JS = """() => {
  const panel = [...document.querySelectorAll('[data-dock-group]')].find(e => e.textContent.includes('Step'));
  if (!panel) return ['no panel'];
  const edge = panel.getBoundingClientRect().right + 1;
  const out = [];
  for (const e of panel.querySelectorAll('div, span, p, b, td, li, label')) {
    const r = e.getBoundingClientRect();
    if (r.width > 0 && r.height > 0 && r.right > edge && e.childElementCount === 0 && e.textContent.trim())
      out.push(e.textContent.trim().slice(0, 60));
  }
  return out;
}"""


def shot(page: Page, out: Path, name: str) -> None:
    ui.dismiss_notifications(page, only_webgl=False)
    page.screenshot(path=str(out / f"{name}.png"))


def fits(page: Page) -> list[str]:
    return list(page.evaluate(OVERFLOW_JS))


def test_words_for_a_newcomer(browser, sessions) -> None:
    out = ARTIFACTS / "words"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    ctl = app.controller
    page = None
    try:
        page = ui.open_studio(browser, app.url())
        # the tab is the studio's; viser's developer settings are not on the page
        page.wait_for_function("() => document.title === 'Teaching Studio'")
        expect(page.locator("[data-dock-header] button:has(.tabler-icon-adjustments)")).to_be_hidden()
        # the task of the set-up, and the stand that holds the handed-over cup up
        expect(page.locator(".task-description")).to_contain_text("Take the cup I hand you")
        assert wait_for(lambda: len(app.panels.task.stands()) == 1)  # drawn in the scene: see the screenshot
        shot(page, out, "1-teach")
        assert fits(page) == []

        # close the gripper around the cup: "Holding the cup"
        plan = teach("stack-cup", 0)
        k = int(np.argmax(np.asarray(plan.gripper)[:, 0] < 50))  # the first sample of the closing
        ctl.teaching.command_arm("left", np.asarray(plan.q[k, :7]))
        assert wait_for(lambda: np.abs(ctl.teaching.arm_q("left") - plan.q[k, :7]).max() < 2e-3, timeout=30)
        ui.click_in_row(page, "Left gripper", "Close")
        expect(page.locator(".grasp-feedback")).to_contain_text("Holding the cup")
        shot(page, out, "2-holding")
        # open, put the cup back, move 3 cm to the side and close: missed, and by how much
        ui.click_in_row(page, "Left gripper", "Open")
        assert wait_for(lambda: ctl.teaching.gripper_width("left") > 95)
        expect(page.locator(".grasp-feedback")).not_to_contain_text("Holding")  # it let go: it holds nothing
        ctl.scene.put_back()
        pos, wxyz = ctl.baxter.fk("left", ctl.teaching.arm_q("left"))
        ctl.teaching.move_gripper("left", np.asarray(pos) + np.array([0.0, 0.03, 0.0]), np.asarray(wxyz))
        assert wait_for(
            lambda: bool(np.linalg.norm(ctl.baxter.fk("left", ctl.teaching.arm_q("left"))[0] - pos) > 0.028)
        )
        ui.click_in_row(page, "Left gripper", "Close")
        expect(page.locator(".grasp-feedback")).to_contain_text(
            re.compile(r"Missed the cup by [23](\.\d)? cm — move 1 cm to the robot's right")
        )
        expect(page.locator(".grasp-feedback")).to_have_attribute("data-held", "")
        # the slider says what the robot's gripper does, as the readout does
        assert wait_for(lambda: ctl.teaching.gripper_width("left") < 5)
        ui.wait_number(page, "Left gripper width (%)", 0)
        shot(page, out, "3-missed")
        ui.click_in_row(page, "Left gripper", "Open")

        # a double-click on Record starts one take and says nothing about another tab
        n = len(ctl.session.recordings)
        page.get_by_role("button", name="Record").dblclick()
        expect(page.get_by_text("● Recording")).to_be_visible()
        assert not any("another" in t for t in ui.notification_texts(page))
        # Discard, then Undo brings the take back
        page.get_by_role("button", name="Discard").click()
        expect(page.get_by_role("button", name="Undo")).to_be_enabled()
        expect(page.locator(".undo-note")).to_contain_text("Thrown away")
        shot(page, out, "4-undo")
        page.get_by_role("button", name="Undo").click()
        expect(page.locator(".demo-row")).to_have_count(n + 1)
        expect(page.get_by_role("button", name="Undo")).to_be_disabled()  # its slot stays: nothing moves
        # Delete is at once, with Undo too (the short take is not for learning)
        ui.choose(page, "Demo", ctl.demos.names()[-1])
        ui.click_in_row(page, "Demo action", "Delete")
        expect(page.locator(".demo-row")).to_have_count(n)
        expect(page.get_by_role("button", name="Undo")).to_be_enabled()

        # the chosen object's place in centimetres
        ui.choose(page, "Object", "bottom cup")
        expect(page.locator(".object-where")).to_contain_text(
            re.compile(r"The bottom cup stands at x -?\d+\.\d, y -?\d+\.\d, z -?\d+\.\d cm\.")
        )
        shot(page, out, "5-object")
        assert fits(page) == []

        # Key-points at the default Detail: the numbered centres (looked at in the screenshot)
        ui.tab(page, "Key-points")
        expect(page.locator(".kp-counts")).to_be_attached()
        shot(page, out, "6-keypoints")

        # Train; the model's terms are folded away, each with a sentence
        ui.tab(page, "Train")
        page.get_by_role("button", name="Train", exact=True).click()
        ui.wait_text(page, "Trained", timeout=180)
        expect(page.locator("details.advanced").first).to_be_attached()
        expect(page.get_by_text("Zero-points", exact=False).first).to_be_hidden()
        shot(page, out, "7-train")
        assert fits(page) == []

        # Preview at twice the speed
        ui.tab(page, "Preview")
        ui.choose(page, "Skill speed", "2×")
        assert wait_for(lambda: ctl.placed.speed == 2.0)
        expect(page.locator(".task-result")).to_be_visible(timeout=60_000)
        expect(page.locator(".task-result")).to_have_attribute("data-ok", "true")
        shot(page, out, "8-preview")
        assert fits(page) == []

        # Sessions: New starts a new name from empty; the box names the session that is open
        ui.tab(page, "Sessions")
        ui.set_text(page, "New name", "my cups")
        ui.click_in_row(page, "Session action", "New")
        assert wait_for(lambda: ctl.session.name == "my cups")
        expect(ui.row(page, "New name").locator("input")).to_have_value("")
        expect(page.get_by_text("· 0 demonstrations")).to_be_visible()
        expect(page.get_by_role("combobox", name="Open session")).to_have_value("my cups")
        # a refused Open leaves the box on the session that is open, not the one chosen
        ctl.teaching.start_recording()
        ui.choose(page, "Open session", "stack-cup")
        ui.click_in_row(page, "Session action", "Open")
        expect(page.get_by_role("combobox", name="Open session")).to_have_value("my cups")
        assert ctl.session.name == "my cups"
        ctl.teaching.discard_recording()
        shot(page, out, "9-sessions")
    finally:
        if page is not None:
            page.close()
        app.stop()
