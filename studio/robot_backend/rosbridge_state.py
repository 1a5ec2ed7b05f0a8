"""What a real Baxter reports: joint states (by name, stamps checked), its ``AssemblyState`` and each
gripper's state and properties.

Used by :mod:`studio.robot_backend.rosbridge`. Joint states that name no arm joint (Baxter's gripper-only
and head messages) make no sample; a message with a non-finite stamp or value is dropped; a stamp that jumps
back (or more than :data:`JUMP_S` ahead of the arrival times) re-bases the clock so times keep increasing;
arm joints missing from :data:`MISSING_AFTER` messages in a row are a fault in plain words.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from studio.core.errors import StudioError
from studio.core.types import ALL_ARM_JOINTS
from studio.robot_backend.base import JointStateBatch, RobotHealth, RobotState

log = logging.getLogger(__name__)

#: A stamp this far (s) from what the arrival times say is a clock jump: the clock is re-based.
JUMP_S = 1.0
#: A stamp this little behind the last one (s) is a repeat or a reordering: that message is dropped.
REORDER_S = 0.1
#: Arm-joint messages in a row that lack a joint before it is a fault.
MISSING_AFTER = 20
#: AssemblyState.estop_button (baxter_core_msgs)
ESTOP_BUTTON_PRESSED = 1
#: AssemblyState.estop_source (baxter_core_msgs)
ESTOP_SOURCES = {1: "its emergency-stop button", 2: "an unknown source", 3: "a joint fault", 4: "a lost heartbeat"}
#: EndEffectorProperties.ui_type (baxter_core_msgs)
GRIPPER_TYPES = {0: "none", 1: "suction", 2: "electric", 3: "custom"}
#: Hardware id of Rethink's electric parallel gripper (until the gripper's own messages say otherwise).
DEFAULT_GRIPPER_ID = 65538


def joint_state(msg: dict[str, Any]) -> tuple[list[Any], list[Any], float] | None:
    """Joint names, positions and the header's stamp (s) of a ``sensor_msgs/JointState``; None if malformed."""
    try:
        names = list(msg.get("name") or [])
        pos = list(msg.get("position") or [])
        stamp = (msg.get("header") or {}).get("stamp") or {}
        return names, pos, float(stamp.get("secs", 0)) + 1e-9 * float(stamp.get("nsecs", 0))
    except (TypeError, ValueError, AttributeError, OverflowError):
        return None


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


