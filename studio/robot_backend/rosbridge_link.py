"""Baxter's ROS 1 topics and messages as rosbridge carries them, and the connection (roslibpy, asyncio).

Topics as in the Baxter SDK (:data:`JOINT_STATES` and the others below): joint states and gripper states
come from the robot; joint commands (position mode, one arm by name), gripper commands (``"go"`` to a
position, by hardware id), enable and the joint-state rate go to it. Used by :mod:`.rosbridge`."""

from __future__ import annotations

import json
import logging
import math
import threading
import time
from collections.abc import Callable
from typing import Any
from urllib.parse import urlparse

import numpy as np

from studio.core.errors import InvalidInput, StudioError
from studio.core.types import ALL_ARM_JOINTS, ARM_JOINTS, Arm
from studio.robot_backend.base import JointStateBatch

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


def gripper_command(gripper_id: int, width: float, sequence: int) -> dict[str, Any]:
    """A ``baxter_core_msgs/EndEffectorCommand`` moving the gripper to ``width`` percent open (0..100)."""
    return {
        "id": int(gripper_id),
        "command": "go",
        "args": json.dumps({"position": float(min(max(width, 0.0), 100.0))}),
        "sender": "teaching-studio",
        "sequence": sequence,
    }


def joint_state(msg: dict[str, Any]) -> tuple[list[Any], list[Any], float] | None:
    """Joint names, positions and the header's time stamp (s) of a ``sensor_msgs/JointState``; None if malformed."""
    try:
        names = list(msg.get("name") or [])
        pos = list(msg.get("position") or [])
        stamp = (msg.get("header") or {}).get("stamp") or {}
        return names, pos, float(stamp.get("secs", 0)) + 1e-9 * float(stamp.get("nsecs", 0))
    except (TypeError, ValueError, AttributeError):
        return None


def gripper_state(msg: dict[str, Any]) -> tuple[float | None, int | None]:
    """Opening (percent, clipped to 0..100) and hardware id of a ``baxter_core_msgs/EndEffectorState``, each
    None when missing or invalid."""
    try:
        p: float | None = float(msg.get("position"))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None, None
    if p is not None and math.isfinite(p):
        p = min(max(p, 0.0), 100.0)
    else:
        p = None
    hid = msg.get("id")
    return p, hid if isinstance(hid, int) and hid > 0 else None


class StateReader:
    """The robot's state as its messages tell it: joint angles matched by name, gripper openings and hardware
    ids, time stamps (s since the first message, increasing).

    Thread-safe with a lock of its own that is never held while calling out. roslibpy calls the state callbacks
    while holding its event lock, and the backend publishes through roslibpy while holding its command lock, so
    the callbacks must not wait on the command lock: they did, and ``start`` deadlocked in CI (2026-11-23).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._names = {n: i for i, n in enumerate(ALL_ARM_JOINTS)}
        self.q = np.full(14, np.nan)
        self.g = np.full(2, np.nan)
        self.t = 0.0
        self._stamp0: float | None = None
        self._last_t = -math.inf
        self.gripper_id = [DEFAULT_GRIPPER_ID, DEFAULT_GRIPPER_ID]

    @property
    def complete(self) -> bool:
        """True once every arm joint has been heard."""
        with self._lock:
            return self._complete()

    def _complete(self) -> bool:
        return not np.any(np.isnan(self.q))

    def measured(self) -> tuple[float, np.ndarray, np.ndarray]:
        """(t, q (14,), gripper (2,)) as last heard, copies; NaN where not heard yet."""
        with self._lock:
            return self.t, self.q.copy(), self.g.copy()

    def hardware_id(self, i: int) -> int:
        """Gripper ``i``'s hardware id (for its commands)."""
        with self._lock:
            return self.gripper_id[i]

    def on_joint_state(self, msg: dict[str, Any]) -> JointStateBatch | None:
        """Take in a ``sensor_msgs/JointState``; the sample to stream, or None (malformed, not every arm joint
        heard yet, or a repeated or older stamp: time must increase for the recorder)."""
        fields = joint_state(msg)
        if fields is None:
            log.warning("ignoring a malformed joint state message")
            return None
        with self._lock:
            return self._take(*fields)

    def _take(self, names: list[Any], pos: list[Any], st: float) -> JointStateBatch | None:
        for n, v in zip(names, pos, strict=False):
            i = self._names.get(n)
            if i is not None and isinstance(v, int | float) and math.isfinite(v):
                self.q[i] = float(v)
        if not self._complete():
            return None
        if st <= 0.0:
            st = time.monotonic()
        if self._stamp0 is None:
            self._stamp0 = st
        t = st - self._stamp0
        if t <= self._last_t:
            return None
        self._last_t = self.t = t
        g = np.where(np.isnan(self.g), 100.0, self.g)
        return JointStateBatch(t=_ro(np.array([t])), q=_ro(self.q[None, :].copy()), gripper=_ro(g[None, :].copy()))

    def on_gripper_state(self, i: int, msg: dict[str, Any]) -> None:
        """Take in gripper ``i``'s ``baxter_core_msgs/EndEffectorState``."""
        position, hardware_id = gripper_state(msg)
        with self._lock:
            if position is not None:
                self.g[i] = position
            if hardware_id is not None:
                self.gripper_id[i] = hardware_id


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


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

    @property
    def open(self) -> bool:
        """True from :meth:`connect` until :meth:`close` (the connection may since have dropped)."""
        return self._ros is not None

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

    def publish(self, name: str, msg_type: str, msg: dict[str, Any]) -> None:
        import roslibpy

        self.topic(name, msg_type).publish(roslibpy.Message(msg))

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


__all__ = [
    "DEFAULT_GRIPPER_ID",
    "POSITION_MODE",
    "RosLink",
    "StateReader",
    "gripper_command",
    "gripper_state",
    "joint_command",
    "joint_state",
    "parse_robot_url",
]
