"""Preview panel: the generalized trajectory in cyan (the stretches the arm cannot follow in red), the drawn robot
playing its joint trajectory, the task result, and "Run on robot" with the judgement of the robot's run (its
status, Stop and Emergency stop are on every step: :mod:`studio.panels.run`)."""

from __future__ import annotations

import html

import numpy as np
import viser

from studio.controller import PREVIEW, Controller, Layer, Topic
from studio.core.feasibility import Feasibility
from studio.core.types import ARMS, Arm, Skill
from studio.panels._charts import APPROACH_COLOR, EXECUTED_COLOR, downsample_path, segments
from studio.words.robot import feasibility_words

CYAN = (0, 200, 230)
IK_FAIL = (230, 30, 30)
NOT_TRAINED = "Train first: the learned path appears here in cyan."
SPEEDS = {"¼×": 0.25, "½×": 0.5, "1×": 1.0, "2×": 2.0, "4×": 4.0}
SKILL_SPEEDS = {"½× (slower)": 0.5, "1× (as taught)": 1.0, "1½×": 1.5, "2×": 2.0, "3×": 3.0}
STALE_RUN = "this run was before you changed the objects or the demonstrations; press Run on robot to try again."
CANNOT_RUN = (
    "In the preview the skill does the task, but the robot cannot follow all of its path (in red), so it will not "
    "run it."
)
NEVER_SHOWN = (
    "In the preview the skill does the task here, but you never showed me the objects here (see above): show one "
    "more demonstration here to be sure."
)
MISSES_NOW = (
    "The preview shows the skill missing the task with the objects where they are now: the robot would do the "
    "same. Train again, or put the objects back where you taught."
)


