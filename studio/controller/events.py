"""Typed topics the views subscribe to: the controller says *what* changed, each panel redraws its part.

Callbacks run on the thread that emitted (a GUI callback, the work thread, or the key-point worker); a
failing callback is logged and never stops the others.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from enum import StrEnum

log = logging.getLogger(__name__)


class Topic(StrEnum):
    """What changed. Every emit of a topic says only that; subscribers read the new state from the controller."""

    #: The taught arm(s) changed (``teaching.selected_arms``).
    ARMS = "arms"
    #: Demonstrations were added, renamed, trimmed, hidden, shown or deleted (``demos``).
    DEMOS = "demos"
    #: Another session is open (everything may have changed).
    SESSION = "session"
    #: The list of sessions on disk changed (``sessions.names()``).
    SESSIONS = "sessions"
    #: A recording started or stopped (``teaching.recording``).
    RECORDING = "recording"
    #: Whether an arm can reach where its handle was dragged changed (``teaching.reach``).
    REACH = "reach"
    #: A new key-point view is ready (``keypoints.view``).
    KEYPOINTS = "keypoints"
    #: The threshold settings changed other than by a slider being moved: Detail, back to automatic, Suggest
    #: applied or undone, another session (``keypoints.settings()``, ``keypoints.params()``).
    THRESHOLDS = "thresholds"
    #: A new live learned path is ready while the thresholds move (``live.paths``).
    LIVE_PATH = "live_path"
    #: Suggest thresholds started, progressed, finished or was undone (``suggest.state``).
    SUGGEST = "suggest"
    #: The verdict on the learned skill changed (``training.verdicts()``).
    VERDICT = "verdict"
    #: Training started or finished (``training.busy``).
    TRAINING = "training"
    #: New skills were learned (``training.skills()``).
    SKILL = "skill"
    #: A preview or replay was loaded or unloaded (``playback.kind``).
    PLAYBACK = "playback"
    #: The step or the shown scene layers changed (``view.step``, ``view.shown(layer)``).
    VIEW = "view"
    #: The objects on the table were set up differently, or put back (``scene.scene``).
    SCENE = "scene"
    #: The object chosen to move or to go above, the gripper the keys move, or whether the gripper's handle
    #: turns it changed (``guide.chosen``, ``guide.key_arm``, ``guide.turning``).
    GUIDE = "guide"
    #: The task result of the learned skill changed (``scene.task_result()``).
    TASK = "task"
    #: A thrown-away take or a deleted demonstration can be brought back, or no longer (``undo.what``).
    UNDO = "undo"
    #: The robot's run started, changed phase (stopping, done, stopped, emergency-stopped), was judged, or the
    #: emergency stop was engaged or released (``execution.status``; the progress within a phase is polled).
    EXECUTION = "execution"


class Events:
    """A small observer list per topic."""

    def __init__(self) -> None:
        self._subs: dict[Topic, list[Callable[[], None]]] = {}
        self._lock = threading.Lock()

    def on(self, topic: Topic, fn: Callable[[], None]) -> Callable[[], None]:
        """Call ``fn()`` after every emit of ``topic``; returns a function that unsubscribes it."""
        topic = Topic(topic)
        with self._lock:
            self._subs.setdefault(topic, []).append(fn)

        def off() -> None:
            with self._lock:
                subs = self._subs.get(topic, [])
                if fn in subs:
                    subs.remove(fn)

        return off

    def clear(self) -> None:
        """Drop every subscription (the views are gone: a job still running tells no one)."""
        with self._lock:
            self._subs.clear()

    def emit(self, topic: Topic) -> None:
        with self._lock:
            subs = list(self._subs.get(Topic(topic), ()))
        for fn in subs:
            try:
                fn()
            except Exception:  # a broken view must not break the others
                log.exception("view update for %s failed", topic)
