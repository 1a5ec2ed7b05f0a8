"""The robot backend interface: what the studio needs from a robot, simulated, replayed or real.

A real-robot backend (e.g. Baxter over ROS) is one new module implementing :class:`RobotBackend`.
Joint order everywhere is :data:`studio.core.types.ALL_ARM_JOINTS` (left s0..w2, then right s0..w2);
grippers are percent open, 0 = closed .. 100 = open, columns left, right.
"""

from __future__ import annotations

import abc
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class JointStateBatch:
    """A batch of consecutive joint-state samples, as streamed (1 kHz on Baxter with the paper's setting).

    Attributes:
        t: (n,) sample times in seconds on the backend's clock, exactly 1 ms apart for the simulator.
        q: (n, 14) joint angles, radians.
        gripper: (n, 2) gripper opening, percent (left, right).
    """

    t: np.ndarray
    q: np.ndarray
    gripper: np.ndarray

    def __len__(self) -> int:
        return int(self.t.shape[0])


@dataclass(frozen=True)
class RobotState:
    """The latest sample: time (s), joints (14,) rad, grippers (2,) percent, and whether it moves."""

    t: float
    q: np.ndarray
    gripper: np.ndarray
    moving: bool = False


#: Called from the backend's streaming thread with each new batch; must return quickly.
StateListener = Callable[[JointStateBatch], None]

log = logging.getLogger(__name__)


class ListenerHub:
    """The listeners of one backend's stream: subscribe, unsubscribe, and deliver each batch to all of them.

    Delivery happens outside any state lock (a listener may read ``state()`` or command the robot); one
    faulty listener is counted in :attr:`errors` and logged, and never stops the stream.
    """

    def __init__(self) -> None:
        self._listeners: list[StateListener] = []
        self._lock = threading.Lock()
        self.errors = 0

    def subscribe(self, listener: StateListener) -> Callable[[], None]:
        with self._lock:
            self._listeners.append(listener)

        def unsubscribe() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)

        return unsubscribe

    def deliver(self, batch: JointStateBatch) -> None:
        if len(batch) == 0:
            return
        with self._lock:
            listeners = list(self._listeners)
        for fn in listeners:
            try:
                fn(batch)
            except Exception:  # one faulty listener must not stop the robot's stream
                self.errors += 1
                log.exception("joint-state listener failed")


class RobotBackend(abc.ABC):
    """Start/stop, a joint-state stream, joint and gripper commands, and the current state."""

    rate_hz: float = 1000.0

    @abc.abstractmethod
    def start(self) -> None:
        """Start streaming joint states (idempotent)."""

    @abc.abstractmethod
    def stop(self) -> None:
        """Stop streaming and release threads (idempotent)."""

    @abc.abstractmethod
    def subscribe(self, listener: StateListener) -> Callable[[], None]:
        """Register ``listener`` for every streamed batch; returns a function that unsubscribes it."""

    @abc.abstractmethod
    def command_joints(self, arm: str, q: np.ndarray) -> None:
        """Set the joint target (7,) rad of ``arm``; the robot moves there within its limits."""

    @abc.abstractmethod
    def command_gripper(self, arm: str, width: float) -> None:
        """Set the gripper target of ``arm``, percent open 0..100."""

    @abc.abstractmethod
    def state(self) -> RobotState:
        """The latest streamed sample."""
