"""A newcomer teaches stack-cup in a new session with the mouse and the keyboard only: View buttons, the handle
dragged out of reach and back while carrying the cup (the arm is not trapped), keys, "Go above", three
demonstrations, Train, Preview, and the preview's words "the skill does the task"; and pick-place taught at one
place, the block moved with its handle, and words that agree with where the block ended. Front and top
screenshots go to the test's temporary folder (and test-artifacts/)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from studio.core.kinematics import Baxter
from studio.panels.teach import joint_label
from tests.e2e import ui
from tests.e2e.conftest import Shots
from tests.e2e.mouse_flow import (
    TEACHING_PARTS,
    Teacher,
    choose_object,
    demonstrate_pick_place,
    drag_handle,
    finish_excursion,
    look,
    new_session,
    out_of_reach_and_back,
    out_of_reach_label,
    preview_to_the_end,
    teach_train_preview,
)
from tests.viser_client import ViserClient

pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parents[2]


def joint_degrees(page: Page) -> dict[str, float]:
    """The left arm's joint angles as the Joints folder shows them (degrees)."""
    out = {}
    for lab in page.locator("label").filter(has_text=re.compile(r"^\s*Left .*\(\w\d\) °\s*$")).all():
        text = re.sub(r"\s+", " ", lab.inner_text()).strip()
        box = lab.locator("xpath=ancestor::div[contains(@class,'mantine-Flex-root')][1]").locator(
            "input.mantine-NumberInput-input"
        )
        out[text] = float(box.input_value())
    return out


def test_teach_stack_cup_with_mouse_and_keys(browser, studio_factory, tmp_path: Path, request) -> None:
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    shutil.copytree(ROOT / "sessions" / "stack-cup", sessions / "stack-cup")
    server = studio_factory("stack-cup", sessions_dir=sessions)
    artifacts = Shots(request.node.name)
    shot_dir = tmp_path / "shots"
    shot_dir.mkdir()

    def shots(page: Page, step: str) -> Path:
        path = artifacts(page, step)
        copy = shot_dir / path.name
        shutil.copyfile(path, copy)
        return copy

    page = ui.open_studio(browser, server.url)
    t = Teacher(page, shots)
    new_session(t)
    expect(page.get_by_role("button", name="bottom cup", exact=True)).to_be_visible()

    # Views: front and top, looked at by a person (and by whoever reads this test's screenshots).
    t.part("views")
    front = look(t, "Front")
    top = look(t, "Top")
    assert front is not None and top is not None and front.stat().st_size > 0 and top.stat().st_size > 0

    # Carrying the cup, the handle goes far out of reach and back: the arm follows back and is not stuck.
    seen = out_of_reach_and_back(t)
    back = np.asarray(seen["back gripper"])
    assert abs(back[1] - 0.14) < 0.03, f"the gripper did not come back near the bottom cup: {back}"
    far = np.asarray(seen["far gripper"])
    assert far[0] > back[0] + 0.1, f"the arm did not reach out while the handle was out of reach: {far}"
    expect(out_of_reach_label(page)).to_have_count(0)
    t.click(page.get_by_text("Joints", exact=True).first)  # a person opens the Joints folder to look
    b = Baxter.load()
    names = [f"left_{j}" for j in ("s0", "s1", "e0", "e1", "w0", "w1", "w2")]
    lows, highs = np.degrees(b.lower_limits("left")), np.degrees(b.upper_limits("left"))
    limits = {n: (float(lows[i]), float(highs[i])) for i, n in enumerate(names)}
    joints = joint_degrees(page)
    assert len(joints) == 7, joints
    for name in names:
        deg = joints[joint_label(name) + " °"]
        lo, hi = limits[name]
        assert lo + 1.0 < deg < hi - 1.0 or (name == "left_e1" and deg < hi - 1.0), f"{name} at a limit: {deg}°"
    # The place the example reaches is reached: above the bottom cup, then open, then home (H).
    finish_excursion(t)
    expect(out_of_reach_label(page)).to_have_count(0)
    home = t.gripper()
    assert np.allclose(home, [0.59, 0.27, 0.11], atol=0.02), f"H did not bring the arm home: {home}"
    t.shot("home again")

    # Three demonstrations with the mouse and the keys, Train, Preview: the skill does the task.
    words = teach_train_preview(t)
    said = r"The skill does the task\. The cup ended in the bottom cup, ([\d.]+ cm|less than 1 mm) from its centre\."
    assert re.fullmatch(said, words), words
    expect(page.locator('.task-result[data-ok="true"]')).to_be_visible()
    expect(page.get_by_text(re.compile(r"The arm can follow all of it"))).to_be_visible()

    teaching = sum(sum(t.parts[p].values()) for p in TEACHING_PARTS)
    print(f"\nactions: {dict(t.counts)} total {t.total}; teaching (new session, 3 demos, train, preview) {teaching}")
    print("parts:", {k: dict(v) for k, v in t.parts.items()})
    print("screenshots:", shot_dir)
    assert teaching <= 60, f"teaching took {teaching} actions"


