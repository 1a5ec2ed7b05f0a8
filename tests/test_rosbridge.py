"""RosbridgeBaxter against a local rosbridge-protocol websocket server written here (a stand-in for
rosbridge_server on a Baxter): topics, message types, op codes, message contents, command rates, joint states
streamed to subscribers, execution, stop and emergency stop; the CLI's --robot option."""

from __future__ import annotations

import asyncio
import json
import threading
import time
from typing import Any

import numpy as np
import pytest

from studio.core.errors import InvalidInput, StudioError
from studio.core.execution import plan_execution
from studio.core.kinematics import Baxter
from studio.core.pipeline import learn_skill
from studio.core.types import ALL_ARM_JOINTS, ARM_JOINTS, Arm
from studio.robot_backend.base import JointStateBatch
from studio.robot_backend.rosbridge import RosbridgeBaxter, parse_robot_url
from tests.conftest import wait_for
from tests.core.teacher_demos import demos

EXPECTED_TYPES = {
    "/robot/joint_states": "sensor_msgs/JointState",
    "/robot/limb/left/joint_command": "baxter_core_msgs/JointCommand",
    "/robot/limb/right/joint_command": "baxter_core_msgs/JointCommand",
    "/robot/end_effector/left_gripper/command": "baxter_core_msgs/EndEffectorCommand",
    "/robot/end_effector/right_gripper/command": "baxter_core_msgs/EndEffectorCommand",
    "/robot/end_effector/left_gripper/state": "baxter_core_msgs/EndEffectorState",
    "/robot/end_effector/right_gripper/state": "baxter_core_msgs/EndEffectorState",
    "/robot/set_super_enable": "std_msgs/Bool",
}
#: Baxter's /robot/joint_states lists every joint, alphabetically, head and grippers included.
BAXTER_NAMES = sorted(["head_pan", "l_gripper_l_finger_joint", "r_gripper_l_finger_joint", *ALL_ARM_JOINTS])


class FakeRosbridge:
    """A rosbridge v2 server (JSON over a websocket) with a position-controlled Baxter behind it.

    It records every operation the client sends, publishes /robot/joint_states at 100 Hz and the grippers'
    states at 10 Hz to subscribers, and moves an arm to each JointCommand it receives.
    """

    def __init__(self) -> None:
        b = Baxter.load()
        self.q = np.concatenate([b.neutral("left"), b.neutral("right")])
        self.grip = np.array([100.0, 100.0])
        self.ops: list[tuple[float, dict[str, Any]]] = []
        self.lock = threading.Lock()
        self.loop = asyncio.new_event_loop()
        self.port = 0
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        assert self._ready.wait(10), "fake rosbridge did not start"

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
            self._ready.set()
            await self._stop.wait()

    def close(self) -> None:
        if self._stop is not None:
            self.loop.call_soon_threadsafe(self._stop.set)
        self.thread.join(timeout=10)

    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.port}"

    async def _handler(self, ws: Any) -> None:
        subs: dict[str, str] = {}

        async def pump() -> None:
            k = 0
            while True:
                await asyncio.sleep(0.01)
                k += 1
                now = time.time()
                stamp = {"secs": int(now), "nsecs": int((now % 1) * 1e9)}
                if "/robot/joint_states" in subs:
                    with self.lock:
                        q = dict(zip(ALL_ARM_JOINTS, self.q.tolist(), strict=True))
                    msg: dict[str, Any] = {
                        "header": {"seq": k, "stamp": stamp, "frame_id": ""},
                        "name": BAXTER_NAMES,
                        "position": [q.get(n, 0.0) for n in BAXTER_NAMES],
                        "velocity": [0.0] * len(BAXTER_NAMES),
                        "effort": [0.0] * len(BAXTER_NAMES),
                    }
                    await ws.send(json.dumps({"op": "publish", "topic": "/robot/joint_states", "msg": msg}))
                for i, arm in enumerate(("left", "right")):
                    topic = f"/robot/end_effector/{arm}_gripper/state"
                    if topic in subs and k % 10 == 0:
                        msg = {"id": 65664 + i, "position": float(self.grip[i]), "calibrated": 1, "ready": 1}
                        await ws.send(json.dumps({"op": "publish", "topic": topic, "msg": msg}))

        task = asyncio.create_task(pump())
        try:
            async for raw in ws:
                op = json.loads(raw)
                with self.lock:
                    self.ops.append((time.monotonic(), op))
                if op.get("op") == "subscribe":
                    subs[op["topic"]] = op.get("type", "")
                elif op.get("op") == "unsubscribe":
                    subs.pop(op.get("topic", ""), None)
                elif op.get("op") == "publish" and op["topic"].endswith("/joint_command"):
                    msg = op["msg"]
                    with self.lock:
                        for n, v in zip(msg["names"], msg["command"], strict=True):
                            self.q[ALL_ARM_JOINTS.index(n)] = v
                elif op.get("op") == "publish" and op["topic"].endswith("_gripper/command"):
                    arm = 0 if "/left_" in op["topic"] else 1
                    self.grip[arm] = json.loads(op["msg"]["args"])["position"]
        except Exception:  # the client closed the connection
            pass
        finally:
            task.cancel()

    def by_op(self, name: str, topic: str | None = None) -> list[tuple[float, dict[str, Any]]]:
        with self.lock:
            return [(t, o) for t, o in self.ops if o.get("op") == name and (topic is None or o.get("topic") == topic)]


