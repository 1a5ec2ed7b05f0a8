"""Playwright helpers that drive the studio the way a person does: by visible labels and buttons."""

from __future__ import annotations

import re
import time

from playwright.sync_api import Locator, Page, expect

VIEWPORT = {"width": 1280, "height": 800}


def open_studio(browser, url: str) -> Page:
    page = browser.new_page(viewport=VIEWPORT)
    page.set_default_timeout(20_000)
    page.goto(url)
    wait_ready(page)
    return page


def wait_ready(page: Page) -> None:
    """Wait until the studio's panel is connected and the robot meshes are drawn."""
    expect(page.get_by_text("Teaching Studio", exact=True).first).to_be_visible(timeout=30_000)
    expect(page.get_by_role("button", name="Record")).to_be_visible(timeout=30_000)
    page.wait_for_function("() => document.querySelector('canvas') !== null", timeout=30_000)
    time.sleep(1.5)  # let the streamed meshes arrive and draw
    dismiss_notifications(page)


def dismiss_notifications(page: Page, only_webgl: bool = True) -> None:
    """Close the "Software WebGL rendering detected" notice (or every notice) so it does not cover the scene."""
    notes = page.locator(".mantine-Notification-root")
    if only_webgl:
        notes = notes.filter(has_text="Software WebGL")
    for note in notes.all():
        try:
            note.locator("button").last.click(timeout=1000)
        except Exception:
            pass


def notification_texts(page: Page) -> list[str]:
    return [n.inner_text() for n in page.locator(".mantine-Notification-root").all()]


def row(page: Page, label: str) -> Locator:
    """The GUI row (label + control) whose label is exactly ``label``."""
    lab = page.locator("label").filter(has_text=re.compile(r"^\s*" + re.escape(label) + r"\s*$")).first
    return lab.locator("xpath=ancestor::div[contains(@class,'mantine-Flex-root')][1]")


def set_number(page: Page, label: str, value: float) -> None:
    """Type a value into a slider's number box and press Enter (as a person would)."""
    box = row(page, label).locator("input.mantine-NumberInput-input")
    box.click()
    box.fill(str(value))
    box.press("Enter")


def number_value(page: Page, label: str) -> float:
    return float(row(page, label).locator("input.mantine-NumberInput-input").input_value())


def click_in_row(page: Page, label: str, button: str) -> None:
    row(page, label).get_by_role("button", name=button, exact=True).click()


def tab(page: Page, name: str) -> None:
    page.get_by_role("tab", name=name).click()
    time.sleep(0.3)


def open_folder(page: Page, title: str) -> None:
    """Expand a collapsed folder by its title (no-op when open)."""
    head = page.get_by_text(title, exact=True).first
    head.scroll_into_view_if_needed()
    head.click()
    time.sleep(0.3)


def choose(page: Page, label: str, option: str) -> None:
    """Pick ``option`` in the dropdown labelled ``label``."""
    sel = row(page, label).locator("input, select").first
    sel.click()
    page.get_by_role("option", name=option, exact=True).click()


def set_text(page: Page, label: str, text: str) -> None:
    box = row(page, label).locator("input").first
    box.fill(text)
    box.press("Enter")


def wait_text(page: Page, pattern: str, timeout: float = 30.0) -> None:
    expect(page.get_by_text(re.compile(pattern)).first).to_be_visible(timeout=timeout * 1000)


def keypoint_counts(page: Page) -> dict[str, int]:
    """Key-point count per demo as shown in the Key-points tab (data attributes of the count rows)."""
    out = {}
    for el in page.locator(".kp-count").all():
        out[f"{el.get_attribute('data-demo')}:{el.get_attribute('data-arm')}"] = int(el.get_attribute("data-count"))
    return out
