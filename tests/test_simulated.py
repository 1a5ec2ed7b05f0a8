"""SimulatedBaxter and ReplayBackend: exact 1 kHz time stamps, limits, grippers, batches, replay controls."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from studio.core.errors import InvalidInput, StudioError
from studio.core.kinematics import Baxter
from studio.core.types import Recording
from studio.robot_backend._clock import BatchClock
from studio.robot_backend.base import JointStateBatch, RobotBackend
from studio.robot_backend.replay import ReplayBackend
from studio.robot_backend.simulated import SimulatedBaxter, rate_limited, rate_limited_series
from tests.conftest import Collector, wait_for


def _busy(stop: threading.Event) -> None:
    x = 0
    while not stop.is_set():
        x += 1


def test_is_a_robot_backend() -> None:
    assert isinstance(SimulatedBaxter(), RobotBackend)


def test_sixty_seconds_give_sixty_thousand_samples_with_exact_stamps_under_cpu_load() -> None:
    # 60 s of simulated time at 30x real time (2 s wall) while two Python threads hog the CPU and the GIL.
    sim = SimulatedBaxter(time_scale=30.0)
    col = Collector()
    sim.subscribe(col)
    stop = threading.Event()
    hogs = [threading.Thread(target=_busy, args=(stop,), daemon=True) for _ in range(2)]
    for h in hogs:
        h.start()
    try:
        sim.start()
        deadline = time.monotonic() + 30
        while sim.state().t < 60.0 and time.monotonic() < deadline:
            time.sleep(0.05)
        sim.stop()
    finally:
        stop.set()
        for h in hogs:
            h.join()
    t, q, g = col.arrays()
    in_60 = t[t < 60.0 - 1e-9]
    assert in_60.shape[0] == 60_000
    assert np.array_equal(t, np.arange(t.shape[0]) / 1000.0)  # exact stamps, no gaps, no repeats
    assert q.shape == (t.shape[0], 14) and g.shape == (t.shape[0], 2)
    assert len(col.batches) > 50  # delivered in batches, not one at the end


def test_real_time_run_is_exact_and_batched() -> None:
    sim = SimulatedBaxter()
    col = Collector()
    sim.subscribe(col)
    t0 = time.perf_counter()
    sim.start()
    _wait(lambda: sim.sim_time >= 0.5)
    sim.stop()
    wall = time.perf_counter() - t0
    t, _, _ = col.arrays()
    assert np.array_equal(t, np.arange(t.shape[0]) / 1000.0)
    assert 0.2 * 1000 <= t.shape[0] <= wall * 1000 + 2
    sizes = [len(b) for b in col.batches]
    assert len(sizes) >= 5 and np.median(sizes) < 100  # ~15 ms batches (a busy machine makes a few larger)


def test_follows_targets_within_velocity_and_position_limits() -> None:
    b = Baxter.load()
    sim = SimulatedBaxter()
    col = Collector()
    sim.subscribe(col)
    far = b.upper_limits("left") + 1.0  # beyond every limit: clipped into them
    sim.command_joints("left", far)
    sim.step(5000)
    t, q, _ = col.arrays()
    vel = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
    vmax = np.concatenate([b.velocity_limits("left"), b.velocity_limits("right")])
    assert np.all(vel <= vmax * (1 + 1e-9))
    assert np.allclose(q[-1, :7], b.upper_limits("left"))
    assert np.allclose(q[:, 7:], b.neutral("right"))  # the other arm holds still
    assert np.all(q <= np.concatenate([b.upper_limits("left"), b.upper_limits("right")]) + 1e-12)
    assert not sim.state().moving


def test_gripper_moves_at_finite_speed_and_stops_anywhere() -> None:
    sim = SimulatedBaxter()
    sim.command_gripper("left", 0.0)
    sim.step(100)  # 0.1 s at 200 %/s: 20 % travelled
    g = sim.state().gripper[0]
    assert g == pytest.approx(80.0, abs=0.5)
    sim.command_gripper("left", g)  # stop where it is
    sim.step(200)
    assert sim.state().gripper[0] == pytest.approx(g)
    sim.command_gripper("right", 250.0)  # clipped to 100
    sim.command_gripper("left", 37.5)
    sim.step(1000)
    assert sim.state().gripper.tolist() == pytest.approx([37.5, 100.0])


def test_bad_commands_are_refused_in_plain_words() -> None:
    sim = SimulatedBaxter()
    with pytest.raises(InvalidInput, match="NaN"):
        sim.command_joints("left", np.array([0, 0, np.nan, 0, 0, 0, 0]))
    with pytest.raises(InvalidInput, match="7 numbers"):
        sim.command_joints("left", np.array([0, 0]))
    with pytest.raises(InvalidInput, match="arm"):
        sim.command_joints("middle", np.zeros(7))  # type: ignore[arg-type]  # on purpose: an unknown arm
    with pytest.raises(InvalidInput):
        sim.command_gripper("left", float("nan"))
    q_before = sim.targets()[0]
    assert np.array_equal(q_before, sim.targets()[0])


def test_manual_steps_are_deterministic_and_refused_while_streaming() -> None:
    def run() -> np.ndarray:
        sim = SimulatedBaxter(sensor_noise=1e-3, seed=3)
        sim.command_joints("right", np.zeros(7))
        return np.concatenate([sim.step(300).q, sim.step(200).q])

    assert np.array_equal(run(), run())
    sim = SimulatedBaxter(time_scale=5)
    sim.start()
    try:
        with pytest.raises(InvalidInput, match="stop it"):
            sim.step(1)
    finally:
        sim.stop()
    n = sim.samples_produced
    sim.step(10)  # allowed again after stop, continuing the same clock
    assert sim.samples_produced == n + 10


def test_run_targets_reproduces_feasible_targets_and_rate_limits_others() -> None:
    b = Baxter.load()
    sim = SimulatedBaxter()
    q0, _ = sim.true_state()
    t = np.arange(2000) / 1000.0
    targets = np.tile(q0, (2000, 1))
    targets[:, 0] = q0[0] + 0.3 * np.sin(t)  # slow: within the 1.5 rad/s limit
    col = Collector()
    sim.subscribe(col)
    sim.run_targets(targets, batch=16)
    _, q, _ = col.arrays()
    assert np.allclose(q, targets)
    assert len(col.batches) == 125
    jump = targets[-1].copy()
    jump[1] += 0.5  # a step: must be rate-limited
    sim.run_targets(np.tile(jump, (100, 1)))
    q2 = col.arrays()[1][2000:]
    assert np.allclose(np.diff(q2[:, 1]), b.velocity_limits("left")[1] / 1000.0)


def test_rate_limited_closed_form_matches_recursion() -> None:
    rng = np.random.default_rng(0)
    q0, target = rng.normal(size=5), rng.normal(size=5)
    step = rng.uniform(0.001, 0.05, size=5)
    closed = rate_limited(q0, target, step, 300)
    rec = rate_limited_series(q0, np.tile(target, (300, 1)), step)
    assert np.allclose(closed, rec)


def test_listener_error_does_not_stop_the_stream() -> None:
    sim = SimulatedBaxter()
    col = Collector()

    def bad(_: JointStateBatch) -> None:
        raise RuntimeError("boom")

    sim.subscribe(bad)
    unsub = sim.subscribe(col)
    sim.step(10)
    assert sim.listener_errors == 1 and len(col.batches) == 1
    unsub()
    sim.step(10)
    assert len(col.batches) == 1


# -- replay ------------------------------------------------------------------------------------------------
def _recording(n: int = 3000) -> Recording:
    t = np.arange(n) / 1000.0
    q = np.zeros((n, 14)) + np.linspace(0, 1, n)[:, None]
    g = np.full((n, 2), 100.0)
    return Recording(t=t, q=q, gripper=g, arms=("left",), name="r")


def _wait(cond, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def test_replay_steps_through_the_recording() -> None:
    rec = _recording()
    rp = ReplayBackend(rec)
    col = Collector()
    rp.subscribe(col)
    rp.step(1000)
    rp.step(5000)  # only 2000 left
    t, q, _ = col.arrays()
    assert np.array_equal(t, rec.t) and np.array_equal(q, rec.q)
    assert rp.finished
    rp.command_joints("left", np.zeros(7))  # ignored
    assert rp.state().q.tolist() == rec.q[-1].tolist()


def test_replay_real_time_seek_and_loop_keep_time_increasing() -> None:
    rec = _recording(500)
    rp = ReplayBackend(rec, speed=10.0, loop=True)
    col = Collector()
    rp.subscribe(col)
    rp.start()
    _wait(lambda: sum(len(b) for b in col.batches) > 1200)  # the 0.5 s recording loops at least twice
    rp.seek(0.25)
    n = sum(len(b) for b in col.batches)
    _wait(lambda: sum(len(b) for b in col.batches) > n + 100)
    rp.stop()
    t, _, _ = col.arrays()
    assert t.shape[0] > 1200
    assert np.all(np.diff(t) > 0)
    assert np.allclose(np.diff(t), 1e-3)  # no gaps, also across loops
    assert rp.position <= 0.5


def test_replay_pause_and_resume() -> None:
    rec = _recording(2000)
    rp = ReplayBackend(rec, speed=5.0)
    col = Collector()
    rp.subscribe(col)
    rp.start()
    time.sleep(0.1)
    rp.pause()
    n = sum(len(b) for b in col.batches)
    time.sleep(0.05)
    assert sum(len(b) for b in col.batches) == n
    rp.play()
    _wait(lambda: rp.finished)
    rp.stop()
    t, q, _ = col.arrays()
    assert np.array_equal(q, rec.q) and np.allclose(np.diff(t), 1e-3)
    assert rp.finished


def test_replay_refuses_empty_recording() -> None:
    empty = Recording(t=np.zeros(0), q=np.zeros((0, 14)), gripper=np.zeros((0, 2)))
    with pytest.raises(InvalidInput, match="no samples"):
        ReplayBackend(empty)


def test_replay_refuses_a_one_sample_recording() -> None:
    one = Recording(t=np.zeros(1), q=np.zeros((1, 14)), gripper=np.full((1, 2), 50.0), name="blip")
    with pytest.raises(InvalidInput, match='"blip" has a single sample'):
        ReplayBackend(one, loop=True)


def test_clock_never_runs_two_threads_after_a_stop_that_timed_out() -> None:
    release = threading.Event()
    entered = threading.Event()

    def busy(_t: float) -> None:  # a wakeup that outlasts stop()'s wait
        entered.set()
        release.wait(10)

    clock = BatchClock(busy, period=0.005, name="test-clock")
    clock.join_timeout = 0.05
    try:
        clock.start()
        assert entered.wait(5)
        clock.stop()
        assert not clock.running
        with pytest.raises(StudioError, match="still finishing"):
            clock.start()
        assert [t.name for t in threading.enumerate()].count("test-clock") == 1
    finally:
        release.set()
    clock.join_timeout = 5.0
    clock.start()  # the old thread finishes its wakeup and exits: a restart works
    try:
        assert clock.running
        assert [t.name for t in threading.enumerate()].count("test-clock") == 1
    finally:
        clock.stop()
    assert not clock.running


def test_a_stop_while_the_clock_starts_in_another_thread_stops_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two tabs: one presses Play (the replay's clock starts), the other seeks at that moment (the clock stops).
    The stop waits for the start and then stops the clock; it never joins a thread that has not started."""
    gate, starting = threading.Event(), threading.Event()
    plain = threading.Thread

    class SlowToStart(threading.Thread):
        def start(self) -> None:
            if self.name == "test-clock":
                starting.set()
                gate.wait(10)
            super().start()

    clock = BatchClock(lambda _t: None, period=0.005, name="test-clock")
    starter = plain(target=clock.start)
    errors: list[BaseException] = []

    def stop() -> None:
        try:
            clock.stop()
        except BaseException as exc:  # the race as it was: "cannot join thread before it is started"
            errors.append(exc)

    stopper = plain(target=stop)
    monkeypatch.setattr(threading, "Thread", SlowToStart)
    try:
        starter.start()
        assert starting.wait(5)
        stopper.start()
        stopper.join(timeout=0.5)  # gives a stop that does not wait for the start the time to fail
    finally:
        gate.set()
        monkeypatch.undo()
    starter.join(10)
    stopper.join(10)
    assert not errors, errors
    assert not clock.running
    assert wait_for(lambda: "test-clock" not in [t.name for t in threading.enumerate()], 10)


def test_a_closed_playback_never_plays_again() -> None:
    """A playback unloaded by one tab while another pressed Play: Play on the closed one starts nothing."""
    from studio.controller.playback import PREVIEW, Playback

    rec = Recording(t=np.linspace(0, 1, 11), q=np.zeros((11, 14)), gripper=np.full((11, 2), 50.0), name="r")
    pb = Playback(PREVIEW, rec, key=None)
    pb.close()
    pb.play()
    assert not pb.backend.running