@pytest.fixture
def bridge():
    srv = FakeRosbridge()
    yield srv
    srv.close()


@pytest.fixture
def robot(bridge: FakeRosbridge):
    r = RosbridgeBaxter(bridge.url, connect_timeout=10.0)
    r.start()
    assert wait_for(lambda: r.has_state), "no joint states from the fake rosbridge"
    yield r
    r.stop()


def test_speaks_baxters_topics_with_the_right_types_and_op_codes(bridge: FakeRosbridge, robot: RosbridgeBaxter) -> None:
    assert wait_for(lambda: len(bridge.by_op("publish", "/robot/set_super_enable")) == 1)
    with bridge.lock:
        ops = [o for _, o in bridge.ops]
    assert {o["op"] for o in ops} <= {"advertise", "subscribe", "publish", "unadvertise", "unsubscribe"}
    subscribed = {o["topic"]: o["type"] for o in ops if o["op"] == "subscribe"}
    advertised = {o["topic"]: o["type"] for o in ops if o["op"] == "advertise"}
    assert subscribed == {t: EXPECTED_TYPES[t] for t in subscribed} and "/robot/joint_states" in subscribed
    assert set(subscribed) >= {"/robot/end_effector/left_gripper/state", "/robot/end_effector/right_gripper/state"}
    assert advertised == {t: EXPECTED_TYPES[t] for t in advertised}
    assert set(advertised) >= {
        "/robot/limb/left/joint_command",
        "/robot/limb/right/joint_command",
        "/robot/end_effector/left_gripper/command",
        "/robot/end_effector/right_gripper/command",
        "/robot/set_super_enable",
    }
    # every publish is on an advertised topic; enabling the robot is std_msgs/Bool true
    assert all(o["topic"] in advertised for o in ops if o["op"] == "publish")
    assert bridge.by_op("publish", "/robot/set_super_enable")[0][1]["msg"] == {"data": True}


def test_joint_states_reach_the_subscribers_by_name(bridge: FakeRosbridge, robot: RosbridgeBaxter) -> None:
    got: list[JointStateBatch] = []
    robot.subscribe(got.append)
    assert wait_for(lambda: len(got) >= 30)
    t = np.concatenate([b.t for b in got])
    q = np.concatenate([b.q for b in got])
    assert np.all(np.diff(t) > 0)
    rate = (len(t) - 1) / (t[-1] - t[0])
    assert 40 < rate < 140  # the robot's 100 Hz
    np.testing.assert_allclose(q[-1], bridge.q)  # joints matched by name (the message is alphabetical)
    assert wait_for(lambda: robot.state().gripper[0] == 100.0)


def test_joint_states_arrive_while_a_command_holds_the_robot(bridge: FakeRosbridge, robot: RosbridgeBaxter) -> None:
    """roslibpy calls the state callbacks holding its own event lock; if they waited for the command lock, a
    command publishing through roslibpy (start's advertise did, in CI) would wait for them: a deadlock."""
    got: list[JointStateBatch] = []
    robot.subscribe(got.append)
    with robot._lock:  # what start, execute and every command tick hold while they publish
        assert wait_for(lambda: len(got) >= 10), "joint states stopped while a command was being sent"
        assert robot.has_state and robot.state().q.shape == (14,)


