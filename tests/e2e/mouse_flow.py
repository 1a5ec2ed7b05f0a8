"""A newcomer teaching stack-cup with the mouse and the keyboard only, in a real browser: every click, drag and
key press goes through Playwright's mouse and keyboard and is counted (``Teacher.counts``). Used by
tests/e2e/test_teach_mouse.py and bench/bench_teaching.py."""

from __future__ import annotations

import io
import math
import re
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np
from playwright.sync_api import Locator, Page, expect

from studio.panels._camera import HOME_CAMERA_FOV_DEG, VIEWS
from tests.conftest import drawn
from tests.e2e import ui

#: The handle's arrow colours on screen (drei's x, y, z).
AXIS_RGB = ((255, 32, 96), (32, 223, 128), (32, 128, 255))
HANDLE_SCALE = 0.22
#: Presses of "Q down" from "Go above the cup" to where the gripper closes around it.
DOWN_PRESSES = 4
NEW_SESSION = "my-stack"


class Teacher:
    """Drives the studio as a person does and counts each action: "click", "drag", "key", "type"."""

    def __init__(self, page: Page, shots: Callable[[Page, str], Path] | None = None) -> None:
        self.page = page
        self.counts: Counter[str] = Counter()
        self.shots = shots
        self.parts: dict[str, Counter[str]] = {}
        self._part = "other"

    # -- counting -------------------------------------------------------------------------------------------
    def part(self, name: str) -> None:
        """Count the following actions under ``name`` (e.g. "new session", "demonstrations")."""
        self._part = name
        self.parts.setdefault(name, Counter())

    def _count(self, kind: str, n: int = 1) -> None:
        self.counts[kind] += n
        self.parts.setdefault(self._part, Counter())[kind] += n

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def shot(self, step: str) -> Path | None:
        return self.shots(self.page, step) if self.shots is not None else None

    # -- actions --------------------------------------------------------------------------------------------
    def click(self, target: Locator) -> None:
        target.click()
        self._count("click")

    def button(self, name: str) -> None:
        self.click(self.page.get_by_role("button", name=name, exact=True).first)

    def in_row(self, label: str, button: str) -> None:
        self.click(ui.row(self.page, label).get_by_role("button", name=button, exact=True))

    def choose(self, label: str, option: str) -> None:
        self.click(ui.row(self.page, label).locator("input, select").first)
        self.click(self.page.get_by_role("option", name=option, exact=True))

    def step(self, name: str) -> None:
        if ui.current_step(self.page) != name:
            self.choose("Step", name)
        expect(self.page.locator(f'.step-title[data-step="{name}"]')).to_be_attached()

    def type_into(self, label: str, text: str) -> None:
        box = ui.row(self.page, label).locator("input").first
        self.click(box)
        box.fill(text)
        self._count("type")
        box.press("Enter")
        self._count("key")

    def key(self, code: str) -> None:
        self.page.keyboard.press(code)
        self._count("key")

    def drag(self, points: list[tuple[float, float]], during: Callable[[], None] | None = None) -> None:
        """Press the mouse at the first point, move through the others (as a hand does, in small steps), release.
        ``during``: called at the farthest point, before coming back (the mouse still pressed). A frame is drawn
        first: the page finds what is under the mouse where it last drew it (test pages draw seldom at rest)."""
        drawn(self.page)
        m = self.page.mouse
        m.move(*points[0])
        m.down()
        far = int(np.argmax([math.dist(points[0], p) for p in points]))
        for i, p in enumerate(points[1:], start=1):
            m.move(*p, steps=12)
            if i == far and during is not None:
                during()
        m.up()
        self._count("drag")

    # -- what the page shows ----------------------------------------------------------------------------------
    def gripper(self, arm: str = "left") -> np.ndarray:
        el = self.page.locator(f'.gripper-status[data-arm="{arm}"]').first
        return np.array([float(el.get_attribute(f"data-{k}") or "nan") for k in ("x", "y", "z")])

    def goal(self) -> np.ndarray:
        """Where the gripper is going, from the Move panel (m)."""
        el = self.page.locator(".gripper-goal").first
        return np.array([float(el.get_attribute(f"data-{k}") or "nan") for k in ("x", "y", "z")]) / 100.0

    def settle(self) -> None:
        ui.wait_arm_settled(self.page)

    def send(self, action: Callable[[], None]) -> None:
        """Send the arm somewhere (a key or a button), then wait as a person does: until the Move panel shows the
        new goal (the studio took the order), until the gripper is where the panel says it is going, and still.
        On a busy machine the order and the arm's status can both come later than the arm's quiet spell, and
        "Go above" may show its first leg (up or across) before the goal."""
        before = self.goal()
        action()
        self.page.wait_for_function(
            """before => {
                const el = document.querySelector('.gripper-goal');
                if (!el) return false;
                const v = ['x', 'y', 'z'].map(k => parseFloat(el.dataset[k]) / 100);
                return Math.hypot(v[0] - before[0], v[1] - before[1], v[2] - before[2]) > 0.01;
            }""",
            arg=[float(v) for v in before],
            polling=100,
            timeout=30_000,
        )
        ui.wait_at_goal(self.page, timeout=40)
        self.settle()

    def press_and_follow(self, code: str, axis: int, sign: int) -> None:
        """Press a key once and wait until the gripper's goal moved that way (a person watches the arm)."""
        before = self.goal()[axis]
        self.key(code)
        self.page.wait_for_function(
            """([axis, before, sign]) => {
                const el = document.querySelector('.gripper-goal');
                if (!el) return false;
                const v = parseFloat(el.dataset[['x', 'y', 'z'][axis]]) / 100;
                return sign * (v - before) > 0.004;
            }""",
            arg=[axis, float(before), sign],
            polling=100,
        )


