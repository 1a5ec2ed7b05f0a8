"""A real Baxter through rosbridge (roslibpy): the ROS 1 topics the robot really speaks, over a websocket.

Joint states, matched by name, stream to the subscribers like the simulator's; joint targets are position
commands republished at ``command_rate_hz`` while a target is live (docs/decisions/022); grippers are
addressed by their hardware id; ``start()`` enables the robot. :meth:`~RosbridgeBaxter.emergency_stop`
publishes a hold at the measured joints at once. Topics and the connection: :mod:`.rosbridge_link`."""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from studio.core.errors import InvalidInput, StudioError
from studio.core.types import ARMS, Arm, check_arm
from studio.robot_backend.base import (
    ExecutionProgress,
    ListenerHub,
    RobotBackend,
    RobotState,
    StateListener,
)
from studio.robot_backend.rosbridge_link import (
    ENABLE,
    ENABLE_TYPE,
    GRIPPER_COMMAND,
    GRIPPER_COMMAND_TYPE,
    GRIPPER_STATE,
    GRIPPER_STATE_TYPE,
    JOINT_COMMAND,
    JOINT_COMMAND_TYPE,
    JOINT_STATE_TYPE,
    JOINT_STATES,
    STATE_RATE,
    STATE_RATE_TYPE,
    RosLink,
    StateReader,
    gripper_command,
    joint_command,
    parse_robot_url,
)

if TYPE_CHECKING:  # pragma: no cover
    from studio.core.execution import ExecutionPlan

log = logging.getLogger(__name__)

#: Seconds a joint target from :meth:`RosbridgeBaxter.command_joints` keeps being republished.
COMMAND_HOLD_S = 1.0


def _cols(arm: Arm) -> slice:
    return slice(0, 7) if arm == "left" else slice(7, 14)


class _Run:
    """A plan being streamed to the robot: progress along it, one command tick at a time, and the report.

    The progress advances by ``rate`` × the tick period each tick; a controlled stop lowers the rate to 0 in
    about a second (so the robot slows down along the path).
    """

    def __init__(self, plan: ExecutionPlan, started_at: float) -> None:
        self.plan = plan
        self.p, self.rate, self.slowing = 0.0, 1.0, 0.0
        self.progress = ExecutionProgress("running", 0.0, plan.duration, started_at, "The robot is running the skill.")

    def stop(self, ticks: float) -> None:
        """Slow down to rest in ``ticks`` command ticks (idempotent)."""
        if self.progress.state == "stopping":
            return
        self.slowing = 1.0 / ticks
        self.progress = replace(self.progress, state="stopping", message="The robot is stopping.")

    def tick(self, period: float) -> tuple[np.ndarray, np.ndarray]:
        """Advance one tick of ``period`` seconds; the joint (14,) and gripper (2,) targets there."""
        if self.slowing:
            self.rate = max(0.0, self.rate - self.slowing)
        duration = self.plan.duration
        self.p = min(self.p + self.rate * period, duration)
        p = self.progress
        state, msg = p.state, p.message
        if self.p >= duration:
            state, msg = "done", "The robot finished the skill."
        elif state == "stopping" and self.rate <= 0.0:
            state, msg = "stopped", f"The robot stopped at {self.p:.1f} s of {duration:.1f} s."
        self.progress = ExecutionProgress(state, self.p, duration, p.started_at, msg)
        return self.plan.at(self.p)

    @property
    def finished(self) -> bool:
        return self.progress.state in ("done", "stopped")


