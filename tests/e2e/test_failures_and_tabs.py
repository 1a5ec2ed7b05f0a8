"""Browser tests: a corrupt upload is refused in plain words and changes nothing; two tabs stay in sync."""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import expect

from tests.e2e import ui
from tests.e2e.conftest import FAST

pytestmark = pytest.mark.e2e


def tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_corrupt_upload_shows_error_and_changes_nothing(browser, studio_factory, shots, tmp_path) -> None:
    sessions = tmp_path / "sessions"
    server = studio_factory("lesson", sessions_dir=sessions)
    page = ui.open_studio(browser, server.url)
    ui.tab(page, "Sessions")
    before = tree(sessions)
    names_before = page.locator("text=Open session:").first.inner_text()

    bad = tmp_path / "broken-session.zip"
    bad.write_bytes(b"PK\x03\x04 this is not really a zip archive" + bytes(range(256)) * 4)
    page.locator("input[type=file]").first.set_input_files(str(bad))
    note = page.locator(".mantine-Notification-root").filter(has_text="The upload did not work")
    expect(note.first).to_be_visible(timeout=30_000)
    text = note.first.inner_text()
    assert "not a session archive" in text or "Nothing was imported" in text, text
    assert "Traceback" not in text
    shots(page, "corrupt upload refused")

    # Nothing changed (the refusal is told when the upload's handling is over): same files on disk, same open
    # session, and the studio still works.
    assert tree(sessions) == before
    assert page.locator("text=Open session:").first.inner_text() == names_before
    ui.tab(page, "Teach")
    ui.click_in_row(page, "Left gripper", "Close")
    expect(page.locator('.gripper-status[data-arm="left"][data-open="0"]')).to_have_count(1, timeout=30_000)
    page.close()


def test_two_tabs_see_the_same_robot_and_session(browser, studio_factory, shots, tmp_path) -> None:
    server = studio_factory("shared", sessions_dir=tmp_path / "sessions", time_scale=FAST)  # not about timing
    a = ui.open_studio(browser, server.url)
    b = ui.open_studio(browser, server.url)

    # A moves the gripper: B sees it.
    ui.click_in_row(a, "Left gripper", "Close")
    expect(b.locator('.gripper-status[data-arm="left"][data-open="0"]')).to_have_count(1, timeout=30_000)

    # A records: B sees the recording and cannot start a second one.
    a.get_by_role("button", name="Record").click()
    ui.wait_text(b, "Recording")
    expect(b.get_by_role("button", name="Record")).to_be_disabled()
    shots(b, "tab B while tab A records")
    ui.open_folder(a, "Joints")
    before = ui.arm_status(a)
    ui.set_number(a, "Left elbow bend (e1) °", 60)
    ui.wait_arm_settled(a, moved_from=before)
    ui.click_in_row(a, "Left gripper", "Open")
    ui.wait_status(b, "s.open > 99")
    b.get_by_role("button", name="Stop", exact=True).click()  # either tab can stop it
    expect(a.locator(".demo-row")).to_have_count(1, timeout=30_000)
    expect(b.locator(".demo-row")).to_have_count(1)
    expect(a.get_by_role("button", name="Record")).to_be_enabled()

    # A changes a threshold: B's slider shows it.
    ui.tab(a, "Key-points")
    ui.tab(b, "Key-points")
    ui.open_folder(a, "All thresholds")
    ui.open_folder(b, "All thresholds")
    ui.set_threshold(a, "Pause speed, cm/s (ε2)", 2)
    expect(b.locator("label", has_text="Pause speed, cm/s · yours")).to_be_visible()
    assert ui.threshold_value(b, "Pause speed, cm/s (ε2)") == pytest.approx(2)

    # Reloading B restores the view of the current state, at the step the studio is at (every tab shares it).
    b.reload()
    ui.wait_ready(b)
    expect(b.locator('.step-title[data-step="Key-points"]')).to_be_attached()
    ui.open_folder(b, "All thresholds")
    assert ui.threshold_value(b, "Pause speed, cm/s (ε2)") == pytest.approx(2)
    ui.tab(b, "Teach")
    expect(b.locator(".demo-row")).to_have_count(1)
    expect(a.locator('.step-title[data-step="Teach"]')).to_be_attached()  # A follows B's step when it arrives
    shots(b, "tab B after reload")
    a.close()
    b.close()
