"""Train panel: learn the skill from the demonstrations, say in plain words how good it is (the verdict, how
well each demonstration fits), and show what it learned (paper § Task Learning)."""

from __future__ import annotations

import html

import numpy as np
import viser

from studio.controller import Controller, SkillVerdict, Step, Topic, UsedDemo
from studio.core.errors import StudioError
from studio.core.types import DEFAULT_FRAMES, DEFAULT_GENERALIZATION, Arm, Generalization, Skill
from studio.panels._charts import heatmap_svg, position_plot_svg
from studio.words import frame_lines, route_label, segment_lines
from studio.words.quality import STUDIO_REMEDIES, fit_note, verdict_lines

#: How each choice of frames is called (the Places chooser).
FRAME_WORDS = {
    "objects": "Follow the objects (each part learned relative to the object it acts on)",
    "robot": "Fixed places (the paper: one path in the robot's frame)",
}
#: How each generalisation mode is called (the Path chooser).
MODE_WORDS: dict[Generalization, str] = {
    Generalization.ALIGNED_MEAN: "Follow the demonstrations (average of your demonstrations, aligned in time)",
    Generalization.PAPER: "Paper's spline (a smooth curve through the learned states, as in the paper)",
}
_LEVEL_COLOR = {"good": "#15803d", "fair": "#b45309", "poor": "#b91c1c"}
#: The fold with the model's own terms, each with a plain sentence.
ADVANCED = "Advanced: how the model sees it"
STATES_WORDS = "the key-points of all demonstrations, grouped into places the hand passes (large red markers)."
REFERENCE_WORDS = "The model explains it best; the others are lined up in time with it before they are averaged."
TRANSITIONS_WORDS = (
    "How likely the hand goes from each state (row) to the next (column): the model's transition matrix. A "
    "dark diagonal band means the demonstrations agree on the order of the places."
)
#: The one line that explains the per-demo list.
FIT_EXPLANATION = (
    "How closely the learned path follows each demonstration. One that fits poorly pulls the skill away from "
    "the others: re-record it or hide it."
)


