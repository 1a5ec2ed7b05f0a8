"""A simulated Baxter: both arms (14 joints) and both grippers on simulated time at 1 kHz, as the paper records.

In real time (:meth:`~SimulatedBaxter.start`) a batch clock wakes every few milliseconds and computes all
due samples at once, time stamps exact (docs/decisions/021); without it, :meth:`~SimulatedBaxter.step` and
:meth:`~SimulatedBaxter.run_targets` advance time synchronously (example sessions, tests). Commands and plans
are followed within the velocity and acceleration limits (:mod:`.motion`, :mod:`.plan_follower`)."""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from studio.core.errors import InvalidInput, StudioError
from studio.core.types import Arm, check_arm
from studio.robot_backend._clock import BatchClock
from studio.robot_backend.base import (
    ExecutionProgress,
    JointStateBatch,
    ListenerHub,
    RobotBackend,
    RobotState,
    StateListener,
)
from studio.robot_backend.motion import (
    Sensors,
    SimArms,
    checked,
    checked_targets,
    empty_batch,
    joined,
    rate_limited,
    rate_limited_series,
)
from studio.robot_backend.plan_follower import PLAN_START_TOLERANCE, PlanFollower, plan_targets
from studio.robot_backend.sim_safety import SimFaults, SimSafety

if TYPE_CHECKING:  # pragma: no cover
    from studio.core.execution import ExecutionPlan

#: Gripper travel speed, percent of the full stroke per second (Baxter's electric gripper: half a second a stroke).
GRIPPER_SPEED = 200.0
#: Largest batch handed to listeners at once (a long stall is delivered as several batches).
MAX_BATCH = 1000

log = logging.getLogger(__name__)


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


