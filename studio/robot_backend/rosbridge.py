"""A real Baxter through rosbridge (roslibpy): the ROS 1 topics the robot really speaks, over a websocket.

Joint states by name stream to the subscribers; ``/robot/state`` and the grippers' state decide what
the robot can do (docs/decisions/040); a closed socket or a stale stream is a lost connection (041); targets
are republished at ``command_rate_hz`` while live (022), a run's on the wall clock at speed ratio 1; the
emergency stop is a hold plus the robot's own stop. Topics: :mod:`.rosbridge_link`; what it reports:
:mod:`.rosbridge_state`; a plan's clock, enabling: :mod:`.rosbridge_run`."""

from __future__ import annotations

import functools
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
    RobotHealth,
    RobotState,
    StateListener,
)
from studio.robot_backend.rosbridge_link import (
    EMPTY_TYPE,
    GRIPPER_COMMAND,
    GRIPPER_COMMAND_TYPE,
    JOINT_COMMAND,
    JOINT_COMMAND_TYPE,
    SPEED_RATIO,
    SPEED_RATIO_TYPE,
    STATE_RATE,
    STATE_RATE_TYPE,
    STOP,
    RosLink,
    gripper_command,
    joint_command,
    open_topics,
    parse_robot_url,
)
from studio.robot_backend.rosbridge_run import PlanClock, calibrate, enable_robot, tick_forever, why_ended
from studio.robot_backend.rosbridge_state import RobotWatch, gripper_words

if TYPE_CHECKING:  # pragma: no cover
    from studio.core.collision import CollisionModel
    from studio.core.execution import ExecutionPlan

log = logging.getLogger(__name__)
#: Seconds a release waits for the robot to confirm the stop it was just sent.
CONFIRM_S = 1.0

#: Seconds a joint target from :meth:`RosbridgeBaxter.command_joints` keeps being republished.
COMMAND_HOLD_S = 1.0
#: No joint state for this long (s) while the command thread runs on time: the connection is lost.
STALE_S = 0.2
#: Baxter's default position-mode speed ratio (limb.py), restored after a run; a run uses :data:`RUN_RATIO`.
DEFAULT_RATIO, RUN_RATIO = 0.3, 1.0
#: What the robot's health says after the link came back, until a person presses Enable robot.
OUTAGE_WORDS = (
    "The connection to the robot came back after it was lost; the studio sends it nothing until you press Enable "
    "robot (when it is safe)."
)


@functools.cache
def _robot_model() -> CollisionModel:
    """Baxter's own collision model (arms and body, no scene), loaded on first use."""
    from studio.core.collision import CollisionModel

    return CollisionModel()


def _cols(arm: Arm) -> slice:
    return slice(0, 7) if arm == "left" else slice(7, 14)


