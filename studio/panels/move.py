"""Move panel (Teach step): move the gripper in the room's axes with keys or their buttons (Shift, or a key held
a second: 5 cm steps), type its position in centimetres, send it above an object or back to the home posture.
Each key is shown on its button, and the keys in plain words above them."""

from __future__ import annotations

import html
import time
from collections.abc import Callable

import viser

from studio.controller import Controller, Topic
from studio.core.types import ARMS
from studio.panels._keys import install_keys

#: Each button of the keypad: (row label, [(button text, key code, what it does)]).
STEPS: tuple[tuple[str, tuple[tuple[str, str, tuple[str, int]], ...]], ...] = (
    ("Toward / away (x)", (("W toward robot", "KeyW", ("x", -1)), ("S away", "KeyS", ("x", 1)))),
    ("Right / left (y)", (("A robot's right", "KeyA", ("y", -1)), ("D robot's left", "KeyD", ("y", 1)))),
    ("Down / up (z)", (("Q down", "KeyQ", ("z", -1)), ("E up", "KeyE", ("z", 1)))),
)
#: The big steps (Shift + a key): (button text, key code, what it does).
BIG_STEPS: tuple[tuple[str, str, tuple[str, int]], ...] = tuple(
    (f"⇧{text[0]}", f"Shift+{code}", what) for _, row in STEPS for text, code, what in row
)
BIG_ROW = "Big steps (Shift)"
CLOSE, OPEN, HOME = "C close", "O open", "H home pose"
NO_OBJECTS = "(no objects)"
KEYS = (
    {code: text for _, row in STEPS for text, code, _ in row}
    | {code: text for text, code, _ in BIG_STEPS}
    | {"KeyC": CLOSE, "KeyO": OPEN, "KeyH": HOME}
)
KEY_WORDS = (
    "**Keys** (when you are not typing in a box): **W** / **S** toward / away from the robot, **A** / **D** to "
    "its right / left, **Q** / **E** down / up, **C** close and **O** open the gripper, **H** home pose. A key "
    "moves 1 cm, with **Shift** 5 cm; held for a second, it goes on in 5 cm steps."
)
#: Seconds after a teacher typed into a position box during which the robot's motion does not overwrite it.
TYPED_HOLD_S = 2.0


