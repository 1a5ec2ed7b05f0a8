"""How the simulated Baxter moves and what its sensors report (used by :mod:`studio.robot_backend.simulated`):
:class:`SimArms` (true state, targets, limits), :func:`rate_limited` and :func:`follow` (towards targets
within the velocity, and acceleration, limits), :class:`Sensors` (noise and encoder quantisation on what is
streamed) and :func:`checked` (numbers given to the simulator, checked with a plain message)."""

from __future__ import annotations

import numpy as np

from studio.core.errors import InvalidInput
from studio.core.types import ARMS
from studio.robot_backend.base import JointStateBatch


def checked(name: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape``, all finite; otherwise :class:`InvalidInput` naming ``name``."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput(f"The {name} must be numbers, got {value!r}.") from exc
    if a.shape != shape:
        raise InvalidInput(f"The {name} must be {shape[0]} numbers, got shape {a.shape}.")
    if not np.all(np.isfinite(a)):
        raise InvalidInput(f"The {name} contain missing or invalid values (NaN or infinity); the command was ignored.")
    return a.copy()


def checked_targets(q_targets: np.ndarray, gripper_targets: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """Per-sample joint targets (n, 14) and optional gripper targets (n, 2, clipped to 0..100), checked.

    Raises:
        InvalidInput: a wrong shape, NaN or infinity.
    """
    qt = np.asarray(q_targets, dtype=np.float64)
    if qt.ndim != 2 or qt.shape[1] != 14:
        raise InvalidInput(f"Joint targets must have shape (N, 14), got {qt.shape}.")
    if not np.all(np.isfinite(qt)):
        raise InvalidInput("The joint targets contain missing or invalid values (NaN or infinity).")
    if gripper_targets is None:
        return qt, None
    gt = np.asarray(gripper_targets, dtype=np.float64)
    n = qt.shape[0]
    if gt.shape != (n, 2) or not np.all(np.isfinite(gt)):
        raise InvalidInput(f"Gripper targets must be finite with shape ({n}, 2), got {gt.shape}.")
    return qt, np.clip(gt, 0.0, 100.0)


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


def follow(
    q: np.ndarray,
    v: np.ndarray,
    prev_target: np.ndarray,
    targets: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    vmax: np.ndarray,
    amax: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(n, d) joint positions following per-sample ``targets`` within the velocity and acceleration limits.

    Starts at position ``q`` with velocity ``v``; ``prev_target`` is the target before ``targets[0]`` (its
    velocity). Each sample reaches its target exactly when the limits allow it from the current position
    and velocity (so a plan within the limits is reproduced exactly — checked for the whole batch at once);
    otherwise each joint moves with the target's velocity plus the fastest approach from which it can still
    brake onto the target (√(2·a·|error|)), as far as the limits allow.

    Returns:
        The positions (n, d) and the velocity after the last one (d,).
    """
    steps = np.diff(np.vstack([q[None, :], targets]), axis=0) / dt  # velocities to hit each target
    dv = np.diff(np.vstack([v[None, :], steps]), axis=0) / dt
    if np.all(np.abs(steps) <= vmax * (1 + 1e-9)) and np.all(np.abs(dv) <= amax * (1 + 1e-9)):
        return targets.astype(np.float64, copy=True), steps[-1].copy()
    out = np.empty_like(targets)
    q, v = q.copy(), v.copy()
    prev = prev_target
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
        q = np.clip(q + v * dt, lower, upper)
        out[i] = q
        prev = x
    return out, v


class Sensors:
    """What the simulated encoders and gripper sensors report of the true state.

    Args:
        sensor_noise: standard deviation (rad) of Gaussian noise on the joint angles; 0 disables it.
        quantum: encoder resolution (rad); joint angles are rounded to multiples of it; 0 disables it.
        gripper_noise: standard deviation (percent) of noise on the gripper openings.
        seed: seed of the noise generator (deterministic streams).
    """

    def __init__(self, sensor_noise: float = 0.0, quantum: float = 0.0, gripper_noise: float = 0.0, seed: int = 0):
        self.sensor_noise = float(sensor_noise)
        self.quantum = float(quantum)
        self.gripper_noise = float(gripper_noise)
        self._rng = np.random.default_rng(seed)

    def measure(self, q: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The streamed joint angles (n, 14) and gripper openings (n, 2) of true ones."""
        qm = q + self._rng.normal(0.0, self.sensor_noise, q.shape) if self.sensor_noise > 0 else q
        if self.quantum > 0:
            qm = np.round(qm / self.quantum) * self.quantum
        gm = g
        if self.gripper_noise > 0:
            gm = np.clip(g + self._rng.normal(0.0, self.gripper_noise, g.shape), 0.0, 100.0)
        return qm, gm


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


class SimArms:
    """Baxter's two arms (14 joints) and grippers as simulated: where they are (``q``, ``g``, exact), where
    they are going (``qt``, ``gt``), the joint velocity ``v``, the limits, and the sample counter ``k``.

    Not thread-safe: the simulator holds its lock around every call.

    Args:
        rate_hz: samples per second.
        q0: (14,) initial joint angles (None: both arms in the SDK's untuck pose), clipped into the limits.
        gripper0: (2,) initial gripper openings, percent.
        gripper_speed: percent of the stroke per second.
        sensors: what is streamed of the true state.
    """

    def __init__(
        self, rate_hz: float, q0: np.ndarray | None, gripper0: object, gripper_speed: float, sensors: Sensors
    ) -> None:
        self.rate_hz = rate_hz
        self.dt = 1.0 / rate_hz
        self.lower, self.upper, self.velocity, self.acceleration, neutral = _limits()
        self.qstep = self.velocity * self.dt
        self.gstep = np.full(2, float(gripper_speed) * self.dt)
        self.sensors = sensors
        self.k = 0  # index of the next sample to produce
        q = neutral if q0 is None else checked("initial joint angles", q0, (14,))
        self.q = np.clip(q, self.lower, self.upper)
        self.qt = self.q.copy()
        self.g = np.clip(checked("initial gripper opening", gripper0, (2,)), 0.0, 100.0)
        self.gt = self.g.copy()
        self.last_q, self.last_g = self.q.copy(), self.g.copy()  # the latest streamed (measured) sample
        self.v = np.zeros(14)  # joint velocity (rad/s) of the latest sample
        self.last_target = self.q.copy()  # the previous plan target (its velocity)

    @property
    def moving(self) -> bool:
        return bool(np.any(np.abs(self.qt - self.q) > 1e-9) or np.any(np.abs(self.gt - self.g) > 1e-9))

    def hold(self) -> None:
        """Stay where the arms and grippers are."""
        self.qt, self.gt = self.q.copy(), self.g.copy()

    def halt(self) -> None:
        """Stop dead where the latest sample is."""
        self.hold()
        self.v = np.zeros(14)

    def teleport(self, q: np.ndarray | None, gripper: np.ndarray | None) -> None:
        """Be at ``q`` (14,) / ``gripper`` (2,) at once and hold there (a reset, not physics)."""
        if q is not None:
            qa = np.clip(checked("joint angles", q, (14,)), self.lower, self.upper)
            self.q, self.qt, self.last_q = qa.copy(), qa.copy(), qa.copy()
        if gripper is not None:
            ga = np.clip(checked("gripper opening", gripper, (2,)), 0.0, 100.0)
            self.g, self.gt, self.last_g = ga.copy(), ga.copy(), ga.copy()

    def toward_targets(self, n: int) -> JointStateBatch:
        """``n`` samples moving towards the targets within the velocity limits."""
        return self.emit(rate_limited(self.q, self.qt, self.qstep, n), rate_limited(self.g, self.gt, self.gstep, n))

    def held(self, n: int) -> JointStateBatch:
        """``n`` samples standing still."""
        return self.emit(np.tile(self.q, (n, 1)), np.tile(self.g, (n, 1)))

    def along(self, targets: np.ndarray, g_targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint and gripper positions following a plan's per-sample targets within the velocity and
        acceleration limits (:func:`follow`); not yet emitted."""
        q, self.v = follow(
            self.q, self.v, self.last_target, targets, self.lower, self.upper, self.velocity, self.acceleration, self.dt
        )
        self.last_target = targets[-1].copy()
        return q, rate_limited_series(self.g, g_targets, self.gstep)

    def through(self, qt: np.ndarray, gt: np.ndarray | None) -> JointStateBatch:
        """Samples following per-sample joint targets (n, 14) and gripper targets (n, 2) (or the gripper
        target) within the velocity limits; the last ones stay the targets."""
        q = rate_limited_series(self.q, qt, self.qstep)
        if gt is None:
            g = rate_limited(self.g, self.gt, self.gstep, qt.shape[0])
        else:
            g = rate_limited_series(self.g, gt, self.gstep)
            self.gt = gt[-1].copy()
        self.qt = qt[-1].copy()
        return self.emit(q, g)

    def emit(self, q: np.ndarray, g: np.ndarray, *, velocity_known: bool = False) -> JointStateBatch:
        """Make samples q (n, 14), g (n, 2) the arms' new state and return them as streamed (time stamps from
        the sample counter, sensors applied). ``velocity_known``: ``v`` was set by :meth:`along`."""
        n = q.shape[0]
        if not velocity_known and n:  # the velocity is what the last step did
            prev = q[-2] if n >= 2 else self.q
            self.v = (q[-1] - prev) / self.dt
        self.q, self.g = q[-1].copy(), g[-1].copy()
        t = (self.k + np.arange(n, dtype=np.float64)) / self.rate_hz
        self.k += n
        qm, gm = self.sensors.measure(q, g)
        self.last_q, self.last_g = qm[-1].copy(), gm[-1].copy()
        return JointStateBatch(t=_ro(t), q=_ro(qm), gripper=_ro(gm))


def empty_batch() -> JointStateBatch:
    return JointStateBatch(_ro(np.empty(0)), _ro(np.empty((0, 14))), _ro(np.empty((0, 2))))


def joined(a: JointStateBatch, b: JointStateBatch) -> JointStateBatch:
    """Two consecutive batches as one."""
    return JointStateBatch(
        _ro(np.concatenate([a.t, b.t])), _ro(np.concatenate([a.q, b.q])), _ro(np.concatenate([a.gripper, b.gripper]))
    )


__all__ = [
    "Sensors",
    "SimArms",
    "checked",
    "checked_targets",
    "empty_batch",
    "follow",
    "joined",
    "rate_limited",
    "rate_limited_series",
]
