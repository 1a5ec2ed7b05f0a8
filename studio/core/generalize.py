"""The generalized trajectory (paper § Generalized Trajectory) and its joint-space execution (§ Robot Execution).

The timed path points are joined by a cubic smoothing spline (scipy ``make_smoothing_spline``), position and
quaternion components together, weighted by the key-points behind each point (the ends most), and sampled at
the demonstrations' rate; the gripper is a step signal between levels, switching at the gripper-event
key-points. Choices and figures: docs/decisions/015. :func:`joint_trajectory` (from
:mod:`studio.core.execution`) turns the path into timed joint angles."""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import make_interp_spline, make_smoothing_spline

from studio.core.errors import InvalidInput
from studio.core.kinematics import make_sign_continuous
from studio.core.types import Demo

#: Dimensionless smoothing: λ = SMOOTHING · h³ (0 interpolates the points exactly).
SMOOTHING = 0.005
#: Extra regression weight of the first and last point: the skill starts and ends where the demos do.
END_WEIGHT = 10.0
#: Openings closer than this (percent) belong to the same gripper level.
GRIPPER_LEVEL_TOL = 10.0
#: Path points closer in time than this (s) are merged before the fit.
MIN_SPACING_S = 0.02
#: Seconds either side over which a path is bent onto a pinned pose (:func:`pin_poses`).
PIN_S = 0.15


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
        smoothing: λ / h³ (docs/decisions/015).

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
    times, points, w = _prepared(times, points, weights)
    t = sample_times(
        float(times[0] if t_start is None else t_start), float(times[-1] if t_end is None else t_end), rate_hz
    )
    tc = np.clip(t, times[0], times[-1])
    y = points[:, :7]
    s = times.shape[0]
    if s == 1:
        pose = np.repeat(y, t.shape[0], axis=0)
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
    return Demo(t, pose[:, :3], q, _steps_at(times, points[:, 7], w, t), name=name)


