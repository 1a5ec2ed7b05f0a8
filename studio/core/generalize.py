"""The generalized trajectory (paper § Generalized Trajectory) and its joint-space execution (§ Robot Execution).

The timed path points (centroids, or the mean of the key-points Viterbi assigned to each state, with
zero-points removed) are joined by cubic smoothing-spline regression (scipy ``make_smoothing_spline``,
penalised least squares Σ w (y − f)² + λ ∫ f''²) and sampled at the demonstrations' rate:

* position and quaternion components are fitted together; λ = ``smoothing`` · h³ with h the median spacing
  of the points in seconds (λ has units of s³, so this keeps the same amount of smoothing whatever the
  pace), weights = number of key-points behind each point (×10 for the first and the last: the skill
  must start and end where the demonstrations do; ``SMOOTHING`` was lowered from 0.02 to 0.005 after the
  quality tests showed the end pose pulled 5–7 mm off by the smoother fit); quaternions are made sign-continuous before
  the fit and renormalised after it;
* the gripper is not splined: it is a step signal. Consecutive path points whose opening differs by less
  than :data:`GRIPPER_LEVEL_TOL` form one level (their weighted mean: the learned opening and grasp width,
  which the paper stresses); the step is half-way in time between the last point of one level and the
  first of the next — both are gripper-event key-points at the grasp pose, so the step happens there.

Execution: :func:`joint_trajectory` runs IK along the trajectory at :data:`IK_RATE_HZ`, each solve seeded
by the previous one, interpolates the joints with a cubic spline to the trajectory's samples (doubling the
IK rate while the interpolated joints stray more than 0.5 mm from the path), clips them to the joint
limits, reports the per-sample Cartesian error by forward kinematics and, where a joint would exceed its
velocity limit, slows the trajectory down locally.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import CubicSpline, make_interp_spline, make_smoothing_spline
from scipy.ndimage import maximum_filter1d, uniform_filter1d

from studio.core.errors import IkFailed, InvalidInput
from studio.core.kinematics import Baxter, make_sign_continuous
from studio.core.types import Demo, JointTrajectory

#: Dimensionless smoothing: λ = SMOOTHING · h³ (0 interpolates the points exactly).
SMOOTHING = 0.005
#: Extra regression weight of the first and last point: the skill starts and ends where the demos do.
END_WEIGHT = 10.0
#: Openings closer than this (percent) belong to the same gripper level.
GRIPPER_LEVEL_TOL = 10.0
#: Path points closer in time than this (s) are merged before the fit.
MIN_SPACING_S = 0.02
#: IK solves per second along the trajectory (joints are a cubic spline between them).
IK_RATE_HZ = 50.0


def _merge_close(
    times: np.ndarray, points: np.ndarray, weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    keep_t, keep_p, keep_w = [times[0]], [points[0].copy()], [weights[0]]
    for t, p, w in zip(times[1:], points[1:], weights[1:], strict=True):
        if t - keep_t[-1] < MIN_SPACING_S:
            W = keep_w[-1] + w
            keep_p[-1] = (keep_p[-1] * keep_w[-1] + p * w) / W
            keep_t[-1] = (keep_t[-1] * keep_w[-1] + t * w) / W
            keep_w[-1] = W
        else:
            keep_t.append(t)
            keep_p.append(p.copy())
            keep_w.append(w)
    return np.array(keep_t), np.array(keep_p), np.array(keep_w)


def gripper_steps(times: np.ndarray, gripper: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Levels and step times of the gripper signal through the path points (time-sorted).

    Returns:
        levels (L,) percent and switch times (L − 1,) seconds.
    """
    levels: list[list[float]] = [[gripper[0] * weights[0], weights[0]]]
    bounds: list[tuple[float, float]] = []
    last_t = times[0]
    for t, g, w in zip(times[1:], gripper[1:], weights[1:], strict=True):
        cur = levels[-1][0] / levels[-1][1]
        if abs(g - cur) > GRIPPER_LEVEL_TOL:
            bounds.append((last_t, t))
            levels.append([g * w, w])
        else:
            levels[-1][0] += g * w
            levels[-1][1] += w
        last_t = t
    lv = np.array([s / w for s, w in levels])
    sw = np.array([(a + b) / 2.0 for a, b in bounds])
    return lv, sw


