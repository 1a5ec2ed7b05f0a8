"""Robot poses the scene can draw: the live robot's, or a replay's or preview's (:class:`Display` picks)."""

from __future__ import annotations

import threading

import numpy as np


class PoseSource:
    """The newest pose of one source: joints (14,) rad, grippers (2,) percent, time; ``version`` counts updates."""

    def __init__(self) -> None:
        self.q = np.zeros(14)
        self.gripper = np.full(2, 100.0)
        self.t = 0.0
        self.version = 0
        self._lock = threading.Lock()

    def set(self, t: float, q: np.ndarray, gripper: np.ndarray) -> None:
        with self._lock:
            self.t = float(t)
            self.q = np.asarray(q, dtype=np.float64)
            self.gripper = np.asarray(gripper, dtype=np.float64)
            self.version += 1

    def get(self) -> tuple[int, float, np.ndarray, np.ndarray]:
        """(version, t, q, gripper) read together."""
        with self._lock:
            return self.version, self.t, self.q, self.gripper

    def touch(self) -> None:
        """Mark the pose as new so the scene redraws it (after switching back to this source)."""
        with self._lock:
            self.version += 1


class Display:
    """Which source the scene follows: :attr:`live` (the robot) or a replay/preview's source."""

    def __init__(self) -> None:
        self.live = PoseSource()
        self.current = self.live

    @property
    def is_live(self) -> bool:
        return self.current is self.live

    def show(self, source: PoseSource) -> None:
        self.current = source

    def show_live(self) -> None:
        """Follow the live robot again (after a replay or preview)."""
        self.current = self.live
        self.live.touch()

    def get(self) -> tuple[int, float, np.ndarray, np.ndarray]:
        """The pose to draw now: (version, t, q (14,), gripper (2,))."""
        return self.current.get()
