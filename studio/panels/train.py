"""Train panel: learn the HMM from the demonstrations and show what it learned (paper § Task Learning)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import viser

from studio.panels._charts import heatmap_svg, position_plot_svg

if TYPE_CHECKING:
    from studio.app import Studio


class TrainPanel:
    """Train button with progress; transition heat map, log-likelihoods, reference demo, zero-points, plots."""

    def __init__(self, app: Studio, gui: viser.GuiApi) -> None:
        self.app = app
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
        self.train_btn.on_click(app.guarded("Could not start training")(self._on_train))
        app.events.on("skill", self.refresh)
        app.events.on("session", self.refresh)
        app.events.on("demos", self.refresh)  # renamed / deleted / trimmed demos: labels, plots and status
        app.events.on("training", self._on_training)
        self.refresh()

    def _status_text(self) -> str:
        if self.app.training:
            return "Training… this takes a few seconds."
        if self.app.skills() and getattr(self.app.session, "skills_stale", False):
            return (
                "The learned skill is **out of date**: demonstrations changed since it was learned. "
                "Press **Train** to learn it again."
            )
        if self.app.skills():
            return "Trained. Press **Train** again after changing demonstrations or key-point settings."
        return "Not trained yet. Record at least two demonstrations, then press **Train**."

    def _on_train(self, event: viser.GuiEvent) -> None:
        self.app.train()

    def _on_training(self) -> None:
        busy = self.app.training
        with self.app.server.atomic():
            self.train_btn.disabled = busy
            self.progress.visible = busy
            self.progress.value = 100.0 if busy else 0.0
            self.status.content = self._status_text()

    def refresh(self) -> None:
        """Redraw the results of the current skill(s)."""
        skills = self.app.skills()
        summary, heat, plots = [], [], []
        for arm, skill in skills.items():
            used = self.app.skill_demos(arm)  # row j: the j-th demo the skill learned from (None: gone since)
            names = [nm if i is not None else f"{nm} (renamed or deleted since)" for nm, i, _ in used]
            ll = np.asarray(getattr(skill, "loglik", []), dtype=float)
            ref = int(skill.reference)
            zero = [int(z) for z in np.atleast_1d(getattr(skill, "zero_points", []))]
            rows = "".join(
                f'<tr class="loglik-row"><td>{_esc(names[i] if i < len(names) else f"demo {i + 1}")}</td>'
                f'<td style="text-align:right">{v:,.1f}</td><td>{"reference" if i == ref else ""}</td></tr>'
                for i, v in enumerate(ll)
            )
            jt = getattr(skill, "joint_trajectory", None)
            ik_note = ""
            if jt is not None:
                bad = int(np.count_nonzero(~np.asarray(jt.converged)))
                ik_note = (
                    "<div>The arm reaches every point of the learned path.</div>"
                    if bad == 0
                    else f'<div style="color:#b91c1c">The arm cannot reach {bad} of {len(jt.converged)} points of the '
                    "learned path exactly (marked red in Preview).</div>"
                )
            summary.append(
                f'<div class="skill-summary" data-arm="{arm}" data-states="{len(skill.centroids)}" '
                f'data-reference="{ref}" style="font-size:0.85em;margin-bottom:8px">'
                f"<b>{arm.capitalize()} arm</b>: {len(skill.centroids)} states (clusters); "
                f"reference demonstration: <b>{_esc(names[ref] if ref < len(names) else str(ref))}</b> "
                "(the one the model explains best).<br>"
                f"Zero-points (states no path visits, left out of the learned path): "
                f"{', '.join(str(z) for z in zero[:30]) or 'none'}{' …' if len(zero) > 30 else ''}<br>"
                '<table class="loglik" style="width:100%;font-size:0.95em"><tr><th style="text-align:left">'
                'Demonstration</th><th style="text-align:right">log-likelihood</th><th></th></tr>'
                f"{rows}</table>{ik_note}</div>"
            )
            heat.append(heatmap_svg(np.asarray(skill.transmat), title=f"{arm.capitalize()} arm: state transitions"))
            for j, (_nm, i, demo) in enumerate(used):
                kps = skill.keypoints[j] if j < len(skill.keypoints) else []
                if i is None or (len(kps) and int(np.max(kps)) >= len(demo.t)):  # gone, or trimmed since
                    continue
                plots.append(
                    position_plot_svg(
                        demo.t - demo.t[0],
                        demo.position,
                        kps,
                        title=f"{demo.name} ({arm})",
                        color=self.app.demo_color(i),
                    )
                )
            traj = skill.trajectory
            plots.append(
                position_plot_svg(
                    traj.t - traj.t[0], traj.position, [], title=f"learned path ({arm})", color=(0, 170, 200)
                )
            )
        with self.app.server.atomic():
            self.summary.content = "".join(summary) or "<div style='font-size:0.85em'>No skill learned yet.</div>"
            self.heatmap.content = "".join(heat)
            self.plots.content = "".join(plots)
            self.status.content = self._status_text()

    def close(self) -> None:
        pass


def _esc(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
