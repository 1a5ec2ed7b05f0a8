"""Demonstrations panel (in the Teach tab): the list of demos with their colours, their traces in the scene,
and the edits (show/hide, rename, trim, delete with Undo)."""

from __future__ import annotations

import html
import threading
import time
from typing import Literal

import numpy as np
import viser

from studio.controller import Controller, Layer, Topic
from studio.core.errors import InvalidInput
from studio.core.pace import TakeClock
from studio.panels._charts import downsample_path, segments
from studio.panels._choice import kept_choice

#: Small markers where a demonstration's gripper closed (dark diamonds) and opened (grey circles).
CLOSE_COLOR = (25, 25, 25)
OPEN_COLOR = (160, 160, 160)
Shape = Literal["diamond", "circle"]
#: Seconds a choice the studio made (the list moved on after a delete) or another tab made must stand before a
#: press of Rename, Trim or Delete acts on it without being pressed again.
CHOICE_SETTLE_S = 5.0


def pause_words(clock: TakeClock | None) -> str:
    """ " · 2 pauses removed (41 s)", " · its 2 pauses kept (45 s)" or "" (no pause)."""
    if clock is None or not clock.pauses:
        return ""
    n = len(clock.pauses)
    what = "1 pause" if n == 1 else f"{n} pauses"
    if clock.kept:
        return f" · its {what} kept ({sum(b - a for a, b in clock.pauses):.0f} s)"
    return f" · {what} removed ({clock.removed:.0f} s)"


