"""Run on robot when the robot itself misbehaves (the simulated Baxter's faults, as a real one's): its e-stop
button pressed mid-run or before, disabled, the connection lost — each ends in the right words, never "the skill
works", and nothing moves afterwards until the teacher starts a new run; a pose outside the joint limits is
refused in words; moves by hand are built from the measured pose."""

from __future__ import annotations

import numpy as np
import pytest

from studio.controller import Controller
from studio.core.errors import StudioError
from studio.robot_backend.simulated import SimulatedBaxter
from tests.conftest import Collector, RecordingNotifier, wait_for
from tests.test_controller_execution import drive, make, rig, trained  # noqa: F401 - fixtures

Rig = tuple[Controller, SimulatedBaxter, RecordingNotifier]


def still_after(stream: Collector, t0: float) -> bool:
    t, q, _ = stream.arrays()
    after = q[t > t0]
    return len(after) > 100 and float(np.abs(after - after[0]).max()) == 0.0


def test_the_robots_estop_button_mid_run(rig: Rig) -> None:  # noqa: F811 - the fixture
    ctl, sim, notes = rig
    stream = Collector()
    sim.subscribe(stream)
    ctl.execution.run()
    drive(ctl, sim, until_fraction=0.3)
    sim.press_estop_button()
    t_press = sim.state().t
    sim.step(500)
    assert wait_for(lambda: not ctl.execution.running)
    st = ctl.execution.status
    assert st.phase == "failed" and st.ok is False
    assert st.message.startswith("The robot's emergency stop was pressed at ") and "% done." in st.message
    pct = int(st.message.split("the skill was ")[1].split(" %")[0])
    assert 25 <= pct <= 35
    assert st.result.startswith(f"The skill did not work: the robot did {pct} % of the run")
    assert "works" not in st.result
    assert wait_for(lambda: ("warning", "The run on the robot failed", st.result) in notes.notes)
    assert still_after(stream, t_press + 2e-3)  # halted at once, and nothing moved it since
    assert ctl.execution.robot.health().light == "e-stopped"
    assert "emergency-stop button is pressed" in ctl.execution.why_not()
    with pytest.raises(StudioError, match="emergency-stop button is pressed"):
        ctl.execution.run()
    with pytest.raises(StudioError, match="emergency-stop button is pressed"):
        ctl.teaching.move_joint(0, 0.1)
    with pytest.raises(StudioError, match="turn it to release it"):
        ctl.execution.robot.enable()
    sim.release_estop_button()
    assert ctl.execution.why_not().startswith("The robot is stopped")  # released, but not reset yet
    ctl.execution.robot.enable()
    assert ctl.execution.why_not() == "" and ctl.execution.robot.health().light == "enabled"
    sim.step(300)
    assert still_after(stream, t_press + 2e-3)  # the old plan never resumes


def test_estopped_or_disabled_before_the_run(rig: Rig) -> None:  # noqa: F811 - the fixture
    ctl, sim, _ = rig
    sim.press_estop_button()
    with pytest.raises(StudioError, match="emergency-stop button is pressed"):
        ctl.execution.run()
    assert ctl.execution.status.phase == "idle" and ctl.execution.plan is None
    sim.release_estop_button()
    ctl.execution.robot.enable()
    sim.disable()
    assert ctl.execution.why_not() == "The robot is disabled: press Enable robot."
    with pytest.raises(StudioError, match="disabled"):
        ctl.execution.run()
    ctl.execution.robot.enable()
    ctl.execution.run()
    drive(ctl, sim, until_fraction=0.2)
    sim.disable()
    sim.step(200)
    assert wait_for(lambda: not ctl.execution.running)
    st = ctl.execution.status
    assert st.phase == "failed" and st.message.startswith("The robot was disabled at ") and not st.ok


def test_connection_lost_mid_run_and_the_emergency_stop_during_it(rig: Rig) -> None:  # noqa: F811 - the fixture
    ctl, sim, _ = rig
    ctl.execution.run()
    drive(ctl, sim, until_fraction=0.3)
    sim.drop_link()
    q_lost = sim.true_state()[0]
    sim.step(3000)  # 3 s without a word from the robot
    assert wait_for(lambda: not ctl.execution.running)
    st = ctl.execution.status
    assert st.phase == "failed" and st.message.startswith("Connection to the robot lost at ") and not st.ok
    assert ctl.execution.robot.health().light == "disconnected"
    ctl.execution.emergency_stop()
    st = ctl.execution.status
    assert st.estop and st.message.startswith("The emergency stop could not be delivered")
    assert "halted" not in st.message
    sim.restore_link()
    sim.step(500)
    np.testing.assert_array_equal(sim.true_state()[0], q_lost)  # nothing moved, nothing resumed


def test_a_pose_outside_the_limits_is_refused_in_words(rig: Rig) -> None:  # noqa: F811 - the fixture
    from studio.core.execution import plan_execution

    ctl, sim, _ = rig
    jts = {a: s.joint_trajectory for a, s in ctl.session.skills.items() if s.joint_trajectory is not None}
    st = sim.state()
    for bad in (3.0, 1e4, 1e6):
        q = st.q.copy()
        q[0] = bad
        with pytest.raises(StudioError, match=r"left_s0 joint at .* rad, outside the range it can move in"):
            plan_execution(jts, q, st.gripper)


def test_moves_by_hand_start_from_the_measured_pose(rig: Rig) -> None:  # noqa: F811 - the fixture
    ctl, sim, _ = rig
    q0 = ctl.teaching.arm_q("left").copy()
    ctl.teaching.move_joint(6, float(q0[6]) + 0.2)  # w2
    sim.step(50)
    ctl.execution.emergency_stop()  # halts the arm part-way
    ctl.execution.release_emergency_stop()
    sim.step(10)
    here = ctl.teaching.arm_q("left").copy()
    ctl.teaching.move_joint(5, float(here[5]) + 0.01)  # w1: every other joint stays where it is measured
    qt = sim.targets()[0][:7]
    np.testing.assert_allclose(np.delete(qt, 5), np.delete(here, 5), atol=1e-9)


def test_releasing_the_studios_stop_while_the_robots_button_is_pressed_says_so(rig: Rig) -> None:  # noqa: F811
    ctl, sim, _ = rig
    ctl.execution.emergency_stop()
    sim.press_estop_button()
    with pytest.raises(StudioError, match="emergency-stop button is pressed"):
        ctl.execution.release_emergency_stop()
    st = ctl.execution.status
    assert not st.estop and st.message.startswith("The emergency stop is released, but the robot cannot move yet.")
    assert "can move again" not in st.message
    assert "emergency-stop button is pressed" in ctl.execution.why_not()