def test_joint_commands_are_position_mode_by_name_at_100_hz(bridge: FakeRosbridge, robot: RosbridgeBaxter) -> None:
    target = robot.state().q[:7] + 0.05
    robot.command_joints("left", target)
    time.sleep(0.6)
    cmds = bridge.by_op("publish", "/robot/limb/left/joint_command")
    assert cmds, "no joint command"
    for _, o in cmds:
        m = o["msg"]
        assert m["mode"] == 1 and m["names"] == list(ARM_JOINTS["left"]) and len(m["command"]) == 7
    np.testing.assert_allclose(cmds[-1][1]["msg"]["command"], target)
    times = np.array([t for t, _ in cmds])
    rate = (len(times) - 1) / (times[-1] - times[0])
    # republished at 100 Hz (Baxter drops a command after 0.2 s); a loaded machine (CI) may drop a few ticks
    assert 50 < rate < 130, rate
    assert wait_for(lambda: np.allclose(robot.state().q[:7], target))
    # after the hold time the arm is no longer commanded (it can be guided by hand again)
    time.sleep(1.3)
    n = len(bridge.by_op("publish", "/robot/limb/left/joint_command"))
    time.sleep(0.3)
    assert len(bridge.by_op("publish", "/robot/limb/left/joint_command")) == n
    assert not bridge.by_op("publish", "/robot/limb/right/joint_command")


def test_gripper_commands_go_to_the_grippers_hardware_id(bridge: FakeRosbridge, robot: RosbridgeBaxter) -> None:
    assert wait_for(lambda: robot._state.hardware_id(1) == 65665)  # learned from the gripper's state messages
    robot.command_gripper("right", 35.0)
    assert wait_for(lambda: bool(bridge.by_op("publish", "/robot/end_effector/right_gripper/command")))
    m = bridge.by_op("publish", "/robot/end_effector/right_gripper/command")[-1][1]["msg"]
    assert m["id"] == 65665 and m["command"] == "go" and json.loads(m["args"]) == {"position": 35.0}
    assert isinstance(m["sequence"], int) and m["sender"]
    assert wait_for(lambda: robot.state().gripper[1] == 35.0)


def test_executes_a_plan_streaming_commands_and_stops(bridge: FakeRosbridge, robot: RosbridgeBaxter) -> None:
    sk = learn_skill(list(demos("stack-cup")), arm="left")
    jt = sk.joint_trajectory
    assert jt is not None and jt.gripper is not None and jt.skill_time is not None
    # the first 3 s of the skill is enough to check the streaming
    cut = int(np.searchsorted(jt.t, jt.t[0] + 3.0))
    from studio.core.types import JointTrajectory

    short = JointTrajectory(
        jt.t[:cut],
        jt.q[:cut],
        jt.position_error[:cut],
        jt.orientation_error[:cut],
        jt.converged[:cut],
        "left",
        jt.gripper[:cut],
        jt.skill_time[:cut],
    )
    st = robot.state()
    plan = plan_execution({"left": short}, st.q, st.gripper, rate_hz=100.0)
    n0 = len(bridge.by_op("publish", "/robot/limb/left/joint_command"))
    robot.execute(plan)
    assert robot.progress().state == "running"
    assert wait_for(lambda: robot.progress().fraction > 0.5, timeout=plan.duration + 30)
    with pytest.raises(StudioError, match="already running"):
        robot.execute(plan)
    assert wait_for(lambda: robot.progress().state == "done", timeout=plan.duration + 30)
    cmds = bridge.by_op("publish", "/robot/limb/left/joint_command")[n0:]
    times = np.array([t for t, _ in cmds])
    rate = (len(times) - 1) / (times[-1] - times[0])
    assert 50 < rate < 130, rate
    # the commands walk along the plan and end at its last pose; the fake robot followed
    np.testing.assert_allclose(cmds[-1][1]["msg"]["command"], plan.q[-1, :7], atol=1e-9)
    assert wait_for(lambda: np.allclose(robot.state().q[:7], plan.q[-1, :7]))
    assert not bridge.by_op("publish", "/robot/limb/right/joint_command")  # only the planned arm moves


LEFT_CMD = "/robot/limb/left/joint_command"