def _prepared(
    times: np.ndarray, points: np.ndarray, weights: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    w = np.ones(times.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    order = np.argsort(times, kind="stable")
    times, points, w = times[order], points[order].copy(), w[order]
    points[:, 3:7] = make_sign_continuous(points[:, 3:7])
    return _merge_close(times, points, w)


def _steps_at(times: np.ndarray, gripper: np.ndarray, weights: np.ndarray, t: np.ndarray) -> np.ndarray:
    levels, switches = gripper_steps(times, gripper, weights)
    return levels[np.searchsorted(switches, t, side="right")]


def sample_times(t_start: float, t_end: float, rate_hz: float) -> np.ndarray:
    """The instants :func:`generalize` samples between ``t_start`` and ``t_end`` at ``rate_hz`` (at least two)."""
    n = max(2, math.floor((t_end - t_start) * rate_hz + 1e-9) + 1)
    return t_start + np.arange(n) / rate_hz


def gripper_at(times: np.ndarray, points: np.ndarray, weights: np.ndarray | None, t: np.ndarray) -> np.ndarray:
    """The gripper signal :func:`generalize` gives for the same path points, at the instants ``t``."""
    times, points, w = _prepared(np.asarray(times, dtype=np.float64), np.asarray(points, dtype=np.float64), weights)
    return _steps_at(times, points[:, 7], w, np.asarray(t, dtype=np.float64))


def _mean_quat(qs: np.ndarray | list[np.ndarray]) -> np.ndarray:
    qs = np.asarray(qs, dtype=np.float64)
    qs = qs * np.where(qs @ qs[0] < 0, -1.0, 1.0)[:, None]
    m = qs.mean(axis=0)
    return m / np.linalg.norm(m)


def pin_poses(
    t: np.ndarray, position: np.ndarray, orientation: np.ndarray, pins: list[tuple[float, np.ndarray, np.ndarray]]
) -> tuple[np.ndarray, np.ndarray]:
    """Bend a path so it passes exactly through each pin at its instant.

    Args:
        t: (N,) seconds; position (N, 3) m; orientation (N, 4) wxyz.
        pins: (time s, position (3,), orientation wxyz (4,)) each; a pin's time is rounded to the nearest sample.

    Returns:
        (position, orientation): the difference at each pin's sample, faded out by a raised cosine over
        :data:`PIN_S` (or half the way to the neighbouring pin, so each pin stays exact) on either side.
    """
    from scipy.spatial.transform import Rotation

    pos = np.array(position, dtype=np.float64)
    ori = np.array(orientation, dtype=np.float64)
    if not pins:
        return pos, ori
    pins = sorted(pins, key=lambda p: p[0])
    idx = [int(np.argmin(np.abs(t - p[0]))) for p in pins]
    times = [float(t[i]) for i in idx]
    corr_p = np.zeros_like(pos)
    corr_r = np.zeros((pos.shape[0], 3))
    for n, ((_, target, q_target), i) in enumerate(zip(pins, idx, strict=True)):
        lo = min(PIN_S, (times[n] - times[n - 1]) / 2) if n > 0 else PIN_S
        hi = min(PIN_S, (times[n + 1] - times[n]) / 2) if n + 1 < len(pins) else PIN_S
        d = t - times[n]
        half = np.where(d < 0, max(lo, 1e-9), max(hi, 1e-9))
        w = np.where(np.abs(d) < half, 0.5 + 0.5 * np.cos(np.pi * np.clip(d / half, -1.0, 1.0)), 0.0)
        w[i] = 1.0
        corr_p += w[:, None] * (np.asarray(target, dtype=np.float64) - pos[i])
        qt = np.asarray(q_target, dtype=np.float64)
        qi = ori[i] * (1.0 if float(np.dot(ori[i], qt)) >= 0 else -1.0)
        rel = Rotation.from_quat(np.r_[qt[1:], qt[0]]) * Rotation.from_quat(np.r_[qi[1:], qi[0]]).inv()
        corr_r += w[:, None] * rel.as_rotvec()[None, :]
    pos += corr_p
    xyzw = (Rotation.from_rotvec(corr_r) * Rotation.from_quat(np.column_stack([ori[:, 1:], ori[:, :1]]))).as_quat()
    wxyz = make_sign_continuous(np.column_stack([xyzw[:, 3], xyzw[:, :3]]))
    if float(np.dot(wxyz[0], ori[0])) < 0:
        wxyz = -wxyz
    return pos, wxyz


def demo_pins(demos: list[Demo], t: np.ndarray, gripper: np.ndarray) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Where a path learned from ``demos`` must pass exactly: the demos' mean start and end pose at ``t``'s ends and,
    when every demo and the path's gripper signal (``gripper`` at ``t``) act the same way, the demos' mean pose at
    each grasp and release, at the path's switch."""
    from studio.core.keypoints import gripper_events

    pins = [
        (float(t[k]), np.mean([d.position[k] for d in demos], axis=0), _mean_quat([d.orientation[k] for d in demos]))
        for k in (0, -1)
    ]
    g = np.asarray(gripper, dtype=np.float64)
    switches = np.flatnonzero(np.abs(np.diff(g)) > 1.0) + 1
    acts = []
    for d in demos:
        ev = gripper_events(np.asarray(d.t), np.asarray(d.gripper))
        dg = np.asarray(d.gripper)
        acts.append([(bool(dg[b] < dg[a]), a, b) for a, b in zip(ev[0::2], ev[1::2], strict=True)])
    kinds = {tuple(c for c, _, _ in a) for a in acts}
    mine = tuple(bool(g[j] < g[j - 1]) for j in switches)
    if len(kinds) != 1 or next(iter(kinds)) != mine:
        return pins
    for n, j in enumerate(switches):
        both = [(d, a[n][1], a[n][2]) for d, a in zip(demos, acts, strict=True)]
        p = np.mean([(d.position[a] + d.position[b]) / 2.0 for d, a, b in both], axis=0)
        q = _mean_quat([d.orientation[(a + b) // 2] for d, a, b in both])
        pins.append((float(t[j]), p, q))
    return pins


# Execution (whole-path IK and timing within the limits) lives in studio.core.execution; re-exported here.
from studio.core.execution import joint_trajectory  # noqa: E402

__all__ = [
    "GRIPPER_LEVEL_TOL",
    "PIN_S",
    "SMOOTHING",
    "demo_pins",
    "generalize",
    "gripper_at",
    "gripper_steps",
    "joint_trajectory",
    "pin_poses",
    "sample_times",
]