class PreviewPanel:
    """Play / Pause / Stop, speed and a time scrubber over the learned joint trajectory, gripper included."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        self.scene = server.scene
        gui = server.gui
        self.info = gui.add_markdown(NOT_TRAINED)
        self.controls = gui.add_button_group("Playback", options=("Play", "Pause", "Stop"))
        self.speed = gui.add_dropdown(
            "Watch at",
            options=list(SPEEDS),
            initial_value="1×",
            hint="How fast the preview plays on the screen (the robot's own speed is Skill speed).",
        )
        self.skill_speed = gui.add_dropdown(
            "Skill speed",
            options=list(SKILL_SPEEDS),
            initial_value=_speed_label(ctl.placed.speed),
            hint="How fast the robot does the skill, in the preview and on the robot: faster than you taught only "
            "where its joints allow.",
        )
        self.time = gui.add_slider("Time (s)", min=0.0, max=1.0, step=0.01, initial_value=0.0)
        self.show_path = gui.add_checkbox("Show the learned path", initial_value=ctl.view.shown(Layer.LEARNED_PATH))
        self.reach = gui.add_html(self._reach_html())  # objects where no demonstration put them
        self.task = gui.add_html(self._task_html())  # the task result in words (see _task_html)
        self.run_btn = gui.add_button(
            "Run on robot",
            icon=viser.Icon.ROBOT,
            hint="Send the learned skill to the robot: it moves to the skill's start, then does the skill while the "
            "studio records what it really does and compares it with the plan.",
        )
        self.run_reason = gui.add_html("")
        self.run_result = gui.add_html("")
        self._nodes: dict[str, viser.SceneNodeHandle] = {}
        self._last_time_sync = 0.0

        self.controls.on_click(ctl.guarded("Could not play the preview")(self._on_controls))
        self.speed.on_update(ctl.guarded("Could not change the speed")(self._on_speed))
        self.time.on_update(ctl.guarded("Could not move to that time")(self._on_time))
        self.skill_speed.on_update(ctl.guarded("Could not change the skill's speed")(self._on_skill_speed))
        self.show_path.on_update(ctl.guarded()(self._on_show))
        self.run_btn.on_click(ctl.guarded("Could not run the skill on the robot")(self._on_run))
        for topic in (Topic.SKILL, Topic.SESSION, Topic.SCENE):  # the objects moved: the path drawn follows
            ctl.events.on(topic, self.refresh)
        ctl.events.on(Topic.TASK, self._on_task)
        ctl.events.on(Topic.VIEW, self._apply_view)
        for topic in (Topic.EXECUTION, Topic.RECORDING, Topic.TRAINING):
            ctl.events.on(topic, self._on_run_state)
        self.refresh()

    def refresh(self) -> None:
        skills = self.ctl.training.skills()
        played = self.ctl.placed.get() if skills else {}  # what Play plays: placed where the objects are now
        with self.server.atomic():
            for n in self._nodes.values():
                n.remove()
            self._nodes.clear()
            feasibility = self.ctl.execution.feasibility()
            unreachable = self.ctl.execution.unreachable_paths()
            for arm in ARMS:
                skill = played.get(arm)
                if skill is None:
                    continue
                pts = downsample_path(self._executed(arm, skill))
                self._nodes[f"path_{arm}"] = self.scene.add_line_segments(
                    f"/preview/{arm}/path",
                    segments(pts),
                    colors=CYAN,
                    thickness=6.0,
                    thickness_units="screen",
                    visible=self.ctl.view.shown(Layer.LEARNED_PATH),
                )
                # the feasibility check's stretches the arm cannot follow, red over the cyan
                self._red(f"fail_{arm}", f"/preview/{arm}/unreachable", unreachable.get(arm, []))
            self._draw_contacts()
            duration = self.ctl.playback.preview_duration()
            self.time.max = round(max(duration, 0.01), 2)
            self.time.value = 0.0
            for h in (self.speed, self.time, self.skill_speed):
                h.disabled = not skills
            self.skill_speed.value = _speed_label(self.ctl.placed.speed)
            self.info.content = _info(duration, feasibility, self.ctl.scene.contact_reason()) if skills else NOT_TRAINED
        self._on_run_state()

    def _executed(self, arm: Arm, skill: Skill) -> np.ndarray:
        """(n, 3) where the gripper goes when the joints Play plays are followed (forward kinematics), else the
        learned path."""
        jt = skill.joint_trajectory
        if jt is None or len(jt.q) == 0:
            return np.asarray(skill.trajectory.position)
        return self.ctl.baxter.fk_batch(arm, np.asarray(jt.q))[0]

    def _draw_contacts(self) -> None:
        """Where the skill touches what it must not (the table, an object, the other arm): red over the path."""
        for arm in ARMS:
            old = self._nodes.pop(f"contact_{arm}", None)
            if old is not None:
                old.remove()
        if not self.ctl.training.skills():
            return
        for arm, stretches in self.ctl.scene.contact_paths().items():
            self._red(f"contact_{arm}", f"/preview/{arm}/contact", stretches)

    def _red(self, key: str, node: str, stretches: list[np.ndarray]) -> None:
        """Stretches (each (n, 3) m) of the learned path drawn red over the cyan, as scene node ``node``."""
        spans = [segments(downsample_path(p, 200)) for p in stretches if len(p) > 1]
        if spans:
            self._nodes[key] = self.scene.add_line_segments(
                node,
                np.concatenate(spans),
                colors=IK_FAIL,
                thickness=10.0,
                thickness_units="screen",
                visible=self.ctl.view.shown(Layer.LEARNED_PATH),
            )

    # -- Run on robot ------------------------------------------------------------------------------------------
    def _on_run(self, event: viser.GuiEvent) -> None:
        self.ctl.execution.run()

    def _on_run_state(self) -> None:
        """Whether "Run on robot" can start (and why not), and the last run's judgement, on every tab."""
        execution = self.ctl.execution
        reason = execution.why_not()
        running = execution.running
        if any(not f.ok for f in execution.feasibility().values()):  # its words are above, with the red path
            reason = "The robot does not run a skill it cannot follow: see what is red on the learned path."
        elif self.ctl.scene.contact_reason():
            reason = "The robot does not run a skill that would hit something: see what is red on the learned path."
        quiet = running or reason.startswith("The emergency stop")  # the run's status says so, on every step
        disabled = bool(reason)
        task = self.ctl.scene.task_result()
        if not reason and task is not None and task.objects and not task.ok:
            reason = MISSES_NOW  # a warning: the teacher may still run it
        with self.server.atomic():
            self.run_btn.disabled = disabled
            self.run_reason.content = (
                ""
                if not reason or quiet
                else f'<div class="run-reason" style="font-size:0.85em;color:#92400e">{html.escape(reason)}</div>'
            )
            self.run_result.content = self._run_html()
            self.time.disabled = running or not self.ctl.training.skills()  # the scene shows the real robot then

    def _run_html(self) -> str:
        st = self.ctl.execution.status
        if not st.result and st.phase == "idle":
            return ""
        color = "#15803d" if st.ok else ("#1d4ed8" if st.ok is None else "#b91c1c")
        head = {True: "On the robot: the skill does the task.", False: "On the robot:", None: "On the robot:"}[st.ok]
        body = st.result or "the robot is running the skill; the result follows when it ends."
        if st.stale:  # of before the change: never a green "does the task" under what the preview says now
            color, head = "#6b7280", "Out of date:"
            body = f"{STALE_RUN} Then, on the robot: {body}"
        legend = (
            f'<div class="run-legend" style="color:#555;margin-top:2px">{_swatch(CYAN)} the plan (learned path) '
            f"{_swatch(EXECUTED_COLOR)} where the robot's gripper went {_swatch(APPROACH_COLOR)} the way to the "
            "skill's start</div>"
        )
        return (
            f'<div class="run-result" data-ok="{str(st.ok).lower()}" data-phase="{st.phase}" data-stale='
            f'"{str(st.stale).lower()}" style="font-size:0.9em;'
            f'border-left:4px solid {color};padding:2px 8px;margin:4px 0"><b style="color:{color}">{head}</b> '
            f"{html.escape(body)}{legend}</div>"
        )

    def _on_controls(self, event: viser.GuiEvent) -> None:
        playback = self.ctl.playback
        if event.target.value == "Play":
            playback.play_preview(SPEEDS[self.speed.value])
        elif event.target.value == "Pause":
            playback.pause(PREVIEW)
        else:  # Stop: back to the live robot
            playback.stop(PREVIEW)
            self.time.value = 0.0

    def _on_speed(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.ctl.playback.set_speed(PREVIEW, SPEEDS[self.speed.value])

    def _on_skill_speed(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.ctl.placed.set_speed(SKILL_SPEEDS[self.skill_speed.value])

    def _on_time(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.ctl.playback.seek_preview(float(self.time.value))

    def _on_show(self, event: viser.GuiEvent) -> None:
        if event.client is not None:
            self.ctl.view.set_shown(Layer.LEARNED_PATH, bool(self.show_path.value))

    def _apply_view(self) -> None:
        """The learned path (and its unreachable points) follow the "Learned path" layer of the step."""
        shown = self.ctl.view.shown(Layer.LEARNED_PATH)
        with self.server.atomic():
            for n in list(self._nodes.values()):
                n.visible = shown
            self.show_path.value = shown

    # -- the task result (what the learned skill does with the objects), self-contained --------------------
    def _on_task(self) -> None:
        with self.server.atomic():
            self.reach.content = self._reach_html()
            self.task.content = self._task_html()
            self._draw_contacts()
            if self.ctl.training.skills():
                duration = self.ctl.playback.preview_duration()
                self.info.content = _info(duration, self.ctl.execution.feasibility(), self.ctl.scene.contact_reason())
        self._on_run_state()

    def _reach_html(self) -> str:
        said, note = self.ctl.placed.warnings(), self.ctl.placed.note()
        if not said and not note:
            return ""
        head = "The objects are somewhere new." if said else "Good to know."
        items = "".join(f"<li>{html.escape(s)}</li>" for s in (said or [note]))
        return (
            f'<div class="reach-warning" data-outside="{str(bool(said)).lower()}" style="font-size:0.9em;'
            f'border-left:4px solid #b45309;padding:2px 8px;margin:4px 0"><b style="color:#b45309">{head}</b>'
            f'<ul style="margin:2px 0 2px 16px;padding:0">{items}</ul></div>'
        )

    def _task_html(self) -> str:
        """The task result under one claim that agrees with the words around it: "does the task" only where the
        objects stand where the demonstrations had them and the robot can follow the whole path."""
        result = self.ctl.scene.task_result()
        if result is None:
            return ""
        claim, head = "misses", "The skill misses the task."
        if not result.objects:
            claim, head = "nothing", "Task result."
        elif result.ok and any(not f.ok for f in self.ctl.execution.feasibility().values()):
            claim, head = "cannot-run", CANNOT_RUN
        elif result.ok and self.ctl.placed.warnings():
            claim, head = "guess", NEVER_SHOWN
        elif result.ok:
            claim, head = "works", "The skill does the task."
        color = {"works": "#15803d", "misses": "#b91c1c"}.get(claim, "#92400e")
        return (
            f'<div class="task-result" data-ok="{str(result.ok).lower()}" data-claim="{claim}" style="font-size:0.9em;'
            f'border-left:4px solid {color};padding:2px 8px;margin:4px 0"><b style="color:{color}">{head}</b> '
            f"{html.escape(result.text)}</div>"
        )

    def tick(self, now: float) -> None:
        pos = self.ctl.playback.position(PREVIEW)
        if pos is not None and now - self._last_time_sync > 0.1:
            self._last_time_sync = now
            self.time.value = round(min(pos, self.time.max), 2)


def _info(duration: float, feasibility: dict[Arm, Feasibility], contacts: str = "") -> str:
    bad = [feasibility_words(f) for f in feasibility.values() if not f.ok] + ([contacts] if contacts else [])
    if bad:
        return f"Learned path ({duration:.1f} s) in cyan. In red: {' '.join(bad)} Press **Play** to watch it."
    return (
        f"Learned path ({duration:.1f} s) in cyan. The arm can follow all of it. "
        "Press **Play** to watch it, or **Run on robot**."
    )


def _speed_label(speed: float) -> str:
    return next((k for k, v in SKILL_SPEEDS.items() if v == speed), "1× (as taught)")


def _swatch(rgb: tuple[int, int, int]) -> str:
    return f'<span style="color:rgb{rgb};font-weight:900">━━</span>'
