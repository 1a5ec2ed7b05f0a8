"""The robot's run, on every step: the robot's status light (enabled / connected / e-stopped / disconnected) with
Enable robot and Calibrate grippers, what the robot is doing with the learned skill (status and progress), Stop,
the red Emergency stop (always there, on a path of its own: never behind other buttons' work) and its release;
a simulated robot's faults to try; in the scene, where the gripper went (magenta) and the way to the start (grey).

"Run on robot" itself is in the Preview step (:mod:`studio.panels.preview`), with the run's judgement.
"""

from __future__ import annotations

import asyncio
import html
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Literal

import numpy as np
import viser

from studio.controller import Controller, Layer, RunStatus, Topic
from studio.controller.run import RobotHealth
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


_LIGHT = {
    "enabled": ("#16a34a", "Robot connected and enabled"),
    "connected": ("#d97706", "Robot connected, not enabled"),
    "e-stopped": ("#dc2626", "Robot emergency-stopped"),
    "disconnected": ("#6b7280", "Robot disconnected"),
}


def light_html(h: RobotHealth) -> str:
    """The status light: a coloured dot, what it means, and what is wrong (in words)."""
    color, words = _LIGHT[h.light]
    why = f"<br>{html.escape(h.message)}" if h.message else ""
    return (
        f'<div class="robot-light" data-light="{h.light}" style="font-size:0.9em">'
        f'<span style="color:{color};font-size:1.2em">●</span> {words}{why}</div>'
    )


class RunPanel:
    """Status, progress, Stop, Emergency stop and Release of the robot's run; its paths in the scene."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        self.scene = server.scene
        gui = server.gui
        self._health = ctl.execution.robot.health()
        self._estop_path = ThreadPoolExecutor(max_workers=1, thread_name_prefix="studio-estop")
        with gui.add_folder("Robot's run", order=0.5):
            self.light = gui.add_html(light_html(self._health))
            self.enable_btn = gui.add_button(
                "Enable robot",
                icon=viser.Icon.POWER,
                color="green",
                visible=False,
                hint="Reset the robot if it was stopped, then enable its motors.",
            )
            self.calibrate_btn = gui.add_button(
                "Calibrate grippers",
                icon=viser.Icon.ARROWS_HORIZONTAL,
                visible=False,
                hint="Each gripper that needs it opens and closes once to find its range. Keep hands clear.",
            )
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
        self._last_light = 0.0
        self._shown = ""
        execution = ctl.execution
        self.stop_btn.on_click(self._stop)
        self.estop_btn.on_click(self._emergency_stop)
        self.enable_btn.on_click(ctl.guarded("Could not enable the robot")(lambda _: execution.robot.enable()))
        self.calibrate_btn.on_click(
            ctl.guarded("Could not calibrate the grippers")(lambda _: execution.robot.calibrate_grippers())
        )
        self._faults_folder()
        self.release_btn.on_click(
            ctl.guarded("Could not release the emergency stop")(lambda _: execution.release_emergency_stop())
        )
        ctl.events.on(Topic.EXECUTION, self.refresh)
        ctl.events.on(Topic.VIEW, self._apply_view)
        self.refresh()

    async def _emergency_stop(self, event: viser.GuiEvent) -> None:
        """Its own path: viser awaits this on its event loop (not its shared pool, where 300 other presses may
        wait), and the stop runs on a thread of its own."""
        await self._urgent(self.ctl.execution.emergency_stop, event)

    async def _stop(self, event: viser.GuiEvent) -> None:
        """Stop takes the same path as the Emergency stop."""
        await self._urgent(self.ctl.execution.stop, event)

    async def _urgent(self, action: Callable[[], None], event: viser.GuiEvent) -> None:
        try:
            await asyncio.get_running_loop().run_in_executor(self._estop_path, action)
            self.server.flush()  # the status goes to every tab now, not at the next window
        except Exception as exc:
            self.ctl.ctx.report(exc, title="Could not stop the robot", client=event.client)

    def _faults_folder(self) -> None:
        faults = self.ctl.execution.robot.faults
        if not faults:
            return
        cause = self.ctl.execution.robot.cause
        with self.server.gui.add_folder("Simulated robot (try its faults)", expand_by_default=False):
            for name in faults:
                btn = self.server.gui.add_button(
                    name, color="gray", hint="What a real Baxter can do; see how the studio answers."
                )
                btn.on_click(self.ctl.guarded(f'Could not "{name}"')(lambda _, n=name: cause(n)))

    def _show_health(self, h: RobotHealth) -> None:
        self._health = h
        self.light.content = light_html(h)
        st = self.ctl.execution.status
        self.enable_btn.visible = h.light in ("connected", "e-stopped") and not st.estop
        grippers = self.ctl.execution.robot.grippers() if h.connected else {}
        self.calibrate_btn.visible = any("calibrat" in w for w in grippers.values())

    def refresh(self) -> None:
        """The run started, changed phase or was judged, or the emergency stop changed (any tab)."""
        st = self.ctl.execution.status
        with self.server.atomic():
            self._show_health(self.ctl.execution.robot.health())
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
        """The status light when it changes (5 times a second); while the robot runs, the time and progress and
        the executed path growing (a few times a second)."""
        if now - self._last_light >= 0.2:
            self._last_light = now
            h = self.ctl.execution.robot.poll()
            if h != self._health:
                with self.server.atomic():
                    self._show_health(h)
        if now - self._last_tick < 0.25 or not self.ctl.execution.running:
            return
        self._last_tick = now
        st = self.ctl.execution.status
        with self.server.atomic():
            self._show_status(st)
        self._draw()
