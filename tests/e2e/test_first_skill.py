"""A new user's first skill, from the Sessions step: a new pick-place session, the block moved with its handle in
the Top view, three takes (one with a 20 s pause while holding the block), Train, Preview — counted actions, the
pause shown as removed in the list, one skill length in Train and Preview within 1.5× the demonstrations' median,
the block on the pad; screenshots of the handle in the Top view and of Teach after the preview."""

from __future__ import annotations

import re
import statistics
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import expect

from tests.e2e import ui
from tests.e2e.conftest import Shots
from tests.e2e.mouse_flow import (
    Teacher,
    choose_object,
    drag_handle,
    grasp,
    let_go_above,
    new_session,
    preview_to_the_end,
)
from tests.viser_client import ViserClient

pytestmark = pytest.mark.e2e

#: How long the teacher stops to think in the second take, holding the block (s).
PAUSE_S = 20.0


def test_first_skill_from_the_sessions_step(browser, studio_factory, tmp_path: Path, request) -> None:
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    server = studio_factory("fresh", sessions_dir=sessions)
    shots = Shots(request.node.name)
    page = ui.open_studio(browser, server.url)
    watch = ViserClient(server.url.replace("http://", "ws://"))  # reads what the page draws; never drives
    try:
        t = Teacher(page, shots)
        new_session(t, "my-first", table="pick-place")

        # The block moved 4 cm with its handle, in the Top view (the handle's arrows are the room's axes).
        choose_object(t, "block")
        assert watch.wait_for(lambda _m: watch.scene().get("/objects_handle", {}).get("visible"), 30)
        at = np.asarray(watch.scene()["/objects_handle"]["position"], dtype=float)
        t.shot("block handle in the top view")
        drag_handle(t, at, np.array([1.0, 0.0, 0.0, 0.0]), axis=1, metres=-0.04)
        assert watch.wait_for(lambda _m: abs(_block_y(watch) - at[1] + 0.04) < 0.015, 30)
        moved = _block(watch)
        t.shot("block moved")

        # Three takes; in the second the teacher stops to think for 20 s, holding the block.
        t.part("demonstrations")
        t.step("Teach")
        for n in range(3):
            t.button("Record")
            ui.wait_text(page, "Recording")
            grasp(t, "block")
            if n == 1:
                page.wait_for_timeout(PAUSE_S * 1000)
            let_go_above(t, "pad")
            t.send(lambda: t.key("KeyH"))
            t.button("Stop")
            ui.wait_text(page, "Not recording")
        rows = page.locator(".demo-row")
        expect(rows).to_have_count(3)
        paused = page.locator('.demo-row[data-demo="1"]')
        expect(paused).to_contain_text(re.compile(r"\d+ pauses? removed \((\d+) s\)"))
        removed = re.search(r"(\d+) pauses? removed \((\d+) s\)", paused.inner_text())
        assert removed is not None and int(removed.group(2)) >= PAUSE_S - 3, paused.inner_text()
        listed = [rows.nth(i).inner_text() for i in range(3)]
        lengths = [float(rows.nth(i).get_attribute("data-length") or "nan") for i in range(3)]
        median = statistics.median(lengths)
        t.shot("three demonstrations")

        t.part("train and preview")
        t.step("Train")
        t.button("Train")
        ui.wait_text(page, r"^Trained\.", timeout=180)
        status = page.get_by_text(re.compile(r"^Trained\.")).first
        expect(status).to_contain_text("The skill lasts")
        said = re.search(r"The skill lasts ([\d.]+) s", status.inner_text())
        assert said is not None, status.inner_text()
        length = float(said.group(1))
        t.shot("trained")
        words = preview_to_the_end(t)
        shown = re.search(
            r"Learned path \(([\d.]+) s\)", page.get_by_text(re.compile(r"Learned path \(")).first.inner_text()
        )
        assert shown is not None and float(shown.group(1)) == length, (shown, length)  # one length everywhere
        assert length <= 1.5 * median, (length, lengths)
        assert re.fullmatch(r"The skill does the task\. The block ended on the pad, .* from its centre\.", words), words

        # Played again and left on the way: Teach shows the live robot at home and the block as the teacher left
        # it (on the pad), not the preview's pose.
        t.in_row("Playback", "Play")
        ui.wait_status(page, "s.z < 0.05", timeout=120)  # the preview's gripper down at the block or the pad
        t.shot("preview on the way")
        t.step("Teach")
        expect(page.get_by_text("Showing the robot live.")).to_be_visible()
        expect(page.get_by_text(re.compile(r"\(preview\)"))).to_have_count(0)
        ui.wait_status(page, "Math.hypot(s.x - 0.59, s.y - 0.27, s.z - 0.11) < 0.02")  # home, where the live arm is
        t.in_row("View", "Reset")
        t.shot("teach after the preview")
        actions = t.total
        print(f"\nactions {dict(t.counts)} total {actions}; demonstrations {lengths} s (median {median:.1f}); "
              f"skill {length:.1f} s; block moved to {moved}; {words!r}; listed {listed}")  # fmt: skip
        assert actions <= 60, f"the first skill took {actions} actions"
    finally:
        watch.close()


def _block_y(watch: ViserClient) -> float:
    """The block's y as the page draws it (nan before it is drawn)."""
    p = _block(watch)
    return float("nan") if p is None else float(p[1])


def _block(watch: ViserClient) -> np.ndarray | None:
    """Where the page draws the block (its bottom centre, m)."""
    for name, v in watch.scene().items():
        if name.startswith("/objects/block") and name.count("/") == 2 and v.get("position") is not None:
            return np.asarray(v["position"], dtype=float)
    return None