class SimulatedBaxter(SimFaults, RobotBackend):
    """Baxter's two arms and grippers, simulated at ``rate_hz`` with exact time stamps.

    Args:
        rate_hz: joint-state rate (1000 like the paper).
        time_scale: simulated seconds per wall second when started in real time (1.0 = real time).
        period: wall seconds between batches in real time (10–20 ms).
        q0: (14,) initial joint angles (default: both arms in the SDK's untuck pose), clipped into limits.
        gripper0: (2,) initial gripper opening percent (default fully open).
        gripper_speed: gripper speed in percent per second.
        sensor_noise: standard deviation (rad) of Gaussian noise added to the streamed joint angles
            (the true state is noise-free); 0 disables it.
        quantum: encoder resolution (rad); streamed joint angles are rounded to multiples of it (Baxter's
            14-bit encoders: 2π/2¹⁴); 0 disables it.
        gripper_noise: standard deviation (percent) of noise on the streamed gripper openings.
        seed: seed of the sensor-noise generator (deterministic streams).
    """

    def __init__(
        self,
        *,
        rate_hz: float = 1000.0,
        time_scale: float = 1.0,
        period: float = 0.015,
        q0: np.ndarray | None = None,
        gripper0: tuple[float, float] | np.ndarray = (100.0, 100.0),
        gripper_speed: float = GRIPPER_SPEED,
        sensor_noise: float = 0.0,
        quantum: float = 0.0,
        gripper_noise: float = 0.0,
        seed: int = 0,
    ) -> None:
        if not (rate_hz > 0 and math.isfinite(rate_hz)):
            raise InvalidInput(f"The joint-state rate must be a positive number of samples per second, got {rate_hz}.")
        self.rate_hz = float(rate_hz)
        self.dt = 1.0 / self.rate_hz
        self._arms = SimArms(
            self.rate_hz, q0, gripper0, gripper_speed, Sensors(sensor_noise, quantum, gripper_noise, seed)
        )
        self._lock = threading.RLock()
        self._deliver_lock = threading.RLock()
        self._hub = ListenerHub()
        self._plan: PlanFollower | None = None  # the plan being executed (under self._lock)
        self._exec = ExecutionProgress()  # the current or last execution's progress
        self._halt_k: int | None = None  # samples from this index on are held (an emergency stop, …)
        self._halt_cause = "ours"  # what holds them: see SimSafety.ended
        self._safety = SimSafety()
        self._clock = BatchClock(self._advance_to, period=period, time_scale=time_scale, name="sim-baxter")

    # -- RobotBackend -------------------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        """True while the real-time clock streams."""
        return self._clock.running

    @property
    def time_scale(self) -> float:
        return self._clock.time_scale

    def start(self) -> None:
        """Stream in real time (scaled by ``time_scale``) from the current simulated time."""
        with self._lock:
            if self._clock.running:
                return
            self._clock.start(sim_start=self._arms.k * self.dt)

    def stop(self) -> None:
        """Stop the real-time stream; simulated time stays where it is (manual stepping allowed again)."""
        self._clock.stop()

    def subscribe(self, listener: StateListener) -> Callable[[], None]:
        return self._hub.subscribe(listener)

    def command_joints(self, arm: Arm, q: np.ndarray) -> None:
        """Move ``arm`` towards ``q`` (7,) rad; targets outside the joint limits are clipped into them."""
        cols = slice(0, 7) if check_arm(arm) == "left" else slice(7, 14)
        qa = checked(f"{arm} arm joint angles", q, (7,))
        with self._lock:
            if not self._obeys("joint"):
                return
            a = self._arms
            a.qt[cols] = np.clip(qa, a.lower[cols], a.upper[cols])

    def command_gripper(self, arm: Arm, width: float) -> None:
        """Move ``arm``'s gripper towards ``width`` percent open (clipped to 0..100) at the gripper speed."""
        i = 0 if check_arm(arm) == "left" else 1
        w = checked(f"{arm} gripper opening", [width], (1,))[0]
        with self._lock:
            if not self._obeys("gripper"):
                return
            self._arms.gt[i] = min(max(w, 0.0), 100.0)

    def state(self) -> RobotState:
        with self._lock:
            a = self._arms
            return RobotState(
                t=max(a.k - 1, 0) * self.dt,
                q=_ro(a.last_q.copy()),
                gripper=_ro(a.last_g.copy()),
                moving=self._plan is not None or a.moving,
            )

    # -- executing a plan ------------------------------------------------------------------------------------
    def execute(self, plan: ExecutionPlan) -> None:
        """Follow ``plan`` from the next sample on, within the velocity and acceleration limits; returns at once."""
        q_plan, g_plan = plan_targets(plan, self.rate_hz)
        with self._lock:
            if self._safety.ours:
                raise StudioError("The robot is emergency-stopped: release the emergency stop before running a skill.")
            if not self._safety.moves:
                raise StudioError(self._safety.health().message)
            if self._plan is not None:
                raise StudioError("The robot is already running a skill: stop it first.")
            follower = PlanFollower(q_plan, g_plan, self.rate_hz, self._arms.k * self.dt)
            follower.check_start(self._arms.q)
            self._plan, self._exec = follower, follower.progress
            self._arms.last_target = self._arms.q.copy()

    def stop_motion(self) -> None:
        """Slow the plan down to rest along its path (0.1–1.5 s); without a plan, hold still."""
        with self._lock:
            a = self._arms
            if self._plan is None:
                if self._safety.moves:
                    a.hold()
                return
            # time to stop: the current joint speeds at half the acceleration limits (0.05–2 s)
            self._plan.slow_down(float(np.clip(np.max(np.abs(a.v) / (0.5 * a.acceleration)), 0.05, 2.0)))
            self._exec = self._plan.progress

    def clear_emergency_stop(self) -> None:
        """Allow commands and plans again (the arms hold where they stopped); the robot is enabled again."""
        with self._lock:
            if self._halt_k is not None and self._halt_k > self._arms.k:
                self._apply_halt()
            self._safety.ours = False
            self._halt_k = None
            self._safety.enable()

    def progress(self) -> ExecutionProgress:
        with self._lock:
            return self._exec

    def _apply_halt(self) -> None:
        """Freeze everything at the latest sample (caller holds the lock)."""
        self._arms.halt()
        if self._plan is not None or self._exec.active:
            self._exec = self._safety.ended(self._exec, self._halt_cause)
        self._plan = None
        if not self._safety.ours:  # the robot's own stop is over once it holds; the studio's lasts
            self._halt_k = None

    # -- extras -------------------------------------------------------------------------------------------
    @property
    def sim_time(self) -> float:
        """Time stamp (s) of the next sample to be produced."""
        return self._arms.k * self.dt

    def now(self) -> float:
        """Simulated time (s) that corresponds to the wall clock now (between two batches' stamps)."""
        return self._clock.now()

    @property
    def samples_produced(self) -> int:
        return self._arms.k

    def targets(self) -> tuple[np.ndarray, np.ndarray]:
        """Current joint targets (14,) and gripper targets (2,)."""
        with self._lock:
            return self._arms.qt.copy(), self._arms.gt.copy()

    def true_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free joint angles (14,) and gripper openings (2,) of the simulated robot."""
        with self._lock:
            return self._arms.q.copy(), self._arms.g.copy()

    def teleport(self, q: np.ndarray | None = None, gripper: np.ndarray | None = None) -> None:
        """Put the robot at ``q`` (14,) / ``gripper`` (2,) instantly and hold it there (reset, not physics)."""
        with self._lock:
            self._arms.teleport(q, gripper)

    def step(self, n: int = 1) -> JointStateBatch:
        """Advance ``n`` samples with the current targets (manual mode) and stream them; returns them."""
        self._require_manual()
        with self._deliver_lock:
            with self._lock:
                batch = self._produce(int(n))
            self._hub.deliver(batch)
        return batch

    def run_targets(self, q_targets: np.ndarray, gripper_targets: np.ndarray | None = None, *, batch: int = 20) -> int:
        """Manual mode: follow per-sample joint targets (n, 14) (and gripper targets (n, 2)).

        Sample i is produced after target i is commanded, so targets that respect the velocity limits are
        reproduced exactly (plus sensor noise). Samples reach listeners in batches of ``batch``, as in real
        time. Returns the number of samples produced.
        """
        self._require_manual()
        qt, gt = checked_targets(q_targets, gripper_targets)
        qt, n = np.clip(qt, self._arms.lower, self._arms.upper), qt.shape[0]
        step = max(1, int(batch))
        with self._deliver_lock:
            for s in range(0, n, step):
                e = min(n, s + step)
                with self._lock:
                    out = self._arms.through(qt[s:e], None if gt is None else gt[s:e])
                self._hub.deliver(out)
        return n

    # -- internals ----------------------------------------------------------------------------------------
    def _require_manual(self) -> None:
        if self._clock.running:
            raise InvalidInput("The simulated robot is streaming in real time; stop it before stepping by hand.")

    def _advance_to(self, sim_t: float) -> None:
        with self._deliver_lock:
            n = math.floor(sim_t * self.rate_hz + 1e-6) - self._arms.k + 1
            while n > 0:
                m = min(n, MAX_BATCH)
                with self._lock:
                    batch = self._produce(m)
                    up = self._safety.link_up
                if up:
                    self._hub.deliver(batch)
                n -= m

    def _produce(self, n: int) -> JointStateBatch:
        k = self._arms.k
        if n <= 0:
            return empty_batch()
        if self._halt_k is not None and k + n > self._halt_k:
            # an emergency stop falls in this batch: move up to it, hold from it on
            m = max(0, self._halt_k - k)
            first = self._produce(m) if m else None
            self._apply_halt()
            rest = self._arms.held(n - m)
            return rest if first is None else joined(first, rest)
        if self._plan is None:
            return self._arms.toward_targets(n)
        batch = self._plan.produce(self._arms, n)
        self._exec = self._plan.progress
        if self._plan.finished:
            self._plan = None
        return batch

    @property
    def listener_errors(self) -> int:
        """How many times a listener raised (each one logged; the stream went on)."""
        return self._hub.errors


__all__ = ["GRIPPER_SPEED", "PLAN_START_TOLERANCE", "SimulatedBaxter", "rate_limited", "rate_limited_series"]
