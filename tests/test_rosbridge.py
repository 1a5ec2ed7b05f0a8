"""RosbridgeBaxter against the Baxter test bed (tests/baxter_bed.py, a rosbridge server with a Baxter built from
the SDK's sources): topics, message types, op codes, message contents, command rates, joint states streamed to
subscribers, execution, stop and emergency stop; the CLI's --robot option. The robot's faults are in
tests/test_rosbridge_safety.py."""

from __future__ import annotations

import json
import threading
import time
from typing import Any

import numpy as np
import pytest

from studio.core.errors import InvalidInput, StudioError
from studio.core.execution import plan_execution
from studio.core.pipeline import learn_skill
from studio.core.types import ARM_JOINTS, Arm
from studio.robot_backend.base import JointStateBatch
from studio.robot_backend.rosbridge import RosbridgeBaxter, parse_robot_url
from tests.baxter_bed import BaxterBed
from tests.conftest import quiet_for, wait_for
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
    "/robot/set_super_reset": "std_msgs/Empty",
    "/robot/set_super_stop": "std_msgs/Empty",
    "/robot/state": "baxter_core_msgs/AssemblyState",
    "/robot/end_effector/left_gripper/properties": "baxter_core_msgs/EndEffectorProperties",
    "/robot/end_effector/right_gripper/properties": "baxter_core_msgs/EndEffectorProperties",
    "/robot/limb/left/set_speed_ratio": "std_msgs/Float64",
    "/robot/limb/right/set_speed_ratio": "std_msgs/Float64",
}


@pytest.fixture
def bridge():
    srv = BaxterBed(gripper_calibrated=True)
    yield srv
    srv.close()


@pytest.fixture
def robot(bridge: BaxterBed):
    r = RosbridgeBaxter(bridge.url, connect_timeout=10.0)
    r.start()
    assert wait_for(lambda: r.has_state and r.health().ready), "the test bed's robot is not ready"
    yield r
    r.stop()


def test_speaks_baxters_topics_with_the_right_types_and_op_codes(bridge: BaxterBed, robot: RosbridgeBaxter) -> None:
    assert wait_for(lambda: len(bridge.by_op("publish", "/robot/set_super_enable")) >= 1)
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


def test_joint_states_reach_the_subscribers_by_name(bridge: BaxterBed, robot: RosbridgeBaxter) -> None:
    got: list[JointStateBatch] = []
    robot.subscribe(got.append)
    assert wait_for(lambda: len(got) >= 30)
    t = np.concatenate([b.t for b in got])
    q = np.concatenate([b.q for b in got])
    assert np.all(np.diff(t) > 0)
    rate = (len(t) - 1) / (t[-1] - t[0])
    assert 40 < rate < 140  # the robot's 100 Hz
    with bridge.lock:
        q_robot = bridge.q.copy()
    np.testing.assert_allclose(q[-1], q_robot)  # joints matched by name (the message is alphabetical)
    assert wait_for(lambda: robot.state().gripper[0] == 100.0)


def test_joint_states_arrive_while_a_command_holds_the_robot(bridge: BaxterBed, robot: RosbridgeBaxter) -> None:
    """roslibpy calls the state callbacks holding its own event lock; if they waited for the command lock, a
    command publishing through roslibpy (start's advertise did, in CI) would wait for them: a deadlock."""
    got: list[JointStateBatch] = []
    robot.subscribe(got.append)
    with robot._lock:  # what start, execute and every command tick hold while they publish
        assert wait_for(lambda: len(got) >= 10), "joint states stopped while a command was being sent"
        assert robot.has_state and robot.state().q.shape == (14,)


def test_joint_commands_are_position_mode_by_name_at_100_hz(bridge: BaxterBed, robot: RosbridgeBaxter) -> None:
    target = robot.state().q[:7] + 0.05
    robot.command_joints("left", target)
    assert wait_for(lambda: len(bridge.by_op("publish", "/robot/limb/left/joint_command")) >= 40)
    cmds = bridge.by_op("publish", "/robot/limb/left/joint_command")
    assert cmds, "no joint command"
    for _, o in cmds:
        m = o["msg"]
        assert m["mode"] == 1 and m["names"] == list(ARM_JOINTS["left"]) and len(m["command"]) == 7
    np.testing.assert_allclose(cmds[-1][1]["msg"]["command"], target)
    times = np.array([t for t, _ in cmds])
    rate = (len(times) - 1) / (times[-1] - times[0])
    # republished at 100 Hz (Baxter drops a command after 0.2 s), never faster; a loaded machine delays ticks (a
    # late one is not caught up): the floor is generous
    assert 20 < rate < 130, rate
    assert wait_for(lambda: np.allclose(robot.state().q[:7], target))
    # after the hold time the arm is no longer commanded (it can be guided by hand again)
    assert quiet_for(lambda: len(bridge.by_op("publish", "/robot/limb/left/joint_command")), 0.3, timeout=5)
    assert not bridge.by_op("publish", "/robot/limb/right/joint_command")


