"""A real Baxter through rosbridge (roslibpy): the ROS 1 topics the robot really speaks, over a websocket.

Baxter runs ROS 1; ``rosbridge_server`` (``roslaunch rosbridge_server rosbridge_websocket.launch``, port 9090)
exposes its topics as JSON over a websocket, and roslibpy is the Python client for that protocol
(its asyncio transport: one background event loop, no Twisted reactor). Topics used, as in the Baxter SDK:

================================================  ==================================  ===============
topic                                             type                                direction
================================================  ==================================  ===============
``/robot/joint_states``                           ``sensor_msgs/JointState``          robot → studio
``/robot/end_effector/<arm>_gripper/state``       ``baxter_core_msgs/EndEffectorState``  robot → studio
``/robot/limb/<arm>/joint_command``               ``baxter_core_msgs/JointCommand``   studio → robot
``/robot/end_effector/<arm>_gripper/command``     ``baxter_core_msgs/EndEffectorCommand``  studio → robot
``/robot/set_super_enable``                       ``std_msgs/Bool``                   studio → robot
================================================  ==================================  ===============

* **Joint states** arrive at the robot's rate (100 Hz by default; the paper raises it to 1 kHz with
  ``/robot/joint_state_publish_rate``, which ``joint_state_rate_hz`` sets). Joints are matched by name, time
  stamps come from the message header (seconds since the first message), each message is one sample streamed
  to the subscribers like the simulator's, so the recorder records a real demonstration or an execution.
* **Joint commands** are position commands (``mode`` 1, ``POSITION_MODE``) for the seven joints of one arm,
  by name. Baxter drops an arm's command after 0.2 s without a new one (its command timeout) and then holds,
  so a command thread republishes the targets at ``command_rate_hz`` (100 Hz) — only while a target is live:
  during an execution, and for :data:`COMMAND_HOLD_S` after :meth:`command_joints` (so the arm is not held
  stiff between gizmo moves and can still be guided by hand in zero-G mode).
* **Grippers**: ``EndEffectorCommand`` ``command="go"``, ``args='{"position": <0..100>}'``, addressed to the
  gripper's hardware id (from its state messages; 65538, Rethink's electric gripper, until one arrives).
* **Enable**: ``start()`` publishes ``True`` on ``/robot/set_super_enable`` (what ``enable_robot.py -e`` does);
  ``stop()`` leaves the robot enabled and holding.
* **Execution** (:meth:`execute`): the plan's joint targets are published at the command rate, its gripper
  targets when they change; :meth:`stop_motion` slows the plan's progress to rest along its path,
  :meth:`emergency_stop` publishes a hold at the measured joints from the calling thread at once (within one
  100 Hz control cycle) and refuses motion until :meth:`clear_emergency_stop`. Baxter's own e-stop button
  remains the hardware stop.
"""

from __future__ import annotations

import json
import logging
import math
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any
from urllib.parse import urlparse

import numpy as np

from studio.core.errors import InvalidInput, StudioError
from studio.core.types import ALL_ARM_JOINTS, ARM_JOINTS, ARMS, check_arm
from studio.robot_backend.base import (
    ExecutionProgress,
    JointStateBatch,
    ListenerHub,
    RobotBackend,
    RobotState,
    StateListener,
)

if TYPE_CHECKING:  # pragma: no cover
    from studio.core.execution import ExecutionPlan

log = logging.getLogger(__name__)

JOINT_STATES = "/robot/joint_states"
JOINT_STATE_TYPE = "sensor_msgs/JointState"
JOINT_COMMAND = "/robot/limb/{arm}/joint_command"
JOINT_COMMAND_TYPE = "baxter_core_msgs/JointCommand"
GRIPPER_COMMAND = "/robot/end_effector/{arm}_gripper/command"
GRIPPER_COMMAND_TYPE = "baxter_core_msgs/EndEffectorCommand"
GRIPPER_STATE = "/robot/end_effector/{arm}_gripper/state"
GRIPPER_STATE_TYPE = "baxter_core_msgs/EndEffectorState"
ENABLE = "/robot/set_super_enable"
ENABLE_TYPE = "std_msgs/Bool"
STATE_RATE = "/robot/joint_state_publish_rate"
STATE_RATE_TYPE = "std_msgs/UInt16"
#: baxter_core_msgs/JointCommand.POSITION_MODE
POSITION_MODE = 1
#: Hardware id of Rethink's electric parallel gripper (used until the gripper's state message says otherwise).
DEFAULT_GRIPPER_ID = 65538
#: Seconds a joint target from :meth:`RosbridgeBaxter.command_joints` keeps being republished.
COMMAND_HOLD_S = 1.0