def drawn_objects(tab: ViserClient) -> dict[str, np.ndarray]:
    """Where the page draws each object (its bottom centre, m), by its name in the world."""
    return {
        n.split("/")[2].rsplit("-", 1)[0]: np.asarray(v["position"], dtype=float)
        for n, v in tab.scene().items()
        if n.count("/") == 2 and n.startswith("/objects/") and v.get("position") is not None
    }


def test_teach_pick_place_at_one_place_then_move_the_block(browser, studio_factory, tmp_path: Path, request) -> None:
    """A newcomer teaches pick-place in a new session with the block in one place (three takes), moves the block
    with its handle, previews, and reads words that agree with where the block really ended (as the page draws it
    at the end of the preview): on the pad, so many cm from its centre — or not, and then the skill did not do
    the task."""
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    server = studio_factory("fresh", sessions_dir=sessions)
    artifacts = Shots(request.node.name)
    page = ui.open_studio(browser, server.url)
    watch = ViserClient(server.url.replace("http://", "ws://"))  # reads what the page draws; never drives
    try:
        t = Teacher(page, artifacts)
        new_session(t, "my-pick", table="pick-place")
        expect(page.locator('.task-goal[data-source="set-up"]')).to_contain_text("Put the block on the pad.")
        words = teach_train_preview(t, take=demonstrate_pick_place)
        done = r"The block ended on the pad, ([\d.]+ cm|less than 1 mm) from its centre\."
        assert re.fullmatch(r"The skill does the task\. " + done, words), words
        t.in_row("Playback", "Stop")  # back to the live robot (the handles are for it)
        t.step("Train")
        expect(page.locator(".verdict-frames").first).to_contain_text(
            "Every demonstration had the block in the same place: I will follow the block for the grasp and the pad "
            "for the release."
        )
        # The block moved 8 cm with its handle, along its own sideways arrow (the pad stays).
        choose_object(t, "block")
        assert watch.wait_for(lambda _m: watch.scene().get("/objects_handle", {}).get("visible"), 30)
        handle = watch.scene()["/objects_handle"]
        at = np.asarray(handle["position"], dtype=float)  # on the block's top, where the set-up has it
        drag_handle(t, at, np.asarray(handle.get("wxyz") or (1.0, 0.0, 0.0, 0.0), dtype=float), axis=1, metres=0.08)
        assert watch.wait_for(lambda _m: np.linalg.norm(drawn_objects(watch)["block"][:2] - at[:2]) > 0.05, 30)
        moved = drawn_objects(watch)["block"]
        t.shot("block moved")
        words = preview_to_the_end(t, "preview after the block moved")
        end = drawn_objects(watch)
        block, pad = end["block"], end["pad"]
        assert np.linalg.norm(block[:2] - moved[:2]) > 0.05, "the preview did not move the block"
        d = float(np.hypot(*(block[:2] - pad[:2])))
        on_pad = d <= 0.06 and block[2] > pad[2] + 0.002  # its centre on the 12 cm pad, resting on it
        said = re.search(done, words)
        if on_pad:
            assert said is not None, words
            cm = 0.0 if said.group(1).startswith("less") else float(said.group(1).split()[0])
            assert abs(cm / 100 - d) < 0.006, (words, d)
            assert "does the task" in words and "misses" not in words
        else:
            assert said is None and "did not do the task" in words and "The skill misses the task" in words, words
        print(f"\nafter the move: {words!r}; the block drawn {d * 100:.1f} cm from the pad's centre")
    finally:
        watch.close()