class DemosPanel:
    """The demo list, a picker with the edit controls, and one coloured 3-D line per shown demo and arm."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        self.scene = server.scene
        gui = server.gui
        self._traces: dict[str, viser.SceneNodeHandle] = {}
        self._marks: dict[str, viser.SceneNodeHandle] = {}
        self._lock = threading.RLock()  # redrawing and the view's show/hide, one at a time
        self._listed: list[str] = []  # the names the picker offered before its last redraw
        # Who made the choice the picker shows (a tab's client id; None: the studio, after a delete), when (viser's
        # clock), the name it moved on from, and the tabs told of that choice since (their next press acts).
        self._chooser: int | None = None
        self._chosen_at = 0.0
        self._moved_from = ""
        self._told: set[int] = set()
        with gui.add_folder("Demonstrations", order=3):
            self.demo_list = gui.add_html(self._demo_list_html())
            self.demo_pick = gui.add_dropdown("Demo", options=["(none)"], initial_value="(none)")
            self.demo_show = gui.add_checkbox("Show in the scene", initial_value=True)
            self.demo_pauses = gui.add_checkbox(
                "Keep its pauses",
                initial_value=False,
                hint="Learn this demonstration with its pauses as they were (a wait that is part of the task). "
                "Unticked, each pause is shortened to a moment, so the robot does not wait where you stopped to think.",
            )
            self.demo_name = gui.add_text("Name", initial_value="")
            self.demo_trim = gui.add_multi_slider(
                "Keep from … to (s)", min=0.0, max=1.0, step=0.01, initial_value=(0.0, 1.0)
            )
            self.demo_actions = gui.add_button_group("Demo action", options=("Rename", "Trim", "Delete"))
        self.demo_pick.on_update(ctl.guarded()(self._on_pick))
        self.demo_show.on_update(ctl.guarded()(self._on_show))
        self.demo_pauses.on_update(ctl.guarded("Could not change the pauses")(self._on_pauses))
        self.demo_actions.on_click(ctl.guarded("Could not change the demonstration")(self._on_demo_action))
        ctl.events.on(Topic.DEMOS, self.refresh_demos)
        ctl.events.on(Topic.SESSION, self._on_session)
        ctl.events.on(Topic.VIEW, self._apply_view)
        self.refresh_demos()

    def _demo_list_html(self) -> str:
        rows = []
        for d in self.ctl.demos.summaries():
            sw = f"background:rgb{d.color};" if d.visible else f"border:2px solid rgb{d.color};"
            c = d.clock
            length = d.duration if c is None else c.duration
            recorded = f" of {d.duration:.1f} s recorded" if length < d.duration - 0.05 else ""
            rows.append(
                f'<div class="demo-row" data-demo="{d.index}" data-length="{length:.2f}" '
                f'data-pauses="{0 if c is None else len(c.pauses)}" data-kept="{int(c is not None and c.kept)}" '
                'style="display:flex;gap:6px;align-items:center;flex-wrap:wrap;font-size:0.85em;margin:2px 0">'
                f'<span style="display:inline-block;width:12px;height:12px;border-radius:6px;{sw}"></span>'
                f"<b>{html.escape(d.name)}</b><span>{length:.1f} s{recorded}{pause_words(c)} · {d.samples:,} samples · "
                f"{'/'.join(d.arms)}{'' if d.visible else ' · hidden'}</span></div>"
            )
            through = self.ctl.scene.demo_contact(d.index)  # recorded through something (imported, a real robot)
            if through:
                rows.append(
                    f'<div class="demo-contact" data-demo="{d.index}" style="font-size:0.8em;color:#b91c1c;'
                    f'margin:0 0 2px 18px">{html.escape(through)}</div>'
                )
        if not rows:
            return '<div class="demo-row-empty" style="font-size:0.85em">No demonstrations yet: press Record.</div>'
        legend = (
            '<div style="font-size:0.8em;color:#555;margin-top:2px">Each demonstration runs from your first move '
            "to your last; pauses (the arm still for a second or more) are shortened unless you keep them. In the "
            "scene: ◆ the gripper closed, ● it opened.</div>"
        )
        return "".join(rows) + legend

    def draw_traces(self) -> None:
        """Each shown demonstration as a coloured 3-D line of the taught gripper(s), with small markers where
        the gripper closed and opened."""
        demos = self.ctl.demos
        wanted: dict[str, tuple[np.ndarray, tuple[int, int, int]]] = {}
        marks: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for i, rec in enumerate(demos.recordings()):
            if rec.name in demos.hidden:
                continue
            for arm in rec.arms:
                pts = downsample_path(np.asarray(demos.demo_of(rec, arm).position))
                wanted[f"/demos/{i}_{arm}"] = (pts, demos.color(i))
                marks[f"/demo_grips/{i}_{arm}"] = demos.gripper_marks(rec, arm)
        traces_on, marks_on = self.ctl.view.shown(Layer.DEMOS), self.ctl.view.shown(Layer.GRIPPER_EVENTS)
        with self._lock, self.server.atomic():
            for key in list(self._traces):
                self._traces.pop(key).remove()
            for key in list(self._marks):
                self._marks.pop(key).remove()
            for key, (pts, color) in wanted.items():
                self._traces[key] = self.scene.add_line_segments(
                    key, segments(pts), colors=color, thickness=3.0, thickness_units="screen", visible=traces_on
                )
            for key, (closes, opens) in marks.items():
                kinds: tuple[tuple[str, np.ndarray, tuple[int, int, int], Shape], ...] = (
                    ("closed", closes, CLOSE_COLOR, "diamond"),
                    ("opened", opens, OPEN_COLOR, "circle"),
                )
                for what, pts, color, shape in kinds:
                    if len(pts):
                        self._marks[f"{key}/{what}"] = self.scene.add_point_cloud(
                            f"{key}/{what}",
                            points=pts.astype(np.float32),
                            colors=color,
                            point_size=0.02,
                            point_shape=shape,
                            visible=marks_on,
                        )

    def _apply_view(self) -> None:
        """Traces and gripper markers follow the "Demonstrations" and "Gripper closes/opens" layers."""
        traces_on, marks_on = self.ctl.view.shown(Layer.DEMOS), self.ctl.view.shown(Layer.GRIPPER_EVENTS)
        with self._lock, self.server.atomic():
            for node in self._traces.values():
                node.visible = traces_on
            for node in self._marks.values():
                node.visible = marks_on

    def _on_session(self) -> None:
        """Another session is open: its last demonstration is chosen (none of the old names carries over)."""
        self._listed = []
        self.refresh_demos()
        self._chosen_at = 0.0  # the new session's choice stands at once (nothing was deleted under a press)

    def refresh_demos(self) -> None:
        try:
            self.draw_traces()
        except Exception as exc:
            self.ctl.report(exc, title="Could not draw the demonstrations")
        names = self.ctl.demos.names()
        with self.server.atomic():
            self.demo_list.content = self._demo_list_html()
            opts = names or ["(none)"]
            current = self.demo_pick.value
            self.demo_pick.options = opts
            if current not in opts:  # a renamed demonstration stays chosen; after a delete, the last one is
                renamed = self.ctl.demos.renamed_to(current)
                self.demo_pick.value = renamed if renamed in opts else kept_choice(self._listed, current, opts, -1)
                if renamed not in opts and current in self._listed and current != "(none)":
                    # A listed one vanished and the studio chose: a press acts on it once it stood, or again.
                    self._chooser, self._chosen_at, self._moved_from = None, time.time(), current
                    self._told = set()
            self._listed = list(opts)
        self._on_pick(None)

    def _selected(self) -> int | None:
        names = self.ctl.demos.names()
        v = self.demo_pick.value
        return names.index(v) if v in names else None

    def _on_pick(self, event: viser.GuiEvent | None) -> None:
        if event is not None and event.client_id is not None:  # a tab chose (the studio's own moves: refresh)
            self._chooser, self._chosen_at, self._told = event.client_id, time.time(), set()
        i = self._selected()
        for h in (self.demo_show, self.demo_pauses, self.demo_name, self.demo_trim):
            h.disabled = i is None
        if i is None:
            return
        demos = self.ctl.demos
        dur = max(demos.duration(i), 0.02)
        self.demo_name.value = demos.names()[i]
        self.demo_show.value = demos.visible(i)
        self.demo_pauses.value = demos.keeps_pauses(i)
        self.demo_trim.max = round(dur + 0.005, 2)
        self.demo_trim.value = (0.0, round(dur + 0.005, 2))

    def _on_show(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        i = self._selected()
        if i is not None:
            self.ctl.demos.set_visible(i, bool(self.demo_show.value))

    def _on_pauses(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        i = self._selected()
        if i is not None and bool(self.demo_pauses.value) != self.ctl.demos.keeps_pauses(i):
            self.ctl.demos.set_keep_pauses(i, bool(self.demo_pauses.value))

    def _on_demo_action(self, event: viser.GuiEvent) -> None:
        i = self._selected()
        action, name = event.target.value, str(self.demo_pick.value)
        if i is None and name == "(none)":
            raise InvalidInput("Choose a demonstration in the list first.")
        demos = self.ctl.demos
        pressed = event.target.update_timestamp
        # i is None here when another tab deleted or renamed the chosen one and the list is not redrawn yet.
        if i is None or self.demo_pick.update_timestamp > pressed:
            # Another tab's action changed the chosen demonstration after this press was sent (two tabs pressing
            # Delete at once would otherwise delete two demonstrations): nothing is done to the one chosen now.
            what = f"{demos.gone(name)} in another tab" if i is None else "another tab deleted or chose one"
            raise InvalidInput(
                f"The chosen demonstration changed before your press arrived ({what}), so nothing was done. "
                "Check the choice and press again."
            )
        tab = event.client_id
        if self._chooser != tab and tab not in self._told and pressed - self._chosen_at < CHOICE_SETTLE_S:
            # The choice is the studio's (the list moved on after a delete) or another tab's, made a moment ago:
            # this press was meant for the one the tab showed before (decision 052).
            if tab is not None:
                self._told.add(tab)
            how = (
                f'the list moved on by itself after "{self._moved_from}" was deleted'
                if self._chooser is None
                else "another tab chose it"
            )
            raise InvalidInput(
                f"The chosen demonstration changed {max(pressed - self._chosen_at, 0.0):.1f} s before your press "
                f'({how}), so nothing was done. The list now shows "{name}": press {action} again to act on it.'
            )
        if action == "Rename":
            demos.rename(i, self.demo_name.value)
        elif action == "Trim":
            t0, t1 = self.demo_trim.value
            demos.trim(i, float(t0), float(t1))
        elif action == "Delete":
            demos.delete(i, name=name)  # at once; Undo (in Teach) brings it back for a while
