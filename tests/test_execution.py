"""Running a skill on the robot backend: plan (approach + skill), execute on the simulated Baxter within its
limits, progress, controlled stop, emergency stop within one control cycle, the execution recorded like a
demonstration and compared with the plan."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from studio.core.errors import StudioError
from studio.core.execution import ExecutionPlan, compare_execution, plan_execution
from studio.core.kinematics import Baxter
from studio.core.pipeline import learn_skill
from studio.core.timing import limit_ratio
from studio.core.types import Recording
from studio.recorder import Recorder
from studio.robot_backend.replay import ReplayBackend
from studio.robot_backend.simulated import SimulatedBaxter
from studio.words.robot import tracking_summary
from tests.conftest import Collector, wait_for
from tests.core.teacher_demos import demos


@pytest.fixture(scope="module")
def skill():
    return learn_skill(list(demos("stack-cup")), arm="left")


def _limits() -> tuple[np.ndarray, np.ndarray]:
    b = Baxter.load()
    return (
        np.concatenate([b.velocity_limits(a) for a in ("left", "right")]),
        np.concatenate([b.acceleration_limits(a) for a in ("left", "right")]),
    )


def test_the_plan_approaches_the_start_then_plays_the_skill_within_the_limits(skill) -> None:
    sim = SimulatedBaxter()
    st = sim.state()
    plan = plan_execution({"left": skill.joint_trajectory}, st.q, st.gripper)
    jt = skill.joint_trajectory
    assert isinstance(plan, ExecutionPlan) and plan.arms == ("left",)
    np.testing.assert_allclose(plan.q[0], st.q)  # starts where the robot is
    k = round(plan.skill_start * plan.rate_hz)
    np.testing.assert_allclose(plan.q[k, :7], jt.q[0], atol=1e-9)  # the skill starts after the approach
    assert np.isnan(plan.skill_time[:k]).all() and plan.skill_time[k] == pytest.approx(jt.skill_time[0])
    np.testing.assert_allclose(plan.q[:, 7:], np.tile(st.q[7:], (len(plan), 1)))  # the right arm holds still
    v, a = _limits()
    assert limit_ratio(plan.q, plan.rate_hz, v, a) <= 1.0
    assert plan.duration == pytest.approx(plan.skill_start + jt.t[-1] - jt.t[0], abs=2e-3)


def test_the_simulated_robot_executes_the_plan_exactly_and_streams_it(skill) -> None:
    sim = SimulatedBaxter()
    col = Collector()
    sim.subscribe(col)
    st = sim.state()
    plan = plan_execution({"left": skill.joint_trajectory}, st.q, st.gripper)
    sim.execute(plan)
    assert sim.progress().state == "running" and sim.progress().started_at == pytest.approx(0.0)
    sim.step(len(plan) // 2)
    p = sim.progress()
    assert p.state == "running" and 0.45 < p.fraction < 0.55 and p.active
    sim.step(len(plan))
    p = sim.progress()
    assert p.state == "done" and p.fraction == 1.0 and not p.active
    t, q, g = col.arrays()
    n = len(plan)
    np.testing.assert_allclose(q[:n], plan.q, atol=1e-12)  # a plan within the limits is followed exactly
    # grippers follow their targets at the gripper's own speed (200 %/s) and end where the plan ends
    assert np.abs(np.diff(g[:n], axis=0)).max() <= 0.2 + 1e-9
    np.testing.assert_allclose(g[n - 1], plan.gripper[-1], atol=1e-6)
    closed = np.flatnonzero(plan.gripper[:, 0] < 50)
    assert closed.size and g[closed[0] + 400, 0] == pytest.approx(plan.gripper[closed[0] + 400, 0])
    assert np.allclose(np.diff(t), 1e-3)
    # done, it holds where the plan ended (not where the batch that finished the plan began)
    sim.step(2000)
    np.testing.assert_allclose(sim.true_state()[0], plan.q[-1], atol=1e-12)
    np.testing.assert_allclose(sim.targets()[0], plan.q[-1], atol=1e-12)


def test_execution_is_recorded_like_a_demonstration_and_compared_with_the_plan(skill, tmp_path: Path) -> None:
    sim = SimulatedBaxter(sensor_noise=2e-4, seed=3)
    sim.step(250)  # the robot has been streaming for a while
    rec = Recorder(sim, tmp_path, arms="left", name="run 1")
    rec.start()
    sim.step(300)  # recording starts 0.3 s before the run
    st = sim.state()
    plan = plan_execution({"left": skill.joint_trajectory}, sim.true_state()[0], st.gripper)
    sim.execute(plan)
    started = sim.progress().started_at
    assert started is not None
    sim.step(len(plan) + 200)
    recording = rec.stop()
    rec.discard()
    assert sim.progress().state == "done"
    # the start found from the joints alone agrees with the backend's own clock
    report = compare_execution(plan, recording)
    assert report.offset == pytest.approx(started - 0.25, abs=0.01)
    given = compare_execution(plan, recording, start_time=started - 0.25)
    assert given.completed == pytest.approx(1.0, abs=1e-3)
    assert given.max_position_error < 3e-3 and given.max_path_error < 3e-3  # sensor noise only
    assert given.joint_error.max() < 2e-3
    assert tracking_summary(given).startswith("The robot ran 100% of the plan; its gripper stayed within ")


def test_controlled_stop_slows_down_along_the_path_within_the_limits(skill) -> None:
    sim = SimulatedBaxter()
    col = Collector()
    sim.subscribe(col)
    st = sim.state()
    plan = plan_execution({"left": skill.joint_trajectory}, st.q, st.gripper)
    sim.execute(plan)
    # stop in the middle of a motion (the fastest moment of the plan's first half)
    speed = np.max(np.abs(np.diff(plan.q, axis=0)), axis=1)
    k = int(np.argmax(speed[: len(plan) // 2]))
    sim.step(k)
    sim.stop_motion()
    assert sim.progress().state == "stopping"
    sim.step(3000)
    p = sim.progress()
    assert p.state == "stopped" and 0 < p.fraction < 0.6
    _, q, _ = col.arrays()
    v, a = _limits()
    assert limit_ratio(q, 1000.0, v, a) <= 1.0 + 1e-6
    assert np.abs(q[-1] - q[-2]).max() == 0.0  # at rest
    sim.step(2000)
    np.testing.assert_allclose(sim.true_state()[0], q[-1], atol=1e-12)  # and holds there
    # it stayed on the planned path: every executed pose is one the plan passes through
    b = Baxter.load()
    _, p_exec = b.rotations_batch("left", q[k:, :7])
    _, p_plan = b.rotations_batch("left", plan.q[:, :7])
    d = np.min(np.linalg.norm(p_exec[::25, None, :] - p_plan[None, ::5, :], axis=2), axis=1)
    assert d.max() < 5e-3
    with pytest.raises(StudioError):  # stopped: a new run needs a new plan from where the robot is
        sim.execute(plan)


def test_emergency_stop_halts_within_one_control_cycle_in_real_time(skill) -> None:
    sim = SimulatedBaxter(time_scale=1.0)
    col = Collector()
    sim.subscribe(col)
    st = sim.state()
    plan = plan_execution({"left": skill.joint_trajectory}, st.q, st.gripper)
    sim.start()
    try:
        sim.execute(plan)
        assert wait_for(lambda: sim.sim_time > 0.6)  # moving by now (the approach)
        t_call = sim.now()
        sim.emergency_stop()
        t_held = sim.held_from  # the first sample after the stop reached the robot (a loaded machine: after t_call)
        assert t_held is not None and t_held >= t_call
        assert wait_for(lambda: sim.sim_time > t_held + 0.2)
    finally:
        sim.stop()
    t, q, _ = col.arrays()
    after = t > t_held + 1e-3  # every sample after the first control cycle past the stop
    assert after.sum() > 100
    moving_before = np.abs(np.diff(q[t <= t_call], axis=0)).max()
    assert moving_before > 1e-5
    held = q[after]
    assert np.abs(held - held[0]).max() == 0.0
    assert sim.progress().state == "emergency-stopped"
    assert "Emergency stop" in sim.progress().message
    # motion is refused until the emergency stop is released
    before = sim.true_state()[0].copy()
    sim.command_joints("left", before[:7] + 0.1)
    sim.step(100)
    np.testing.assert_allclose(sim.true_state()[0], before)
    with pytest.raises(StudioError, match="emergency-stopped"):
        sim.execute(plan_execution({"left": skill.joint_trajectory}, before, sim.state().gripper))
    sim.clear_emergency_stop()
    sim.command_joints("left", before[:7] + 0.1)
    sim.step(200)
    assert np.abs(sim.true_state()[0][:7] - (before[:7] + 0.1)).max() < 1e-9


def test_emergency_stop_in_manual_stepping_holds_from_the_next_sample(skill) -> None:
    sim = SimulatedBaxter()
    st = sim.state()
    sim.execute(plan_execution({"left": skill.joint_trajectory}, st.q, st.gripper))
    sim.step(700)
    sim.emergency_stop()
    b = sim.step(50)
    assert np.abs(b.q - sim.true_state()[0]).max() == 0.0


def test_a_plan_that_breaks_the_limits_is_followed_within_them() -> None:
    sim = SimulatedBaxter()
    st = sim.state()
    n = 1500
    q = np.tile(st.q, (n, 1))
    q[100:, 0] += 0.5  # a step of 0.5 rad: impossible to follow exactly
    plan = ExecutionPlan(np.arange(n) / 1000.0, q, np.tile(st.gripper, (n, 1)), ("left",), 0.0, np.zeros(n), 1000.0)
    col = Collector()
    sim.subscribe(col)
    sim.execute(plan)
    sim.step(n + 1000)
    _, qq, _ = col.arrays()
    v, a = _limits()
    assert limit_ratio(qq, 1000.0, v, a) <= 1.0 + 1e-9
    assert qq[-1, 0] == pytest.approx(st.q[0] + 0.5, abs=1e-6)  # it gets there without overshooting
    assert qq[:, 0].max() <= st.q[0] + 0.5 + 1e-4  # no overshoot beyond 0.1 mrad
    assert sim.progress().state == "done"


def test_refusals_are_plain() -> None:
    sim = SimulatedBaxter()
    st = sim.state()
    n = 10
    far = np.tile(st.q + 0.3, (n, 1))
    plan = ExecutionPlan(np.arange(n) / 1000.0, far, np.tile(st.gripper, (n, 1)), ("left",), 0.0, np.zeros(n), 1000.0)
    with pytest.raises(StudioError, match="press Run again"):
        sim.execute(plan)
    here = np.tile(st.q, (n, 1))
    ok = ExecutionPlan(np.arange(n) / 1000.0, here, np.tile(st.gripper, (n, 1)), ("left",), 0.0, np.zeros(n), 1000.0)
    sim.execute(ok)
    with pytest.raises(StudioError, match="already running"):
        sim.execute(ok)
    rec = Recording(np.arange(5) / 1000.0, np.zeros((5, 14)), np.full((5, 2), 50.0), ("left",), "d")
    with pytest.raises(StudioError, match="replayed"):
        ReplayBackend(rec).execute(ok)


def test_both_arms_run_together_and_a_partial_run_is_reported(tmp_path: Path) -> None:
    from studio.teacher import recording_from_plan, teach
    from tests.core.teacher_demos import skills_of

    recs = [recording_from_plan(teach("stack-cup", s, arm="both")) for s in (0, 1)]
    skills = skills_of(recs)
    jts = {a: s.joint_trajectory for a, s in skills.items() if s.joint_trajectory is not None}
    assert set(jts) == {"left", "right"}
    sim = SimulatedBaxter()
    st = sim.state()
    plan = plan_execution(jts, st.q, st.gripper)
    assert plan.arms == ("left", "right")
    k = round(plan.skill_start * plan.rate_hz)
    np.testing.assert_allclose(plan.q[k, :7], jts["left"].q[0], atol=1e-9)
    np.testing.assert_allclose(plan.q[k, 7:], jts["right"].q[0], atol=1e-9)
    # the shorter skill ends first and its arm holds its last pose until the other finishes
    np.testing.assert_allclose(plan.q[-1, :7], jts["left"].q[-1], atol=1e-9)
    np.testing.assert_allclose(plan.q[-1, 7:], jts["right"].q[-1], atol=1e-9)
    v, a = _limits()
    assert limit_ratio(plan.q, plan.rate_hz, v, a) <= 1.0
    # run 40 % of it, stop, and compare the recording with the plan
    rec = Recorder(sim, tmp_path, arms="both", name="run")
    rec.start()
    sim.execute(plan)
    sim.step(int(0.4 * len(plan)))
    sim.stop_motion()
    sim.step(3000)
    recording = rec.stop()
    rec.discard()
    report = compare_execution(plan, recording, start_time=0.0)
    assert set(report.position_error) == {"left", "right"}
    assert 0.4 < report.completed < 0.6
    # it stopped along the path (within the acceleration limits): close to the planned path all along, while
    # the same-time error grows once the plan goes on without the robot
    assert report.max_path_error < 5e-3 and report.max_position_error > 0.05
    assert f"The robot ran {round(report.completed * 100)}% of the plan" in tracking_summary(report)


def test_a_run_verdict_is_facts_and_every_failure_has_its_words() -> None:
    """The core says what failed (``RunFailure``) and keeps the numbers; ``words.robot`` says it, each failure in
    its own phrase, in the verdict's order."""
    from studio.core.execution import COMPLETE_MIN, RunFailure, RunVerdict
    from studio.words.robot import run_failure_words

    works = RunVerdict(1.0, 0.004, 0.001, 2, 2, True)
    assert works.works and works.failures() == [] and run_failure_words(works) == []
    worst = RunVerdict(0.42, 0.031, 0.0062, 1, 2, False, same_time=False)
    assert worst.failures() == list(RunFailure)
    assert run_failure_words(worst) == [
        "the robot did 42 % of the run",
        "its gripper was up to 3.1 cm from the planned path",
        "it ended 6.2 mm from the plan's last pose",
        "it did 1 of the 2 gripper actions",
        "the objects did not end where you put them",
    ]
    late = RunVerdict(COMPLETE_MIN, 0.025, 0.0, 0, 0, None)
    assert late.failures() == [RunFailure.OFF_TRACK]
    assert run_failure_words(late) == ["its gripper was up to 2.5 cm from where the plan was at the same moment"]