class TrainPanel:
    """Train button with progress; the verdict; how the skill is made (the generalisation mode); per arm the
    states, reference, zero-points and how well each demonstration fits; transition heat map; plots."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        gui = server.gui
        self.train_btn = gui.add_button(
            "Train",
            icon=viser.Icon.BRAIN,
            hint="Learn the skill from the shown demonstrations with the current key-point settings.",
        )
        self.progress = gui.add_progress_bar(0.0, animated=True, visible=False)
        self.status = gui.add_markdown(self._status_text())
        self.verdict = gui.add_html("")
        self.way = gui.add_dropdown(
            "Way",
            options=("—",),
            visible=False,
            hint="Your demonstrations go more than one way: the skill learns one of them, never a path between "
            "them. Choose which; it is learned again at once.",
        )
        self._ways: dict[str, tuple[Arm, int]] = {}
        with gui.add_folder("How the skill is made", expand_by_default=False):
            self.mode = gui.add_dropdown(
                "Path",
                options=tuple(MODE_WORDS.values()),
                initial_value=MODE_WORDS[ctl.training.generalization],
                hint="How the learned path is made from your demonstrations. 'Follow the demonstrations' (the "
                "default) keeps their shape between key-points; 'Paper's spline' is the paper's method, for the "
                "curious. Press Train again after changing it.",
            )
            self.frames = gui.add_dropdown(
                "Places",
                options=tuple(FRAME_WORDS.values()),
                initial_value=FRAME_WORDS[ctl.training.frames],
                hint="'Follow the objects' (the default) learns each part of the task relative to the object it acts "
                "on, so the skill still works when you move the objects; 'Fixed places' is the paper's method: the "
                "robot goes where your demonstrations went. Press Train again after changing it.",
            )
        with gui.add_folder("What the robot learned"):
            self.summary = gui.add_html("")
            self.heatmap = gui.add_html("")
        with gui.add_folder("Position over time", expand_by_default=True):
            self.plots = gui.add_html("")
        self.train_btn.on_click(ctl.guarded("Could not start training")(self._on_train))
        self.mode.on_update(ctl.guarded("Could not change how the skill is made")(self._on_mode))
        self.frames.on_update(ctl.guarded("Could not change how the skill is made")(self._on_frames))
        self.way.on_update(ctl.guarded("Could not learn the other way")(self._on_way))
        ctl.events.on(Topic.SKILL, self.refresh)
        ctl.events.on(Topic.SESSION, self.refresh)
        ctl.events.on(Topic.DEMOS, self.refresh)  # renamed / deleted / trimmed demos: labels, plots and status
        ctl.events.on(Topic.TRAINING, self._on_training)
        ctl.events.on(Topic.VERDICT, self.refresh)
        self.refresh()

    def _status_text(self) -> str:
        training, session = self.ctl.training, self.ctl.session
        if training.busy:
            return "Training… this takes a few seconds."
        if session.skills and session.skills_stale:
            return (
                "The learned skill is **out of date**: demonstrations changed since it was learned. "
                "Press **Train** to learn it again."
            )
        if session.skills:
            again = "Press **Train** again after changing demonstrations or key-point settings."
            return f"Trained.{self._length_words()} {again}"
        return "Not trained yet. Record at least two demonstrations, then press **Train**."

    def _played(self) -> dict[Arm, Skill]:
        """The skills as Preview and Run on robot play them ({} when they cannot be placed where the objects are)."""
        try:
            return self.ctl.placed.get()
        except StudioError:
            return {}

    def _length_words(self) -> str:
        """How long the skill lasts as Preview plays it (:meth:`PlacedSkills.duration`) against the median
        demonstration as taught, in words ("" when it cannot be placed where the objects are)."""
        if not self._played():
            return ""
        length = self.ctl.placed.duration()
        taught = [d.clock.duration for d in self.ctl.demos.summaries() if d.visible and d.clock is not None]
        of = f" (your demonstrations: {float(np.median(taught)):.1f} s, the median as taught)" if taught else ""
        return f" The skill lasts **{length:.1f} s**{of}."

    def _on_train(self, event: viser.GuiEvent) -> None:
        self.ctl.training.train()  # the work thread learns; TRAINING and SKILL events redraw
        if self.ctl.view.step != Step.TRAIN:  # the scene shows the Train step (the learned path)
            self.ctl.view.set_step(Step.TRAIN)

    def _on_mode(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        mode = next((m for m, words in MODE_WORDS.items() if words == self.mode.value), DEFAULT_GENERALIZATION)
        self.ctl.training.set_generalization(mode)

    def _on_frames(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        frames = next((f for f, words in FRAME_WORDS.items() if words == self.frames.value), DEFAULT_FRAMES)
        self.ctl.training.set_frames(frames)

    def _on_way(self, event: viser.GuiEvent) -> None:
        choice = self._ways.get(self.way.value)
        if event.client is None or choice is None or self.ctl.training.busy:
            return
        arm, route = choice
        sk = self.ctl.training.skills().get(arm)
        if sk is not None and sk.route != route:
            self.ctl.training.set_route(arm, route)

    def _refresh_way(self, skills: dict[Arm, Skill]) -> None:
        """The Way chooser: one entry per way of each arm whose demonstrations go several ways."""
        ways: dict[str, tuple[Arm, int]] = {}
        current = ""
        several = sum(1 for sk in skills.values() if sk.routes) > 1
        for arm, sk in skills.items():
            for i in range(len(sk.routes)):
                label = (f"{arm.capitalize()} arm, " if several else "") + route_label(sk.routes, i)
                ways[label] = (arm, i)
                if i == sk.route and not current:
                    current = label
        self._ways = ways
        if ways:
            self.way.options = tuple(ways)
            self.way.value = current
        self.way.visible = bool(ways)

    def _on_training(self) -> None:
        busy = self.ctl.training.busy
        with self.server.atomic():
            self.train_btn.disabled = busy
            self.progress.visible = busy
            self.progress.value = 100.0 if busy else 0.0
            self.status.content = self._status_text()
            self.mode.value = MODE_WORDS[self.ctl.training.generalization]
            self.frames.value = FRAME_WORDS[self.ctl.training.frames]

    def refresh(self) -> None:
        """Redraw the verdict and the results of the current skill(s)."""
        summary, heat, plots = [], [], []
        verdicts = self.ctl.training.verdicts()
        for arm, skill in self.ctl.training.skills().items():
            used = self.ctl.training.skill_demos(arm)  # row j: the j-th demo the skill learned from
            summary.append(self._summary_html(arm, skill, used, verdicts.get(arm)))
            heat.append(
                f'<details class="advanced"><summary style="cursor:pointer;color:#555;font-size:0.85em">{ADVANCED}: '
                f'{arm} arm\'s state transitions</summary><div style="font-size:0.85em;color:#555">'
                f"{TRANSITIONS_WORDS}</div>"
                + heatmap_svg(np.asarray(skill.transmat), title=f"{arm.capitalize()} arm: state transitions")
                + "</details>"
            )
            plots += self._plots(arm, skill, used)
        with self.server.atomic():
            self.verdict.content = self._verdict_html(verdicts)
            self.summary.content = "".join(summary) or "<div style='font-size:0.85em'>No skill learned yet.</div>"
            self.heatmap.content = "".join(heat)
            self.plots.content = "".join(plots)
            self.status.content = self._status_text()
            self.mode.value = MODE_WORDS[self.ctl.training.generalization]
            self._refresh_way(self.ctl.training.skills())

    # -- the verdict ---------------------------------------------------------------------------------------
    def _verdict_html(self, verdicts: dict[Arm, SkillVerdict]) -> str:
        skills = self.ctl.training.skills()
        if not skills:
            return ""
        if self.ctl.training.judging and set(verdicts) != set(skills):
            return '<div class="verdict" data-level="" style="font-size:0.9em">Checking how good the skill is…</div>'
        blocks = []
        for arm, v in verdicts.items():
            who = f"<b>{arm.capitalize()} arm.</b> " if len(skills) > 1 else ""
            if v.verdict is None:
                blocks.append(
                    f'<div class="verdict" data-arm="{arm}" data-level="" style="font-size:0.9em">{who}'
                    f"{html.escape(v.message)}</div>"
                )
                continue
            head, *notes = verdict_lines(v.verdict, STUDIO_REMEDIES)
            color = _LEVEL_COLOR.get(v.verdict.level, "#333")
            bullets = "".join(f"<li>{html.escape(n)}</li>" for n in notes)
            bullets += "".join(f'<li class="verdict-segment">{html.escape(n)}</li>' for n in segment_lines(v.segments))
            bullets += "".join(f'<li class="verdict-frames">{html.escape(n)}</li>' for n in frame_lines(v.choices))
            blocks.append(
                f'<div class="verdict" data-arm="{arm}" data-level="{v.verdict.level}" '
                f'style="font-size:0.9em;border-left:4px solid {color};padding:4px 8px;margin:4px 0">'
                f'{who}<span class="verdict-head" style="color:{color};font-weight:600">{html.escape(head)}</span>'
                + (f'<ul style="margin:4px 0 0 0;padding-left:18px">{bullets}</ul>' if bullets else "")
                + "</div>"
            )
        return "".join(blocks)

    # -- what it learned -----------------------------------------------------------------------------------
    def _summary_html(self, arm: Arm, skill: Skill, used: list[UsedDemo], verdict: SkillVerdict | None) -> str:
        names = [u.name if u.index is not None else f"{u.name} (renamed or deleted since)" for u in used]
        ref = int(skill.reference)
        zero = [int(z) for z in np.atleast_1d(skill.zero_points)]
        zero_words = (
            ("state " if len(zero) == 1 else "states ")
            + ", ".join(str(z) for z in zero[:30])
            + (" …" if len(zero) > 30 else "")
            if zero
            else "none (the path visits every state)"
        )
        fits = {f.index: f for f in verdict.fits} if verdict is not None else {}
        rows = []
        for i in range(len(skill.keypoints)):
            name = names[i] if i < len(names) else f"demo {i + 1}"
            f = fits.get(i)
            if f is None:
                fit = "…"
            elif f.well:
                fit = '<span style="color:#15803d">well</span>'
            else:
                fit = f'<span style="color:#b91c1c" title="{html.escape(fit_note(f))}">poorly</span>'
            well = "" if f is None else ("1" if f.well else "0")
            rows.append(
                f'<tr class="fit-row" data-well="{well}"><td>{html.escape(name)}</td><td>{fit}</td><td></td></tr>'
            )
            if f is not None and not f.well:
                note = html.escape(fit_note(f))
                rows.append(f'<tr><td colspan="3" style="color:#555;font-size:0.9em">{note}</td></tr>')
        jt = skill.joint_trajectory
        ik_note = ""
        if jt is not None:
            bad = int(np.count_nonzero(~np.asarray(jt.converged)))
            ik_note = (
                "<div>The arm reaches every point of the learned path.</div>"
                if bad == 0
                else f'<div style="color:#b91c1c">The arm cannot reach {bad} of {len(jt.converged)} points of the '
                "learned path exactly (marked red in Preview).</div>"
            )
        mode = MODE_WORDS.get(skill.generalization, skill.generalization)
        ref_name = html.escape(names[ref] if ref < len(names) else str(ref))
        return (
            f'<div class="skill-summary" data-arm="{arm}" data-states="{len(skill.centroids)}" '
            f'data-reference="{ref}" data-mode="{html.escape(skill.generalization)}" '
            'style="font-size:0.85em;margin-bottom:8px;overflow-wrap:anywhere">'
            f"<b>{arm.capitalize()} arm</b><br>"
            f'<span class="skill-mode">Path made by: <b>{html.escape(mode)}</b></span><br>'
            f'<div style="color:#555;margin-top:4px">{html.escape(FIT_EXPLANATION)}</div>'
            '<table class="fits" style="width:100%;font-size:0.95em"><tr><th style="text-align:left">'
            'Demonstration</th><th style="text-align:left">fits the skill</th><th></th></tr>'
            f"{''.join(rows)}</table>{ik_note}"
            f'<details class="advanced"><summary style="cursor:pointer;color:#555">{ADVANCED}</summary>'
            f"<div>{len(skill.centroids)} states (clusters): {STATES_WORDS}</div>"
            f"<div>Reference demonstration: <b>{ref_name}</b>. {REFERENCE_WORDS}</div>"
            f'<div class="zero-points">Zero-points (states no demonstration passes through, left out of the path): '
            f"{zero_words}.</div></details></div>"
        )

    def _plots(self, arm: Arm, skill: Skill, used: list[UsedDemo]) -> list[str]:
        plots = []
        for j, u in enumerate(used):
            kps = skill.keypoints[j] if j < len(skill.keypoints) else np.zeros(0, dtype=int)
            demo = u.demo
            if u.index is None or demo is None or (len(kps) and int(np.max(kps)) >= len(demo.t)):
                continue  # gone, or trimmed since
            plots.append(
                position_plot_svg(
                    demo.t - demo.t[0],
                    demo.position,
                    kps,
                    title=f"{demo.name} ({arm})",
                    color=self.ctl.demos.color(u.index),
                )
            )
        traj, played = skill.trajectory, self._played().get(arm)
        jt = played.joint_trajectory if played is not None else None
        t, pos = np.asarray(traj.t) - traj.t[0], np.asarray(traj.position)
        if played is not None and jt is not None and jt.skill_time is not None and len(jt.t) > 1:
            # on the clock the robot plays it (the joint limits may stretch it): the length Preview shows
            along = np.asarray(played.trajectory.t)
            pos = np.column_stack([np.interp(jt.skill_time, along, played.trajectory.position[:, c]) for c in range(3)])
            t = np.asarray(jt.t) - jt.t[0]
        plots.append(position_plot_svg(t, pos, [], title=f"learned path ({arm}, {t[-1]:.1f} s)", color=(0, 170, 200)))
        return plots