# -- the handle on screen ---------------------------------------------------------------------------------------
def project(view: str, p: np.ndarray, width: int = ui.VIEWPORT["width"], height: int = ui.VIEWPORT["height"]):
    """Screen pixel of world point ``p`` seen from one of the studio's views (+z up, vertical fov)."""
    pos, at = (np.array(v, dtype=float) for v in VIEWS[view])
    f = at - pos
    f /= np.linalg.norm(f)
    r = np.cross(f, [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    d = np.asarray(p, dtype=float) - pos
    x, y, z = d @ r, d @ u, d @ f
    s = (height / 2) / math.tan(math.radians(HOME_CAMERA_FOV_DEG) / 2)
    return width / 2 + s * x / z, height / 2 - s * y / z


def pixels_per_metre(view: str, p: np.ndarray, axis: int) -> np.ndarray:
    """Screen displacement (pixels) of one metre along room ``axis`` at ``p`` in ``view``."""
    e = np.zeros(3)
    e[axis] = 0.01
    return (np.array(project(view, p + e)) - np.array(project(view, p))) * 100.0


def arrow_point(page: Page, view: str, p: np.ndarray, axis: int) -> tuple[float, float]:
    """A pixel on the handle's arrow along room ``axis`` (the projected tip, refined by the arrow's colour)."""
    from PIL import Image

    center = np.array(project(view, p))
    e = np.zeros(3)
    e[axis] = HANDLE_SCALE * 0.85
    tip = np.array(project(view, p + e))
    img = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
    d = tip - center
    length = max(float(np.linalg.norm(d)), 1.0)
    ys, xs = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    near = np.hypot(xs - center[0], ys - center[1]) < 1.5 * length + 15
    colour = np.abs(img - np.array(AXIS_RGB[axis])).sum(axis=2) < 90
    m = near & colour
    if m.sum() < 5:
        return float(tip[0]), float(tip[1])
    px = np.stack([xs[m], ys[m]], axis=1).astype(float)
    along = (px - center) @ (d / length)
    pick = px[np.argsort(along)[int(0.75 * (len(along) - 1))]]
    return float(pick[0]), float(pick[1])


def out_of_reach_label(page: Page) -> Locator:
    """The words under the robot's status while a handle is out of reach (the red marker in the scene is drawn,
    not text of the page)."""
    return page.get_by_text(re.compile("cannot reach the handle's position"))


# -- the flow -------------------------------------------------------------------------------------------------
def new_session(t: Teacher, name: str = NEW_SESSION, table: str = "stack-cup") -> None:
    """Sessions step → a new session on the ``table`` set-up → back to Teach."""
    t.part("new session")
    t.step("Sessions")
    t.type_into("New name", name)
    t.choose("New session's table", table)
    t.in_row("Session action", "New")
    ui.wait_text(t.page, re.escape(name))
    t.step("Teach")
    expect(t.page.locator(".demo-row")).to_have_count(0)


def look(t: Teacher, view: str) -> Path | None:
    """Press a View button and take a screenshot once the camera stopped (the handle is where the view says)."""
    t.in_row("View", view)
    t.page.mouse.move(20, ui.VIEWPORT["height"] - 20)  # the pointer leaves the button (its hint closes)
    _wait_view_still(t.page)
    return t.shot(f"{view.lower()} view")


def _wait_view_still(page: Page) -> None:
    """Wait until two screenshots a moment apart are the same picture (the camera arrived; the arm is still)."""
    prev = None
    for _ in range(60):
        cur = page.screenshot()
        if cur == prev:
            return
        prev = cur
        page.wait_for_timeout(250)


def grasp(t: Teacher, name: str) -> None:
    """Go above object ``name``, down with the keys (to 1 cm below its top), close the gripper (C)."""
    t.send(lambda: t.in_row("Go above the", name))
    for _ in range(DOWN_PRESSES):
        t.press_and_follow("KeyQ", 2, -1)
    t.settle()
    t.key("KeyC")
    ui.wait_status(t.page, "s.open < 1")


def let_go_above(t: Teacher, name: str) -> None:
    """Carry what the gripper holds above object ``name`` and open the gripper (O): it comes down onto (into) it."""
    t.send(lambda: t.in_row("Go above the", name))
    t.key("KeyO")
    ui.wait_status(t.page, "s.open > 99")


def grasp_the_cup(t: Teacher) -> None:
    grasp(t, "cup")


def take(t: Teacher, carried: str, target: str) -> None:
    """One take: Record, ``carried`` onto ``target``, back home (H), Stop (so the next take starts at home)."""
    t.button("Record")
    ui.wait_text(t.page, "Recording")
    grasp(t, carried)
    let_go_above(t, target)
    t.send(lambda: t.key("KeyH"))
    t.button("Stop")
    ui.wait_text(t.page, "Not recording")


def demonstrate(t: Teacher) -> None:
    """One take of stack-cup: the cup into the bottom cup."""
    take(t, "cup", "bottom cup")


def out_of_reach_and_back(t: Teacher) -> dict[str, object]:
    """Carrying the cup: drag the handle's x arrow (Top view) far beyond reach and back in one drag, then its y
    arrow towards the bottom cup; returns what was seen."""
    seen: dict[str, object] = {}
    t.part("out of reach and back")
    grasp_the_cup(t)
    t.in_row("View", "Top")
    _wait_view_still(t.page)
    p = t.gripper()
    start = arrow_point(t.page, "Top", p, 0)
    along = pixels_per_metre("Top", p, 0)
    far = (start[0] + along[0] * 0.9, start[1] + along[1] * 0.9)
    back = (start[0] + along[0] * 0.1, start[1] + along[1] * 0.1)
    out_label = out_of_reach_label(t.page)

    def beyond() -> None:
        expect(out_label).to_be_visible()
        # held out of reach, the arm reaches out as far as it can at the speed it moves (the caller checks how far)
        _wait_status_or_go_on(t.page, f"s.x > {float(p[0]) + 0.22:.4f}")
        seen["far shot"] = t.shot("handle out of reach")
        seen["far gripper"] = t.gripper()

    t.drag([start, far, back], during=beyond)
    # the arm comes back to where the handle was let go (0.1 m out), then rests: a busy page can be quiet for a
    # moment while the arm still moves, and the next drag aims at the handle where the arm is
    back_x = float(p[0]) + 0.1
    _wait_status_or_go_on(t.page, f"Math.abs(s.x - {back_x:.4f}) < 0.015")
    t.settle()
    p = t.gripper()
    start = arrow_point(t.page, "Top", p, 1)
    along = pixels_per_metre("Top", p, 1)
    dy = 0.14 - float(p[1])  # towards the bottom cup (y = 0.14 m)
    t.drag([start, (start[0] + along[0] * dy, start[1] + along[1] * dy)])
    _wait_status_or_go_on(t.page, "Math.abs(s.y - 0.14) < 0.02")
    t.settle()
    seen["back gripper"] = t.gripper()
    seen["back shot"] = t.shot("handle back near the bottom cup")
    return seen


def _wait_status_or_go_on(page: Page, expr: str, timeout: float = 40.0) -> None:
    """Wait until the robot status holds ``expr`` (see :func:`ui.wait_status`); if it never does, go on: the
    caller's own check then says where the gripper is."""
    try:
        ui.wait_status(page, expr, timeout=timeout)
    except Exception:
        pass


def finish_excursion(t: Teacher) -> None:
    """After the handle came back: above the bottom cup (a place the example reaches), open, home (H)."""
    t.send(lambda: t.in_row("Go above the", "bottom cup"))
    ui.wait_status(t.page, "Math.abs(s.x - 0.78) < 0.01 && Math.abs(s.y - 0.14) < 0.01")
    t.key("KeyO")
    ui.wait_status(t.page, "s.open > 99")
    t.send(lambda: t.key("KeyH"))


def teach_train_preview(t: Teacher, take: Callable[[Teacher], None] = demonstrate) -> str:
    """Three demonstrations (each one ``take``), Train, Preview played to its end; returns the preview's task
    result in words."""
    t.part("demonstrations")
    t.in_row("View", "Reset")
    for _ in range(3):
        take(t)
    expect(t.page.locator(".demo-row")).to_have_count(3)
    t.shot("three demonstrations")
    t.part("train and preview")
    t.step("Train")
    t.button("Train")
    ui.wait_text(t.page, r"^Trained\.", timeout=180)
    t.shot("trained")
    return preview_to_the_end(t)


def preview_to_the_end(t: Teacher, shot: str = "preview: the skill works") -> str:
    """The Preview step, Play, until the time reaches the end; returns the task result in words."""
    t.step("Preview")
    t.in_row("Playback", "Play")
    ui.wait_text(t.page, "learned skill \\(preview\\), playing")
    result = t.page.locator(".task-result").first
    expect(result).to_contain_text(re.compile(r"ended|picked up|in the gripper"), timeout=120_000)
    m = re.search(r"Learned path \(([\d.]+) s\)", t.page.get_by_text(re.compile(r"Learned path \(")).first.inner_text())
    assert m is not None
    length = float(m.group(1))
    t.page.wait_for_function(
        """(end) => {
            const lab = [...document.querySelectorAll('label')].find(l => l.textContent.trim() === 'Time (s)');
            const row = lab && lab.closest('.mantine-Flex-root');
            const box = row && row.querySelector('input.mantine-NumberInput-input');
            return box !== null && box !== undefined && parseFloat(box.value) >= end;
        }""",
        arg=length - 0.2,
        polling=200,
        timeout=120_000,
    )
    ui.wait_text(t.page, "learned skill \\(preview\\), at its end")  # the picture is the skill's end
    t.shot(shot)
    return result.inner_text()


def choose_object(t: Teacher, name: str) -> None:
    """Teach step: choose object ``name`` (its handle appears on it) and look from the top."""
    t.part("move an object")
    t.step("Teach")
    t.choose("Object", name)
    t.in_row("View", "Top")
    _wait_view_still(t.page)


def drag_handle(t: Teacher, at: np.ndarray, wxyz: np.ndarray, axis: int, metres: float, scale: float = 0.16) -> None:
    """Drag the chosen object's handle (``scale`` m, at ``at``, turned as ``wxyz``) along its own arrow ``axis`` by
    ``metres`` (Top view), pressing on the arrow's head."""
    from studio.core.rotations import matrix_from_quat_wxyz

    along = matrix_from_quat_wxyz(np.asarray(wxyz, dtype=float))[:, axis]
    grab = np.asarray(at, dtype=float) + along * 0.85 * scale  # the arrow's head, beyond the turning ring
    t.drag([project("Top", grab), project("Top", grab + along * metres)])


TEACHING_PARTS = ("new session", "demonstrations", "train and preview")
