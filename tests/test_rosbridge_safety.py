"""The real-robot backend against a Baxter that misbehaves as real ones do (tests/baxter_bed.py): its own e-stop
pressed during a run or before it, disabled, the link dropped (closed or silent), the speed ratio at its
default, grippers uncalibrated or of another kind, gripper-only joint states, bad stamps, renamed joints."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np
import pytest

from studio.core.errors import StudioError
from studio.core.execution import ExecutionPlan, plan_execution
from studio.core.kinematics import Baxter
from studio.core.types import JointTrajectory
from studio.robot_backend.base import JointStateBatch
from studio.robot_backend.rosbridge import RosbridgeBaxter
from studio.robot_backend.rosbridge_run import PlanClock
from tests.baxter_bed import BaxterBed
from tests.conftest import wait_for

LEFT_CMD = "/robot/limb/left/joint_command"


def swing(q0: np.ndarray, seconds: float = 4.0, amp: float = 0.4, gripper: bool = False) -> JointTrajectory:
    """The left arm swings its shoulder (s0) and elbow (e1) out and back, at the speed limits' ~60 %."""
    t = np.arange(0.0, seconds + 1e-9, 0.01)
    s = 0.5 - 0.5 * np.cos(2 * np.pi * t / seconds)
    q = np.tile(q0[:7], (len(t), 1))
    q[:, 0] += amp * s
    q[:, 3] += amp * s
    g = np.where((t > seconds / 3) & (t < 2 * seconds / 3), 20.0, 100.0) if gripper else np.full(len(t), 100.0)
    z = np.zeros(len(t))
    return JointTrajectory(t, q, z, z, np.ones(len(t), bool), "left", g, t)


def plan_for(robot: RosbridgeBaxter, seconds: float = 4.0, gripper: bool = False) -> ExecutionPlan:
    st = robot.state()
    return plan_execution({"left": swing(st.q, seconds, gripper=gripper)}, st.q, st.gripper, rate_hz=100.0)


@pytest.fixture
def bed() -> Iterator[BaxterBed]:
    b = BaxterBed(gripper_calibrated=True)
    yield b
    b.close()


def connect(bed: BaxterBed) -> RosbridgeBaxter:
    r = RosbridgeBaxter(bed.url, connect_timeout=10.0)
    r.start()
    assert wait_for(lambda: r.has_state), "no joint states from the test bed"
    return r


@pytest.fixture
def robot(bed: BaxterBed) -> Iterator[RosbridgeBaxter]:
    r = connect(bed)
    assert wait_for(lambda: r.health().ready)
    yield r
    r.stop()


def settled(bed: BaxterBed) -> None:
    """Wait until the enable messages of enabling (sent every 50 ms until the robot said so) have all arrived:
    on a loaded machine one still on its way would enable the robot again after a test disables it."""
    last = [-1]

    def quiet() -> bool:
        n = len(bed.by_op("publish", "/robot/set_super_enable"))
        same, last[0] = n == last[0], n
        return same

    def quiet_a_while() -> bool:
        if not quiet():
            return False
        time.sleep(0.3)
        return quiet()

    assert wait_for(quiet_a_while)


def disable(bed: BaxterBed) -> None:
    """The robot disabled from outside (its screen, another program)."""
    settled(bed)
    with bed.lock:
        bed.enabled = False


