"""A Baxter behind a rosbridge v2 server, for conformance tests and bench/bench_robot.py.

Built from the Baxter SDK's sources (baxter_interface ``robot_enable.py``, ``limb.py``, ``gripper.py``;
baxter_core_msgs ``AssemblyState``, ``JointCommand``, ``EndEffectorCommand``/``State``/``Properties``) and
rosbridge's ROSBRIDGE_PROTOCOL.md, not from the studio's backend. JSON ops over a websocket on 127.0.0.1:

* ``/robot/joint_states``: the 17 joints, alphabetical, stamped with the robot's clock (wall time), at
  ``joint_rate``; gripper-only JointState messages (``l_gripper_l_finger_joint`` …) at ``finger_rate``.
* ``/robot/state`` (AssemblyState) at ``state_rate``; ``/robot/set_super_enable`` (Bool),
  ``/robot/set_super_reset`` and ``/robot/set_super_stop`` (Empty) behave as ``robot_enable.py`` expects;
  the e-stop button (``press_estop`` / ``release_estop``) stops and disables the robot until a reset.
* ``/robot/limb/<arm>/joint_command`` mode 1 moves the arm towards the target at ``speed_ratio`` × the joint
  velocity limits (``set_speed_ratio``, Float64, default 0.3) — only while enabled; no command timeout.
* Grippers: ``state`` and ``properties`` per arm; commands addressed to another id are ignored; "go" does
  nothing until "calibrate" (which takes ``calibrate_s``); suction or no gripper via ``gripper_type``.
* Faults: ``drop(seconds, silent=)`` (close every socket and refuse new ones, or go silent), ``stamp_fault``
  (Infinity, an hour back), ``rename_joint``, ``slow`` (the robot computer publishes late).
"""

from __future__ import annotations

import asyncio
import json
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from studio.core.kinematics import Baxter
from studio.core.types import ALL_ARM_JOINTS, Arm

ARMS: tuple[Arm, Arm] = ("left", "right")
NAMES = sorted(["head_nod", "head_pan", "torso_t0", *ALL_ARM_JOINTS])
FINGERS = {"left": ["l_gripper_l_finger_joint", "l_gripper_r_finger_joint"],
           "right": ["r_gripper_l_finger_joint", "r_gripper_r_finger_joint"]}  # fmt: skip
# AssemblyState constants (baxter_core_msgs/msg/AssemblyState.msg)
ESTOP_BUTTON_UNPRESSED, ESTOP_BUTTON_PRESSED, ESTOP_BUTTON_UNKNOWN, ESTOP_BUTTON_RELEASED = 0, 1, 2, 3
ESTOP_SOURCE_NONE, ESTOP_SOURCE_USER, ESTOP_SOURCE_UNKNOWN = 0, 1, 2
# EndEffectorProperties.ui_type
UI_TYPE = {"none": 0, "suction": 1, "electric": 2, "custom": 3}
GRIPPER_IDS = {"left": 65538, "right": 65539}


@dataclass
class Gripper:
    kind: str = "electric"
    hid: int = 65538
    calibrated: bool = False
    calibrate_at: float | None = None
    error: bool = False
    position: float = 0.0
    target: float = 0.0
    gos: list[float] = field(default_factory=list)