def test_emergency_stop_holds_at_once_and_refuses_motion(
    bridge: FakeRosbridge, robot: RosbridgeBaxter, monkeypatch: pytest.MonkeyPatch
) -> None:
    sk = learn_skill(list(demos("stack-cup")), arm="left")
    assert sk.joint_trajectory is not None
    st = robot.state()
    plan = plan_execution({"left": sk.joint_trajectory}, st.q, st.gripper, rate_hz=100.0)
    robot.execute(plan)
    time.sleep(1.0)
    held = robot.state().q[:7].copy()
    n_before = len(bridge.by_op("publish", LEFT_CMD))
    caller, sent = threading.get_ident(), {}
    command = robot._joint_command

    def spy(arm: Arm, q: np.ndarray) -> None:
        if threading.get_ident() == caller:
            sent[arm] = [float(v) for v in q]
        command(arm, q)

    monkeypatch.setattr(robot, "_joint_command", spy)
    robot.emergency_stop()
    # Within one control cycle, whatever the load: the hold of both arms is published by the call itself
    # (not at the command loop's next tick). The time to the bridge is the network's, measured by no test.
    assert sorted(sent) == ["left", "right"]
    assert robot.progress().state == "emergency-stopped"
    np.testing.assert_allclose(sent["left"], held, atol=0.05)
    assert wait_for(lambda: sent["left"] in [m["msg"]["command"] for _, m in bridge.by_op("publish", LEFT_CMD)])
    time.sleep(0.5)
    after = [m["msg"]["command"] for _, m in bridge.by_op("publish", LEFT_CMD)[n_before:]]
    # Commands already on their way arrive before the hold (the websocket keeps the order); after it, nothing.
    assert after[-1] == sent["left"] and after.count(sent["left"]) == 1
    robot.command_joints("left", held + 0.1)  # ignored until released
    time.sleep(0.2)
    assert len(bridge.by_op("publish", LEFT_CMD)) == n_before + len(after)
    with pytest.raises(StudioError, match="emergency-stopped"):
        robot.execute(plan)
    robot.clear_emergency_stop()
    robot.command_joints("left", held + 0.01)
    assert wait_for(lambda: np.allclose(robot.state().q[:7], held + 0.01))


def test_controlled_stop_slows_to_rest(bridge: FakeRosbridge, robot: RosbridgeBaxter) -> None:
    sk = learn_skill(list(demos("stack-cup")), arm="left")
    assert sk.joint_trajectory is not None
    st = robot.state()
    plan = plan_execution({"left": sk.joint_trajectory}, st.q, st.gripper, rate_hz=100.0)
    robot.execute(plan)
    time.sleep(1.5)
    robot.stop_motion()
    assert robot.progress().state == "stopping"
    assert wait_for(lambda: robot.progress().state == "stopped")
    p = robot.progress()
    assert 0 < p.fraction < 0.5 and "stopped" in p.message


def test_unreachable_robot_is_a_plain_error() -> None:
    r = RosbridgeBaxter("ws://127.0.0.1:9", connect_timeout=1.0)
    with pytest.raises(StudioError, match=r"Could not connect to the robot at ws://127\.0\.0\.1:9"):
        r.start()


def test_robot_addresses() -> None:
    assert parse_robot_url("ws://baxter.local:9090") == "ws://baxter.local:9090"
    assert parse_robot_url("192.168.0.10") == "ws://192.168.0.10:9090"
    for bad in ("http://x:9090", "ws://", "ws://x:notaport"):
        with pytest.raises(InvalidInput):
            parse_robot_url(bad)


def test_cli_robot_option_selects_the_rosbridge_backend(monkeypatch: pytest.MonkeyPatch) -> None:
    import studio.app
    from studio import cli

    seen: dict[str, Any] = {}
    monkeypatch.setattr(studio.app, "serve", lambda **kw: seen.update(kw))
    assert cli.main(["serve", "--robot", "ws://10.0.0.5:9090", "--port", "8123"]) == 0
    assert isinstance(seen["backend"], RosbridgeBaxter) and seen["backend"].url == "ws://10.0.0.5:9090"
    seen.clear()
    assert cli.main(["serve"]) == 0
    assert seen["backend"] is None  # the default stays the simulated robot
    assert cli.main(["serve", "--robot", "http://nope"]) == 2