def test_the_robots_estop_mid_run_ends_it_in_words_and_nothing_is_sent(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    plan = plan_for(robot)
    robot.execute(plan)
    assert wait_for(lambda: robot.progress().t > 1.0)
    pressed = bed.press_estop()
    assert wait_for(lambda: robot.progress().state == "failed")
    p = robot.progress()
    assert p.message.startswith("The robot's emergency stop was pressed at ")
    assert f"{round(p.fraction * 100)} % done" in p.message and 0.1 < p.fraction < 0.9
    assert robot.health().light == "e-stopped"
    time.sleep(0.3)
    n = len(bed.by_op("publish", LEFT_CMD))
    time.sleep(0.3)
    assert len(bed.by_op("publish", LEFT_CMD)) == n, "commands kept streaming after the robot's e-stop"
    assert not bed.commands_after(pressed)  # and the robot obeyed none
    with pytest.raises(StudioError, match="emergency-stop button is pressed"):
        robot.execute(plan_for(robot))


def test_estopped_or_disabled_at_start_is_refused_in_words(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    bed.press_estop()
    assert wait_for(lambda: robot.health().estopped)
    with pytest.raises(StudioError, match="emergency-stop button is pressed"):
        robot.execute(plan_for(robot))
    with pytest.raises(StudioError, match="emergency-stop button is pressed"):
        robot.enable()
    bed.release_estop()
    robot.enable()  # reset, then enable, as robot_enable.py does
    assert robot.health().ready and bed.enabled
    disable(bed)
    assert wait_for(lambda: robot.health().light == "connected")
    with pytest.raises(StudioError, match="The robot is disabled"):
        robot.execute(plan_for(robot))


def test_disabled_mid_run(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    robot.execute(plan_for(robot))
    assert wait_for(lambda: robot.progress().t > 0.5)
    disable(bed)
    assert wait_for(lambda: robot.progress().state == "failed")
    assert robot.progress().message.startswith("The robot was disabled at ")


#: closed: longer than what is left of the 6 s run, and several reconnection attempts refused (2 s apart at most);
#: silent: the link comes back while the run would still be going.
@pytest.mark.parametrize(("seconds", "silent"), [(6.0, False), (3.0, True)], ids=["closed-6s", "silent-3s"])
def test_a_lost_link_fails_the_run_and_nothing_resumes_after_it(
    bed: BaxterBed, robot: RosbridgeBaxter, seconds: float, silent: bool
) -> None:
    robot.execute(plan_for(robot, seconds=6.0))
    assert wait_for(lambda: robot.progress().t > 1.0)
    lost = bed.drop(seconds, silent=silent)
    assert wait_for(lambda: robot.progress().state == "failed")
    assert robot.progress().message.startswith("Connection to the robot lost at ")
    assert robot.health().light == "disconnected"
    # the studio's emergency stop during the outage says it could not be delivered
    assert robot.emergency_stop() == "undelivered"
    assert wait_for(lambda: robot.health().connected, timeout=seconds + 30)  # roslibpy reconnected
    back = time.monotonic()
    time.sleep(1.5)
    assert bed.by_op("publish", LEFT_CMD)[-1][0] < lost + 0.05 or not silent  # nothing queued
    assert not bed.commands_after(back), "commands reached the robot after the link came back"
    assert bed.largest_step_after(lost) < 0.05
    assert robot.progress().state == "failed"


def test_speed_ratio_is_set_for_the_run_and_the_arm_keeps_up(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    """Every command of the run reaches the robot at the full speed ratio (Baxter's default, 0.3, would leave the
    arm behind the plan), the default comes back after it, and the arm comes to rest at the plan's last pose."""
    assert bed.speed_ratio == [0.3, 0.3]  # Baxter's default
    plan = plan_for(robot, seconds=3.0)
    robot.execute(plan)
    assert wait_for(lambda: bed.speed_ratio[0] == 1.0)
    assert wait_for(lambda: robot.progress().state == "done")
    assert wait_for(lambda: bed.speed_ratio[0] == 0.3)  # the default again for moves by hand
    # In the order the robot received them: the full ratio, the run's commands, the default again, then only
    # the hold of the last pose (as after a move by hand).
    with bed.lock:
        sent = [(o["topic"], o.get("msg") or {}) for _, o in bed.ops if o.get("op") == "publish"]
    ratios = [(i, m.get("data")) for i, (topic, m) in enumerate(sent) if topic == "/robot/limb/left/set_speed_ratio"]
    full = next(i for i, r in ratios if r == 1.0)
    default = next(i for i, r in ratios if r == 0.3 and i > full)
    commands = [i for i, (topic, _) in enumerate(sent) if topic == LEFT_CMD]
    assert commands and full < commands[0] < default, (full, commands[:1], default)
    held = [sent[i][1]["command"] for i in commands if i > default]
    assert np.allclose(held, plan.q[-1, :7], atol=1e-9) if held else True

    def at_rest() -> bool:
        with bed.lock:
            return bed.target[0] is not None and bool(np.max(np.abs(bed.q[:7] - bed.target[0])) < 1e-9)

    assert wait_for(at_rest)
    with bed.lock:
        q_end = bed.q[:7].copy()
    assert np.max(np.abs(q_end - plan.q[-1, :7])) < 0.01


def test_grippers_uncalibrated_suction_or_missing_are_refused_in_words() -> None:
    bed = BaxterBed(gripper_calibrated=False)
    robot = connect(bed)
    try:
        assert wait_for(lambda: "not calibrated" in robot.grippers()["left"]), robot.grippers()
        with pytest.raises(StudioError, match="left gripper is not calibrated"):
            robot.execute(plan_for(robot, gripper=True))
        robot.execute(plan_for(robot, seconds=1.0))  # a skill that never moves the gripper runs
        assert wait_for(lambda: robot.progress().state not in ("running", "stopping")), robot.progress()
        assert robot.progress().state == "done", robot.progress()
        robot.calibrate_grippers(("left",))
        assert robot.grippers()["left"] == ""
        robot.execute(plan_for(robot, gripper=True))
        assert wait_for(lambda: robot.progress().state not in ("running", "stopping")), robot.progress()
        assert robot.progress().state == "done", robot.progress()
        assert 20.0 in bed.grippers["left"].gos  # the robot's gripper really closed
    finally:
        robot.stop()
        bed.close()
    for kind, words in (("suction", "suction cup"), ("none", "no gripper")):
        other = BaxterBed(gripper_type=kind)
        r = connect(other)
        try:
            assert wait_for(lambda r=r, words=words: words in r.grippers()["left"]), r.grippers()  # type: ignore[misc]
            with pytest.raises(StudioError, match=words):
                r.execute(plan_for(r, gripper=True))
        finally:
            r.stop()
            other.close()


def test_gripper_only_joint_states_make_no_samples(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    got: list[JointStateBatch] = []
    robot.subscribe(got.append)
    before = dict(bed.sent)
    robot.execute(plan_for(robot, seconds=2.0))
    assert wait_for(lambda: robot.progress().state == "done")
    after, samples = dict(bed.sent), sum(len(b.t) for b in got)
    joints, fingers = after["joints"] - before["joints"], after["fingers"] - before["fingers"]
    assert fingers > 20  # the robot did send finger-only messages meanwhile (2 × 30 a second)
    # one sample per arm message, none per finger message (a few arm messages were on their way at the start)
    assert samples <= joints + 10, f"{samples} samples from {joints} arm and {fingers} finger messages"
    t = np.concatenate([b.t for b in got])
    rate = (len(t) - 1) / (t[-1] - t[0])
    assert rate < 130  # the arm's 100 Hz, not 100 + 2 × 30 Hz of finger messages


def test_bad_stamps_are_dropped_or_rebased_and_the_stream_goes_on(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    got: list[JointStateBatch] = []
    robot.subscribe(got.append)
    assert wait_for(lambda: len(got) > 20)
    bed.stamp_fault("inf")
    assert wait_for(lambda: robot.health().warnings == 1)
    n = len(got)
    assert wait_for(lambda: len(got) > n + 20)
    bed.stamp_fault("back")
    assert wait_for(lambda: "jumped back by 3600 s" in robot.health().warning)
    n = len(got)
    assert wait_for(lambda: len(got) > n + 20), "the stream froze after the clock stepped back"
    t = np.concatenate([b.t for b in got])
    assert np.all(np.diff(t) > 0) and np.all(np.diff(t) < 0.5)
    # a plan still runs, and a move by hand is built on a live pose
    robot.execute(plan_for(robot, seconds=1.0))
    assert wait_for(lambda: robot.progress().state == "done")


def test_a_renamed_joint_is_a_plain_error(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    bed.rename_joint("left_w2", "left_wrist_2")
    assert wait_for(lambda: "left_w2" in robot.health().message)
    assert robot.health().light == "connected" and not robot.has_state
    with pytest.raises(StudioError, match="do not name left_w2"):
        robot.execute(plan_for(robot))


def test_the_studios_estop_is_confirmed_by_the_robot_and_released_by_reset(
    bed: BaxterBed, robot: RosbridgeBaxter
) -> None:
    robot.execute(plan_for(robot))
    assert wait_for(lambda: robot.progress().t > 0.5)
    assert robot.emergency_stop() == "sent"
    assert robot.progress().state == "emergency-stopped"
    assert wait_for(lambda: bed.stopped and robot.health().estopped)
    robot.clear_emergency_stop()
    assert bed.enabled and not bed.stopped and robot.health().ready


def test_the_plan_clock_follows_the_wall_clock_through_a_stall() -> None:
    b = Baxter.load()
    q0 = np.concatenate([b.neutral("left"), b.neutral("right")])
    plan = plan_execution({"left": swing(q0, 4.0)}, q0, np.array([100.0, 100.0]), rate_hz=100.0)
    clock = PlanClock(plan, 0.0, now=10.0)
    for now in (10.01, 10.02, 10.43, 10.44):  # a 0.41 s stall of the command thread
        clock.advance(now)
    assert math.isclose(clock.p, 0.44, abs_tol=1e-9)
    clock.stop(1.0)
    clock.advance(10.94)
    clock.advance(11.50)
    assert clock.progress.state == "stopped" and math.isclose(clock.p, 0.44 + 0.5, abs_tol=1e-6)


def test_kinesthetic_teaching_records_the_robots_own_stamps_and_says_the_rate(bed: BaxterBed, tmp_path) -> None:
    """The paper's data collection on the real robot: the teacher moves the arm by hand (zero-g) while the
    studio records; the take keeps the robot's stamps (no resampling), the gripper from its state topic, no
    finger messages as samples, and the studio says the rate it really got."""
    from studio.controller import Controller
    from studio.storage import SessionStore
    from tests.conftest import RecordingNotifier

    robot = RosbridgeBaxter(bed.url, connect_timeout=10.0)
    notes = RecordingNotifier()
    ctl = Controller(store=SessionStore(tmp_path), session="by-hand", backend=robot, notifier=notes)
    ctl.start()
    try:
        assert wait_for(lambda: robot.health().ready)
        with bed.lock:
            start = bed.q[:7].copy()
        sent0 = bed.sent["joints"]
        ctl.teaching.start_recording()
        bed.guide(start + np.array([0.3, -0.2, 0.0, 0.3, 0.0, 0.2, 0.0]))
        assert wait_for(lambda: np.allclose(robot.state().q[:7], bed.hand, atol=1e-3))  # type: ignore[arg-type]
        with bed.lock:
            bed.grippers["left"].position = 40.0  # the teacher closed the gripper (its state topic says so)
            bed.grippers["left"].target = 40.0
        assert wait_for(lambda: robot.state().gripper[0] == 40.0)
        time.sleep(0.3)
        ctl.teaching.stop_recording()
        sent = bed.sent["joints"] - sent0
        demo = ctl.session.recordings[-1]
        dt = np.diff(demo.t)
        assert 0.005 < float(np.median(dt)) < 0.02  # the robot's ~100 Hz, as stamped, not resampled to 1 kHz
        assert np.all(dt > 0)
        assert demo.gripper[0, 0] == 100.0 and demo.gripper[-1, 0] == 40.0
        np.testing.assert_allclose(demo.q[-1, :7], bed.hand, atol=1e-3)  # type: ignore[arg-type]
        # every sample is one of the robot's joint-state messages (finger messages and resampling make no
        # copies: the robot may report one pose twice, each with its own stamp, but never more samples than it sent)
        assert len(demo) <= sent, (len(demo), sent)
        saved = [body for kind, title, body in notes.notes if title == "Demonstration saved"]
        rate = (len(demo) - 1) / demo.duration
        assert saved and f"{rate:.0f} a second as the robot sent them" in saved[-1], saved
    finally:
        ctl.close()
        ctl.shutdown()


# -- issue 29: never a harmful target (decision 088) ---------------------------------------------------------------
STOP_TOPIC = "/robot/set_super_stop"


def test_the_estop_stops_first_and_never_holds_a_faulty_reading(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    """A reading of 1e6 rad (a faulty encoder) went out as ``left_s0 = 1000000.0`` before the stop: now the stop
    goes first, and a reading outside the joint limits is never a target."""
    with bed.lock:
        bed.q[0] = 1e6
    assert wait_for(lambda: robot.state().q[0] == 1e6)
    before = time.monotonic()
    assert robot.emergency_stop() == "sent"
    assert wait_for(lambda: bed.stopped and bool(bed.by_op("publish", STOP_TOPIC)))
    time.sleep(0.3)
    cmds = [o for t, o in bed.by_op("publish", LEFT_CMD) if t > before]
    assert not cmds, f"a target went out after the e-stop: {cmds[:1]}"
    assert robot.commands_refused >= 1


def test_the_estop_hold_follows_the_stop_and_stays_within_the_limits(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    robot.execute(plan_for(robot))
    assert wait_for(lambda: robot.progress().t > 0.5)
    before = time.monotonic()
    assert robot.emergency_stop() == "sent"
    assert wait_for(lambda: bool(bed.by_op("publish", STOP_TOPIC)))
    time.sleep(0.3)
    stop_at = min(t for t, _ in bed.by_op("publish", STOP_TOPIC) if t > before)
    sent = [(t, o) for t, o in bed.by_op("publish", LEFT_CMD) if t > before]
    holds = [o for t, o in sent if t >= stop_at]
    assert holds, "no hold at the measured joints after the stop"
    # before the stop the run was still streaming its own targets: none of them may be the hold
    held = {tuple(o["msg"]["command"]) for o in holds}
    early = [o for t, o in sent if t < stop_at]
    assert not [o for o in early if tuple(o["msg"]["command"]) in held], "a hold reached the robot before the stop"
    lo, hi = bed.lower[:7], bed.upper[:7]
    for o in holds:
        q = np.array(o["msg"]["command"])
        assert np.all(q >= lo) and np.all(q <= hi)


def test_after_a_lost_link_only_the_speed_ratio_goes_out_until_enable(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    """Baxter keeps a speed ratio until told another (limb.py): a run leaves it at 1; after the link came back the
    studio sets the SDK's 0.3 and sends nothing else until a person presses Enable robot."""
    robot.execute(plan_for(robot, seconds=6.0))
    assert wait_for(lambda: bed.speed_ratio[0] == 1.0 and robot.progress().t > 1.0)
    bed.drop(3.0)
    assert wait_for(lambda: robot.progress().state == "failed")
    assert wait_for(lambda: robot.health().connected, timeout=40)
    back = time.monotonic()
    assert wait_for(lambda: bed.speed_ratio == [0.3, 0.3]), "the speed ratio was left at the run's"
    assert "press Enable robot" in robot.health().message and not robot.health().ready
    with pytest.raises(StudioError, match="Enable robot"):
        robot.command_joints("left", robot.state().q[:7])
    time.sleep(0.5)
    assert not [o for t, o in bed.by_op("publish", LEFT_CMD) if t > back], "a joint command went out before Enable"
    robot.enable()
    assert robot.health().ready
    target = robot.state().q[:7] + np.array([0.05, 0, 0, 0, 0, 0, 0])
    robot.command_joints("left", target)
    assert wait_for(lambda: bool(bed.commands_after(back)))


def test_a_stall_never_replays_late_targets_in_a_burst(bed: BaxterBed, robot: RosbridgeBaxter) -> None:
    """The connection's loop is busy for 0.5 s (a slow listener of the joint states) while the studio holds a
    target at 100 Hz: the targets made meanwhile are dropped, never sent in a burst afterwards."""
    slow = {"once": True}

    def busy(batch: JointStateBatch) -> None:
        if slow["once"] and time.monotonic() > start + 0.2:
            slow["once"] = False
            time.sleep(0.5)

    robot.subscribe(busy)
    start = time.monotonic()
    robot.command_joints("left", robot.state().q[:7] + np.array([0.05, 0, 0, 0, 0, 0, 0]))
    time.sleep(1.2)
    times = np.array([t for t, _ in bed.by_op("publish", LEFT_CMD) if t > start])
    assert times.size > 20 and not slow["once"], (times.size, slow)
    after = times[int(np.argmax(np.diff(times))) + 1]  # the first target after the stall
    # 100 ms after the stall holds about 10 targets at 100 Hz; the 0.5 s stall's own targets replayed would add
    # about 50. Generous: a busy machine delivers a few at once (a quiet fresh clone saw 5 within 30 ms).
    burst = int(np.sum((times >= after) & (times < after + 0.1)))
    assert burst <= 20, f"{burst} targets arrived within 100 ms after the stall"
    # the late targets were dropped (how many depends on how busy the machine is)
    assert robot._link.skipped > 0, (robot._link.skipped, np.round(np.diff(times), 3).tolist())
