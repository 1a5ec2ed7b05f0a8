"""Browser walk of issue 11 on the example session: a threshold step redraws the live dashed path with its
figure, the counts stay in sight next to the orientation sliders, Suggest shows its progress, is applied and
undone, and training ends with the verdict in plain words and how well each demonstration fits.
Screenshots of each step in test-artifacts/."""

from __future__ import annotations

import re

import pytest
from playwright.sync_api import Page, expect

from tests.e2e import ui

pytestmark = pytest.mark.e2e

EPS5 = "Travel distance, cm"  # the paper's ε5 is in its hint
EPS14 = "Turn range, °"


def live_version(page: Page) -> int:
    return int(page.locator(".live-path").first.get_attribute("data-version") or -1)


def in_viewport(page: Page, selector_or_locator) -> bool:
    box = selector_or_locator.bounding_box()
    vp = page.viewport_size or ui.VIEWPORT
    return box is not None and box["y"] >= 0 and box["y"] + box["height"] <= vp["height"]


def test_live_path_suggest_and_verdict(browser, studio_factory, shots, sessions) -> None:
    server = studio_factory("stack-cup", sessions_dir=sessions)
    page = ui.open_studio(browser, server.url)
    ui.tab(page, "Key-points")
    expect(page.locator(".kp-count")).to_have_count(3, timeout=30_000)
    ui.open_folder(page, "All thresholds")
    expect(page.locator(".kp-whose").first).to_contain_text("Every threshold follows your demonstrations")

    # Every control's hint is on its label too (a person hovering the words reads what the slider does).
    label = page.locator("label").filter(has_text=re.compile(r"^\s*" + re.escape(EPS5) + r"\s*$")).first
    expect(label).to_have_attribute("title", re.compile("Moving this far from the last key-point"), timeout=30_000)

    # One arrow-key step on the focused ε5 slider: new key-points, and the live path (thin, dashed) is
    # recomputed and redrawn with its figure.
    auto5 = ui.threshold_value(page, EPS5)
    shown = ui.threshold(page, EPS5).locator("input.mantine-NumberInput-input").input_value()
    thumb = ui.threshold(page, EPS5).locator("[role=slider]").first
    thumb.focus()
    page.keyboard.press("ArrowRight")
    expect(page.locator(".live-path").first).to_contain_text("The learned path would stay within", timeout=30_000)
    box = ui.threshold(page, EPS5).locator("input.mantine-NumberInput-input")
    expect(box).not_to_have_value(shown, timeout=30_000)  # the step reached the slider's box
    v1 = live_version(page)
    assert ui.threshold_value(page, EPS5) > auto5
    expect(page.locator("label", has_text=f"{EPS5} · yours")).to_be_visible()  # the teacher's value now
    shots(page, "eps5 one step right: key-points and the dashed live path")
    counts = ui.keypoint_counts(page)
    thumb.focus()  # the screenshot closed a notice, which took the focus
    for _ in range(3):
        page.keyboard.press("ArrowRight")
    page.wait_for_function(
        f"() => parseInt(document.querySelector('.live-path').dataset.version) > {v1}", timeout=30_000
    )
    expect(page.locator(".live-path").first).to_contain_text(re.compile(r"within \d"))
    shots(page, "eps5 three more steps: the live path redrawn")

    # Moving an orientation slider far down the panel, the key-point counts stay in sight above it.
    ui.open_folder(page, "Orientation")
    row14 = ui.threshold(page, EPS14)
    row14.scroll_into_view_if_needed()
    before = ui.keypoint_counts(page)
    row14.locator("[role=slider]").first.focus()
    for _ in range(6):
        page.keyboard.press("ArrowLeft")
    line = page.locator(".kp-line").nth(1)  # the counts line of the orientation folder
    expect(line).to_contain_text("Key-points now")
    assert in_viewport(page, row14) and in_viewport(page, line), "the counts scrolled out of sight"
    shots(page, "orientation slider moved: the counts line stays in sight")
    assert before != {} and counts != {}

    # Suggest: progress while it searches, applied as one change, before/after figures, Undo puts mine back.
    # My travel distance is made far too long first (a few key-points only), so that Suggest has something
    # clearly better to offer on any machine: its first round alone beats it.
    counts_line = page.locator(".kp-line").first
    old_counts = counts_line.inner_text()
    ui.set_threshold(page, EPS5, 30)
    expect(counts_line).not_to_have_text(old_counts)  # the studio has my new value: fewer key-points
    mine = ui.threshold_value(page, EPS5)
    assert mine == pytest.approx(30)
    page.get_by_role("button", name="Suggest thresholds").scroll_into_view_if_needed()
    page.get_by_role("button", name="Suggest thresholds").click()
    expect(page.locator('.suggest-state[data-running="1"]')).to_have_count(1, timeout=30_000)
    expect(page.get_by_role("button", name="Stop suggesting")).to_be_visible()
    shots(page, "Suggest searching: progress bar and Stop")
    undo = page.get_by_role("button", name="Undo suggestion")
    expect(undo).to_be_visible(timeout=120_000)
    expect(page.locator(".suggest-state").first).to_contain_text("Suggested")
    expect(page.locator(".suggest-state").first).to_contain_text("misses it by")
    expect(page.locator(".kp-whose").first).to_contain_text("Every threshold follows your demonstrations")
    shots(page, "Suggest applied: before and after figures, Undo")
    undo.click()
    expect(undo).to_be_hidden(timeout=30_000)
    expect(page.locator(".suggest-state").first).to_contain_text("Undone")
    expect(page.locator("label", has_text=f"{EPS5} · yours")).to_be_visible()
    assert ui.threshold_value(page, EPS5) == pytest.approx(mine)
    shots(page, "Suggest undone: my values back")

    # Train: the verdict in plain words, how well each demonstration fits, the mode the skill used.
    ui.tab(page, "Train")
    page.get_by_role("button", name="Train").click()
    ui.wait_text(page, r"^Trained\.", timeout=120)
    verdict = page.locator(".verdict[data-level]").first
    expect(verdict).to_contain_text(re.compile(r"^(Good|Fair|Poor): the skill"), timeout=120_000)
    expect(page.locator("tr.fit-row")).to_have_count(3)
    expect(page.locator(".skill-summary").first).to_contain_text("Path made by: Follow the demonstrations")
    expect(page.locator(".zero-points").first).to_contain_text(re.compile(r"Zero-points .*: (none|states? \d)"))
    shots(page, "trained: the verdict and how each demonstration fits")

    # The curious choose the paper's spline; the Train panel says which the skill used.
    ui.open_folder(page, "How the skill is made")
    ui.choose(page, "Path", "Paper's spline (a smooth curve through the learned states, as in the paper)")
    page.get_by_role("button", name="Train").click()
    expect(page.locator(".skill-summary").first).to_contain_text("Path made by: Paper's spline", timeout=120_000)
    expect(page.locator(".verdict[data-level]").first).to_contain_text(re.compile(r"^(Good|Fair|Poor): "))
    shots(page, "trained in paper mode")
    page.close()
