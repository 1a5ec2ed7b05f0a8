"""Baxter's ROS 1 topics and messages as rosbridge carries them, and the connection (roslibpy, asyncio).

Topics as in the Baxter SDK (:data:`JOINT_STATES` and the others below): joint, robot and gripper states come
from the robot; joint commands (position mode, one arm by name), speed ratios, gripper commands (by hardware
id), enable, reset, stop and the joint-state rate go to it. :meth:`RosLink.publish` drops a message while the
socket is down (roslibpy would queue it and send it on reconnecting), and a late target after a stall. Used by
:mod:`.rosbridge`."""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable
from typing import Any
from urllib.parse import urlparse

import numpy as np

from studio.core.errors import InvalidInput, StudioError
from studio.core.types import ARM_JOINTS, Arm

log = logging.getLogger(__name__)

#: A command still waiting on the connection's loop after this long (s) is late: it is dropped, never sent.
LATE_S = 0.05

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
GRIPPER_PROPERTIES = "/robot/end_effector/{arm}_gripper/properties"
GRIPPER_PROPERTIES_TYPE = "baxter_core_msgs/EndEffectorProperties"
ROBOT_STATE = "/robot/state"
ROBOT_STATE_TYPE = "baxter_core_msgs/AssemblyState"
RESET = "/robot/set_super_reset"
STOP = "/robot/set_super_stop"
EMPTY_TYPE = "std_msgs/Empty"
SPEED_RATIO = "/robot/limb/{arm}/set_speed_ratio"
SPEED_RATIO_TYPE = "std_msgs/Float64"
STATE_RATE = "/robot/joint_state_publish_rate"
STATE_RATE_TYPE = "std_msgs/UInt16"
#: baxter_core_msgs/JointCommand.POSITION_MODE
POSITION_MODE = 1


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


def joint_command(arm: Arm, q: np.ndarray) -> dict[str, Any]:
    """A ``baxter_core_msgs/JointCommand``: position mode, ``arm``'s seven joints by name."""
    return {"mode": POSITION_MODE, "command": [float(x) for x in q], "names": list(ARM_JOINTS[arm])}


def gripper_command(gripper_id: int, width: float | None, sequence: int, command: str = "go") -> dict[str, Any]:
    """A ``baxter_core_msgs/EndEffectorCommand``: "go" to ``width`` percent open (0..100), or another command
    ("calibrate", "reset") without arguments."""
    args = json.dumps({"position": float(min(max(width, 0.0), 100.0))}) if width is not None else "{}"
    return {"id": int(gripper_id), "command": command, "args": args, "sender": "teaching-studio", "sequence": sequence}


def open_topics(
    link: RosLink,
    on_joint_state: Callable[[dict[str, Any]], None],
    on_robot_state: Callable[[dict[str, Any]], None],
    on_gripper: Callable[[int, dict[str, Any], bool], None],
) -> None:
    """Subscribe to the robot's state topics and advertise every command topic (advertise before publish)."""
    link.topic(JOINT_STATES, JOINT_STATE_TYPE).subscribe(on_joint_state)
    link.topic(ROBOT_STATE, ROBOT_STATE_TYPE).subscribe(on_robot_state)
    for i, arm in enumerate(("left", "right")):
        link.topic(GRIPPER_STATE.format(arm=arm), GRIPPER_STATE_TYPE).subscribe(lambda m, i=i: on_gripper(i, m, False))
        link.topic(GRIPPER_PROPERTIES.format(arm=arm), GRIPPER_PROPERTIES_TYPE).subscribe(
            lambda m, i=i: on_gripper(i, m, True)
        )
        link.topic(JOINT_COMMAND.format(arm=arm), JOINT_COMMAND_TYPE).advertise()
        link.topic(SPEED_RATIO.format(arm=arm), SPEED_RATIO_TYPE).advertise()
        link.topic(GRIPPER_COMMAND.format(arm=arm), GRIPPER_COMMAND_TYPE).advertise()
    for name, typ in ((ENABLE, ENABLE_TYPE), (RESET, EMPTY_TYPE), (STOP, EMPTY_TYPE)):
        link.topic(name, typ).advertise()


