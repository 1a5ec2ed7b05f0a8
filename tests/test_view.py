"""The scene's step and layer toggles (studio/controller/view.py)."""

from __future__ import annotations

from studio.controller.events import Events, Topic
from studio.controller.view import DEFAULTS, Layer, Step, View


def test_each_step_shows_its_layers_and_a_toggle_lasts_until_the_next_step() -> None:
    events = Events()
    seen: list[int] = []
    events.on(Topic.VIEW, lambda: seen.append(1))
    view = View(events)
    assert view.step is Step.TEACH
    assert view.shown(Layer.DEMOS) and not view.shown(Layer.KEYPOINTS) and not view.shown(Layer.LEARNED_PATH)
    view.set_step("Key-points")
    assert view.shown(Layer.KEYPOINTS) and view.shown(Layer.CENTROIDS) and len(seen) == 1
    view.set_shown(Layer.DEMOS, False)
    assert not view.shown(Layer.DEMOS) and len(seen) == 2
    view.set_shown(Layer.DEMOS, False)  # no change: no redraw
    assert len(seen) == 2
    view.set_step(Step.TRAIN)
    assert view.layers() == {layer: layer in DEFAULTS[Step.TRAIN] for layer in Layer}
    assert view.shown(Layer.LEARNED_PATH) and not view.shown(Layer.DEMOS) and len(seen) == 3
    view.set_step(Step.TRAIN)  # the same step again, nothing overridden: no redraw
    assert len(seen) == 3
