"""Teach panel: move the arm (the gripper handle in the room's axes with IK, joint sliders, gripper buttons) and
record demos."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import viser

from studio.controller import Controller, Step, Topic
from studio.controller.teaching import REACH_HOLD_S
from studio.core.arms import arm_columns
from studio.core.rotations import matrix_from_quat_wxyz, quat_wxyz_from_matrix
from studio.core.types import ALL_ARM_JOINTS, ARMS, Arm
from studio.words import length_words

JOINT_WORDS = {
    "s0": "shoulder turn",
    "s1": "shoulder lift",
    "e0": "upper-arm twist",
    "e1": "elbow bend",
    "w0": "forearm twist",
    "w1": "wrist bend",
    "w2": "wrist twist",
}
#: Seconds after a user touches a slider or handle during which the robot's own motion does not move it.
USER_HOLD_S = 0.8
UNREACHABLE_COLOR = (230, 40, 40)
SAVING = "Saving the demonstration…"

GuiCallback = Callable[[viser.GuiEvent], None]
#: The gripper handle's orientation: the room's axes (x away from the robot, y to its left, z up).
ROOM_AXES = (1.0, 0.0, 0.0, 0.0)


class HandleMode(NamedTuple):
    """The gripper handle's look: arrows in the room's axes to move the gripper, or smaller rings to turn it."""

    disable_axes: bool
    disable_rotations: bool
    scale: float
    line_width: float


def handle_mode(turning: bool) -> HandleMode:
    return HandleMode(True, False, 0.15, 2.0) if turning else HandleMode(False, True, 0.22, 2.5)


def out_of_reach_words(arm: Arm, handle: np.ndarray, reached: np.ndarray) -> str:
    """What an out-of-reach drag did, in the room's terms: how far short of the handle the gripper stopped, and
    its height when that changed (a later key moves from there)."""
    short = float(np.hypot(*(handle[:2] - reached[:2])))
    up = float(reached[2] - handle[2])
    said = [f"{length_words(short)} short of it"] if short >= 0.005 else []
    if abs(up) >= 0.005:
        said.append(f"{length_words(up)} {'higher' if up > 0 else 'lower'} than the handle")
    where = f": {' and '.join(said)}" if said else ""
    height = f" The gripper is now {reached[2] * 100:.1f} cm high (z), the handle was at {handle[2] * 100:.1f} cm."
    return (
        f"The {arm} arm cannot put its gripper where you left the handle; it stopped at the closest pose it can "
        f"reach{where}.{height if abs(up) >= 0.005 else ''} Drag the handle closer to the robot, or press H for the "
        "home pose."
    )


def joint_label(name: str) -> str:
    arm, j = name.split("_")
    return f"{arm.capitalize()} {JOINT_WORDS[j]} ({j})"


class TeachPanel:
    """Gripper handles (IK), joint sliders, gripper buttons and the recording controls."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        self.scene = server.scene
        gui = server.gui
        self._dragging = {arm: False for arm in ARMS}
        self._drag_end = {arm: 0.0 for arm in ARMS}
        self._slider_touched = 0.0
        self._last_slider_sync = 0.0
        self._last_timer = 0.0
        self._last_q: np.ndarray | None = None
        self._drag_end_any = 0.0
        self._build_handles()
        self._build_gui(gui)
        ctl.events.on(Topic.ARMS, self._on_arms)
        ctl.events.on(Topic.REACH, self._on_reach)
        ctl.events.on(Topic.RECORDING, self._on_recording_state)
        ctl.events.on(Topic.VIEW, self._on_arms)
        ctl.events.on(Topic.GUIDE, self._on_arms)

    def _build_handles(self) -> None:
        """A handle on each gripper (arrows along the room's axes, or rings to turn it), and a red marker where a
        handle is out of reach."""
        ctl = self.ctl
        self.handles: dict[str, viser.TransformControlsHandle] = {}
        self.miss_markers: dict[str, viser.IcosphereHandle] = {}
        self.miss_labels: dict[str, viser.LabelHandle] = {}
        self._turn_from: dict[Arm, np.ndarray] = {}
        for arm in ARMS:
            pos, _ = ctl.baxter.fk(arm, ctl.teaching.arm_q(arm))
            h = self.scene.add_transform_controls(
                f"/teach/{arm}_handle",
                position=tuple(pos),
                wxyz=ROOM_AXES,
                depth_test=False,
                disable_sliders=True,  # a plane square jumps in depth under a perspective view
                visible=self._handle_shown(arm),
            )
            self._apply_mode(h, handle_mode(ctl.guide.turning))
            self.handles[arm] = h
            self.miss_markers[arm] = self.scene.add_icosphere(
                f"/teach/{arm}_unreachable", radius=0.03, color=UNREACHABLE_COLOR, opacity=0.6, visible=False
            )
            self.miss_labels[arm] = self.scene.add_label(
                f"/teach/{arm}_unreachable/label", "Out of reach", visible=False
            )
            h.on_update(self._make_gizmo_cb(arm))

    def _build_gui(self, gui: viser.GuiApi) -> None:
        ctl = self.ctl
        with gui.add_folder("Record a demonstration", order=0):
            self.record_btn = gui.add_button(
                "Record", icon=viser.Icon.PLAYER_RECORD, color="red", hint="Start recording while you guide the arm."
            )
            self.stop_btn = gui.add_button(
                "Stop", icon=viser.Icon.PLAYER_STOP, disabled=True, hint="Stop and keep this demonstration."
            )
            self.discard_btn = gui.add_button(
                "Discard", icon=viser.Icon.TRASH, disabled=True, hint="Stop and throw this demonstration away."
            )
            self.rec_status = gui.add_markdown("Not recording.")
            # where to put the objects for the next take (a skill that follows them learns more places)
            self.next_place = gui.add_markdown(ctl.placed.suggestion())
            for topic in (Topic.SKILL, Topic.SESSION):
                ctl.events.on(topic, lambda: setattr(self.next_place, "content", ctl.placed.suggestion()))

        with gui.add_folder("Grippers", order=1):
            self.grip_width: dict[Arm, viser.GuiSliderHandle[float]] = {}
            for arm in ARMS:
                grp = gui.add_button_group(f"{arm.capitalize()} gripper", options=("Open", "Close"))
                w = gui.add_slider(
                    f"{arm.capitalize()} gripper width (%)",
                    min=0.0,
                    max=100.0,
                    step=1.0,
                    initial_value=ctl.teaching.gripper_width(arm),
                    hint="0 = closed, 100 = fully open.",
                )
                self.grip_width[arm] = w
                grp.on_click(self._make_grip_button_cb(arm))
                w.on_update(self._make_grip_width_cb(arm))

        with gui.add_folder("Joints", order=2, expand_by_default=False):
            self.sliders: dict[str, viser.GuiSliderHandle[float]] = {}
            lo = np.concatenate([ctl.baxter.lower_limits(a) for a in ARMS])
            hi = np.concatenate([ctl.baxter.upper_limits(a) for a in ARMS])
            q = ctl.teaching.robot_q()
            for i, name in enumerate(ALL_ARM_JOINTS):
                s = gui.add_slider(
                    joint_label(name) + " °",
                    min=round(math.degrees(lo[i]), 1),
                    max=round(math.degrees(hi[i]), 1),
                    step=0.5,
                    initial_value=round(math.degrees(q[i]), 1),
                )
                s.on_update(self._make_slider_cb(i))
                self.sliders[name] = s

        t = ctl.teaching
        self.record_btn.on_click(ctl.guarded("Could not start recording")(lambda e: t.start_recording(by=e.client)))
        self.stop_btn.on_click(ctl.guarded("Could not save the recording")(lambda _: t.stop_recording()))
        self.discard_btn.on_click(ctl.guarded("Could not discard the recording")(self._on_discard))

    # -- gizmo -> IK -> robot ------------------------------------------------------------------------------
    def _make_gizmo_cb(self, arm: Arm) -> Callable[[viser.TransformControlsEvent], None]:
        def cb(event: viser.TransformControlsEvent) -> None:
            phase = getattr(event, "phase", "update")  # viser versions before 1.0 send no phase
            guide = self.ctl.guide
            h = self.handles[arm]
            if phase == "start" or arm not in self._turn_from:
                self._dragging[arm] = True
                # the handle starts in room axes: its turn from there is the gripper's turn
                self._turn_from[arm] = matrix_from_quat_wxyz(guide.pose(arm)[1])
            try:
                if phase not in ("start", "end"):  # a grab and a release bring no new pose
                    if guide.turning:
                        R = matrix_from_quat_wxyz(np.asarray(h.wxyz)) @ self._turn_from[arm]
                        guide.move(arm, np.asarray(h.position), quat_wxyz_from_matrix(R))
                    else:
                        guide.move(arm, np.asarray(h.position))
            except Exception as exc:
                self.ctl.report(exc, title="Could not move the arm", client=event.client)
            if phase == "end":
                self._turn_from.pop(arm, None)
                h.wxyz = ROOM_AXES
                self._dragging[arm] = False
                self._drag_end[arm] = self._drag_end_any = time.monotonic()
                r = self.ctl.teaching.reach.get(arm)
                if r is not None and r.blocked:
                    self.ctl.notify("Stopped before touching", r.blocked, kind="warning", client=event.client)
                elif self.ctl.teaching.unreachable(arm):
                    self.ctl.notify(
                        "Out of reach",
                        out_of_reach_words(arm, np.asarray(h.position), guide.pose(arm)[0]),
                        kind="warning",
                        client=event.client,
                    )

        return cb

    def _on_reach(self) -> None:
        """Show the red "Out of reach" marker where a taught arm's handle cannot be reached."""
        teaching = self.ctl.teaching
        with self.server.atomic():
            for arm in ARMS:
                r = teaching.reach.get(arm)
                off = r is None or r.ok or arm not in teaching.selected_arms or self.ctl.view.step != Step.TEACH
                if r is not None:
                    self.miss_markers[arm].position = r.target
                    label = "Would touch" if r.blocked else "Out of reach"
                    if self.miss_labels[arm].text != label:
                        self.miss_labels[arm].text = label
                self.miss_markers[arm].visible = not off
                self.miss_labels[arm].visible = not off

    # -- sliders and grippers --------------------------------------------------------------------------
    def _make_slider_cb(self, i: int) -> GuiCallback:
        def cb(event: viser.GuiEvent) -> None:
            if event.client is None:  # our own sync from the robot state
                return
            self._slider_touched = time.monotonic()
            self.ctl.teaching.move_joint(i, math.radians(float(self.sliders[ALL_ARM_JOINTS[i]].value)))

        return self.ctl.guarded("Could not move the joint")(cb)

    def _make_grip_button_cb(self, arm: Arm) -> GuiCallback:
        def cb(event: viser.GuiEvent) -> None:
            width = 100.0 if event.target.value == "Open" else 0.0
            self._slider_touched = time.monotonic()
            self.ctl.teaching.set_gripper(arm, width)
            self.grip_width[arm].value = width

        return self.ctl.guarded("Could not move the gripper")(cb)

    def _make_grip_width_cb(self, arm: Arm) -> GuiCallback:
        def cb(event: viser.GuiEvent) -> None:
            if event.client is None:
                return
            self._slider_touched = time.monotonic()
            self.ctl.teaching.set_gripper(arm, float(self.grip_width[arm].value))

        return self.ctl.guarded("Could not move the gripper")(cb)

    def _handle_shown(self, arm: Arm) -> bool:
        """A taught gripper's handle shows in the Teach step while no object is chosen (one handle at a time)."""
        ctl = self.ctl
        return ctl.view.step == Step.TEACH and arm in ctl.teaching.selected_arms and ctl.guide.chosen is None

    @staticmethod
    def _apply_mode(h: viser.TransformControlsHandle, mode: HandleMode) -> None:
        for key, value in mode._asdict().items():
            if getattr(h, key) != value:
                setattr(h, key, value)

    def _on_arms(self) -> None:
        """The taught arms, the step, the chosen object or the handle's mode changed: a handle on each taught
        gripper, in the Teach step only, with arrows or rings."""
        self._last_q = None  # snap the newly shown handles to the grippers
        mode = handle_mode(self.ctl.guide.turning)
        with self.server.atomic():
            for arm in ARMS:
                h = self.handles[arm]
                h.visible = self._handle_shown(arm)
                self._apply_mode(h, mode)
        self._on_reach()

    # -- recording -------------------------------------------------------------------------------------
    def _on_discard(self, event: viser.GuiEvent) -> None:
        self.ctl.teaching.discard_recording(by=event.client)  # from another tab: asks first

    def _on_recording_state(self) -> None:
        rec = self.ctl.teaching.recording
        self.record_btn.disabled = rec or self.ctl.teaching.saving
        self.stop_btn.disabled = not rec
        self.discard_btn.disabled = not rec
        if self.ctl.teaching.saving:
            self.rec_status.content = SAVING
        elif not rec:
            self.rec_status.content = "Not recording."

    # -- periodic (pose pump thread) -------------------------------------------------------------------
    def tick(self, now: float) -> None:
        ctl = self.ctl
        # An out-of-reach target is told for a while after its drag; the handle is back on the gripper then.
        ctl.teaching.forget_reach(tuple(a for a in ARMS if not self._dragging[a]), older_than=REACH_HOLD_S)
        if ctl.display.is_live:
            q = ctl.teaching.robot_q()
            self._follow_robot(q)
            if now - self._last_slider_sync > 0.2 and time.monotonic() - self._slider_touched > USER_HOLD_S:
                self._last_slider_sync = now
                deg = np.round(np.degrees(q) * 2.0) / 2.0
                for i, name in enumerate(ALL_ARM_JOINTS):
                    self.sliders[name].value = float(deg[i])
                for arm, w in self.grip_width.items():  # the width the robot reports, as the readout says
                    w.value = float(round(ctl.teaching.gripper_width(arm)))
        rec = ctl.teaching.recorder
        if rec is not None and now - self._last_timer > 0.25:
            self._last_timer = now
            self.rec_status.content = f"**● Recording** {rec.elapsed:5.1f} s · {rec.n_samples:,} samples"

    def _follow_robot(self, q: np.ndarray) -> None:
        """Keep the handles on the grippers while the robot moves (not while the user drags one)."""
        mono = time.monotonic()
        moved = self._last_q is None or not np.array_equal(q, self._last_q) or mono - self._drag_end_any < 2.0
        self._last_q = q
        if not moved:
            return
        with self.server.atomic():
            for arm in self.ctl.teaching.selected_arms:
                if self._dragging[arm] or mono - self._drag_end[arm] < USER_HOLD_S:
                    continue
                pos, _ = self.ctl.baxter.fk(arm, q[arm_columns(arm)])
                self.handles[arm].position = tuple(pos)
