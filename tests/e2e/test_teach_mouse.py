"""A newcomer teaches stack-cup in a new session with the mouse and the keyboard only: View buttons, the handle
dragged out of reach and back while carrying the cup (the arm is not trapped), keys, "Go above", three
demonstrations, Train, Preview, and the preview's words "the skill does the task". (Pick-place taught at one place,
then the block moved: tests/e2e/test_first_skill.py.) Front and top screenshots go to the test's temporary folder
(and test-artifacts/)."""

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
    finish_excursion,
    look,
    new_session,
    out_of_reach_and_back,
    out_of_reach_label,
    teach_train_preview,
)

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