class BaxterBed:
    """The robot and its rosbridge server (see the module docstring). ``close()`` when done."""

    def __init__(
        self,
        *,
        joint_rate: float = 100.0,
        state_rate: float = 20.0,
        finger_rate: float = 30.0,
        enabled: bool = False,
        gripper_type: str = "electric",
        gripper_calibrated: bool = False,
        calibrate_s: float = 0.3,
        speed_ratio: float = 0.3,
    ) -> None:
        b = Baxter.load()
        self.baxter = b
        self.vmax = np.concatenate([b.velocity_limits(a) for a in ARMS])
        self.lower = np.concatenate([b.lower_limits(a) for a in ARMS])
        self.upper = np.concatenate([b.upper_limits(a) for a in ARMS])
        self.q = np.concatenate([b.neutral("left"), b.neutral("right")])
        self.target: list[np.ndarray | None] = [None, None]
        self.speed_ratio = [float(speed_ratio)] * 2
        self.joint_rate, self.state_rate, self.finger_rate = joint_rate, state_rate, finger_rate
        self.enabled, self.stopped, self.error = bool(enabled), False, False
        self.estop_button, self.estop_source = ESTOP_BUTTON_UNPRESSED, ESTOP_SOURCE_NONE
        self.grippers = {
            a: Gripper(gripper_type, GRIPPER_IDS[a], gripper_calibrated, position=100.0, target=100.0) for a in ARMS
        }
        self.calibrate_s = calibrate_s
        self.lock = threading.Lock()
        self.ops: list[tuple[float, dict[str, Any]]] = []
        #: (receive time, arm, target, the arm's joints then) of every joint command the robot obeyed
        self.commands: list[tuple[float, str, np.ndarray, np.ndarray]] = []
        self.hand: np.ndarray | None = None
        self.hand_speed = 0.5
        self.stamp_offset = 0.0
        self._stamp_once: float | None = None
        self._epoch = time.time() - time.monotonic()  # the robot's clock: wall time of a monotonic instant
        self._tick = time.monotonic()
        #: how many arm and finger-only JointState messages reached a subscriber
        self.sent = {"joints": 0, "fingers": 0}
        self.renamed: dict[str, str] = {}
        self.delay = 0.0
        self._refuse_until = 0.0
        self._silent_until = 0.0
        self._sockets: set[Any] = set()
        self._subs: dict[Any, set[str]] = {}
        self._out: dict[Any, asyncio.Queue[str]] = {}
        self.connections = 0
        self.loop = asyncio.new_event_loop()
        self.port = 0
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self.thread = threading.Thread(target=self._run, name="baxter-bed", daemon=True)
        self.thread.start()
        assert self._ready.wait(10), "the Baxter test bed did not start"

    # -- the robot, as a person or a fault acts on it --------------------------------------------------------
    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.port}"

    def press_estop(self) -> float:
        """The red button: stopped, disabled; returns the time (monotonic) it was pressed."""
        with self.lock:
            self.stopped, self.enabled = True, False
            self.estop_button, self.estop_source = ESTOP_BUTTON_PRESSED, ESTOP_SOURCE_USER
            self.target = [None, None]
            return time.monotonic()  # the studio hears of it with the next /robot/state message

    def release_estop(self) -> None:
        """The button turned back: still stopped until a reset (robot_enable.py)."""
        with self.lock:
            if self.estop_button == ESTOP_BUTTON_PRESSED:
                self.estop_button = ESTOP_BUTTON_RELEASED

    def drop(self, seconds: float, silent: bool = False) -> float:
        """Lose the link for ``seconds``: close every socket and refuse new ones, or (``silent``) keep the
        sockets but send nothing and ignore everything received. Returns the time (monotonic) it dropped."""
        t = time.monotonic()
        if silent:
            self._silent_until = t + seconds
        else:
            self._refuse_until = t + seconds
            for ws in list(self._sockets):
                asyncio.run_coroutine_threadsafe(ws.close(), self.loop)
        return t

    def stamp_fault(self, kind: str) -> None:
        """ "inf": the next arm joint state's stamp is Infinity; "back": the clock steps back an hour from now on."""
        if kind == "inf":
            self._stamp_once = math.inf
        elif kind == "back":
            self.stamp_offset -= 3600.0
        else:
            raise ValueError(kind)

    def guide(self, q_left: np.ndarray, speed: float = 0.5) -> None:
        """The teacher squeezes the left cuff (zero-g) and moves the arm by hand towards ``q_left`` (7,)."""
        with self.lock:
            self.hand = np.array(q_left, dtype=np.float64)
            self.hand_speed = speed

    def rename_joint(self, old: str, new: str) -> None:
        self.renamed[old] = new

    def slow(self, delay: float) -> None:
        """The robot computer answers ``delay`` seconds late (each message it sends waits that long)."""
        self.delay = delay

    def by_op(self, name: str, topic: str | None = None) -> list[tuple[float, dict[str, Any]]]:
        with self.lock:
            return [(t, o) for t, o in self.ops if o.get("op") == name and (topic is None or o.get("topic") == topic)]

    def largest_step_after(self, t: float) -> float:
        """Largest distance (rad, one joint) between a command received after ``t`` (monotonic) and where the
        arm was when it arrived: 0 when nothing commanded it."""
        with self.lock:
            steps = [float(np.max(np.abs(tgt - at))) for tt, _, tgt, at in self.commands if tt > t]
        return max(steps, default=0.0)

    def commands_after(self, t: float) -> list[tuple[float, str, np.ndarray, np.ndarray]]:
        with self.lock:
            return [c for c in self.commands if c[0] > t]

    def close(self) -> None:
        if self._stop is not None:
            self.loop.call_soon_threadsafe(self._stop.set)
        self.thread.join(timeout=10)

    # -- server ----------------------------------------------------------------------------------------------
    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        try:
            self.loop.run_until_complete(self._main())
        finally:
            self.loop.close()

    async def _main(self) -> None:
        from websockets.asyncio.server import serve

        self._stop = asyncio.Event()
        async with serve(self._handler, "127.0.0.1", 0) as server:
            self.port = next(iter(server.sockets)).getsockname()[1]
            tasks = [asyncio.create_task(self._physics())]
            tasks += [asyncio.create_task(self._every(1.0 / r, f)) for r, f in self._publishers()]
            self._ready.set()
            await self._stop.wait()
            for t in tasks:
                t.cancel()

    def _publishers(self) -> list[tuple[float, Any]]:
        return [
            (self.joint_rate, self._send_joints),
            (self.state_rate, self._send_state),
            (self.finger_rate, self._send_fingers),
            (10.0, self._send_grippers),
        ]

    async def _every(self, period: float, fn: Any) -> None:
        nxt = time.monotonic()
        while True:
            nxt += period
            await asyncio.sleep(max(0.0, nxt - time.monotonic()))
            if self.delay:
                await asyncio.sleep(self.delay)
            self._tick = nxt  # the robot stamps a message when it samples, however late this loop sends it
            fn()

    async def _handler(self, ws: Any) -> None:
        if time.monotonic() < self._refuse_until:
            await ws.close()
            return
        self._sockets.add(ws)
        self._subs[ws] = set()
        out: asyncio.Queue[str] = asyncio.Queue()
        self._out[ws] = out
        self.connections += 1
        writer = asyncio.create_task(self._writer(ws, out))
        try:
            async for raw in ws:
                if time.monotonic() < self._silent_until:
                    continue
                op = json.loads(raw)
                with self.lock:
                    self.ops.append((time.monotonic(), op))
                if op.get("op") == "subscribe":
                    self._subs[ws].add(op["topic"])
                elif op.get("op") == "unsubscribe":
                    self._subs[ws].discard(op.get("topic", ""))
                elif op.get("op") == "publish":
                    self._on_publish(op["topic"], op.get("msg") or {})
        except Exception:  # the client went away
            pass
        finally:
            writer.cancel()
            self._sockets.discard(ws)
            self._subs.pop(ws, None)
            self._out.pop(ws, None)

    def _publish(self, topic: str, msg: dict[str, Any]) -> int:
        """Queue ``msg`` to every subscriber of ``topic``; returns how many."""
        if time.monotonic() < self._silent_until:
            return 0
        text = json.dumps({"op": "publish", "topic": topic, "msg": msg})
        n = 0
        for ws, subs in list(self._subs.items()):
            if topic in subs and ws in self._out:
                self._out[ws].put_nowait(text)
                n += 1
        return n

    @staticmethod
    async def _writer(ws: Any, out: asyncio.Queue[str]) -> None:
        try:
            while True:
                await ws.send(await out.get())
        except Exception:  # closed
            pass

    # -- what the robot does with what it hears --------------------------------------------------------------
    def _on_publish(self, topic: str, msg: dict[str, Any]) -> None:
        with self.lock:
            if topic == "/robot/set_super_enable":
                if not self.stopped and not self.error:
                    self.enabled = bool(msg.get("data"))
            elif topic == "/robot/set_super_reset":
                if not (self.stopped and self.estop_button == ESTOP_BUTTON_PRESSED):
                    self.stopped = self.error = self.enabled = False
                    self.estop_button, self.estop_source = ESTOP_BUTTON_UNPRESSED, ESTOP_SOURCE_NONE
            elif topic == "/robot/set_super_stop":
                self.stopped, self.enabled = True, False
                self.estop_button, self.estop_source = ESTOP_BUTTON_UNKNOWN, ESTOP_SOURCE_UNKNOWN
                self.target = [None, None]
            elif topic.startswith("/robot/limb/"):
                self._on_limb(topic.split("/")[3], topic.split("/")[4], msg)
            elif topic.startswith("/robot/end_effector/") and topic.endswith("_gripper/command"):
                self._on_gripper(topic.split("/")[3].split("_")[0], msg)

    def _on_limb(self, arm: str, what: str, msg: dict[str, Any]) -> None:
        i = ARMS.index(arm)
        if what == "set_speed_ratio":
            self.speed_ratio[i] = float(min(max(float(msg.get("data", 0.3)), 0.0), 1.0))
        elif what == "joint_command" and msg.get("mode") == 1 and self.enabled and not self.stopped:
            cols = slice(0, 7) if arm == "left" else slice(7, 14)
            tgt = self.q[cols].copy() if self.target[i] is None else np.array(self.target[i])
            for n, v in zip(msg.get("names", []), msg.get("command", []), strict=False):
                if n in ALL_ARM_JOINTS[cols]:
                    tgt[ALL_ARM_JOINTS.index(n) - cols.start] = float(v)
            new = np.clip(tgt, self.lower[cols], self.upper[cols])
            self.target[i] = new
            self.commands.append((time.monotonic(), arm, new.copy(), self.q[cols].copy()))

    def _on_gripper(self, arm: str, msg: dict[str, Any]) -> None:
        g = self.grippers["left" if arm == "left" else "right"]
        if msg.get("id") != g.hid or g.kind != "electric":
            return
        cmd = msg.get("command")
        if cmd == "calibrate":
            g.calibrated, g.calibrate_at = False, time.monotonic() + self.calibrate_s
        elif cmd == "clear_calibration":
            g.calibrated = False
        elif cmd == "reset":
            g.error = False
        elif cmd == "go" and g.calibrated and not g.error and self.enabled:  # uncalibrated: silently nothing
            pos = float(json.loads(msg.get("args") or "{}").get("position", g.target))
            g.target = min(max(pos, 0.0), 100.0)
            g.gos.append(g.target)

    async def _physics(self) -> None:
        last = time.monotonic()
        while True:
            await asyncio.sleep(0.002)
            now = time.monotonic()
            dt, last = now - last, now  # a real arm keeps moving while this loop waits for the CPU
            with self.lock:
                if self.hand is not None:  # moved by hand in zero-g: the arm goes where the teacher takes it
                    by_hand = self.hand_speed * dt
                    self.q[:7] += np.clip(self.hand - self.q[:7], -by_hand, by_hand)
                    self.target[0] = None
                for i, arm in enumerate(ARMS):
                    tgt = self.target[i]
                    if tgt is None or not self.enabled or self.stopped:
                        continue
                    cols = slice(0, 7) if arm == "left" else slice(7, 14)
                    step = self.vmax[cols] * self.speed_ratio[i] * dt
                    self.q[cols] += np.clip(tgt - self.q[cols], -step, step)
                for g in self.grippers.values():
                    if g.calibrate_at is not None and now >= g.calibrate_at:
                        g.calibrated, g.calibrate_at, g.position, g.target = True, None, 100.0, 100.0
                    g.position += float(np.clip(g.target - g.position, -200.0 * dt, 200.0 * dt))

    def _stamp(self, arm: bool = False) -> dict[str, Any]:
        s = self._epoch + self._tick + self.stamp_offset
        if arm and self._stamp_once is not None:  # a finger-only message must not take the arm's bad stamp
            s, self._stamp_once = self._stamp_once, None
            return {"secs": s, "nsecs": 0}
        return {"secs": int(s), "nsecs": int((s % 1) * 1e9)}

    def _send_joints(self) -> None:
        with self.lock:
            q = dict(zip(ALL_ARM_JOINTS, self.q.tolist(), strict=True))
        names = [self.renamed.get(n, n) for n in NAMES]
        msg = {
            "header": {"seq": 0, "stamp": self._stamp(arm=True), "frame_id": ""},
            "name": names,
            "position": [q.get(n, 0.0) for n in NAMES],
            "velocity": [0.0] * len(NAMES),
            "effort": [0.0] * len(NAMES),
        }
        if self._publish("/robot/joint_states", msg):
            self.sent["joints"] += 1

    def _send_fingers(self) -> None:
        for arm in ARMS:
            g = self.grippers[arm]
            if g.kind != "electric":
                continue
            w = 0.0208 * g.position / 100.0
            msg = {
                "header": {"seq": 0, "stamp": self._stamp(), "frame_id": ""},
                "name": FINGERS[arm],
                "position": [w, -w],
                "velocity": [0.0, 0.0],
                "effort": [0.0, 0.0],
            }
            if self._publish("/robot/joint_states", msg):
                self.sent["fingers"] += 1

    def _send_state(self) -> None:
        with self.lock:
            msg = {
                "ready": self.enabled and not self.stopped,
                "enabled": self.enabled,
                "stopped": self.stopped,
                "error": self.error,
                "estop_button": self.estop_button,
                "estop_source": self.estop_source,
            }
        self._publish("/robot/state", msg)

    def _send_grippers(self) -> None:
        for arm in ARMS:
            g = self.grippers[arm]
            base = f"/robot/end_effector/{arm}_gripper/"
            self._publish(base + "properties", {"id": g.hid, "ui_type": UI_TYPE[g.kind], "product": g.kind})
            if g.kind == "none":
                continue
            state = {
                "id": g.hid,
                "enabled": 1,
                "calibrated": int(g.calibrated),
                "ready": int(g.calibrated and not g.error),
                "moving": int(abs(g.target - g.position) > 0.5),
                "gripping": 0,
                "missed": 0,
                "error": int(g.error),
                "position": g.position,
                "force": 0.0,
            }
            self._publish(base + "state", state)
