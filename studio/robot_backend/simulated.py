"""A simulated Baxter: both arms (14 joints) and both grippers on simulated time at 1 kHz.

The paper raises Baxter's joint-state rate from 100 Hz to 1 kHz (§ Data Collection, Demonstrations); the
simulator streams at the same rate. It follows commanded joint targets within the URDF's position and
velocity limits (that is how a dragged gizmo or a slider moves the arm in kinesthetic mode) and moves the
grippers 0 (closed) … 100 (open) at a finite speed, stopping at any width.

Two ways to drive it:

* **real time** — :meth:`start` runs a :class:`~studio.robot_backend._clock.BatchClock` that wakes every
  ~15 ms of wall time and computes all due 1 ms samples at once, vectorised. Time stamps are ``k / rate``
  for the sample counter ``k``: exact, gap-free, whatever the wakeup jitter. ``time_scale`` > 1 runs
  faster than real time (tests).
* **manual steps** — without :meth:`start`, :meth:`step` and :meth:`run_targets` advance simulated time
  synchronously; generation of example sessions uses this to run far faster than real time, deterministic
  by seed.

**Executing a plan** (:meth:`execute`, "Run on robot"): the arms follow the plan's joint targets sample by
sample with the simulator's own limits — the URDF velocity limits *and* the joint acceleration limits
(:data:`~studio.core.kinematics.ACCELERATION_LIMITS`) — and the grippers follow theirs at the gripper
speed; the joint states stream exactly as during a demonstration, so a recorder records the execution. A
plan that respects the limits is reproduced exactly. :meth:`stop_motion` slows the plan's progress down to
rest along its path; :meth:`emergency_stop` holds the arms from the first sample after the call (one
control cycle) and ignores motion commands until :meth:`clear_emergency_stop`.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from studio.core.errors import InvalidInput, StudioError
from studio.core.types import ARMS, check_arm
from studio.robot_backend._clock import BatchClock
from studio.robot_backend.base import (
    ExecutionProgress,
    JointStateBatch,
    ListenerHub,
    RobotBackend,
    RobotState,
    StateListener,
)

if TYPE_CHECKING:  # pragma: no cover
    from studio.core.execution import ExecutionPlan

#: Gripper travel speed, percent of the full stroke per second (Baxter's electric gripper: ~0.5 s stroke).
GRIPPER_SPEED = 200.0
#: Largest batch handed to listeners at once (a long stall is delivered as several batches).
MAX_BATCH = 1000
#: A plan must start within this (rad, every joint) of where the arms are.
PLAN_START_TOLERANCE = 0.01

log = logging.getLogger(__name__)


def _limits() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(14,) lower, upper, velocity, acceleration limits and the neutral pose for both arms."""
    from studio.core.kinematics import Baxter

    b = Baxter.load()
    lo = np.concatenate([b.lower_limits(a) for a in ARMS])
    hi = np.concatenate([b.upper_limits(a) for a in ARMS])
    v = np.concatenate([b.velocity_limits(a) for a in ARMS])
    acc = np.concatenate([b.acceleration_limits(a) for a in ARMS])
    q0 = np.concatenate([b.neutral(a) for a in ARMS])
    return lo, hi, v, acc, q0


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def rate_limited(q0: np.ndarray, target: np.ndarray, step: np.ndarray, n: int) -> np.ndarray:
    """(n, d) positions moving from ``q0`` towards a fixed ``target`` by at most ``step`` per sample.

    Closed form of ``q[k] = q[k-1] + clip(target - q[k-1], -step, step)`` for k = 1..n: vectorised over
    samples, which is what lets one wakeup compute 15 samples at once.
    """
    d = target - q0
    k = np.arange(1, n + 1, dtype=np.float64)[:, None]
    return q0 + np.sign(d) * np.minimum(np.abs(d), step * k)