class MovePanel:
    """The keypad, the position boxes, "Go above" and "Home pose"."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        gui = server.gui
        self._typed = 0.0
        self._last_sync = 0.0
        guarded = ctl.guarded("Could not move the gripper")
        with gui.add_folder("Move the gripper", order=0.5):
            self.key_words = gui.add_markdown(KEY_WORDS)
            self.key_arm = gui.add_dropdown(
                "Keys move the",
                options=tuple(f"{a} gripper" for a in ARMS),
                initial_value=f"{ctl.guide.key_arm} gripper",
                visible=len(ctl.teaching.selected_arms) > 1,
            )
            self.rows: dict[str, viser.GuiButtonGroupHandle] = {}
            for label, row in STEPS:
                grp = gui.add_button_group(label, options=tuple(text for text, _, _ in row))
                grp.on_click(guarded(self._make_step({text: what for text, _, what in row})))
                self.rows[label] = grp
            self.rows[BIG_ROW] = gui.add_button_group(
                BIG_ROW,
                options=tuple(text for text, _, _ in BIG_STEPS),
                hint="5 cm steps: Shift with W, S, A, D, Q or E, or these buttons.",
            )
            self.rows[BIG_ROW].on_click(guarded(self._make_step({text: what for text, _, what in BIG_STEPS}, big=True)))
            self.grip = gui.add_button_group("Gripper", options=(CLOSE, OPEN))
            self.home = gui.add_button(HOME, hint="Put the arm back in the posture it started in.")
            self.above = gui.add_button_group(
                "Go above the",
                options=self._object_names(),
                hint="The gripper goes above that object, pointing down (what it carries stays clear of the object).",
            )
            self.boxes = {
                axis: gui.add_number(
                    f"Gripper {axis} (cm)",
                    initial_value=0.0,
                    step=0.5,
                    hint=hint,
                )
                for axis, hint in (
                    ("x", "Away from the robot (its front), in centimetres: type a number and press Enter."),
                    ("y", "To the robot's left, in centimetres: type a number and press Enter."),
                    ("z", "Up, in centimetres (the table top is at -7): type a number and press Enter."),
                )
            }
            self.where = gui.add_html("")
            self.turn = gui.add_checkbox(
                "Turn with the handle",
                initial_value=ctl.guide.turning,
                hint="On: the gripper's handle shows rings that turn the gripper. Off: arrows that move it.",
            )
        self.key_arm.on_update(ctl.guarded()(self._on_key_arm))
        self.turn.on_update(ctl.guarded()(self._on_turn))
        self.grip.on_click(ctl.guarded("Could not move the gripper")(self._on_grip))
        self.home.on_click(ctl.guarded("Could not move the arm home")(lambda _: ctl.guide.home()))
        self.above.on_click(guarded(self._on_above))
        for axis, box in self.boxes.items():
            box.on_update(guarded(self._make_box(axis)))
        for topic in (Topic.GUIDE, Topic.ARMS):
            ctl.events.on(topic, self._on_chosen)
        for topic in (Topic.SCENE, Topic.SESSION):
            ctl.events.on(topic, self._on_scene)
        self._on_chosen()
        self._on_scene()
        self.sync(force=True)
        install_keys(server, KEYS)

    # -- callbacks -------------------------------------------------------------------------------------------
    def _make_step(self, what: dict[str, tuple[str, int]], big: bool = False) -> Callable[[viser.GuiEvent], None]:
        def cb(event: viser.GuiEvent) -> None:
            axis, sign = what[event.target.value]
            self.ctl.guide.step(axis, sign, big=big)

        return cb

    def _make_box(self, axis: str) -> Callable[[viser.GuiEvent], None]:
        def cb(event: viser.GuiEvent) -> None:
            if event.client is None:  # our own sync from the robot
                return
            self._typed = time.monotonic()
            self.ctl.guide.move_axis(self.ctl.guide.key_arm, axis, float(self.boxes[axis].value) / 100.0)

        return cb

    def _on_above(self, event: viser.GuiEvent) -> None:
        name = str(event.target.value)
        if name in self.ctl.scene.scene.names():
            self.ctl.guide.above(name)

    def _object_names(self) -> tuple[str, ...]:
        return tuple(self.ctl.scene.scene.names()) or (NO_OBJECTS,)

    def _on_scene(self) -> None:
        names = self._object_names()
        if tuple(self.above.options) != names:
            self.above.options = names
        self.above.visible = names != (NO_OBJECTS,)  # a button group cannot be disabled

    def _on_grip(self, event: viser.GuiEvent) -> None:
        arm = self.ctl.guide.key_arm
        self.ctl.teaching.set_gripper(arm, 0.0 if event.target.value == CLOSE else 100.0)

    def _on_key_arm(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.ctl.guide.set_key_arm(str(self.key_arm.value).split()[0])

    def _on_turn(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.ctl.guide.set_turning(bool(self.turn.value))

    def _on_chosen(self) -> None:
        guide = self.ctl.guide
        with self.server.atomic():
            self.key_arm.visible = len(self.ctl.teaching.selected_arms) > 1
            self.key_arm.value = f"{guide.key_arm} gripper"
            self.turn.value = guide.turning

    # -- periodic (pose pump thread) -----------------------------------------------------------------------------
    def sync(self, *, force: bool = False) -> None:
        """Show where the gripper is going in the boxes (not while the teacher is typing into one)."""
        if not force and time.monotonic() - self._typed < TYPED_HOLD_S:
            return
        arm = self.ctl.guide.key_arm
        p = self.ctl.guide.pose(arm)[0] * 100.0
        with self.server.atomic():
            for axis, v in zip("xyz", p, strict=True):
                shown = round(float(v), 1)
                if force or abs(float(self.boxes[axis].value) - shown) >= 0.05:
                    self.boxes[axis].value = shown
            content = (
                f'<div class="gripper-goal" data-arm="{arm}" data-x="{p[0]:.1f}" data-y="{p[1]:.1f}" '
                f'data-z="{p[2]:.1f}" style="font-size:0.85em;color:#333">The {html.escape(arm)} gripper is going to '
                f"x {p[0]:.1f}, y {p[1]:.1f}, z {p[2]:.1f} cm.</div>"
            )
            if self.where.content != content:
                self.where.content = content

    def tick(self, now: float) -> None:
        if now - self._last_sync > 0.25 and self.ctl.display.is_live:
            self._last_sync = now
            self.sync()