class RosbridgeBaxter(RobotBackend):
    """A real Baxter over rosbridge (topics: :mod:`.rosbridge_link`; commands: docs/decisions/022).

    Args:
        url: the rosbridge websocket, e.g. ``ws://baxter.local:9090``.
        command_rate_hz: rate of the joint commands while a target is live (Baxter's SDK uses 100 Hz).
        connect_timeout: seconds :meth:`start` waits for the connection.
        joint_state_rate_hz: if given, asks the robot to publish joint states at this rate (the paper: 1000).
        enable: publish "enable" on start.
        ros_factory: builds the roslibpy connection from the URL (tests inject their own).
    """

    def __init__(
        self,
        url: str,
        *,
        command_rate_hz: float = 100.0,
        connect_timeout: float = 10.0,
        joint_state_rate_hz: int | None = None,
        enable: bool = True,
        ros_factory: Callable[[str], Any] | None = None,
    ) -> None:
        self.url = parse_robot_url(url)
        if not (command_rate_hz > 0 and math.isfinite(command_rate_hz)):
            raise InvalidInput("The command rate must be a positive number of messages per second.")
        self.command_rate_hz = float(command_rate_hz)
        self.rate_hz = float(joint_state_rate_hz or 100)
        self.connect_timeout = float(connect_timeout)
        self.joint_state_rate_hz = joint_state_rate_hz
        self.enable = bool(enable)
        self._link = RosLink(self.url, self.connect_timeout, ros_factory)
        self._hub = ListenerHub()
        self._lock = threading.RLock()
        self._state = StateReader()  # its own lock: the state callbacks never wait for ``_lock``
        self._seq = 0
        # commands
        self._target: dict[Arm, np.ndarray] = {}
        self._target_until: dict[Arm, float] = {}
        self._run: _Run | None = None
        self._last_grip_cmd = np.full(2, np.nan)
        self._exec = ExecutionProgress()
        self._estopped = False
        self._thread: threading.Thread | None = None
        self._stop_evt = threading.Event()
        self.commands_sent = 0

    # -- connection -------------------------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Connect, subscribe to the joint and gripper states, advertise the commands, enable the robot."""
        with self._lock:
            if self.running:
                return
            link = self._link
            link.connect()
            link.topic(JOINT_STATES, JOINT_STATE_TYPE).subscribe(self._on_joint_state)
            for i, arm in enumerate(ARMS):
                link.topic(GRIPPER_STATE.format(arm=arm), GRIPPER_STATE_TYPE).subscribe(
                    lambda m, i=i: self._on_gripper_state(i, m)
                )
                link.topic(JOINT_COMMAND.format(arm=arm), JOINT_COMMAND_TYPE).advertise()
                link.topic(GRIPPER_COMMAND.format(arm=arm), GRIPPER_COMMAND_TYPE).advertise()
            link.topic(ENABLE, ENABLE_TYPE).advertise()
            if self.enable:
                link.publish(ENABLE, ENABLE_TYPE, {"data": True})
            if self.joint_state_rate_hz:
                link.publish(STATE_RATE, STATE_RATE_TYPE, {"data": int(self.joint_state_rate_hz)})
            self._stop_evt.clear()
            self._thread = threading.Thread(target=self._command_loop, name="rosbridge-commands", daemon=True)
            self._thread.start()

    def stop(self) -> None:
        """Stop commanding, unsubscribe and close the connection (the robot stays enabled and holds)."""
        self._stop_evt.set()
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(timeout=2.0)
        self._thread = None
        with self._lock:
            ros = self._link.detach()
        RosLink.disconnect(ros)  # outside the lock: closing waits for roslibpy's thread, whose callbacks take it

    def subscribe(self, listener: StateListener) -> Callable[[], None]:
        return self._hub.subscribe(listener)

    # -- incoming ---------------------------------------------------------------------------------------------
    def _on_joint_state(self, msg: dict[str, Any]) -> None:
        batch = self._state.on_joint_state(msg)
        if batch is not None:
            self._hub.deliver(batch)

    def _on_gripper_state(self, i: int, msg: dict[str, Any]) -> None:
        self._state.on_gripper_state(i, msg)

    # -- commands ---------------------------------------------------------------------------------------------
    def _joint_command(self, arm: Arm, q: np.ndarray) -> None:
        self._link.publish(JOINT_COMMAND.format(arm=arm), JOINT_COMMAND_TYPE, joint_command(arm, q))
        self.commands_sent += 1

    def _gripper_command(self, i: int, width: float) -> None:
        self._seq += 1
        msg = gripper_command(self._state.hardware_id(i), width, self._seq)
        self._link.publish(GRIPPER_COMMAND.format(arm=ARMS[i]), GRIPPER_COMMAND_TYPE, msg)
        self._last_grip_cmd[i] = width

    def _require_connection(self) -> None:
        if not self._link.open:
            raise StudioError("The robot is not connected; start the studio with the robot reachable.")

    def command_joints(self, arm: Arm, q: np.ndarray) -> None:
        """Move ``arm`` to ``q`` (7,) rad: republished at the command rate for :data:`COMMAND_HOLD_S`."""
        check_arm(arm)
        qa = np.asarray(q, dtype=np.float64)
        if qa.shape != (7,) or not np.all(np.isfinite(qa)):
            raise InvalidInput(f"The {arm} arm joint angles must be 7 finite numbers.")
        with self._lock:
            if self._estopped:
                log.info("emergency-stopped: joint command ignored")
                return
            self._require_connection()
            self._hold(arm, qa.copy())
            self._joint_command(arm, qa)

    def _hold(self, arm: Arm, q: np.ndarray) -> None:
        self._target[arm] = q
        self._target_until[arm] = time.monotonic() + COMMAND_HOLD_S

    def command_gripper(self, arm: Arm, width: float) -> None:
        i = ARMS.index(check_arm(arm))
        w = float(width)
        if not math.isfinite(w):
            raise InvalidInput(f"The {arm} gripper opening must be a number 0..100.")
        with self._lock:
            if self._estopped:
                log.info("emergency-stopped: gripper command ignored")
                return
            self._require_connection()
            self._gripper_command(i, w)

    def state(self) -> RobotState:
        t, q, g = self._state.measured()
        q, g = np.where(np.isnan(q), 0.0, q), np.where(np.isnan(g), 100.0, g)
        return RobotState(t, _ro(q), _ro(g), moving=self._run is not None)

    @property
    def has_state(self) -> bool:
        """True once every arm joint has been heard from the robot."""
        return self._state.complete

    # -- execution --------------------------------------------------------------------------------------------
    def execute(self, plan: ExecutionPlan) -> None:
        with self._lock:
            self._require_connection()
            if self._estopped:
                raise StudioError("The robot is emergency-stopped: release the emergency stop before running a skill.")
            if self._run is not None:
                raise StudioError("The robot is already running a skill: stop it first.")
            if not self.has_state:
                raise StudioError("No joint states from the robot yet; check that it is on and enabled.")
            t, q, _ = self._state.measured()
            off = float(np.max(np.abs(np.asarray(plan.q[0]) - q)))
            if off > 0.02:
                raise StudioError(
                    f"The robot moved since the run was planned (by {math.degrees(off):.0f}° at one joint); "
                    "press Run again to plan from where it is now."
                )
            self._run = _Run(plan, t)
            self._last_grip_cmd[:] = np.nan
            self._exec = self._run.progress

    def stop_motion(self) -> None:
        with self._lock:
            if self._run is None:
                self._target.clear()
                return
            self._run.stop(ticks=1.0 * self.command_rate_hz)  # to rest in about a second, along the path
            self._exec = self._run.progress

    def emergency_stop(self) -> None:
        """Publish a hold at the measured joints now, from this thread, and stop commanding anything else."""
        with self._lock:
            self._estopped = True
            was_running = self._run is not None
            self._run = None
            self._target.clear()
            q = self._state.measured()[1]
            if self._link.open and not np.any(np.isnan(q)):
                for arm in ARMS:
                    try:
                        self._joint_command(arm, q[_cols(arm)])
                    except Exception:  # the connection dropped: nothing more can be sent
                        log.exception("emergency hold could not be sent")
            if was_running or self._exec.active:
                why = "Emergency stop: the robot holds where it is. Release the emergency stop to move it again."
                self._exec = replace(self._exec, state="emergency-stopped", message=why)

    def clear_emergency_stop(self) -> None:
        with self._lock:
            self._estopped = False

    def progress(self) -> ExecutionProgress:
        with self._lock:
            return self._exec

    def _command_loop(self) -> None:
        period = 1.0 / self.command_rate_hz
        next_t = time.monotonic()
        while not self._stop_evt.is_set():
            try:
                self._command_tick(period)
            except Exception:  # keep commanding: a lost message must not end the loop
                log.exception("rosbridge command tick failed")
            next_t += period
            delay = next_t - time.monotonic()
            if delay < 0:
                next_t = time.monotonic()
                delay = 0.0
            self._stop_evt.wait(delay)

    def _command_tick(self, period: float) -> None:
        with self._lock:
            if self._estopped or not self._link.open:
                return
            run = self._run
            if run is not None:
                q, g = run.tick(period)
                arms = run.plan.arms
                for arm in arms:
                    self._joint_command(arm, q[_cols(arm)])
                for i, arm in enumerate(ARMS):
                    if arm in arms and not (abs(g[i] - self._last_grip_cmd[i]) < 0.5):
                        self._gripper_command(i, float(g[i]))
                self._exec = run.progress
                if run.finished:
                    self._run = None
                    for arm in arms:  # hold the last target a moment, as after a gizmo move
                        self._hold(arm, q[_cols(arm)])
                return
            now = time.monotonic()
            for arm in list(self._target):
                if now > self._target_until.get(arm, 0.0):
                    del self._target[arm]
                    continue
                self._joint_command(arm, self._target[arm])


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


__all__ = ["COMMAND_HOLD_S", "RosbridgeBaxter", "parse_robot_url"]
