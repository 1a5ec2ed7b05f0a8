"""Step panel: which step the teacher is at (Teach, Key-points, Train, Preview, Sessions), the "Show" toggles of
the scene's layers, and the View buttons (Front, Top, Side, Reset).

The step is a dropdown the server hears (docs/decisions/019): choosing one sets the controller's step
(:meth:`studio.controller.View.set_step`), every tab shows that step's section, and each panel draws the layers
the step shows (:attr:`studio.controller.Topic.VIEW`). Arrow keys on a slider stay on it: :mod:`studio.panels._page`."""

from __future__ import annotations

import html
from collections.abc import Callable, Mapping

import viser

from studio.controller import Controller, Layer, Step, Topic
from studio.panels._camera import (
    HOME_CAMERA_FOV_DEG,
    HOME_CAMERA_LOOK_AT,
    HOME_CAMERA_POSITION,
    keep_above_floor,
    set_view,
)

#: The views the "View" buttons choose (:mod:`studio.panels._camera`); "Reset" is the home view.
VIEW_BUTTONS = ("Front", "Top", "Side", "Reset")

HINTS = {
    Step.TEACH: "Guide the gripper with its handle, put the objects where you want them, record three demonstrations.",
    Step.KEYPOINTS: "Where each demonstration changes (key-points) and the cluster centres the skill is built on.",
    Step.TRAIN: "Learn the skill from the shown demonstrations.",
    Step.PREVIEW: "Watch the robot do the learned skill, and what happens to the objects.",
    Step.SESSIONS: "Open, save, copy, download or replay your work.",
}


class StepPanel:
    """The step chooser above one section per step, the "Show" toggles and the View buttons."""

    def __init__(self, ctl: Controller, server: viser.ViserServer, sections: Mapping[Step, viser.GuiFolderHandle]):
        self.ctl = ctl
        self.server = server
        self.sections = dict(sections)
        gui = server.gui
        self.steps = gui.add_dropdown(
            "Step",
            options=tuple(s.value for s in Step),
            initial_value=ctl.view.step.value,
            order=1,
            hint="What you are doing now: each step shows its own controls and what the scene draws for it.",
        )
        self.title = gui.add_html(self._title_html(), order=1.1)
        self.views = gui.add_button_group(
            "View",
            options=VIEW_BUTTONS,
            order=1.2,
            hint="Look from the front, from above or from the robot's left; Reset: the robot and the table again.",
        )
        with gui.add_folder("Show in the scene", order=1.3, expand_by_default=False):
            self.toggles = {
                layer: gui.add_checkbox(layer.value, initial_value=ctl.view.shown(layer)) for layer in Layer
            }
        self.steps.on_update(ctl.guarded("Could not change the step")(self._on_step))
        self.views.on_click(ctl.guarded("Could not change the view")(self._on_view))
        keep_above_floor(server)
        for layer, box in self.toggles.items():
            box.on_update(ctl.guarded("Could not change what is shown")(self._make_toggle(layer)))
        ctl.events.on(Topic.VIEW, self.refresh)
        self.refresh()

    def _on_step(self, event: viser.GuiEvent) -> None:
        if event.client is None:  # our own sync from the view
            return
        self.ctl.view.set_step(Step(self.steps.value))

    def _make_toggle(self, layer: Layer) -> Callable[[viser.GuiEvent], None]:
        def cb(event: viser.GuiEvent) -> None:
            if event.client is None:  # our own sync from the view
                return
            self.ctl.view.set_shown(layer, bool(self.toggles[layer].value))

        return cb

    def _on_view(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        set_view(event.client, str(event.target.value))

    def _title_html(self) -> str:
        step = self.ctl.view.step
        n = list(Step).index(step) + 1
        return (
            f'<div class="step-title" data-step="{html.escape(step.value)}" style="font-size:0.9em;margin:0 4px">'
            f"<b>Step {n} of {len(Step)}</b> · {html.escape(HINTS[step])}</div>"
        )

    def refresh(self) -> None:
        """The step or the layers changed (in any tab): show that step's section and the toggles' state."""
        view = self.ctl.view
        with self.server.atomic():
            for step, section in self.sections.items():
                section.visible = step == view.step
            self.steps.value = view.step.value
            for layer, box in self.toggles.items():
                box.value = view.shown(layer)
            self.title.content = self._title_html()


def reset_camera(client: viser.ClientHandle) -> None:
    """Put one tab's camera back to the home view (robot and table)."""
    set_view(client, "Reset")


__all__ = ["HOME_CAMERA_FOV_DEG", "HOME_CAMERA_LOOK_AT", "HOME_CAMERA_POSITION", "StepPanel", "reset_camera"]
