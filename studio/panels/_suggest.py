"""The "Suggest thresholds" controls of the Key-points tab: the button, a progress bar with Stop while it
searches, Undo once a suggestion was applied, and the before/after figures in words."""

from __future__ import annotations

import html

import viser

from studio.controller import Controller, Step, Topic
from studio.panels._sliders import SPECS


class SuggestControls:
    def __init__(self, ctl: Controller, gui: viser.GuiApi) -> None:
        self.ctl = ctl
        self.button = gui.add_button(
            "Suggest thresholds",
            icon=viser.Icon.WAND,
            hint="Try fewer and more key-points and other numbers of clusters, and keep what reproduces a "
            "demonstration the skill did not learn from best (a few seconds).",
        )
        self.progress = gui.add_progress_bar(0.0, animated=True, visible=False)
        self.stop = gui.add_button("Stop suggesting", icon=viser.Icon.PLAYER_STOP, visible=False, color="gray")
        self.undo = gui.add_button(
            "Undo suggestion",
            icon=viser.Icon.ARROW_BACK_UP,
            visible=False,
            hint="Put back the thresholds and clusters you had before Suggest.",
        )
        self.text = gui.add_html(self._html())
        self.button.on_click(ctl.guarded("Could not suggest thresholds")(self._on_suggest))
        self.stop.on_click(ctl.guarded("Could not stop")(lambda _: ctl.suggest.cancel()))
        self.undo.on_click(ctl.guarded("Could not undo the suggestion")(lambda _: ctl.suggest.undo()))
        ctl.events.on(Topic.SUGGEST, self.refresh)

    def _on_suggest(self, event: viser.GuiEvent) -> None:
        self.ctl.suggest.start()  # the work thread searches; SUGGEST events redraw
        if self.ctl.view.step != Step.KEYPOINTS:  # the scene shows what Suggest changes
            self.ctl.view.set_step(Step.KEYPOINTS)

    def refresh(self) -> None:
        st = self.ctl.suggest.state
        self.button.disabled = st.running
        self.progress.visible = st.running
        self.progress.value = round(100.0 * st.fraction, 1)
        self.stop.visible = st.running
        self.undo.visible = st.can_undo and not st.running
        self.text.content = self._html()

    def _html(self) -> str:
        st = self.ctl.suggest.state
        if st.running:
            body = f"{html.escape(st.step)}… ({100 * st.fraction:.0f} %)"
        else:
            body = html.escape(st.summary)
            if st.replaced and st.can_undo:
                names = " and ".join(SPECS[n].words for n in st.replaced if n in SPECS)
                body += (
                    f'<div class="suggest-replaced" style="color:#92400e">Your own value for {html.escape(names)} '
                    "was replaced by an automatic one: press Undo suggestion to have it back.</div>"
                )
        return (
            f'<div class="suggest-state" data-running="{int(st.running)}" data-undo="{int(st.can_undo)}" '
            f'style="font-size:0.85em;overflow-wrap:anywhere">{body}</div>'
        )
