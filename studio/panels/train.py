"""Train panel: learn the HMM from the demonstrations and show what it learned (paper § Task Learning)."""

from __future__ import annotations

import html

import numpy as np
import viser

from studio.controller import Controller, Topic, UsedDemo
from studio.core.types import Skill
from studio.panels._charts import heatmap_svg, position_plot_svg


class TrainPanel:
    """Train button with progress; transition heat map, log-likelihoods, reference demo, zero-points, plots."""

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
        with gui.add_folder("What the robot learned"):
            self.summary = gui.add_html("")
            self.heatmap = gui.add_html("")
        with gui.add_folder("Position over time", expand_by_default=True):
            self.plots = gui.add_html("")
        self.train_btn.on_click(ctl.guarded("Could not start training")(self._on_train))
        ctl.events.on(Topic.SKILL, self.refresh)
        ctl.events.on(Topic.SESSION, self.refresh)
        ctl.events.on(Topic.DEMOS, self.refresh)  # renamed / deleted / trimmed demos: labels, plots and status
        ctl.events.on(Topic.TRAINING, self._on_training)
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
            return "Trained. Press **Train** again after changing demonstrations or key-point settings."
        return "Not trained yet. Record at least two demonstrations, then press **Train**."

    def _on_train(self, event: viser.GuiEvent) -> None:
        self.ctl.training.train()  # the work thread learns; TRAINING and SKILL events redraw

    def _on_training(self) -> None:
        busy = self.ctl.training.busy
        with self.server.atomic():
            self.train_btn.disabled = busy
            self.progress.visible = busy
            self.progress.value = 100.0 if busy else 0.0
            self.status.content = self._status_text()

    def refresh(self) -> None:
        """Redraw the results of the current skill(s)."""
        summary, heat, plots = [], [], []
        for arm, skill in self.ctl.training.skills().items():
            used = self.ctl.training.skill_demos(arm)  # row j: the j-th demo the skill learned from
            summary.append(self._summary_html(arm, skill, used))
            heat.append(heatmap_svg(np.asarray(skill.transmat), title=f"{arm.capitalize()} arm: state transitions"))
            plots += self._plots(arm, skill, used)
        with self.server.atomic():
            self.summary.content = "".join(summary) or "<div style='font-size:0.85em'>No skill learned yet.</div>"
            self.heatmap.content = "".join(heat)
            self.plots.content = "".join(plots)
            self.status.content = self._status_text()

    def _summary_html(self, arm: str, skill: Skill, used: list[UsedDemo]) -> str:
        names = [u.name if u.index is not None else f"{u.name} (renamed or deleted since)" for u in used]
        ll = np.asarray(skill.loglik, dtype=float)
        ref = int(skill.reference)
        zero = [int(z) for z in np.atleast_1d(skill.zero_points)]
        rows = "".join(
            f'<tr class="loglik-row"><td>{html.escape(names[i] if i < len(names) else f"demo {i + 1}")}</td>'
            f'<td style="text-align:right">{v:,.1f}</td><td>{"reference" if i == ref else ""}</td></tr>'
            for i, v in enumerate(ll)
        )
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
        return (
            f'<div class="skill-summary" data-arm="{arm}" data-states="{len(skill.centroids)}" '
            f'data-reference="{ref}" style="font-size:0.85em;margin-bottom:8px">'
            f"<b>{arm.capitalize()} arm</b>: {len(skill.centroids)} states (clusters); "
            f"reference demonstration: <b>{html.escape(names[ref] if ref < len(names) else str(ref))}</b> "
            "(the one the model explains best).<br>"
            f"Zero-points (states no path visits, left out of the learned path): "
            f"{', '.join(str(z) for z in zero[:30]) or 'none'}{' …' if len(zero) > 30 else ''}<br>"
            '<table class="loglik" style="width:100%;font-size:0.95em"><tr><th style="text-align:left">'
            'Demonstration</th><th style="text-align:right">log-likelihood</th><th></th></tr>'
            f"{rows}</table>{ik_note}</div>"
        )

    def _plots(self, arm: str, skill: Skill, used: list[UsedDemo]) -> list[str]:
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
        traj = skill.trajectory
        plots.append(
            position_plot_svg(traj.t - traj.t[0], traj.position, [], title=f"learned path ({arm})", color=(0, 170, 200))
        )
        return plots