class StateReader:
    """Joint states as samples: arm joints by name, times in seconds since the first message, increasing.

    Thread-safe with a lock of its own that is never held while calling out (roslibpy calls back holding its
    event lock while the backend publishes holding its own lock). ``clock`` gives arrival times (monotonic s).
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._lock = threading.Lock()
        self._clock = clock
        self._names = {n: i for i, n in enumerate(ALL_ARM_JOINTS)}
        self.q = np.full(14, np.nan)
        self.g = np.full(2, np.nan)
        self.t = 0.0
        self._stamp0: float | None = None
        self._last_t = -math.inf
        self._last_arrival: float | None = None
        self._missing = np.zeros(14, dtype=np.int64)
        #: Monotonic time the last arm sample arrived (None before the first).
        self.arrived: float | None = None
        #: Messages that named no arm joint (Baxter's gripper-only and head messages): never samples.
        self.other_messages = 0
        self.warnings = 0
        self.warning = ""
        self.fault = ""

    @property
    def complete(self) -> bool:
        """Every arm joint heard, and no joint missing since."""
        with self._lock:
            return not np.any(np.isnan(self.q)) and not self.fault

    def measured(self) -> tuple[float, np.ndarray, np.ndarray]:
        """(t, q (14,), gripper (2,)) as last heard, copies; NaN where not heard yet."""
        with self._lock:
            return self.t, self.q.copy(), self.g.copy()

    def set_gripper(self, i: int, position: float) -> None:
        with self._lock:
            self.g[i] = position

    def _warn(self, text: str) -> None:
        self.warnings += 1
        self.warning = text
        log.warning(text)

    def on_joint_state(self, msg: dict[str, Any]) -> JointStateBatch | None:
        """Take in a ``sensor_msgs/JointState``; the sample to stream, or None (see the module docstring)."""
        fields = joint_state(msg)
        arrival = self._clock()
        with self._lock:
            if fields is None:
                self._warn("The robot sent a joint state the studio cannot read; it was ignored.")
                return None
            return self._take(*fields, arrival)

    def _take(self, names: list[Any], pos: list[Any], stamp: float, arrival: float) -> JointStateBatch | None:
        idx = [(self._names.get(n) if isinstance(n, str) else None, v) for n, v in zip(names, pos, strict=False)]
        arm = [(i, v) for i, v in idx if i is not None]
        if not arm:
            self.other_messages += 1
            return None
        if stamp == 0.0:  # no stamp at all: the arrival time stands in
            stamp = arrival
        if not all(isinstance(v, int | float) and math.isfinite(v) for _, v in arm) or not math.isfinite(stamp):
            self._warn("The robot sent a joint state with an invalid value or time; it was ignored.")
            return None
        seen = np.zeros(14, dtype=bool)
        for i, v in arm:
            self.q[i], seen[i] = float(v), True
        self._missing = np.where(seen, 0, self._missing + 1)
        if np.any(self._missing >= MISSING_AFTER):
            lost = [ALL_ARM_JOINTS[i] for i in np.flatnonzero(self._missing >= MISSING_AFTER)]
            if not self.fault:
                self.fault = (
                    f"The robot's joint states do not name {', '.join(lost)}: the studio cannot follow this "
                    "robot. Check that it is a Baxter with its standard joint names."
                )
                log.warning(self.fault)
            return None
        self.fault = ""
        if np.any(np.isnan(self.q)):
            return None
        t = self._time(stamp, arrival)
        if t is None:
            return None
        self._last_t = self.t = t
        self._last_arrival = self.arrived = arrival
        g = np.where(np.isnan(self.g), 100.0, self.g)
        return JointStateBatch(t=_ro(np.array([t])), q=_ro(self.q[None, :].copy()), gripper=_ro(g[None, :].copy()))

    def _time(self, stamp: float, arrival: float) -> float | None:
        if self._stamp0 is None or self._last_arrival is None:
            self._stamp0 = stamp
            return 0.0
        t = stamp - self._stamp0
        step, waited = t - self._last_t, max(arrival - self._last_arrival, 1e-3)
        if -REORDER_S < step <= 0:
            return None
        if step <= 0 or step > waited + JUMP_S:
            how = "back" if step <= 0 else "forward"
            self._warn(
                f"The robot's clock jumped {how} by {abs(step - waited):.0f} s; the studio continues its times "
                "from the previous sample."
            )
            t = self._last_t + waited
            self._stamp0 = stamp - t
        return t


@dataclass(frozen=True)
class GripperInfo:
    """One gripper as it reports itself: hardware id, type ("electric", "suction", "custom", "none", or "" not
    heard), calibrated, ready, error, position (percent open) and when its state was last heard (monotonic)."""

    hid: int = DEFAULT_GRIPPER_ID
    kind: str = ""
    calibrated: bool = False
    ready: bool = False
    error: bool = False
    heard: float | None = None


@dataclass(frozen=True)
class AssemblyState:
    """``baxter_core_msgs/AssemblyState``: enabled, stopped (e-stop asserted), error, the button and the source."""

    enabled: bool = False
    stopped: bool = False
    error: bool = False
    estop_button: int = 0
    estop_source: int = 0

    @classmethod
    def from_msg(cls, msg: dict[str, Any]) -> AssemblyState | None:
        try:
            return cls(
                bool(msg.get("enabled")),
                bool(msg.get("stopped")),
                bool(msg.get("error")),
                int(msg.get("estop_button") or 0),
                int(msg.get("estop_source") or 0),
            )
        except (TypeError, ValueError, AttributeError):
            return None

    def why_stopped(self) -> str:
        """Who stopped the robot, in words ("its emergency-stop button", …)."""
        return ESTOP_SOURCES.get(self.estop_source, "its emergency stop")


def gripper_info(old: GripperInfo, msg: dict[str, Any], now: float, *, properties: bool = False) -> GripperInfo:
    """``old`` updated with an ``EndEffectorState`` (or, with ``properties``, an ``EndEffectorProperties``)."""
    hid = msg.get("id")
    hid = hid if isinstance(hid, int) and hid > 0 else old.hid
    if properties:
        ui = msg.get("ui_type")
        kind = GRIPPER_TYPES.get(ui, "custom") if isinstance(ui, int) else old.kind
        return GripperInfo(hid, kind, old.calibrated, old.ready, old.error, old.heard)
    return GripperInfo(hid, old.kind, msg.get("calibrated") == 1, msg.get("ready") == 1, msg.get("error") == 1, now)


def gripper_words(arm: str, g: GripperInfo) -> str:
    """ "" when ``g`` can open and close on command; otherwise why not, in plain words."""
    if g.kind in ("suction", "none", "custom"):
        what = {"suction": "a suction cup", "none": "no gripper", "custom": "a gripper the studio cannot drive"}
        return f"The {arm} arm has {what[g.kind]}: the studio only opens and closes Baxter's electric gripper."
    if g.heard is None:
        return f"The {arm} gripper does not report its state; check that it is attached."
    if g.error:
        return f"The {arm} gripper reports an error: press Calibrate grippers to reset it."
    if not g.calibrated or not g.ready:
        return f"The {arm} gripper is not calibrated: press Calibrate grippers (it opens and closes once)."
    return ""


HALTED = "Emergency stop: the robot halted. Release the emergency stop to move it again."


def robot_health(st: AssemblyState | None, fault: str, ours: bool) -> tuple[bool, bool, bool, str]:
    """(connected, enabled, e-stopped, what is wrong) of a connected robot that reports ``st`` (None: nothing
    heard), with joint-state ``fault`` words, ``ours``: the studio's emergency stop is on."""
    if fault:
        return True, False, ours, fault
    if st is None:
        return True, False, ours, "The robot does not report whether it is enabled: is Baxter's SDK running?"
    if st.stopped:
        if ours:
            return True, False, True, HALTED
        if st.estop_button == ESTOP_BUTTON_PRESSED:
            return (
                True,
                False,
                True,
                ("The robot's emergency-stop button is pressed: turn it to release it, then press Enable robot."),
            )
        return True, False, True, f"The robot is stopped (by {st.why_stopped()}): press Enable robot when it is safe."
    if st.error:
        return True, st.enabled, ours, "The robot reports an error: press Enable robot."
    if not st.enabled:
        return True, False, ours, "The robot is disabled: press Enable robot."
    return True, True, ours, ""


