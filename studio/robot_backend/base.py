"""The robot backend interface: what the studio needs from a robot, simulated, replayed or real.

A backend implements :class:`RobotBackend`: it streams joint states (:class:`JointStateBatch`) to its
subscribers, follows joint and gripper commands, and executes a plan (``execute``, ``progress``,
``stop_motion``, ``emergency_stop``, ``clear_emergency_stop``). Joint order everywhere is
:data:`studio.core.types.ALL_ARM_JOINTS` (left s0..w2, then right); grippers are percent open, 0 = closed."""

from __future__ import annotations

import abc
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from studio.core.types import Arm

if TYPE_CHECKING:  # pragma: no cover
    from studio.core.execution import ExecutionPlan


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


#: What the status light shows: "enabled" (ready to move), "connected" (heard, but disabled or in error),
#: "e-stopped" (the robot's emergency stop is engaged), "disconnected" (nothing heard from the robot).
LIGHTS = ("enabled", "connected", "e-stopped", "disconnected")


@dataclass(frozen=True)
class RobotHealth:
    """The robot as it reports itself now.

    Attributes:
        connected: its joint states arrive (fresh) over an open connection.
        enabled: its motors are enabled (it obeys motion commands).
        estopped: its emergency stop is engaged (its button, a fault, or the studio's Emergency stop).
        message: what is wrong, in plain words ("" when it is ready to move).
        warnings: how many faulty messages were dropped or re-based so far; ``warning`` the latest, in words.
    """

    connected: bool = True
    enabled: bool = True
    estopped: bool = False
    message: str = ""
    warnings: int = 0
    warning: str = ""

    @property
    def light(self) -> str:
        """One of :data:`LIGHTS`."""
        if not self.connected:
            return "disconnected"
        if self.estopped:
            return "e-stopped"
        return "enabled" if self.enabled and not self.message else "connected"

    @property
    def ready(self) -> bool:
        return self.light == "enabled"


#: What :meth:`RobotBackend.emergency_stop` achieved: the robot confirmed it halted; the stop was sent and the
#: robot has not confirmed yet (watch :meth:`RobotBackend.health`); nothing could be sent (no connection).
ESTOP_RESULTS = ("halted", "sent", "undelivered")

#: Execution states reported by :meth:`RobotBackend.progress`.
EXECUTION_STATES = ("idle", "running", "stopping", "done", "stopped", "emergency-stopped", "failed")


@dataclass(frozen=True)
class ExecutionProgress:
    """Where the execution of a plan is.

    Attributes:
        state: one of :data:`EXECUTION_STATES`: "idle" (nothing executed yet), "running", "stopping" (slowing
            down after :meth:`RobotBackend.stop_motion`), "done" (the plan's end reached), "stopped",
            "emergency-stopped", "failed" (the robot stopped by itself, was disabled or in error, or the
            connection was lost; see ``message``).
        t: plan time reached (s).
        duration: the plan's duration (s).
        started_at: backend time (s, the joint-state stream's clock) of the plan's t = 0; None before.
        message: a plain sentence for the teacher.
    """

    state: str = "idle"
    t: float = 0.0
    duration: float = 0.0
    started_at: float | None = None
    message: str = "Nothing is running on the robot."

    @property
    def fraction(self) -> float:
        """0..1 of the plan executed."""
        return (
            min(max(self.t / self.duration, 0.0), 1.0) if self.duration > 0 else (1.0 if self.state == "done" else 0.0)
        )

    @property
    def active(self) -> bool:
        """True while the robot is moving under the plan (running or slowing down to stop)."""
        return self.state in ("running", "stopping")


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
    def command_joints(self, arm: Arm, q: np.ndarray) -> None:
        """Set the joint target (7,) rad of ``arm``; the robot moves there within its limits."""

    @abc.abstractmethod
    def command_gripper(self, arm: Arm, width: float) -> None:
        """Set the gripper target of ``arm``, percent open 0..100."""

    @abc.abstractmethod
    def state(self) -> RobotState:
        """The latest streamed sample."""

    # -- execution ------------------------------------------------------------------------------------------
    # Defaults for a backend that cannot move a robot (a replay, a test double): it refuses to execute, so
    # nothing can be running and the stops have nothing to do. A robot overrides all five.
    def execute(self, plan: ExecutionPlan) -> None:
        """Start following ``plan`` (joints and grippers over time) now; returns at once.

        The plan must start where the robot is (``plan_execution`` adds the approach). Raises
        :class:`~studio.core.errors.StudioError` with a plain message when the robot cannot run it (not
        streaming, emergency-stopped, another plan running, a replay).
        """
        from studio.core.errors import StudioError

        raise StudioError("This robot connection cannot run a skill (it only plays back or records).")

    def stop_motion(self) -> None:  # noqa: B027 - deliberately a no-op default (see above)
        """Controlled stop: slow down along the plan's path to rest within the limits (idempotent)."""

    def emergency_stop(self) -> str:
        """Halt within one control cycle and refuse motion until :meth:`clear_emergency_stop` (idempotent);
        returns one of :data:`ESTOP_RESULTS`. Must return quickly from any thread (it runs on its own path)."""
        return "halted"

    def clear_emergency_stop(self) -> None:  # noqa: B027 - deliberately a no-op default (see above)
        """Allow motion again after an emergency stop (the robot holds where it stopped); raises
        :class:`~studio.core.errors.StudioError` in plain words when the robot cannot be enabled."""

    def enable(self) -> None:  # noqa: B027 - deliberately a no-op default (see above)
        """Enable the robot's motors (after a reset when it was stopped); raises
        :class:`~studio.core.errors.StudioError` in plain words when it cannot."""

    def health(self) -> RobotHealth:
        """Connected, enabled, e-stopped, and what is wrong (see :class:`RobotHealth`)."""
        return RobotHealth()

    def grippers(self) -> dict[str, str]:
        """arm -> "" when its gripper opens and closes on command, otherwise why not, in plain words."""
        return {"left": "", "right": ""}

    def calibrate_grippers(self, arms: tuple[str, ...] = ("left", "right")) -> None:  # noqa: B027 - nothing to do
        """Calibrate the grippers of ``arms`` that need it (the teacher agreed: they open and close once)."""

    def fault_switches(self) -> dict[str, Callable[[], None]]:
        """A simulated robot's faults the teacher may cause to try the studio's answers ({} for a real one)."""
        return {}

    def progress(self) -> ExecutionProgress:
        """Where the current (or last) execution is."""
        return ExecutionProgress()