def rate_limited_series(q0: np.ndarray, targets: np.ndarray, step: np.ndarray) -> np.ndarray:
    """(n, d) positions following per-sample ``targets`` (n, d), moving at most ``step`` per sample."""
    n = targets.shape[0]
    if n == 0:
        return np.empty((0, q0.shape[0]))
    # Fast path: targets that respect the limits from where we are are followed exactly.
    jumps = np.abs(np.diff(np.vstack([q0[None, :], targets]), axis=0))
    if np.all(jumps <= step * (1.0 + 1e-9)):
        return targets.astype(np.float64, copy=True)
    out = np.empty((n, q0.shape[0]))
    q = q0.astype(np.float64, copy=True)
    for i in range(n):
        q = q + np.clip(targets[i] - q, -step, step)
        out[i] = q
    return out


class SimulatedBaxter(RobotBackend):
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
        self.lower, self.upper, self.velocity, self.acceleration, neutral = _limits()
        self._qstep = self.velocity * self.dt
        self._gstep = float(gripper_speed) * self.dt
        self.sensor_noise = float(sensor_noise)
        self.quantum = float(quantum)
        self.gripper_noise = float(gripper_noise)
        self._rng = np.random.default_rng(seed)
        self._lock = threading.RLock()
        self._deliver_lock = threading.RLock()
        self._hub = ListenerHub()
        self._k = 0  # index of the next sample to produce
        q = neutral if q0 is None else self._check_q("initial joint angles", q0, (14,))
        self._q = np.clip(q, self.lower, self.upper)
        self._qt = self._q.copy()
        self._g = np.clip(self._check_q("initial gripper opening", gripper0, (2,)), 0.0, 100.0)
        self._gt = self._g.copy()
        self._last_q = self._q.copy()
        self._last_g = self._g.copy()
        self._v = np.zeros(14)  # joint velocity (rad/s) of the latest sample
        self._last_target: np.ndarray | None = None  # the follower's previous target (its velocity)
        # execution of a plan (all under self._lock)
        self._plan_q: np.ndarray | None = None  # (M, 14) targets at this simulator's rate
        self._plan_g: np.ndarray | None = None  # (M, 2)
        self._plan_k0 = 0  # sample index of the plan's t = 0
        self._p = 0.0  # plan progress, in plan samples (advances by self._r a sample)
        self._r = 1.0  # progress rate: 1 as planned, falling to 0 during a controlled stop
        self._dr = 0.0
        self._exec = ExecutionProgress()
        self._halt_k: int | None = None  # samples from this index on are held (emergency stop)
        self._estopped = False
        self._clock = BatchClock(self._advance_to, period=period, time_scale=time_scale, name="sim-baxter")

    # -- helpers -------------------------------------------------------------------------------------------
    @staticmethod
    def _check_q(name: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
        try:
            a = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InvalidInput(f"The {name} must be numbers, got {value!r}.") from exc
        if a.shape != shape:
            raise InvalidInput(f"The {name} must be {shape[0]} numbers, got shape {a.shape}.")
        if not np.all(np.isfinite(a)):
            raise InvalidInput(
                f"The {name} contain missing or invalid values (NaN or infinity); the command was ignored."
            )
        return a.copy()

    @staticmethod
    def _cols(arm: str) -> slice:
        return slice(0, 7) if check_arm(arm) == "left" else slice(7, 14)

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
            self._clock.start(sim_start=self._k * self.dt)

    def stop(self) -> None:
        """Stop the real-time stream; simulated time stays where it is (manual stepping allowed again)."""
        self._clock.stop()

    def subscribe(self, listener: StateListener) -> Callable[[], None]:
        return self._hub.subscribe(listener)

    def command_joints(self, arm: str, q: np.ndarray) -> None:
        """Move ``arm`` towards ``q`` (7,) rad; targets outside the joint limits are clipped into them."""
        cols = self._cols(arm)
        qa = self._check_q(f"{arm} arm joint angles", q, (7,))
        with self._lock:
            if self._estopped:
                log.info("emergency-stopped: joint command ignored")
                return
            self._qt[cols] = np.clip(qa, self.lower[cols], self.upper[cols])

    def command_gripper(self, arm: str, width: float) -> None:
        """Move ``arm``'s gripper towards ``width`` percent open (clipped to 0..100) at the gripper speed."""
        i = 0 if check_arm(arm) == "left" else 1
        w = self._check_q(f"{arm} gripper opening", [width], (1,))[0]
        with self._lock:
            if self._estopped:
                log.info("emergency-stopped: gripper command ignored")
                return
            self._gt[i] = min(max(w, 0.0), 100.0)

    def state(self) -> RobotState:
        with self._lock:
            return RobotState(
                t=max(self._k - 1, 0) * self.dt,
                q=_ro(self._last_q.copy()),
                gripper=_ro(self._last_g.copy()),
                moving=bool(
                    self._plan_q is not None
                    or np.any(np.abs(self._qt - self._q) > 1e-9)
                    or np.any(np.abs(self._gt - self._g) > 1e-9)
                ),
            )

    # -- executing a plan ------------------------------------------------------------------------------------
    def execute(self, plan: ExecutionPlan) -> None:
        """Follow ``plan`` from the next sample on (see the module docstring); returns at once."""
        q_plan = np.asarray(plan.q, dtype=np.float64)
        g_plan = np.asarray(plan.gripper, dtype=np.float64)
        if q_plan.ndim != 2 or q_plan.shape[1] != 14 or g_plan.shape != (q_plan.shape[0], 2) or not len(q_plan):
            raise InvalidInput("The plan must give 14 joint targets and 2 gripper targets per sample.")
        if abs(float(plan.rate_hz) - self.rate_hz) > 1e-9:  # resample onto this simulator's samples
            t_src = np.asarray(plan.t, dtype=np.float64) - float(plan.t[0])
            t_new = np.arange(math.floor(t_src[-1] * self.rate_hz + 1e-9) + 1) / self.rate_hz
            q_plan = np.column_stack([np.interp(t_new, t_src, q_plan[:, j]) for j in range(14)])
            k = np.clip(np.searchsorted(t_src, t_new + 1e-9, side="right") - 1, 0, len(t_src) - 1)
            g_plan = g_plan[k]
        with self._lock:
            if self._estopped:
                raise StudioError("The robot is emergency-stopped: release the emergency stop before running a skill.")
            if self._plan_q is not None:
                raise StudioError("The robot is already running a skill: stop it first.")
            off = float(np.max(np.abs(q_plan[0] - self._q)))
            if off > PLAN_START_TOLERANCE:
                raise StudioError(
                    f"The robot moved since the run was planned (by {math.degrees(off):.0f}° at one joint); "
                    "press Run again to plan from where it is now."
                )
            self._plan_q, self._plan_g = q_plan, np.clip(g_plan, 0.0, 100.0)
            self._plan_k0 = self._k
            # progress of the latest sample: the first sample produced from now on is the plan's sample 0
            self._p, self._r, self._dr = -1.0, 1.0, 0.0
            self._last_target = self._q.copy()
            duration = (len(q_plan) - 1) * self.dt
            self._exec = ExecutionProgress(
                "running", 0.0, duration, self._k * self.dt, "The robot is running the skill."
            )

    def stop_motion(self) -> None:
        """Slow the plan down to rest along its path (about 0.1–1.5 s); without a plan, hold still."""
        with self._lock:
            if self._plan_q is None:
                if not self._estopped:
                    self._qt = self._q.copy()
                    self._gt = self._g.copy()
                return
            if self._exec.state == "stopping":
                return
            # time to stop: the current joint speeds at half the acceleration limits (0.05–2 s)
            t_stop = float(np.clip(np.max(np.abs(self._v) / (0.5 * self.acceleration)), 0.05, 2.0))
            self._dr = 1.0 / (t_stop * self.rate_hz)
            self._exec = ExecutionProgress(
                "stopping", self._exec.t, self._exec.duration, self._exec.started_at, "The robot is stopping."
            )

    def emergency_stop(self) -> None:
        """Hold the arms and grippers from the first sample after this call; ignore motion until cleared."""
        with self._lock:
            if self._clock.running:
                k_now = math.floor(self._clock.now() * self.rate_hz + 1e-6) + 1
                self._halt_k = max(self._k, k_now)
            else:
                self._halt_k = self._k
            self._estopped = True
            if self._halt_k <= self._k:  # nothing produced yet past the call: apply now
                self._apply_halt()

    def clear_emergency_stop(self) -> None:
        """Allow commands and plans again; the arms hold where they stopped."""
        with self._lock:
            if self._halt_k is not None and self._halt_k > self._k:
                self._apply_halt()
            self._estopped = False
            self._halt_k = None

    def progress(self) -> ExecutionProgress:
        with self._lock:
            return self._exec

    @property
    def emergency_stopped(self) -> bool:
        with self._lock:
            return self._estopped

    def _apply_halt(self) -> None:
        """Freeze everything at the latest sample (caller holds the lock)."""
        self._qt = self._q.copy()
        self._gt = self._g.copy()
        self._v = np.zeros(14)
        if self._plan_q is not None or self._exec.active:
            self._exec = ExecutionProgress(
                "emergency-stopped",
                self._exec.t,
                self._exec.duration,
                self._exec.started_at,
                "Emergency stop: the robot halted. Release the emergency stop to move it again.",
            )
        self._plan_q = self._plan_g = None

    # -- extras -------------------------------------------------------------------------------------------
    @property
    def sim_time(self) -> float:
        """Time stamp (s) of the next sample to be produced."""
        return self._k * self.dt

    @property
    def samples_produced(self) -> int:
        return self._k

    def targets(self) -> tuple[np.ndarray, np.ndarray]:
        """Current joint targets (14,) and gripper targets (2,)."""
        with self._lock:
            return self._qt.copy(), self._gt.copy()

    def true_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free joint angles (14,) and gripper openings (2,) of the simulated robot."""
        with self._lock:
            return self._q.copy(), self._g.copy()

    def teleport(self, q: np.ndarray | None = None, gripper: np.ndarray | None = None) -> None:
        """Put the robot at ``q`` (14,) / ``gripper`` (2,) instantly and hold it there (reset, not physics)."""
        with self._lock:
            if q is not None:
                qa = np.clip(self._check_q("joint angles", q, (14,)), self.lower, self.upper)
                self._q, self._qt, self._last_q = qa.copy(), qa.copy(), qa.copy()
            if gripper is not None:
                ga = np.clip(self._check_q("gripper opening", gripper, (2,)), 0.0, 100.0)
                self._g, self._gt, self._last_g = ga.copy(), ga.copy(), ga.copy()

    def step(self, n: int = 1) -> JointStateBatch:
        """Advance ``n`` samples with the current targets (manual mode) and stream them; returns them."""
        self._require_manual()
        with self._deliver_lock:
            with self._lock:
                batch = self._produce(int(n))
            self._deliver(batch)
        return batch

    def run_targets(self, q_targets: np.ndarray, gripper_targets: np.ndarray | None = None, *, batch: int = 20) -> int:
        """Manual mode: follow per-sample joint targets (n, 14) (and gripper targets (n, 2)).

        Sample i is produced after target i is commanded, so targets that respect the velocity limits are
        reproduced exactly (plus sensor noise). Samples reach listeners in batches of ``batch``, as in real
        time. Returns the number of samples produced.
        """
        self._require_manual()
        qt = np.asarray(q_targets, dtype=np.float64)
        if qt.ndim != 2 or qt.shape[1] != 14:
            raise InvalidInput(f"Joint targets must have shape (N, 14), got {qt.shape}.")
        if not np.all(np.isfinite(qt)):
            raise InvalidInput("The joint targets contain missing or invalid values (NaN or infinity).")
        n = qt.shape[0]
        gt = None
        if gripper_targets is not None:
            gt = np.asarray(gripper_targets, dtype=np.float64)
            if gt.shape != (n, 2) or not np.all(np.isfinite(gt)):
                raise InvalidInput(f"Gripper targets must be finite with shape ({n}, 2), got {gt.shape}.")
            gt = np.clip(gt, 0.0, 100.0)
        qt = np.clip(qt, self.lower, self.upper)
        step = max(1, int(batch))
        with self._deliver_lock:
            for s in range(0, n, step):
                e = min(n, s + step)
                with self._lock:
                    q = rate_limited_series(self._q, qt[s:e], self._qstep)
                    if gt is None:
                        g = rate_limited(self._g, self._gt, np.full(2, self._gstep), e - s)
                    else:
                        g = rate_limited_series(self._g, gt[s:e], np.full(2, self._gstep))
                        self._gt = gt[e - 1].copy()
                    self._qt = qt[e - 1].copy()
                    out = self._emit(q, g)
                self._deliver(out)
        return n

    # -- internals ----------------------------------------------------------------------------------------
    def _require_manual(self) -> None:
        if self._clock.running:
            raise InvalidInput("The simulated robot is streaming in real time; stop it before stepping by hand.")

    def _advance_to(self, sim_t: float) -> None:
        with self._deliver_lock:
            last_due = math.floor(sim_t * self.rate_hz + 1e-6)
            n = last_due - self._k + 1
            while n > 0:
                m = min(n, MAX_BATCH)
                with self._lock:
                    batch = self._produce(m)
                self._deliver(batch)
                n -= m

    def _produce(self, n: int) -> JointStateBatch:
        if n <= 0:
            return JointStateBatch(_ro(np.empty(0)), _ro(np.empty((0, 14))), _ro(np.empty((0, 2))))
        if self._halt_k is not None and self._k + n > self._halt_k:
            # an emergency stop falls in this batch: move up to it, hold from it on
            m = max(0, self._halt_k - self._k)
            first = self._produce(m) if m else None
            self._apply_halt()
            rest = self._emit(np.tile(self._q, (n - m, 1)), np.tile(self._g, (n - m, 1)))
            if first is None:
                return rest
            return JointStateBatch(
                _ro(np.concatenate([first.t, rest.t])),
                _ro(np.concatenate([first.q, rest.q])),
                _ro(np.concatenate([first.gripper, rest.gripper])),
            )
        if self._plan_q is not None:
            return self._produce_plan(n)
        q = rate_limited(self._q, self._qt, self._qstep, n)
        g = rate_limited(self._g, self._gt, np.full(2, self._gstep), n)
        return self._emit(q, g)

    def _produce_plan(self, n: int) -> JointStateBatch:
        """n samples following the plan with the velocity and acceleration limits (caller holds the lock)."""
        assert self._plan_q is not None and self._plan_g is not None
        pq, pg = self._plan_q, self._plan_g
        last = pq.shape[0] - 1
        # plan progress of each of the n samples
        if self._dr == 0.0:
            prog = self._p + np.arange(1, n + 1, dtype=np.float64)
            rates = np.ones(n)
        else:
            rates = np.maximum(self._r - self._dr * np.arange(1, n + 1), 0.0)
            prog = self._p + np.cumsum(rates)
        prog = np.clip(prog, 0.0, last)
        i0 = np.floor(prog).astype(np.int64)
        i1 = np.minimum(i0 + 1, last)
        w = (prog - i0)[:, None]
        targets = pq[i0] * (1 - w) + pq[i1] * w
        g_targets = pg[np.round(prog).astype(np.int64)]
        q = self._follow(targets)
        g = rate_limited_series(self._g, g_targets, np.full(2, self._gstep))
        self._p, self._r = float(prog[-1]), float(rates[-1])
        t_plan = max(self._p, 0.0) * self.dt
        state, msg = self._exec.state, self._exec.message
        at_rest = bool(np.max(np.abs(self._v)) < 1e-6) if n else True
        if self._p >= last and at_rest:
            state, msg = "done", "The robot finished the skill."
        elif state == "stopping" and self._r <= 0.0 and at_rest:
            state, msg = "stopped", f"The robot stopped at {t_plan:.1f} s of {self._exec.duration:.1f} s."
        self._exec = ExecutionProgress(state, t_plan, self._exec.duration, self._exec.started_at, msg)
        if state in ("done", "stopped"):
            self._qt, self._gt = self._q.copy(), g[-1].copy()
            self._plan_q = self._plan_g = None
        return self._emit(q, g)

    def _follow(self, targets: np.ndarray) -> np.ndarray:
        """(n, 14) joint positions following per-sample ``targets`` within the velocity and acceleration limits.

        Each sample reaches its target exactly when the limits allow it from the current position and
        velocity (so a plan within the limits is reproduced exactly — checked for the whole batch at once);
        otherwise each joint moves with the target's velocity plus the fastest approach from which it can
        still brake onto the target (√(2·a·|error|)), as far as the limits allow.
        """
        dt = self.dt
        vmax, amax = self.velocity, self.acceleration
        steps = np.diff(np.vstack([self._q[None, :], targets]), axis=0) / dt  # velocities to hit each target
        dv = np.diff(np.vstack([self._v[None, :], steps]), axis=0) / dt
        if np.all(np.abs(steps) <= vmax * (1 + 1e-9)) and np.all(np.abs(dv) <= amax * (1 + 1e-9)):
            self._v = steps[-1].copy()
            self._last_target = targets[-1].copy()
            return targets.astype(np.float64, copy=True)
        out = np.empty_like(targets)
        q, v = self._q.copy(), self._v.copy()
        prev = self._last_target if self._last_target is not None else q
        amax_dt = amax * dt
        for i in range(targets.shape[0]):
            x = targets[i]
            need = (x - q) / dt
            exact = (np.abs(need) <= vmax) & (np.abs(need - v) <= amax_dt)
            e = x - q
            v_t = (x - prev) / dt
            # braking in steps of a·dt from speed u covers u²/(2a) + u·dt/2: the fastest u that still stops
            brake = np.sqrt((0.5 * amax_dt) ** 2 + 2.0 * amax * np.abs(e)) - 0.5 * amax_dt
            v_des = v_t + np.sign(e) * np.minimum(brake, np.abs(e) / dt)
            v_new = np.clip(np.clip(v_des, v - amax_dt, v + amax_dt), -vmax, vmax)
            v = np.where(exact, need, v_new)
            q = np.clip(q + v * dt, self.lower, self.upper)
            out[i] = q
            prev = x
        self._v = v
        self._last_target = prev.copy()
        return out

    def _emit(self, q: np.ndarray, g: np.ndarray) -> JointStateBatch:
        n = q.shape[0]
        if self._plan_q is None and n:  # outside a plan the velocity is what the last step did
            prev = q[-2] if n >= 2 else self._q
            self._v = (q[-1] - prev) / self.dt
        self._q = q[-1].copy()
        self._g = g[-1].copy()
        t = (self._k + np.arange(n, dtype=np.float64)) / self.rate_hz
        self._k += n
        qm = q + self._rng.normal(0.0, self.sensor_noise, q.shape) if self.sensor_noise > 0 else q
        if self.quantum > 0:
            qm = np.round(qm / self.quantum) * self.quantum
        gm = g
        if self.gripper_noise > 0:
            gm = np.clip(g + self._rng.normal(0.0, self.gripper_noise, g.shape), 0.0, 100.0)
        batch = JointStateBatch(t=_ro(t), q=_ro(qm), gripper=_ro(gm))
        self._last_q = qm[-1].copy()
        self._last_g = gm[-1].copy()
        return batch

    def _deliver(self, batch: JointStateBatch) -> None:
        self._hub.deliver(batch)

    @property
    def listener_errors(self) -> int:
        """How many times a listener raised (each one logged; the stream went on)."""
        return self._hub.errors


__all__ = ["GRIPPER_SPEED", "SimulatedBaxter", "rate_limited", "rate_limited_series"]
