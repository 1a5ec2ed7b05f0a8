"""Playwright helpers that drive the studio the way a person does: by visible labels and buttons."""

from __future__ import annotations

import re

from playwright.sync_api import Locator, Page, expect

VIEWPORT = {"width": 1280, "height": 800}


def open_studio(browser, url: str) -> Page:
    page = browser.new_page(viewport=VIEWPORT)
    page.set_default_timeout(30_000)  # CI runs the other tests beside the browser: slow, not broken
    page.goto(url)
    wait_ready(page)
    return page


def wait_ready(page: Page) -> None:
    """Wait until the studio's panel is connected and the robot meshes are drawn."""
    expect(page.get_by_text("Teaching Studio", exact=True).first).to_be_visible(timeout=30_000)
    # The step is the studio's (shared by every tab): a reload shows the step the studio is at.
    expect(page.locator(".step-title")).to_be_attached(timeout=30_000)
    page.wait_for_function("() => document.querySelector('canvas') !== null", timeout=30_000)
    # The robot's status arrives after its meshes (viser replays the scene in the order it was built).
    expect(page.locator(".gripper-status").first).to_be_attached(timeout=30_000)
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


def threshold(page: Page, label: str) -> Locator:
    """The row of a threshold slider by its automatic label (e.g. "Travel distance, cm"), also once the
    teacher set it (then the label ends in "· yours")."""
    pattern = re.compile(r"^\s*" + re.escape(plain(label)) + r"( · yours)?\s*$")
    lab = page.locator("label").filter(has_text=pattern).first
    return lab.locator("xpath=ancestor::div[contains(@class,'mantine-Flex-root')][1]")


def set_threshold(page: Page, label: str, value: float) -> None:
    """Type a value into a threshold slider's number box (opening its folders if they are closed)."""
    box = threshold(page, label).locator("input.mantine-NumberInput-input")
    reveal(box)
    box.click()
    box.fill(str(value))
    box.press("Enter")


def threshold_value(page: Page, label: str) -> float:
    return float(threshold(page, label).locator("input.mantine-NumberInput-input").input_value())


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
    """Go to a step (Teach, Key-points, Train, Preview, Sessions) with the "Step" chooser at the top of the panel;
    returns once the page shows that step (every tab of the studio follows the step)."""
    if current_step(page) != name:
        choose(page, "Step", name)
    expect(page.locator(f'.step-title[data-step="{name}"]')).to_be_attached()


def current_step(page: Page) -> str:
    return str(page.locator(".step-title").first.get_attribute("data-step"))


def plain(label: str) -> str:
    """A threshold's label or folder title as the page shows it: the paper's ε names are only in the hints
    ("Travel distance, cm (ε5)" is shown as "Travel distance, cm")."""
    return re.sub(r"\s*\(ε[\d–-]+(ε\d+)?\)", "", label)


def open_folder(page: Page, title: str) -> None:
    """Open a folder by its title (a folder already open stays open); returns once it shows open."""
    head = page.get_by_text(plain(title), exact=True).first
    head.scroll_into_view_if_needed()
    if head.locator("svg.tabler-icon-chevron-down").count():
        head.click()
    expect(head.locator("svg.tabler-icon-chevron-up")).to_be_attached()


def reveal(target: Locator) -> None:
    """Open every closed folder around ``target``, outermost first, and return once it is visible (a folder
    drawn again, e.g. when the page reconnects, starts closed)."""
    closed = target.locator("xpath=ancestor::div[@aria-hidden='true']/preceding-sibling::div[1]")
    for _ in range(8):  # folders nest a few deep; each pass opens the outermost closed one
        n = closed.count()
        if n == 0:
            break
        closed.first.click()
        expect(closed).to_have_count(n - 1)
    expect(target).to_be_visible()


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
        key = f"{el.get_attribute('data-demo')}:{el.get_attribute('data-arm')}"
        out[key] = int(el.get_attribute("data-count") or -1)
    return out


def wait_number(page: Page, label: str, value: float, timeout: float = 30.0) -> None:
    """Wait until the number box of the slider ``label`` shows ``value`` (e.g. a change made in another tab)."""
    box = row(page, label).locator("input.mantine-NumberInput-input")
    expect(box).to_have_value(re.compile(rf"^{re.escape(str(value))}0*$"), timeout=timeout * 1000)


_SETTLED_JS = """([arm, quietMs, movedFrom]) => {
    const el = document.querySelector(`.gripper-status[data-arm="${arm}"]`);
    if (!el) return false;
    const v = ["x", "y", "z", "open"].map(k => el.dataset[k]).join(",");
    const now = performance.now();
    const key = "__settled_" + arm;
    const st = window[key];
    if (movedFrom !== null && !st && v === movedFrom) return false;
    if (!st || st.v !== v) { window[key] = {v, since: now}; return false; }
    return now - st.since >= quietMs;
}"""


def arm_status(page: Page, arm: str = "left") -> str:
    """The robot's status for ``arm`` (gripper x, y, z and opening) as one string, to wait for it to change."""
    return str(
        page.evaluate(
            """arm => {
                const el = document.querySelector(`.gripper-status[data-arm="${arm}"]`);
                return el ? ["x", "y", "z", "open"].map(k => el.dataset[k]).join(",") : "";
            }""",
            arm,
        )
    )


def wait_arm_settled(
    page: Page, arm: str = "left", quiet_s: float = 0.6, timeout: float = 40.0, moved_from: str | None = None
) -> None:
    """Wait until the robot's status (gripper position and opening) has not changed for ``quiet_s`` seconds:
    the arm arrived where it was sent, as a teacher waits before the next step. With ``moved_from`` (an
    :func:`arm_status` taken before sending the arm), first wait until the status left it: on a busy machine
    the order can reach the robot later than the quiet spell."""
    page.evaluate("arm => { delete window['__settled_' + arm]; }", arm)
    page.wait_for_function(_SETTLED_JS, arg=[arm, quiet_s * 1000, moved_from], polling=100, timeout=timeout * 1000)