def test_gripper_commands_go_to_the_grippers_hardware_id(bridge: BaxterBed, robot: RosbridgeBaxter) -> None:
    assert wait_for(lambda: robot.grippers()["right"] == "")  # its state and type heard: ready to command
    robot.command_gripper("right", 35.0)
    assert wait_for(lambda: bool(bridge.by_op("publish", "/robot/end_effector/right_gripper/command")))
    m = bridge.by_op("publish", "/robot/end_effector/right_gripper/command")[-1][1]["msg"]
    assert m["id"] == 65539 and m["command"] == "go" and json.loads(m["args"]) == {"position": 35.0}
    assert isinstance(m["sequence"], int) and m["sender"]
    assert wait_for(lambda: robot.state().gripper[1] == 35.0)


def test_executes_a_plan_streaming_commands_and_stops(bridge: BaxterBed, robot: RosbridgeBaxter) -> None:
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

    def commands() -> list:
        return bridge.by_op("publish", "/robot/limb/left/joint_command")[n0:]

    # the commands walk along the plan and end at its last pose (the last may still be on its way); the fake
    # robot followed
    assert wait_for(lambda: np.allclose(commands()[-1][1]["msg"]["command"], plan.q[-1, :7], atol=1e-9))
    cmds = commands()
    times = np.array([t for t, _ in cmds])
    rate = (len(times) - 1) / (times[-1] - times[0])
    # 100 Hz, never faster; a loaded machine delays ticks (a late one is not caught up): the floor is generous
    assert 20 < rate < 130, rate
    assert wait_for(lambda: np.allclose(robot.state().q[:7], plan.q[-1, :7]))
    assert not bridge.by_op("publish", "/robot/limb/right/joint_command")  # only the planned arm moves


LEFT_CMD = "/robot/limb/left/joint_command"


def test_emergency_stop_holds_at_once_and_refuses_motion(
    bridge: BaxterBed, robot: RosbridgeBaxter, monkeypatch: pytest.MonkeyPatch
) -> None:
    sk = learn_skill(list(demos("stack-cup")), arm="left")
    assert sk.joint_trajectory is not None
    st = robot.state()
    plan = plan_execution({"left": sk.joint_trajectory}, st.q, st.gripper, rate_hz=100.0)
    robot.execute(plan)
    assert wait_for(lambda: robot.progress().t > 1.0)
    held = robot.state().q[:7].copy()
    n_before = len(bridge.by_op("publish", LEFT_CMD))
    caller, sent = threading.get_ident(), {}
    command = robot._joint_command

    def spy(arm: Arm, q: np.ndarray) -> None:
        if threading.get_ident() == caller:
            sent[arm] = [float(v) for v in q]
        command(arm, q)

    monkeypatch.setattr(robot, "_joint_command", spy)
    assert robot.emergency_stop() == "sent"
    # the robot's own stop follows the hold: the robot confirms it (its state says stopped)
    assert wait_for(lambda: bridge.stopped and "halted" in robot.health().message)  # heard back from the robot
    assert robot.health().estopped
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
    with pytest.raises(StudioError, match="emergency stop is on"):
        robot.command_joints("left", held + 0.1)  # refused until released
    time.sleep(0.2)
    assert len(bridge.by_op("publish", LEFT_CMD)) == n_before + len(after)
    with pytest.raises(StudioError, match="emergency stop is on"):
        robot.execute(plan)
    robot.clear_emergency_stop()
    robot.command_joints("left", held + 0.01)
    assert wait_for(lambda: np.allclose(robot.state().q[:7], held + 0.01))


def test_controlled_stop_slows_to_rest(bridge: BaxterBed, robot: RosbridgeBaxter) -> None:
    sk = learn_skill(list(demos("stack-cup")), arm="left")
    assert sk.joint_trajectory is not None
    st = robot.state()
    plan = plan_execution({"left": sk.joint_trajectory}, st.q, st.gripper, rate_hz=100.0)
    robot.execute(plan)
    assert wait_for(lambda: robot.progress().t > 1.5)
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