class RosLink:
    """One rosbridge connection and its topics (roslibpy).

    Args:
        url: the rosbridge websocket (checked by :func:`parse_robot_url`).
        connect_timeout: seconds :meth:`connect` waits.
        ros_factory: builds the roslibpy connection from the URL (tests inject their own).
    """

    def __init__(self, url: str, connect_timeout: float, ros_factory: Callable[[str], Any] | None = None) -> None:
        self.url = url
        self.connect_timeout = connect_timeout
        self._factory = ros_factory
        self._ros: Any = None
        self._topics: dict[str, Any] = {}
        self._pending: dict[str, tuple[float, str, dict[str, Any]]] = {}  # topic -> its newest command, unsent
        self._pending_lock = threading.Lock()
        #: Commands overtaken by a newer one on their topic, or late, while the loop was busy: never sent.
        self.skipped = 0

    @property
    def open(self) -> bool:
        """True from :meth:`connect` until :meth:`close` (the connection may since have dropped)."""
        return self._ros is not None

    @property
    def connected(self) -> bool:
        """The websocket is up now."""
        ros = self._ros
        return ros is not None and bool(getattr(ros, "is_connected", False))

    def call_soon(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` on roslibpy's event loop (the one that reads the robot's messages); at once without one."""
        loop = self._loop()
        if loop is None:
            fn()
        else:
            loop.call_soon_threadsafe(fn)

    def on_close(self, fn: Callable[[], None]) -> None:
        """Call ``fn`` (from roslibpy's thread) whenever the websocket closes."""
        ros = self._ros
        if ros is not None and hasattr(ros, "on"):
            ros.on("close", lambda *_: fn())

    def connect(self) -> None:
        """Connect, unless connected already.

        Raises:
            StudioError: the robot computer did not answer within ``connect_timeout``, in plain words.
        """
        if self._ros is not None and getattr(self._ros, "is_connected", False):
            return
        if self._factory is not None:
            self._ros = self._factory(self.url)
            return
        import roslibpy

        ros = roslibpy.Ros(self.url, transport="asyncio")
        ros.factory.maxDelay = 2.0  # after a drop, try to reconnect every ≤ 2 s (not up to an hour apart)
        try:
            ros.run(timeout=self.connect_timeout)
        except Exception as exc:
            ros.factory._stop = True  # give up the background reconnection attempts
            raise StudioError(
                f"Could not connect to the robot at {self.url} within {self.connect_timeout:.0f} s. Check that the "
                "robot computer is on this network and runs rosbridge "
                "(roslaunch rosbridge_server rosbridge_websocket.launch)."
            ) from exc
        self._ros = ros

    def topic(self, name: str, msg_type: str) -> Any:
        import roslibpy

        t = self._topics.get(name)
        if t is None:
            t = self._topics[name] = roslibpy.Topic(self._ros, name, msg_type, queue_size=1)
        return t

    def publish(self, name: str, msg_type: str, msg: dict[str, Any], *, newest: bool = False) -> bool:
        """Send ``msg`` now, or drop it when the connection is down (never queued); True when sent.

        ``newest``: a stream of targets (joint commands): only the newest waits for the connection's loop, and one
        that waited more than :data:`LATE_S` is dropped, so a stall never replays old targets in a burst (the SDK's
        own joint command publisher keeps one message, ``queue_size=1``)."""
        import roslibpy

        if not self.connected:
            return False
        if not newest or self._loop() is None:
            self.topic(name, msg_type).publish(roslibpy.Message(msg))
            return True
        with self._pending_lock:
            waiting = name in self._pending
            if waiting:
                self.skipped += 1
            self._pending[name] = (time.monotonic(), msg_type, msg)
        if not waiting:
            self.call_soon(lambda: self._flush(name))
        return True

    def _flush(self, name: str) -> None:
        """On the connection's loop: send the newest target waiting for ``name``, unless it is late."""
        import roslibpy

        with self._pending_lock:
            item = self._pending.pop(name, None)
        if item is None:
            return
        made, msg_type, msg = item
        if time.monotonic() - made > LATE_S or not self.connected:
            self.skipped += 1
            return
        self.topic(name, msg_type).publish(roslibpy.Message(msg))

    def _loop(self) -> Any:
        loop = getattr(getattr(getattr(self._ros, "factory", None), "manager", None), "loop", None)
        return None if loop is None or loop.is_closed() else loop

    def detach(self) -> Any:
        """Unsubscribe and unadvertise every topic, forget the connection and return it (for :meth:`disconnect`,
        which may wait on roslibpy's thread: call it without holding a lock that thread's callbacks take)."""
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
        return ros

    @staticmethod
    def disconnect(ros: Any) -> None:
        """Close a connection :meth:`detach` returned (a dropped one too)."""
        if ros is not None:
            try:
                ros.close()
            except Exception:
                log.debug("closing the rosbridge connection", exc_info=True)


__all__ = ["POSITION_MODE", "RosLink", "gripper_command", "joint_command", "open_topics", "parse_robot_url"]
