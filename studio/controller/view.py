"""What the scene shows: the step the teacher is at and which layers are drawn (shared by every tab).

Each panel draws its own scene nodes and shows or hides them from :meth:`View.shown` on :attr:`Topic.VIEW`;
the view itself draws nothing. A layer is visible when the current step shows it by default, unless the
teacher switched it on or off with the "Show" toggles (a choice kept until the next step change).
"""

from __future__ import annotations

import threading
from enum import StrEnum

from studio.controller.events import Events, Topic


class Step(StrEnum):
    """The steps of teaching a skill (the side bar's sections)."""

    TEACH = "Teach"
    KEYPOINTS = "Key-points"
    TRAIN = "Train"
    PREVIEW = "Preview"
    SESSIONS = "Sessions"


class Layer(StrEnum):
    """What can be drawn in the scene, each a toggle in the "Show" row."""

    OBJECTS = "Objects"
    DEMOS = "Demonstrations"
    GRIPPER_EVENTS = "Gripper closes/opens"
    KEYPOINTS = "Key-points"
    CENTROIDS = "Cluster centres"
    LEARNED_PATH = "Learned path"
    EXECUTION = "Robot's run"


#: The layers each step shows unless the teacher asks otherwise (the robot itself is always drawn).
DEFAULTS: dict[Step, frozenset[Layer]] = {
    Step.TEACH: frozenset({Layer.OBJECTS, Layer.DEMOS, Layer.GRIPPER_EVENTS}),
    Step.KEYPOINTS: frozenset({Layer.OBJECTS, Layer.DEMOS, Layer.GRIPPER_EVENTS, Layer.KEYPOINTS, Layer.CENTROIDS}),
    Step.TRAIN: frozenset({Layer.OBJECTS, Layer.LEARNED_PATH}),
    Step.PREVIEW: frozenset({Layer.OBJECTS, Layer.LEARNED_PATH, Layer.EXECUTION}),
    Step.SESSIONS: frozenset({Layer.OBJECTS, Layer.DEMOS, Layer.GRIPPER_EVENTS}),
}


class View:
    """The current step and the layer toggles; every change emits :attr:`Topic.VIEW`."""

    def __init__(self, events: Events) -> None:
        self._events = events
        self._lock = threading.Lock()
        self._step = Step.TEACH
        self._overrides: dict[Layer, bool] = {}

    @property
    def step(self) -> Step:
        return self._step

    def shown(self, layer: Layer) -> bool:
        """Whether ``layer`` is drawn now."""
        with self._lock:
            return self._shown(layer)

    def layers(self) -> dict[Layer, bool]:
        """Every layer and whether it is drawn now (for the "Show" toggles)."""
        return {layer: self.shown(layer) for layer in Layer}

    def set_step(self, step: Step | str) -> None:
        """The teacher moved to ``step``: its default layers are drawn again."""
        step = Step(step)
        with self._lock:
            if step == self._step and not self._overrides:
                return
            self._step = step
            self._overrides = {}
        self._events.emit(Topic.VIEW)

    def set_shown(self, layer: Layer | str, shown: bool) -> None:
        """The teacher switched ``layer`` on or off (until the next step change)."""
        layer = Layer(layer)
        with self._lock:
            if self._shown(layer) == bool(shown):
                return
            self._overrides[layer] = bool(shown)
        self._events.emit(Topic.VIEW)

    def _shown(self, layer: Layer) -> bool:  # with the lock held
        return self._overrides.get(layer, layer in DEFAULTS[self._step])
