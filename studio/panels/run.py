"""The robot's run, on every step: what the robot is doing with the learned skill (status and progress), Stop, the
red Emergency stop (always there: it halts the robot whatever it does, a run or a move by hand) and its release;
and in the scene, where the gripper really went (magenta) and the planned way to the skill's start (grey).

"Run on robot" itself is in the Preview step (:mod:`studio.panels.preview`), with the run's judgement.
"""

from __future__ import annotations

import html
from typing import Literal

import numpy as np
import viser

from studio.controller import Controller, Layer, RunStatus, Topic
from studio.panels._charts import APPROACH_COLOR, EXECUTED_COLOR, dashes, downsample_path, segments

_PHASE_COLOR = {
    "running": "#1d4ed8",
    "stopping": "#b45309",
    "done": "#15803d",
    "stopped": "#555",
    "emergency-stopped": "#b91c1c",
    "failed": "#b91c1c",
}
_BAR_COLOR: dict[str, Literal["blue", "yellow", "green", "gray", "red"]] = {
    "running": "blue",
    "stopping": "yellow",
    "done": "green",
    "stopped": "gray",
    "emergency-stopped": "red",
    "failed": "red",
}


class RunPanel:
    """Status, progress, Stop, Emergency stop and Release of the robot's run; its paths in the scene."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        self.scene = server.scene
        gui = server.gui
        with gui.add_folder("Robot's run", order=0.5):
            self.status = gui.add_html(self._status_html(ctl.execution.status))
            self.progress = gui.add_progress_bar(0.0, visible=False)
            self.stop_btn = gui.add_button(
                "Stop",
                icon=viser.Icon.PLAYER_STOP,
                color="dark",
                visible=False,
                hint="Slow the robot down along the skill's path until it stands still.",
            )
            self.estop_btn = gui.add_button(
                "Emergency stop",
                icon=viser.Icon.HAND_STOP,
                color="red",
                hint="Halt the robot at once, whatever it is doing. It does not move again until you release "
                "the emergency stop.",
            )
            self.release_btn = gui.add_button(
                "Release emergency stop",
                icon=viser.Icon.LOCK_OPEN,
                color="yellow",
                visible=False,
                hint="Allow the robot to move again (it stays where it halted). Only when it is safe.",
            )
        self._nodes: dict[str, viser.SceneNodeHandle] = {}
        self._drawn_key: object = None
        self._last_tick = 0.0
        self._shown = ""
        execution = ctl.execution
        self.stop_btn.on_click(ctl.guarded("Could not stop the robot")(lambda _: execution.stop()))
        self.estop_btn.on_click(ctl.guarded("Could not stop the robot")(lambda _: execution.emergency_stop()))
        self.release_btn.on_click(
            ctl.guarded("Could not release the emergency stop")(lambda _: execution.release_emergency_stop())
        )
        ctl.events.on(Topic.EXECUTION, self.refresh)
        ctl.events.on(Topic.VIEW, self._apply_view)
        self.refresh()

    def refresh(self) -> None:
        """The run started, changed phase or was judged, or the emergency stop changed (any tab)."""
        st = self.ctl.execution.status
        with self.server.atomic():
            self._show_status(st)
            self.stop_btn.visible = st.active
            self.estop_btn.visible = not st.estop
            self.release_btn.visible = st.estop
            self.progress.visible = st.phase != "idle"
            self.progress.color = _BAR_COLOR.get(st.phase)
            self.progress.animated = st.active
        self._draw()

    def _show_status(self, st: RunStatus) -> None:
        text = self._status_html(st)
        if text != self._shown:
            self._shown = text
            self.status.content = text
            self.progress.value = round(st.fraction * 100.0, 1)

    @staticmethod
    def _status_html(st: RunStatus) -> str:
        color = "#b91c1c" if st.estop else _PHASE_COLOR.get(st.phase, "#333")
        when = f" {st.t:.1f} s of {st.duration:.1f} s." if st.active else ""
        return (
            f'<div class="run-status" data-phase="{st.phase}" data-estop="{str(st.estop).lower()}" '
            f'data-t="{st.t:.2f}" data-duration="{st.duration:.2f}" '
            f'style="font-size:0.9em;border-left:4px solid {color};padding:2px 8px">'
            f"{html.escape(st.message)}{when}</div>"
        )

    # -- the run's paths in the scene ------------------------------------------------------------------------
    def _draw(self) -> None:
        paths = self.ctl.execution.paths()
        if paths.key == self._drawn_key:
            return
        self._drawn_key = paths.key
        shown = self.ctl.view.shown(Layer.EXECUTION)
        wanted: dict[str, tuple[np.ndarray, tuple[int, int, int], float]] = {}
        for arm, p in paths.executed.items():
            if len(p) > 1:
                wanted[f"/run/{arm}/executed"] = (segments(downsample_path(p, 3000)), EXECUTED_COLOR, 3.0)
        for arm, p in paths.approach.items():
            if len(p) > 1:
                wanted[f"/run/{arm}/approach"] = (dashes(p, 40), APPROACH_COLOR, 3.0)
        with self.server.atomic():
            for name in [n for n in self._nodes if n not in wanted]:
                self._nodes.pop(name).remove()
            for name, (segs, color, width) in wanted.items():
                self._nodes[name] = self.scene.add_line_segments(
                    name, segs, colors=color, thickness=width, thickness_units="screen", visible=shown
                )

    def _apply_view(self) -> None:
        shown = self.ctl.view.shown(Layer.EXECUTION)
        with self.server.atomic():
            for n in self._nodes.values():
                n.visible = shown

    def tick(self, now: float) -> None:
        """While the robot runs: the time and progress, and the executed path growing (a few times a second)."""
        if now - self._last_tick < 0.25 or not self.ctl.execution.running:
            return
        self._last_tick = now
        st = self.ctl.execution.status
        with self.server.atomic():
            self._show_status(st)
        self._draw()