class RobotWatch:
    """Everything the robot reports (joint states, its state, its grippers) and whether it is fresh.

    The callbacks run on roslibpy's thread and take no lock of the backend's.
    """

    def __init__(self, deliver: Callable[[JointStateBatch], None], stale_s: float) -> None:
        self.reader = StateReader()
        self.robot: AssemblyState | None = None
        self.grippers = [GripperInfo(), GripperInfo()]
        self.stale_s = stale_s
        #: When the newest ping that roslibpy's event loop has run was sent (monotonic): messages that arrived
        #: before it have been read, so staleness is the link's, not a busy machine's.
        self.loop_seen = time.monotonic()
        self._deliver = deliver

    def on_joint_state(self, msg: dict[str, Any]) -> None:
        batch = self.reader.on_joint_state(msg)
        if batch is not None:
            self._deliver(batch)

    def on_robot_state(self, msg: dict[str, Any]) -> None:
        st = AssemblyState.from_msg(msg)
        if st is not None:
            self.robot = st

    def on_gripper(self, i: int, msg: dict[str, Any], properties: bool) -> None:
        self.grippers[i] = gripper_info(self.grippers[i], msg, time.monotonic(), properties=properties)
        if not properties and (p := gripper_position(msg)) is not None:
            self.reader.set_gripper(i, p)

    def fresh(self, connected: bool, now: float) -> bool:
        """Joint states arrive: the socket is up, and none is missing for ``stale_s`` by the clock of the event
        loop that reads them (a loop that a loaded machine holds up has not yet read what did arrive)."""
        arrived = self.reader.arrived
        if not connected or arrived is None:
            return False
        return now - arrived <= self.stale_s or self.loop_seen - arrived <= self.stale_s

    def ping(self, sent: float) -> None:
        """Run on the event loop that reads the robot's messages: it has read everything before ``sent``."""
        self.loop_seen = max(self.loop_seen, sent)

    def health(self, connected: bool, ours: bool) -> RobotHealth:
        """The robot's :class:`RobotHealth` (``connected``: the socket is up; ``ours``: the studio's e-stop)."""
        r = self.reader
        if not self.fresh(connected, time.monotonic()):
            why = "Connection to the robot lost" if r.arrived is not None else "Not connected to the robot yet"
            return RobotHealth(False, False, ours, f"{why}: nothing is sent to it.", r.warnings, r.warning)
        c, e, s, msg = robot_health(self.robot, r.fault, ours)
        return RobotHealth(c, e, s, msg, r.warnings, r.warning)

    def gripper_words(self) -> dict[str, str]:
        """arm -> "" when its gripper can open and close on command, otherwise why not (plain words)."""
        return {arm: gripper_words(arm, self.grippers[i]) for i, arm in enumerate(("left", "right"))}

    def state(self, moving: bool) -> RobotState:
        t, q, g = self.reader.measured()
        q, g = np.where(np.isnan(q), 0.0, q), np.where(np.isnan(g), 100.0, g)
        return RobotState(t, _ro(q), _ro(g), moving=moving)

    def check_plan(self, arms: tuple[str, ...], q0: np.ndarray, gripper: np.ndarray) -> float:
        """Refuse, in plain words, a plan of ``arms`` starting at ``q0`` (14,) with ``gripper`` (M, 2) targets
        the robot cannot start now; returns the stream time of the start."""
        if not self.reader.complete:
            raise StudioError(self.reader.fault or "No joint states from the robot yet; check that it is on.")
        words = self.gripper_words()
        why = [words[a] for i, a in enumerate(("left", "right")) if a in arms and np.ptp(gripper[:, i]) > 0.5]
        if any(why):
            raise StudioError(" ".join(w for w in why if w) + " The skill opens and closes the gripper.")
        t, q, _ = self.reader.measured()
        off = float(np.max(np.abs(np.asarray(q0) - q)))
        if off > 0.02:
            raise StudioError(
                f"The robot moved since the run was planned (by {math.degrees(off):.0f}° at one joint); "
                "press Run again to plan from where it is now."
            )
        return t


def gripper_position(msg: dict[str, Any]) -> float | None:
    """Opening (percent, clipped to 0..100) of an ``EndEffectorState``; None when missing or invalid."""
    try:
        p = float(msg.get("position"))  # type: ignore[arg-type]  # None is caught below
    except (TypeError, ValueError):
        return None
    return min(max(p, 0.0), 100.0) if math.isfinite(p) else None


__all__ = [
    "DEFAULT_GRIPPER_ID",
    "AssemblyState",
    "GripperInfo",
    "RobotWatch",
    "StateReader",
    "gripper_info",
    "gripper_position",
    "gripper_words",
    "joint_state",
    "robot_health",
]
