"""Task panel (Teach step): the task of the set-up in one sentence, its goal in words (to confirm or correct when
it was read from the demonstrations), what the gripper just did when it closed ("Holding the cup" / "Missed the
cup by 3 cm — move 1 cm to the robot's left"), Undo for a take thrown away or a deleted demonstration (each in a
fixed slot), and a stand drawn under every object held out in the air."""

from __future__ import annotations

import html
import threading
import zlib

import viser

from studio.controller import Controller, GraspNote, Layer, Placement, Topic, WorldEvent
from studio.words import GOAL_SOURCES, goal_words, grasp_words, task_words

#: Fixed slots (docs/decisions/092): the grasp feedback keeps room for three lines, the Undo note for one, so
#: that nothing below them moves when they change.
GRASP_SLOT = "min-height:5.2em"
UNDO_SLOT = "min-height:1.6em;padding:0 12px"
NO_GRASP = "When the gripper closes, what it caught is said here."
NOTHING_TO_UNDO = "Nothing to undo."
STAND_COLOR = (120, 120, 120)
STAND_RADIUS = 0.008
FLOOR_Z = -0.93
HELD_OUT_LABEL = "held out for the robot"
#: The goal chooser's first entry (nothing chosen).
KEEP_GOAL = "—"


class TaskPanel:
    """The task, the grasp feedback and the stands under held-out objects (redrawn at the pose pump)."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        self.scene = server.scene
        gui = server.gui
        self._lock = threading.Lock()
        self._last: WorldEvent | None = None
        self._drawn: object = None
        self._stands: dict[str, tuple[viser.SceneNodeHandle, viser.LabelHandle, tuple[float, float, float]]] = {}
        self.task = gui.add_html(self._task_html(), order=-0.5)
        self.goal = gui.add_html("", order=-0.47)
        self.goal_ok = gui.add_button(
            "Yes, that is the goal",
            icon=viser.Icon.CHECK,
            color="green",
            visible=False,
            order=-0.46,
            hint="The skill is judged by this goal, and where it cannot tell from your demonstrations which object "
            "to follow, it follows the one the goal names.",
        )
        self.goal_pick = gui.add_dropdown(
            "Or the goal is",
            options=(KEEP_GOAL,),
            visible=False,
            order=-0.45,
            hint="Choose what the task is really about if I read it wrongly; press Train again afterwards.",
        )
        self._goals: dict[str, tuple[Placement, ...]] = {}
        self.goal_ok.on_click(ctl.guarded("Could not keep the goal")(lambda _: ctl.scene.confirm_goal()))
        self.goal_pick.on_update(ctl.guarded("Could not change the goal")(self._on_goal_pick))
        self.grasp = gui.add_html(self._grasp_html(None), order=-0.4)
        self.undo_text = gui.add_html(self._undo_html(""), order=-0.3)
        self.undo = gui.add_button(
            "Undo",
            icon=viser.Icon.ARROW_BACK_UP,
            color="gray",
            disabled=True,
            order=-0.2,
            hint="Bring back the demonstration you just threw away or deleted.",
        )
        self.undo.on_click(ctl.guarded("Could not bring it back")(lambda _: ctl.undo.undo()))
        ctl.events.on(Topic.UNDO, self._on_undo)
        for topic in (Topic.SCENE, Topic.SESSION):
            ctl.events.on(topic, self._on_scene)
        ctl.events.on(Topic.DEMOS, self._show_goal)
        ctl.events.on(Topic.VIEW, self._apply_view)
        self._show_goal()

    # -- words --------------------------------------------------------------------------------------------
    def _task_html(self) -> str:
        words = task_words(self.ctl.scene.scene.preset)
        return (
            f'<div class="task-description" style="font-size:0.9em;border-left:4px solid #1d4ed8;padding:2px 8px;'
            f'margin:2px 0;overflow-wrap:anywhere"><b>Your task:</b> {html.escape(words)}</div>'
        )

    def _show_goal(self) -> None:
        """The task's goal in words; when it was read from the demonstrations, Yes and the other goals."""
        scene = self.ctl.scene
        goal = scene.goal()
        kinds = {o.name: o.kind for o in scene.scene.objects}
        words = goal_words(goal.placements, kinds)
        choices = {goal_words(g, kinds): g for g in scene.goal_choices()} if goal.placements else {}
        choices.pop(words, None)
        if not words:
            content = ""
        else:
            head = GOAL_SOURCES.get(goal.source, "The goal:")
            ask = " Is that right?" if goal.source == "demonstrations" else ""
            differs = ""
            if goal.differs:
                differs = (
                    f" None of your demonstrations did this ({goal_words(goal.differs, kinds)[:-1].lower()}): "
                    "show it again, or choose the goal they show."
                )
            content = (
                f'<div class="task-goal" data-source="{goal.source}" style="font-size:0.9em;border-left:4px solid '
                f'#1d4ed8;padding:2px 8px;margin:2px 0;overflow-wrap:anywhere"><b>{html.escape(head)}</b> '
                f"{html.escape(words)}{html.escape(ask)}{html.escape(differs)}</div>"
            )
        with self.server.atomic():
            self._goals = choices
            self.goal.content = content
            self.goal_ok.visible = goal.source == "demonstrations"
            self.goal_pick.options = (KEEP_GOAL, *choices)
            self.goal_pick.value = KEEP_GOAL
            self.goal_pick.visible = bool(choices)

    def _on_goal_pick(self, event: viser.GuiEvent) -> None:
        chosen = self._goals.get(self.goal_pick.value)
        if event.client is None or chosen is None:
            return
        self.ctl.scene.set_goal(chosen)

    @staticmethod
    def _grasp_html(note: GraspNote | None) -> str:
        """The grasp feedback in its fixed slot (a quiet line until the gripper first closes)."""
        color = "#d1d5db" if note is None else ("#15803d" if note.held else "#b45309")
        words = (
            f'<span style="color:#6b7280">{NO_GRASP}</span>'
            if note is None
            else f'<b style="color:{color}">{html.escape(grasp_words(note))}</b>'
        )
        held = "" if note is None else html.escape(note.held or "")
        return (
            f'<div class="grasp-feedback" data-held="{held}" style="font-size:0.9em;{GRASP_SLOT};'
            f'border-left:4px solid {color};padding:2px 8px;margin:2px 0;overflow-wrap:anywhere">{words}</div>'
        )

    @staticmethod
    def _undo_html(what: str) -> str:
        text = f"Thrown away: {html.escape(what)}." if what else f'<span style="color:#6b7280">{NOTHING_TO_UNDO}</span>'
        return f'<div class="undo-note" style="font-size:0.85em;{UNDO_SLOT};overflow-wrap:anywhere">{text}</div>'

    def _on_undo(self) -> None:
        what = self.ctl.undo.what
        with self.server.atomic():
            self.undo_text.content = self._undo_html(what)
            self.undo.disabled = not what

    def _on_scene(self) -> None:
        with self._lock:
            self._last = None
            self._drawn = None
        self.task.content = self._task_html()
        self.grasp.content = self._grasp_html(None)
        self._show_goal()

    # -- periodic (pose pump) -----------------------------------------------------------------------------
    def tick(self, now: float) -> None:
        grip = self.ctl.scene.last_grip()
        ev, note = grip if grip is not None else (None, None)
        with self._lock:
            new = ev is not self._last
            self._last = ev
        if new and note is None:  # the objects were put back (a new take, Put all back): nothing to tell
            self.grasp.content = self._grasp_html(None)
        elif new and note is not None:
            self.grasp.content = self._grasp_html(note)
            if not self.ctl.execution.running:
                self.ctl.notify("Gripper closed", grasp_words(note), kind="success" if note.held else "warning")
        self._draw_stands()
        if not self.undo.disabled and not self.ctl.undo.what:  # kept long enough: nothing to undo any more
            self._on_undo()

    def _draw_stands(self) -> None:
        """A grey stand from the table up to the bottom of each object held out in the air."""
        key, poses = self.ctl.scene.shown()
        with self._lock:
            if key == self._drawn:
                return
            self._drawn = key
            table = self.ctl.scene.scene.table
            floor = table.top_z if table is not None else FLOOR_Z
            wanted = {p.name: p.position for p in poses if p.on == "hand" and p.position[2] > floor + 0.01}
            shown = self.ctl.view.shown(Layer.OBJECTS)
            with self.server.atomic():
                for name in list(self._stands):
                    if name not in wanted or self._stands[name][2] != wanted[name]:
                        pole, label, _ = self._stands.pop(name)
                        pole.remove()
                        label.remove()
                for name, (x, y, z) in wanted.items():
                    if name in self._stands:
                        continue
                    i = f"{zlib.crc32(name.encode()):08x}"
                    h = z - floor
                    pole = self.scene.add_cylinder(
                        f"/stands/{i}",
                        radius=STAND_RADIUS,
                        height=h,
                        color=STAND_COLOR,
                        position=(x, y, floor + h / 2),
                        cast_shadow=False,
                        visible=shown,
                    )
                    label = self.scene.add_label(
                        f"/stands/{i}_label", HELD_OUT_LABEL, position=(x, y, floor + h * 0.4), visible=shown
                    )
                    self._stands[name] = (pole, label, (x, y, z))

    def stands(self) -> list[tuple[float, float, float]]:
        """Where the drawn stands hold an object up (the bottom centre of each object held out)."""
        with self._lock:
            return [at for _, _, at in self._stands.values()]

    def _apply_view(self) -> None:
        shown = self.ctl.view.shown(Layer.OBJECTS)
        with self._lock, self.server.atomic():
            for pole, label, _ in self._stands.values():
                pole.visible = shown
                label.visible = shown
