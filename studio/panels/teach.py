"""Teach panel: move the arm (gripper handle with IK, joint sliders, gripper buttons), record demos, manage them."""

from __future__ import annotations

import math
import threading
import time
from typing import TYPE_CHECKING

import numpy as np
import viser

from studio.core.types import ALL_ARM_JOINTS, ARMS
from studio.panels._charts import downsample_path, segments

if TYPE_CHECKING:
    from studio.app import Studio

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


def joint_label(name: str) -> str:
    arm, j = name.split("_")
    return f"{arm.capitalize()} {JOINT_WORDS[j]} ({j})"


class TeachPanel:
    """Gripper handles (IK), joint sliders, gripper buttons, recording controls and the demo list."""

    def __init__(self, app: Studio, gui: viser.GuiApi) -> None:
        self.app = app
        self.scene = app.server.scene
        self._dragging = {arm: False for arm in ARMS}
        self._drag_end = {arm: 0.0 for arm in ARMS}
        self._ik_lock = {arm: threading.Lock() for arm in ARMS}
        self._slider_touched = 0.0
        self._last_slider_sync = 0.0
        self._last_timer = 0.0
        self.unreachable = {arm: False for arm in ARMS}
        self._traces: dict[str, viser.SceneNodeHandle] = {}
        self._last_q: np.ndarray | None = None
        self._drag_end_any = 0.0

        # -- gripper handles (transform gizmos) -----------------------------------------------------------
        self.handles: dict[str, viser.TransformControlsHandle] = {}
        self.miss_markers: dict[str, viser.IcosphereHandle] = {}
        self.miss_labels: dict[str, viser.LabelHandle] = {}
        for arm in ARMS:
            pos, wxyz = app.baxter.fk(arm, app.arm_q(arm))
            h = self.scene.add_transform_controls(
                f"/teach/{arm}_handle",
                scale=0.22,
                line_width=2.5,
                position=tuple(pos),
                wxyz=tuple(wxyz),
                depth_test=False,
                visible=arm in app.selected_arms,
            )
            self.handles[arm] = h
            self.miss_markers[arm] = self.scene.add_icosphere(
                f"/teach/{arm}_unreachable", radius=0.03, color=UNREACHABLE_COLOR, opacity=0.6, visible=False
            )
            self.miss_labels[arm] = self.scene.add_label(
                f"/teach/{arm}_unreachable/label", "Out of reach", visible=False
            )
            h.on_update(self._make_gizmo_cb(arm))

        # -- GUI ------------------------------------------------------------------------------------------
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

        with gui.add_folder("Grippers", order=1):
            self.grip_open: dict[str, viser.GuiButtonHandle] = {}
            self.grip_close: dict[str, viser.GuiButtonHandle] = {}
            self.grip_width: dict[str, viser.GuiSliderHandle] = {}
            for arm in ARMS:
                grp = gui.add_button_group(f"{arm.capitalize()} gripper", options=("Open", "Close"))
                w = gui.add_slider(
                    f"{arm.capitalize()} gripper width (%)",
                    min=0.0,
                    max=100.0,
                    step=1.0,
                    initial_value=float(app.robot_gripper()[0 if arm == "left" else 1]),
                    hint="0 = closed, 100 = fully open.",
                )
                self.grip_width[arm] = w
                grp.on_click(self._make_grip_button_cb(arm))
                w.on_update(self._make_grip_width_cb(arm))

        with gui.add_folder("Joints", order=2, expand_by_default=False):
            self.sliders: dict[str, viser.GuiSliderHandle] = {}
            lo = np.concatenate([app.baxter.lower_limits(a) for a in ARMS])
            hi = np.concatenate([app.baxter.upper_limits(a) for a in ARMS])
            q = app.robot_q()
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

        with gui.add_folder("Demonstrations", order=3):
            self.demo_list = gui.add_html(self._demo_list_html())
            self.demo_pick = gui.add_dropdown("Demo", options=["(none)"], initial_value="(none)")
            self.demo_show = gui.add_checkbox("Show in the scene", initial_value=True)
            self.demo_name = gui.add_text("Name", initial_value="")
            self.demo_trim = gui.add_multi_slider(
                "Keep from … to (s)", min=0.0, max=1.0, step=0.01, initial_value=(0.0, 1.0)
            )
            self.demo_actions = gui.add_button_group("Demo action", options=("Rename", "Trim", "Delete"))

        self.record_btn.on_click(app.guarded("Could not start recording")(self._on_record))
        self.stop_btn.on_click(app.guarded("Could not save the recording")(self._on_stop))
        self.discard_btn.on_click(app.guarded("Could not discard the recording")(self._on_discard))
        self.demo_pick.on_update(app.guarded()(self._on_pick))
        self.demo_show.on_update(app.guarded()(self._on_show))
        self.demo_actions.on_click(app.guarded("Could not change the demonstration")(self._on_demo_action))

        app.events.on("arms", self._on_arms)
        app.events.on("demos", self.refresh_demos)
        app.events.on("session", self.refresh_demos)
        app.events.on("recording", self._on_recording_state)
        self.refresh_demos()

    # -- gizmo -> IK -> robot ------------------------------------------------------------------------------
    def _make_gizmo_cb(self, arm: str):
        def cb(event: viser.TransformControlsEvent) -> None:
            phase = getattr(event, "phase", "update")
            if phase == "start":
                self._dragging[arm] = True
            h = self.handles[arm]
            try:
                with self._ik_lock[arm]:
                    res = self.app.move_gripper(arm, np.asarray(h.position), np.asarray(h.wxyz))
                self._show_reach(arm, res.converged, np.asarray(h.position))
            except Exception as exc:
                self.app.report(exc, title="Could not move the arm", client=event.client)
            if phase == "end":
                self._dragging[arm] = False
                self._drag_end[arm] = self._drag_end_any = time.monotonic()
                if self.unreachable[arm]:
                    self.app.notify(
                        "Out of reach",
                        f"The {arm} arm cannot put its gripper where you left the handle; it stopped at the "
                        "closest pose it can reach. Drag the handle closer to the robot.",
                        kind="warning",
                        client=event.client,
                    )

        return cb

    def _show_reach(self, arm: str, ok: bool, target: np.ndarray) -> None:
        self.unreachable[arm] = not ok
        with self.app.server.atomic():
            self.miss_markers[arm].position = tuple(target)
            self.miss_markers[arm].visible = not ok
            self.miss_labels[arm].visible = not ok
        if not ok:
            self.app.panels.robot.set_status(
                f"The {arm} gripper cannot reach the handle's position: the arm stops at the closest pose."
            )
        else:
            self.app.panels.robot.set_status("")

    # -- sliders and grippers --------------------------------------------------------------------------
    def _make_slider_cb(self, i: int):
        @self.app.guarded("Could not move the joint")
        def cb(event: viser.GuiEvent) -> None:
            if event.client is None:  # our own sync from the robot state
                return
            self._slider_touched = time.monotonic()
            self.app.move_joint(i, math.radians(float(self.sliders[ALL_ARM_JOINTS[i]].value)))

        return cb

    def _make_grip_button_cb(self, arm: str):
        @self.app.guarded("Could not move the gripper")
        def cb(event: viser.GuiEvent) -> None:
            width = 100.0 if event.target.value == "Open" else 0.0
            self.app.set_gripper(arm, width)
            self.grip_width[arm].value = width

        return cb

    def _make_grip_width_cb(self, arm: str):
        @self.app.guarded("Could not move the gripper")
        def cb(event: viser.GuiEvent) -> None:
            if event.client is None:
                return
            self.app.set_gripper(arm, float(self.grip_width[arm].value))

        return cb

    def _on_arms(self) -> None:
        self._last_q = None  # snap the newly shown handles to the grippers
        with self.app.server.atomic():
            for arm in ARMS:
                on = arm in self.app.selected_arms
                self.handles[arm].visible = on
                if not on:
                    self.miss_markers[arm].visible = False
                    self.miss_labels[arm].visible = False

    # -- recording -------------------------------------------------------------------------------------
    def _on_record(self, event: viser.GuiEvent) -> None:
        self.app.start_recording()

    def _on_stop(self, event: viser.GuiEvent) -> None:
        self.app.stop_recording()

    def _on_discard(self, event: viser.GuiEvent) -> None:
        self.app.discard_recording()

    def _on_recording_state(self) -> None:
        rec = self.app.recorder is not None
        self.record_btn.disabled = rec
        self.stop_btn.disabled = not rec
        self.discard_btn.disabled = not rec
        if not rec:
            self.rec_status.content = "Not recording."

    # -- periodic (pose pump thread) -------------------------------------------------------------------
    def tick(self, now: float) -> None:
        app = self.app
        if app.display is app.live:
            q = app.robot_q()
            mono = time.monotonic()
            moved = self._last_q is None or not np.array_equal(q, self._last_q) or mono - self._drag_end_any < 2.0
            self._last_q = q
            with app.server.atomic():
                for arm in app.selected_arms if moved else ():
                    if self._dragging[arm] or mono - self._drag_end[arm] < USER_HOLD_S:
                        continue
                    pos, wxyz = app.baxter.fk(arm, q[:7] if arm == "left" else q[7:])
                    h = self.handles[arm]
                    h.position = tuple(pos)
                    h.wxyz = tuple(wxyz)
            if now - self._last_slider_sync > 0.2 and time.monotonic() - self._slider_touched > USER_HOLD_S:
                self._last_slider_sync = now
                deg = np.round(np.degrees(q) * 2.0) / 2.0
                for i, name in enumerate(ALL_ARM_JOINTS):
                    self.sliders[name].value = float(deg[i])
        rec = app.recorder
        if rec is not None and now - self._last_timer > 0.25:
            self._last_timer = now
            self.rec_status.content = f"**● Recording** {rec.elapsed:5.1f} s · {rec.n_samples:,} samples"

    # -- demo list -------------------------------------------------------------------------------------
    def _demo_list_html(self) -> str:
        rows = []
        for i, (name, color, dur, n, arms, visible) in enumerate(self.app.demo_summaries()):
            sw = f"background:rgb{color};" if visible else f"border:2px solid rgb{color};"
            rows.append(
                f'<div class="demo-row" data-demo="{i}" style="display:flex;gap:6px;align-items:center;'
                f'font-size:0.85em;margin:2px 0"><span style="display:inline-block;width:12px;height:12px;'
                f'border-radius:6px;{sw}"></span><b>{_esc(name)}</b>'
                f"<span>{dur:.1f} s · {n:,} samples · {'/'.join(arms)}{'' if visible else ' · hidden'}</span></div>"
            )
        if not rows:
            return '<div class="demo-row-empty" style="font-size:0.85em">No demonstrations yet: press Record.</div>'
        return "".join(rows)

    def draw_traces(self) -> None:
        """Each shown demonstration as a coloured 3-D line of the taught gripper(s)."""
        app = self.app
        wanted: dict[str, tuple[np.ndarray, tuple[int, int, int]]] = {}
        for i, rec in enumerate(app.recordings()):
            if rec.name in app.hidden_demos:
                continue
            for arm in rec.arms:
                pts = downsample_path(np.asarray(app.demo_of(rec, arm).position))
                wanted[f"/demos/{i}_{arm}"] = (pts, app.demo_color(i))
        with app.server.atomic():
            for key in list(self._traces):
                self._traces.pop(key).remove()
            for key, (pts, color) in wanted.items():
                self._traces[key] = self.scene.add_line_segments(
                    key, segments(pts), colors=color, thickness=3.0, thickness_units="screen"
                )

    def refresh_demos(self) -> None:
        try:
            self.draw_traces()
        except Exception as exc:
            self.app.report(exc, title="Could not draw the demonstrations")
        names = self.app.demo_names()
        with self.app.server.atomic():
            self.demo_list.content = self._demo_list_html()
            opts = names or ["(none)"]
            current = self.demo_pick.value
            self.demo_pick.options = opts
            if current not in opts:
                self.demo_pick.value = opts[-1]
        self._on_pick(None)

    def _selected(self) -> int | None:
        names = self.app.demo_names()
        v = self.demo_pick.value
        return names.index(v) if v in names else None

    def _on_pick(self, event: viser.GuiEvent | None) -> None:
        i = self._selected()
        for h in (self.demo_show, self.demo_name, self.demo_trim):
            h.disabled = i is None
        if i is None:
            return
        dur = max(self.app.demo_duration(i), 0.02)
        self.demo_name.value = self.app.demo_names()[i]
        self.demo_show.value = self.app.demo_visible(i)
        self.demo_trim.max = round(dur + 0.005, 2)
        self.demo_trim.value = (0.0, round(dur + 0.005, 2))

    def _on_show(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        i = self._selected()
        if i is not None:
            self.app.set_demo_visible(i, bool(self.demo_show.value))

    def _on_demo_action(self, event: viser.GuiEvent) -> None:
        i = self._selected()
        if i is None:
            raise _nothing()
        action = event.target.value
        if action == "Rename":
            self.app.rename_demo(i, self.demo_name.value)
        elif action == "Trim":
            t0, t1 = self.demo_trim.value
            self.app.trim_demo(i, float(t0), float(t1))
        elif action == "Delete":
            self.app.delete_demo_confirmed(i)  # asks first: a second press deletes


def _nothing() -> Exception:
    from studio.core.errors import InvalidInput

    return InvalidInput("Choose a demonstration in the list first.")


def _esc(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