_STATUS_JS = """([arm, expr]) => {
    const el = document.querySelector(`.gripper-status[data-arm="${arm}"]`);
    if (!el) return false;
    const s = Object.fromEntries(["x", "y", "z", "open"].map(k => [k, parseFloat(el.dataset[k])]));
    return Function("s", "return (" + expr + ");")(s);
}"""


def wait_status(page: Page, expr: str, arm: str = "left", timeout: float = 30.0) -> None:
    """Wait until the JavaScript expression ``expr`` over the robot status ``s`` (s.x, s.y, s.z in m, s.open in
    percent) holds, e.g. ``"s.open < 1"``."""
    page.wait_for_function(_STATUS_JS, arg=[arm, expr], polling=100, timeout=timeout * 1000)


_AT_GOAL_JS = """([arm, metres]) => {
    const at = document.querySelector(`.gripper-status[data-arm="${arm}"]`);
    const goal = document.querySelector(`.gripper-goal[data-arm="${arm}"]`);
    if (!at || !goal) return false;
    const d = ["x", "y", "z"].map(k => parseFloat(at.dataset[k]) - parseFloat(goal.dataset[k]) / 100);
    return Math.hypot(...d) < metres;
}"""


def wait_at_goal(page: Page, arm: str = "left", metres: float = 0.005, timeout: float = 30.0) -> None:
    """Wait until the gripper (its status) is within ``metres`` of where the Move panel says it is going, read
    anew at each look (a move in two legs shows its first leg, then the goal); a timeout says both."""
    try:
        page.wait_for_function(_AT_GOAL_JS, arg=[arm, metres], polling=100, timeout=timeout * 1000)
    except Exception as e:
        shown = page.evaluate(
            """arm => [".gripper-status", ".gripper-goal"].map(c => {
                const el = document.querySelector(`${c}[data-arm="${arm}"]`);
                return el ? `${c}: ${JSON.stringify(el.dataset)}` : `${c}: none`;
            })""",
            arm,
        )
        raise AssertionError(f"the {arm} gripper did not reach its goal within {timeout:g} s: {shown}") from e


_COUNTS_JS = """before => {
    const now = {};
    for (const el of document.querySelectorAll(".kp-count")) {
        now[el.dataset.demo + ":" + el.dataset.arm] = parseInt(el.dataset.count);
    }
    const keys = Object.keys(now);
    return keys.length > 0 && (keys.length !== Object.keys(before).length || keys.some(k => now[k] !== before[k]));
}"""


def wait_keypoint_counts_change(page: Page, before: dict[str, int], timeout: float = 30.0) -> dict[str, int]:
    """Wait until the key-point counts shown differ from ``before``; returns the new counts."""
    page.wait_for_function(_COUNTS_JS, arg=before, polling=100, timeout=timeout * 1000)
    return keypoint_counts(page)


def _screenshot(page: Page):
    """A screenshot of ``page``: its PNG bytes and its pixels (RGB, int)."""
    import io

    import numpy as np
    from PIL import Image

    png = page.screenshot()
    return png, np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)


def settle(page: Page, timeout: float = 30.0, path=None):
    """Screenshots until three in a row agree (camera and drawing have come to rest); returns the last (and
    writes it to ``path`` if given)."""
    import time
    from pathlib import Path

    import numpy as np

    shots = [_screenshot(page)]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        page.wait_for_timeout(200)
        shots.append(_screenshot(page))
        if len(shots) >= 3 and all(np.abs(a - shots[-1][1]).max() <= 8 for _, a in shots[-3:-1]):
            if path is not None:
                Path(path).write_bytes(shots[-1][0])
            return shots[-1][1]
    raise AssertionError("the page never came to rest")


def look(client, pos, at, up=(0.0, 0.0, 1.0), timeout: float = 30.0) -> None:
    """Point a page's camera (``client`` = its viser ClientHandle) in one batch, as the View buttons do (a half-way
    pose can be lifted above the floor by the studio), and wait until the page reports it back; sent again, nudged
    by 0.1 mm so that viser sends it, every 2 s until it does."""
    import threading
    import time

    import numpy as np

    seen = threading.Event()
    cam = client.camera

    def on_update(c) -> None:
        if np.allclose(c.position, pos, atol=1e-3) and np.allclose(c.look_at, at, atol=1e-3):
            seen.set()

    cam.on_update(on_update)
    deadline = time.monotonic() + timeout
    for attempt in range(1_000):
        with client.atomic():
            cam.up_direction = up
            cam.position = pos
            cam.look_at = at
        if seen.wait(max(0.0, min(2.0, deadline - time.monotonic()))):
            return
        if time.monotonic() >= deadline:
            break
        cam.look_at = np.asarray(at, dtype=float) + np.array([0.0, 0.0, 1e-4 * (-1) ** attempt])
    raise AssertionError(f"the page did not take the camera pose {pos} → {at}")


def views(server, page: Page, out, step: str, poses: dict, rest: bool = True) -> None:
    """Screenshots of ``step`` from each named camera pose ((position, look-at) pairs).

    ``rest``: once the drawing has come to rest; False (something is moving): once the page drew a frame.
    """
    client = next(iter(server.get_clients().values()))
    for view, (pos, at) in poses.items():
        look(client, pos, at)
        dismiss_notifications(page, only_webgl=False)
        path = out / f"{step}-{view}.png"
        if rest:
            settle(page, path=path)  # the last of the screenshots that agree
        else:
            page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
            page.screenshot(path=str(path))