def parse_robot_url(url: str) -> str:
    """Check a rosbridge address like ``ws://192.168.0.10:9090`` and return it normalised.

    Raises:
        InvalidInput: with a plain message for anything else.
    """
    text = str(url).strip()
    if "://" not in text:
        text = "ws://" + text
    p = urlparse(text)
    if p.scheme not in ("ws", "wss") or not p.hostname:
        raise InvalidInput(
            f'"{url}" is not a rosbridge address; give it as ws://HOST:9090 (the robot computer\'s name or IP).'
        )
    try:
        port = p.port or 9090
    except ValueError as exc:
        raise InvalidInput(f'"{url}" has an invalid port number.') from exc
    host = f"[{p.hostname}]" if ":" in p.hostname else p.hostname
    return f"{p.scheme}://{host}:{port}{p.path or ''}"


class RosbridgeBaxter(RobotBackend):
    """A real Baxter over rosbridge (see the module docstring for the topics and the behaviour).

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
        self._ros_factory = ros_factory
        self._ros: Any = None
        self._topics: dict[str, Any] = {}
        self._hub = ListenerHub()
        self._lock = threading.RLock()
        self._names = {n: i for i, n in enumerate(ALL_ARM_JOINTS)}
        self._q = np.full(14, np.nan)
        self._g = np.full(2, np.nan)
        self._t = 0.0
        self._stamp0: float | None = None
        self._last_t = -math.inf
        self._samples = 0
        self._gripper_id = [DEFAULT_GRIPPER_ID, DEFAULT_GRIPPER_ID]
        self._seq = 0
        # commands
        self._target: dict[str, np.ndarray] = {}
        self._target_until: dict[str, float] = {}
        self._plan: Any = None
        self._plan_wall0 = 0.0
        self._p = 0.0  # plan time reached (s)
        self._r = 1.0  # plan progress rate (1 as planned; falls to 0 when stopping)
        self._dr = 0.0
        self._last_grip_cmd = np.full(2, np.nan)
        self._exec = ExecutionProgress()
        self._estopped = False
        self._thread: threading.Thread | None = None
        self._stop_evt = threading.Event()
        self.commands_sent = 0

    # -- connection -------------------------------------------------------------------------------------------
    def _connect(self) -> Any:
        if self._ros_factory is not None:
            return self._ros_factory(self.url)
        import roslibpy

        ros = roslibpy.Ros(self.url, transport="asyncio")
        try:
            ros.run(timeout=self.connect_timeout)
        except Exception as exc:
            ros.factory._stop = True  # give up the background reconnection attempts
            raise StudioError(
                f"Could not connect to the robot at {self.url} within {self.connect_timeout:.0f} s. Check that the "
                "robot computer is on this network and runs rosbridge "
                "(roslaunch rosbridge_server rosbridge_websocket.launch)."
            ) from exc
        return ros

    def _topic(self, name: str, msg_type: str) -> Any:
        import roslibpy

        t = self._topics.get(name)
        if t is None:
            t = self._topics[name] = roslibpy.Topic(self._ros, name, msg_type, queue_size=1)
        return t

    def _publish(self, name: str, msg_type: str, msg: dict[str, Any]) -> None:
        import roslibpy

        self._topic(name, msg_type).publish(roslibpy.Message(msg))

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Connect, subscribe to the joint and gripper states, advertise the commands, enable the robot."""
        with self._lock:
            if self.running:
                return
            if self._ros is None or not getattr(self._ros, "is_connected", False):
                self._ros = self._connect()
            self._topic(JOINT_STATES, JOINT_STATE_TYPE).subscribe(self._on_joint_state)
            for i, arm in enumerate(ARMS):
                self._topic(GRIPPER_STATE.format(arm=arm), GRIPPER_STATE_TYPE).subscribe(
                    lambda m, i=i: self._on_gripper_state(i, m)
                )
                self._topic(JOINT_COMMAND.format(arm=arm), JOINT_COMMAND_TYPE).advertise()
                self._topic(GRIPPER_COMMAND.format(arm=arm), GRIPPER_COMMAND_TYPE).advertise()
            self._topic(ENABLE, ENABLE_TYPE).advertise()
            if self.enable:
                self._publish(ENABLE, ENABLE_TYPE, {"data": True})
            if self.joint_state_rate_hz:
                self._publish(STATE_RATE, STATE_RATE_TYPE, {"data": int(self.joint_state_rate_hz)})
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
            for topic in list(self._topics.values()):
                try:
                    if topic.is_subscribed:
                        topic.unsubscribe()
                    if topic.is_advertised:
                        topic.unadvertise()
                except Exception:  # a dropped connection: nothing left to undo
                    log.debug("closing topic %s", getattr(topic, "name", "?"), exc_info=True)
            self._topics.clear()
            ros, self._ros = self._ros, None
        if ros is not None:
            try:
                ros.close()
            except Exception:
                log.debug("closing the rosbridge connection", exc_info=True)

    def subscribe(self, listener: StateListener) -> Callable[[], None]:
        return self._hub.subscribe(listener)

    # -- incoming ---------------------------------------------------------------------------------------------
    def _on_joint_state(self, msg: dict[str, Any]) -> None:
        try:
            names = list(msg.get("name") or [])
            pos = list(msg.get("position") or [])
            stamp = (msg.get("header") or {}).get("stamp") or {}
            st = float(stamp.get("secs", 0)) + 1e-9 * float(stamp.get("nsecs", 0))
        except (TypeError, ValueError, AttributeError):
            log.warning("ignoring a malformed joint state message")
            return
        with self._lock:
            for n, v in zip(names, pos, strict=False):
                i = self._names.get(n)
                if i is not None and isinstance(v, int | float) and math.isfinite(v):
                    self._q[i] = float(v)
            if np.any(np.isnan(self._q)):
                return  # not every arm joint heard yet
            if st <= 0.0:
                st = time.monotonic()
            if self._stamp0 is None:
                self._stamp0 = st
            t = st - self._stamp0
            if t <= self._last_t:  # a repeated or older stamp: time must increase for the recorder
                return
            self._last_t = t
            self._t = t
            self._samples += 1
            g = np.where(np.isnan(self._g), 100.0, self._g)
            batch = JointStateBatch(
                t=_ro(np.array([t])), q=_ro(self._q[None, :].copy()), gripper=_ro(g[None, :].copy())
            )
        self._hub.deliver(batch)

    def _on_gripper_state(self, i: int, msg: dict[str, Any]) -> None:
        try:
            p = float(msg.get("position"))  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return
        with self._lock:
            if math.isfinite(p):
                self._g[i] = min(max(p, 0.0), 100.0)
            hid = msg.get("id")
            if isinstance(hid, int) and hid > 0:
                self._gripper_id[i] = hid

    # -- commands ---------------------------------------------------------------------------------------------
    def _joint_command(self, arm: str, q: np.ndarray) -> None:
        msg = {"mode": POSITION_MODE, "command": [float(x) for x in q], "names": list(ARM_JOINTS[arm])}
        self._publish(JOINT_COMMAND.format(arm=arm), JOINT_COMMAND_TYPE, msg)
        self.commands_sent += 1

    def _gripper_command(self, i: int, width: float) -> None:
        arm = ARMS[i]
        self._seq += 1
        msg = {
            "id": int(self._gripper_id[i]),
            "command": "go",
            "args": json.dumps({"position": float(min(max(width, 0.0), 100.0))}),
            "sender": "teaching-studio",
            "sequence": self._seq,
        }
        self._publish(GRIPPER_COMMAND.format(arm=arm), GRIPPER_COMMAND_TYPE, msg)
        self._last_grip_cmd[i] = width

    def _require_connection(self) -> None:
        if self._ros is None:
            raise StudioError("The robot is not connected; start the studio with the robot reachable.")

    def command_joints(self, arm: str, q: np.ndarray) -> None:
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
            self._target[arm] = qa.copy()
            self._target_until[arm] = time.monotonic() + COMMAND_HOLD_S
            self._joint_command(arm, qa)

    def command_gripper(self, arm: str, width: float) -> None:
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
        with self._lock:
            q = np.where(np.isnan(self._q), 0.0, self._q)
            g = np.where(np.isnan(self._g), 100.0, self._g)
            return RobotState(self._t, _ro(q.copy()), _ro(g.copy()), moving=self._plan is not None)

    @property
    def has_state(self) -> bool:
        """True once every arm joint has been heard from the robot."""
        with self._lock:
            return not np.any(np.isnan(self._q))

    # -- execution --------------------------------------------------------------------------------------------
    def execute(self, plan: ExecutionPlan) -> None:
        with self._lock:
            self._require_connection()
            if self._estopped:
                raise StudioError("The robot is emergency-stopped: release the emergency stop before running a skill.")
            if self._plan is not None:
                raise StudioError("The robot is already running a skill: stop it first.")
            if not self.has_state:
                raise StudioError("No joint states from the robot yet; check that it is on and enabled.")
            off = float(np.max(np.abs(np.asarray(plan.q[0]) - self._q)))
            if off > 0.02:
                raise StudioError(
                    f"The robot moved since the run was planned (by {math.degrees(off):.0f}° at one joint); "
                    "press Run again to plan from where it is now."
                )
            self._plan = plan
            self._plan_wall0 = time.monotonic()
            self._p, self._r, self._dr = 0.0, 1.0, 0.0
            self._last_grip_cmd[:] = np.nan
            self._exec = ExecutionProgress("running", 0.0, plan.duration, self._t, "The robot is running the skill.")

    def stop_motion(self) -> None:
        with self._lock:
            if self._plan is None:
                self._target.clear()
                return
            if self._exec.state == "stopping":
                return
            self._dr = 1.0 / (1.0 * self.command_rate_hz)  # to rest in about a second, along the path
            self._exec = ExecutionProgress(
                "stopping", self._exec.t, self._exec.duration, self._exec.started_at, "The robot is stopping."
            )

    def emergency_stop(self) -> None:
        """Publish a hold at the measured joints now, from this thread, and stop commanding anything else."""
        with self._lock:
            self._estopped = True
            was_running = self._plan is not None
            self._plan = None
            self._target.clear()
            if self._ros is not None and self.has_state:
                for arm in ARMS:
                    cols = slice(0, 7) if arm == "left" else slice(7, 14)
                    try:
                        self._joint_command(arm, self._q[cols])
                    except Exception:  # the connection dropped: nothing more can be sent
                        log.exception("emergency hold could not be sent")
            if was_running or self._exec.active:
                self._exec = ExecutionProgress(
                    "emergency-stopped",
                    self._exec.t,
                    self._exec.duration,
                    self._exec.started_at,
                    "Emergency stop: the robot holds where it is. Release the emergency stop to move it again.",
                )

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
            if self._estopped or self._ros is None:
                return
            plan = self._plan
            if plan is not None:
                if self._dr:
                    self._r = max(0.0, self._r - self._dr)
                self._p = min(self._p + self._r * period, plan.duration)
                q, g = plan.at(self._p)
                for arm in plan.arms:
                    self._joint_command(arm, q[0:7] if arm == "left" else q[7:14])
                for i, arm in enumerate(ARMS):
                    if arm in plan.arms and not (abs(g[i] - self._last_grip_cmd[i]) < 0.5):
                        self._gripper_command(i, float(g[i]))
                state, msg = self._exec.state, self._exec.message
                if self._p >= plan.duration:
                    state, msg = "done", "The robot finished the skill."
                elif state == "stopping" and self._r <= 0.0:
                    state, msg = "stopped", f"The robot stopped at {self._p:.1f} s of {plan.duration:.1f} s."
                self._exec = ExecutionProgress(state, self._p, plan.duration, self._exec.started_at, msg)
                if state in ("done", "stopped"):
                    self._plan = None
                    for arm in plan.arms:  # hold the last target a moment, as after a gizmo move
                        self._target[arm] = q[0:7] if arm == "left" else q[7:14]
                        self._target_until[arm] = time.monotonic() + COMMAND_HOLD_S
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


__all__ = ["RosbridgeBaxter", "parse_robot_url"]