def generalize(
    times: np.ndarray,
    points: np.ndarray,
    *,
    weights: np.ndarray | None = None,
    t_start: float | None = None,
    t_end: float | None = None,
    rate_hz: float = 1000.0,
    smoothing: float = SMOOTHING,
    name: str = "learned skill",
) -> Demo:
    """Cubic smoothing spline through timed 8-D points, sampled at ``rate_hz``.

    Args:
        times: (S,) seconds on the common (reference) time line.
        points: (S, 8) x, y, z, qw, qx, qy, qz, gripper.
        weights: (S,) positive regression weights (default 1).
        t_start, t_end: sampled interval (default the first and last point); outside the points the
            trajectory holds the end values.
        rate_hz: output rate.
        smoothing: λ / h³ (see module docstring).

    Returns:
        A :class:`Demo` (t, position, unit sign-continuous orientation, step gripper).
    """
    times = np.asarray(times, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 8 or times.shape != (points.shape[0],) or points.shape[0] == 0:
        raise InvalidInput("The path needs S times and S 8-D points (x, y, z, quaternion, gripper).")
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(points))):
        raise InvalidInput("The path contains missing or invalid values.")
    if not (rate_hz > 0 and smoothing >= 0):
        raise InvalidInput("The rate must be positive and the smoothing not negative.")
    w = np.ones(times.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    order = np.argsort(times, kind="stable")
    times, points, w = times[order], points[order].copy(), w[order]
    points[:, 3:7] = make_sign_continuous(points[:, 3:7])
    times, points, w = _merge_close(times, points, w)
    t0 = float(times[0] if t_start is None else t_start)
    t1 = float(times[-1] if t_end is None else t_end)
    n = max(2, math.floor((t1 - t0) * rate_hz + 1e-9) + 1)
    t = t0 + np.arange(n) / rate_hz
    tc = np.clip(t, times[0], times[-1])
    y = points[:, :7]
    s = times.shape[0]
    if s == 1:
        pose = np.repeat(y, n, axis=0)
    elif s < 5:
        pose = make_interp_spline(times, y, k=min(3, s - 1))(tc)
    else:
        h = float(np.median(np.diff(times)))
        wn = w / w.mean()
        wn[[0, -1]] *= END_WEIGHT
        spline = make_smoothing_spline(times, y, w=wn, lam=smoothing * h**3)
        pose = spline(tc)
    q = pose[:, 3:7]
    nrm = np.linalg.norm(q, axis=1, keepdims=True)
    q = make_sign_continuous(q / np.maximum(nrm, 1e-12))
    levels, switches = gripper_steps(times, points[:, 7], w)
    g = levels[np.searchsorted(switches, t, side="right")]
    return Demo(t, pose[:, :3], q, g, name=name)


def joint_trajectory(
    trajectory: Demo,
    arm: str,
    q_seed: np.ndarray,
    baxter: Baxter | None = None,
    *,
    ik_rate_hz: float = IK_RATE_HZ,
) -> JointTrajectory:
    """Joint angles that execute ``trajectory`` with ``arm``: IK seeded by the previous solve.

    Args:
        trajectory: the generalized trajectory (Cartesian).
        arm: "left" or "right".
        q_seed: (7,) joint angles near the trajectory's start (e.g. the reference demo's first sample).
        ik_rate_hz: IK solves per second; joints are a cubic spline between solves.

    Returns:
        A :class:`JointTrajectory`; ``t`` equals ``trajectory.t`` unless a joint velocity limit forced a
        local slow-down, in which case the time line is stretched there and resampled at the same rate.

    Raises:
        IkFailed: the start pose cannot be reached at all (more than 1 cm or 0.1 rad away).
    """
    b = baxter or Baxter.load()
    n = len(trajectory)
    t = trajectory.t
    step = max(1, round((1.0 / ik_rate_hz) / max(float(np.median(np.diff(t))) if n > 1 else 1.0, 1e-9)))
    knots = np.unique(np.concatenate([np.arange(0, n, step), [n - 1]]))
    P, O = trajectory.position, trajectory.orientation
    res = b.ik(
        arm,
        P[0],
        O[0],
        np.asarray(q_seed, dtype=float),
        max_iterations=500,
        position_tolerance=2e-5,
        orientation_tolerance=2e-4,
    )
    if res.position_error > 0.01 or res.orientation_error > 0.1:
        raise IkFailed(
            f"The {arm} arm cannot reach the learned skill's start pose "
            f"({res.position_error * 1000:.0f} mm away, gripper turned "
            f"{math.degrees(res.orientation_error):.0f}° from the taught direction). "
            "Teach the task closer to the robot, with the gripper in a direction the arm can hold."
        )
    qk = np.empty((knots.shape[0], 7))
    q = res.q
    for j, i in enumerate(knots):
        q = b.ik(arm, P[i], O[i], q, max_iterations=100, position_tolerance=2e-5, orientation_tolerance=2e-4).q
        qk[j] = q
    lo, hi = b.lower_limits(arm), b.upper_limits(arm)
    Q = np.clip(CubicSpline(t[knots], qk, axis=0)(t) if knots.shape[0] > 1 else np.repeat(qk, n, 0), lo, hi)
    pos, ori = b.fk_batch(arm, Q)
    perr = np.linalg.norm(pos - P, axis=1)
    oerr = 2.0 * np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", ori, O)), 0.0, 1.0))
    if (perr.max() > 5e-4 or oerr.max() > 5e-3) and ik_rate_hz < 400.0 and step > 1:
        # fast joint motion: the cubic between solves drifts from the path; solve more often
        return joint_trajectory(trajectory, arm, q_seed, b, ik_rate_hz=ik_rate_hz * 2)
    conv = (perr <= 1e-3) & (oerr <= 1e-2)
    # Velocity limits: stretch time where a joint would be too fast.
    vmax = b.velocity_limits(arm)
    if n > 2:
        v = np.abs(np.gradient(Q, t, axis=0)) / vmax
        ratio = v.max(axis=1)
        if ratio.max() > 1.0:
            w = max(1, round(0.2 * n / max(t[-1] - t[0], 1e-9)))
            stretch = np.maximum(1.0, uniform_filter1d(maximum_filter1d(ratio, 2 * w + 1), w) * 1.05)
            dt = np.diff(t) * stretch[1:]
            tn = np.concatenate([[t[0]], t[0] + np.cumsum(dt)])
            rate = 1.0 / float(np.median(np.diff(t)))
            grid = t[0] + np.arange(math.floor((tn[-1] - t[0]) * rate) + 1) / rate
            Q = np.column_stack([np.interp(grid, tn, Q[:, j]) for j in range(7)])
            perr = np.interp(grid, tn, perr)
            oerr = np.interp(grid, tn, oerr)
            conv = np.interp(grid, tn, conv.astype(float)) > 0.5
            g = np.asarray(trajectory.gripper)[np.clip(np.searchsorted(tn, grid, side="right") - 1, 0, n - 1)]
            return JointTrajectory(grid, Q, perr, oerr, conv, arm, g)
    return JointTrajectory(t, Q, perr, oerr, conv, arm, trajectory.gripper)


__all__ = [
    "GRIPPER_LEVEL_TOL",
    "IK_RATE_HZ",
    "SMOOTHING",
    "generalize",
    "gripper_steps",
    "joint_trajectory",
]