class RosbridgeBaxter(RobotBackend):
    """A real Baxter over rosbridge (topics: :mod:`.rosbridge_link`; decisions 022, 040, 041).

    Args:
        url: the rosbridge websocket, e.g. ``ws://baxter.local:9090``.
        command_rate_hz: rate of the joint commands while a target is live (Baxter's SDK uses 100 Hz).
        connect_timeout: seconds :meth:`start` waits for the connection.
        joint_state_rate_hz: if given, asks the robot to publish joint states at this rate (the paper: 1000).
        enable: enable the robot on start (a failure is shown by :meth:`health`, not raised).
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
        self.enable_on_start = bool(enable)
        self._link = RosLink(self.url, self.connect_timeout, ros_factory)
        self._hub = ListenerHub()
        self._lock = threading.RLock()
        self._watch = RobotWatch(self._hub.deliver, STALE_S)  # never waits for ``_lock``
        self._seq = 0
        self._target: dict[Arm, np.ndarray] = {}
        self._target_until: dict[Arm, float] = {}
        self._run: PlanClock | None = None
        self._last_grip_cmd = np.full(2, np.nan)
        self._exec = ExecutionProgress()
        self._estopped = False
        self._thread: threading.Thread | None = None
        self._stop_evt = threading.Event()
        self.commands_sent = 0
        #: Targets never sent: outside the joint limits, or running an arm into the robot (decision 088).
        self.commands_refused = 0
        self._link_was_up: bool | None = None  # None: never connected yet
        self._after_outage = False  # the link came back: nothing is sent until a person presses Enable
        self._lost_busy = False  # the link was lost while the robot moved under the studio's commands, or closed
        from studio.core.kinematics import Baxter

        b = Baxter.load()
        self._limits = {arm: (b.lower_limits(arm), b.upper_limits(arm)) for arm in ARMS}

    # -- connection -------------------------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Connect, subscribe to the robot's state topics, advertise the commands, enable the robot."""
        with self._lock:
            if self.running:
                return
            link = self._link
            link.connect()
            w = self._watch
            open_topics(link, w.on_joint_state, w.on_robot_state, w.on_gripper)
            if self.joint_state_rate_hz:
                link.publish(STATE_RATE, STATE_RATE_TYPE, {"data": int(self.joint_state_rate_hz)})
            self._stop_evt.clear()
            args = (1.0 / self.command_rate_hz, self._command_tick, self._stop_evt, self._ping)
            self._thread = threading.Thread(target=tick_forever, args=args, name="rosbridge-commands", daemon=True)
            self._thread.start()
        if self.enable_on_start:
            try:
                self.enable()
            except StudioError as exc:  # shown by health() and the Enable button; the studio still starts
                log.warning("the robot was not enabled: %s", exc)

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

    def _ping(self, sent: float) -> None:
        self._link.call_soon(lambda: self._watch.ping(sent))

    # -- the robot's health -----------------------------------------------------------------------------------
    def health(self) -> RobotHealth:
        h = self._watch.health(self._link.connected, self._estopped)
        if self._after_outage and h.connected and not h.message:
            return replace(h, message=OUTAGE_WORDS)
        return h

    def grippers(self) -> dict[str, str]:
        return self._watch.gripper_words()

    def enable(self) -> None:
        """As ``robot_enable.py``: wait for the robot's state, reset it when stopped, enable it (plain errors).
        After a lost connection, this is what lets the studio command the robot again."""
        enable_robot(self._link, lambda: self._watch.robot)
        self._after_outage = False

    def calibrate_grippers(self, arms: tuple[str, ...] = ARMS) -> None:
        """Calibrate each electric gripper of ``arms`` that needs it (it opens and closes once); plain errors."""
        calibrate(lambda i: self._watch.grippers[i], lambda i, cmd: self._gripper_send(i, None, cmd), arms)

    # -- commands ---------------------------------------------------------------------------------------------
    def _joint_command(self, arm: Arm, q: np.ndarray) -> None:
        """Send one target (the newest waits for the connection; a late one is dropped); never one outside the
        joint limits."""
        if not self._within_limits(arm, q):
            self.commands_refused += 1
            log.warning("a %s arm target outside the joint limits was not sent: %s", arm, np.round(q, 3))
            return
        if self._link.publish(JOINT_COMMAND.format(arm=arm), JOINT_COMMAND_TYPE, joint_command(arm, q), newest=True):
            self.commands_sent += 1

    def _within_limits(self, arm: Arm, q: np.ndarray) -> bool:
        lo, hi = self._limits[arm]
        q = np.asarray(q, dtype=np.float64)
        return bool(np.all(np.isfinite(q)) and np.all(q >= lo - 1e-9) and np.all(q <= hi + 1e-9))

    def _collides(self, q14: np.ndarray) -> bool:
        """The arms at ``q14`` run into each other or the robot's body (its own collision model, no scene)."""
        near = _robot_model().near(q14[None, :], np.full((1, 2), 100.0))
        return bool((near.distance < 0.0).any())

    def _gripper_send(self, i: int, width: float | None, command: str = "go") -> None:
        self._seq += 1
        msg = gripper_command(self._watch.grippers[i].hid, width, self._seq, command)
        self._link.publish(GRIPPER_COMMAND.format(arm=ARMS[i]), GRIPPER_COMMAND_TYPE, msg)
        if width is not None:
            self._last_grip_cmd[i] = width

    def _ratio(self, arms: tuple[str, ...], ratio: float) -> None:
        for arm in arms:
            self._link.publish(SPEED_RATIO.format(arm=arm), SPEED_RATIO_TYPE, {"data": float(ratio)})

    def _require_ready(self, doing: str) -> None:
        if self._estopped:
            raise StudioError(f"The emergency stop is on: release it before {doing}.")
        h = self.health()
        if not h.ready:
            raise StudioError(h.message)

    def command_joints(self, arm: Arm, q: np.ndarray) -> None:
        """Move ``arm`` to ``q`` (7,) rad: republished at the command rate for :data:`COMMAND_HOLD_S`."""
        check_arm(arm)
        qa = np.asarray(q, dtype=np.float64)
        if qa.shape != (7,) or not np.all(np.isfinite(qa)):
            raise InvalidInput(f"The {arm} arm joint angles must be 7 finite numbers.")
        if not self._within_limits(arm, qa):
            raise InvalidInput(f"The {arm} arm's target is outside the range its joints can move in; nothing was sent.")
        with self._lock:
            self._require_ready("moving the robot")
            both = self._watch.reader.measured()[1]
            for a, t in self._target.items():
                both[_cols(a)] = t
            both[_cols(arm)] = qa
            if np.all(np.isfinite(both)) and self._collides(both):
                self.commands_refused += 1
                raise StudioError(f"The {arm} arm would run into the robot itself there; nothing was sent.")
            self._target[arm] = qa.copy()
            self._target_until[arm] = time.monotonic() + COMMAND_HOLD_S
            self._joint_command(arm, qa)

    def command_gripper(self, arm: Arm, width: float) -> None:
        i = ARMS.index(check_arm(arm))
        w = float(width)
        if not math.isfinite(w):
            raise InvalidInput(f"The {arm} gripper opening must be a number 0..100.")
        with self._lock:
            self._require_ready("moving the gripper")
            why = gripper_words(arm, self._watch.grippers[i])
            if why:
                raise StudioError(why)
            self._gripper_send(i, w)

    def state(self) -> RobotState:
        return self._watch.state(moving=self._run is not None)

    @property
    def has_state(self) -> bool:
        """True once every arm joint has been heard (and none is missing since)."""
        return self._watch.reader.complete

    # -- execution --------------------------------------------------------------------------------------------
    def execute(self, plan: ExecutionPlan) -> None:
        with self._lock:
            self._require_ready("running a skill")
            if self._run is not None:
                raise StudioError("The robot is already running a skill: stop it first.")
            t = self._watch.check_plan(plan.arms, plan.q[0], plan.gripper)
            self._ratio(plan.arms, RUN_RATIO)
            self._target.clear()
            self._run = PlanClock(plan, t, time.monotonic())
            self._last_grip_cmd[:] = np.nan
            self._exec = self._run.progress

    def stop_motion(self) -> None:
        with self._lock:
            if self._run is None:
                self._target.clear()
                return
            self._run.stop(1.0)  # to rest in about a second, along the path
            self._exec = self._run.progress

    def emergency_stop(self) -> str:
        """The robot's own stop first, sent now from this thread (never queued); then a hold at the measured joints,
        only when they are a pose the arms may hold (within the joint limits, clear of each other and the body): a
        faulty reading never becomes a target (decision 088)."""
        with self._lock:
            self._estopped = True
            run, self._run = self._run, None
            self._target.clear()
            if run is not None:
                why = "Emergency stop sent: waiting for the robot to confirm that it halted."
                self._exec = run.end("emergency-stopped", why)
            if not self._link.connected:
                return "undelivered"
            sent = self._link.publish(STOP, EMPTY_TYPE, {})  # safe whenever it arrives
            fresh = self.health().connected
            q = self._watch.reader.measured()[1]
            # a hold at a stale pose, arriving late, would move the arm; one outside the limits is a faulty reading
            holdable = fresh and all(self._within_limits(a, q[_cols(a)]) for a in ARMS) and not self._collides(q)
            if holdable:
                for arm in ARMS:
                    self._joint_command(arm, q[_cols(arm)])
            elif fresh:
                self.commands_refused += 1
        return "sent" if sent and fresh else "undelivered"

    def clear_emergency_stop(self) -> None:
        """Release the studio's emergency stop: reset and enable the robot (plain errors when it cannot).

        A release right after the stop first waits (up to :data:`CONFIRM_S`) for the robot's state to say it
        stopped: enabling a robot whose stop is still on its way would leave it stopped."""
        with self._lock:
            was = self._estopped
            self._estopped = False
        deadline = time.monotonic() + CONFIRM_S
        while was and self._link.connected and time.monotonic() < deadline:
            st = self._watch.robot
            if st is not None and st.stopped:
                break
            time.sleep(0.01)
        self.enable()

    def progress(self) -> ExecutionProgress:
        with self._lock:
            return self._exec

    def _command_tick(self) -> None:
        now = time.monotonic()
        with self._lock:
            h = self.health()
            if h.connected and self._link_was_up is False:  # the socket, or the robot's stream, is back
                self._came_back()
                h = self.health()
            if not h.connected and self._link_was_up:  # lost now: while moving the robot, or the socket closed?
                self._lost_busy = self._run is not None or bool(self._target)
            if not self._link.connected and self._link_was_up is not None:
                self._lost_busy = True
            if h.connected or self._link_was_up is not None:  # None until first connected
                self._link_was_up = h.connected
            run = self._run
            if run is not None:
                why = why_ended(h, self._watch.robot, run.progress, self._estopped)
                if why:
                    self._exec = run.end("failed", why)
                    self._run = None
                    self._target.clear()
                    if h.connected:
                        self._ratio(run.plan.arms, DEFAULT_RATIO)
                    return
            if not h.connected:
                self._target.clear()  # nothing resumes when the link comes back
                return
            if self._estopped or h.estopped or run is None:
                if self._estopped and self._exec.state == "emergency-stopped" and h.estopped:
                    self._exec = ExecutionProgress(
                        "emergency-stopped", self._exec.t, self._exec.duration, self._exec.started_at,
                        "Emergency stop: the robot halted. Release the emergency stop to move it again.",
                    )  # fmt: skip
                if not self._estopped and not h.estopped:
                    self._hold_tick(now)
                return
            self._run_tick(run, now)

    def _came_back(self) -> None:
        """The link is back after an outage: the SDK's default speed ratio again (a run may have left it at 1); after
        a closed socket, or an outage while the robot moved under the studio's commands, nothing else until a
        person presses Enable robot (:data:`OUTAGE_WORDS`). A stream that only paused while idle needs no Enable."""
        self._target.clear()
        self._ratio(ARMS, DEFAULT_RATIO)
        self._after_outage = self._after_outage or self._lost_busy
        self._lost_busy = False

    def _run_tick(self, run: PlanClock, now: float) -> None:
        q, g = run.advance(now)
        arms = run.plan.arms
        for arm in arms:
            self._joint_command(arm, q[_cols(arm)])
        for i, arm in enumerate(ARMS):
            if arm in arms and not (abs(g[i] - self._last_grip_cmd[i]) < 0.5):
                self._gripper_send(i, float(g[i]))
        self._exec = run.progress
        if run.finished:
            self._run = None
            self._ratio(arms, DEFAULT_RATIO)
            for arm in arms:  # hold the last target a moment, as after a move by hand
                self._target[arm] = q[_cols(arm)].copy()
                self._target_until[arm] = now + COMMAND_HOLD_S

    def _hold_tick(self, now: float) -> None:
        for arm in list(self._target):
            if now > self._target_until.get(arm, 0.0):
                del self._target[arm]
                continue
            self._joint_command(arm, self._target[arm])


__all__ = ["COMMAND_HOLD_S", "STALE_S", "RosbridgeBaxter", "parse_robot_url"]
