"""The generalized trajectory (paper § Generalized Trajectory): :func:`learned_path` makes the skill's path from the
timed path points, either the paper's cubic smoothing spline (:func:`generalize`: position and quaternion
together, weighted by the key-points behind each point, the gripper a step signal; decision 015) or the demos
averaged along their DTW alignment, pinned to their mean start, end, grasps and releases (decisions 003, 083).
:func:`joint_trajectory` (from :mod:`studio.core.execution`) turns a path into timed joint angles."""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_interp_spline, make_smoothing_spline

from studio.core import quality
from studio.core.caches import LearningCaches
from studio.core.errors import InvalidInput
from studio.core.keypoints import KeypointCache
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
#: Points per curve when the plain mean is matched to the aligned mean (:func:`_plain_mean_along`).
_ALONG_POINTS = 400
#: Shares of the plain mean tried when the aligned mean is farther from the demos than it (decision 083).
PLAIN_MEAN_SHARES = (0.25, 0.5, 0.75, 1.0)


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


def _pin_weights(t: np.ndarray, pins: list[tuple[float, np.ndarray, np.ndarray]]) -> list[tuple[int, np.ndarray]]:
    """Per pin (``pins`` sorted by time): its sample and its weight over ``t`` (1 there, a raised cosine fading
    out over :data:`PIN_S` or half the way to the neighbouring pin)."""
    idx = [int(np.argmin(np.abs(t - p[0]))) for p in pins]
    times = [float(t[i]) for i in idx]
    out = []
    for n, i in enumerate(idx):
        lo = min(PIN_S, (times[n] - times[n - 1]) / 2) if n > 0 else PIN_S
        hi = min(PIN_S, (times[n + 1] - times[n]) / 2) if n + 1 < len(pins) else PIN_S
        d = t - times[n]
        half = np.where(d < 0, max(lo, 1e-9), max(hi, 1e-9))
        w = np.where(np.abs(d) < half, 0.5 + 0.5 * np.cos(np.pi * np.clip(d / half, -1.0, 1.0)), 0.0)
        w[i] = 1.0
        out.append((i, w))
    return out


def pin_positions(t: np.ndarray, position: np.ndarray, pins: list[tuple[float, np.ndarray, np.ndarray]]) -> np.ndarray:
    """The positions :func:`pin_poses` gives (the same numbers), without turning the orientation."""
    pos = np.array(position, dtype=np.float64)
    if not pins:
        return pos
    pins = sorted(pins, key=lambda p: p[0])
    corr = np.zeros_like(pos)
    for (_, target, _), (i, w) in zip(pins, _pin_weights(t, pins), strict=True):
        corr += w[:, None] * (np.asarray(target, dtype=np.float64) - pos[i])
    return pos + corr


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
    corr_p = np.zeros_like(pos)
    corr_r = np.zeros((pos.shape[0], 3))
    for (_, target, q_target), (i, w) in zip(pins, _pin_weights(t, pins), strict=True):
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


# -- the learned path: the paper's spline or the aligned mean ----------------------------------------------------
@dataclass(frozen=True, eq=False)
class PathBasis:
    """What a learned path is made of: the timed path points (the spline's) and, per demo, the smoothed inverse
    of its DTW time map onto the reference's time line (the aligned mean's).

    Attributes:
        times: (P,) path point times, s from the reference's start; points: (P, 8); weights: (P,) key-points
            behind each point.
        ref: index of the reference demo.
        inverse: per demo, reference time (from its start) -> demo time (from its start).
    """

    times: np.ndarray
    points: np.ndarray
    weights: np.ndarray
    ref: int
    inverse: list[Callable[[np.ndarray], np.ndarray]]


def learned_path(
    demos: list[Demo],
    basis: PathBasis,
    *,
    generalization: str,
    smoothing: float,
    caches: LearningCaches,
    rate_hz: float | None = None,
) -> Demo:
    """The skill's path: the smoothing spline through the path points (``generalization="paper"``) or the demos
    averaged along their DTW alignment, pinned to their mean start, end, grasps and releases and moved toward
    the plain mean where that is nearer the demos (decision 083); at ``rate_hz`` (default: the demos' rate)."""
    ref_demo = demos[basis.ref]
    dt = float(np.median(np.diff(ref_demo.t)))
    traj = generalize(
        basis.times,
        basis.points,
        weights=basis.weights,
        t_start=0.0,
        t_end=ref_demo.duration,
        rate_hz=rate_hz or 1.0 / dt,
        smoothing=smoothing,
        name="learned skill",
    )
    if generalization == "paper":
        return traj
    t = np.asarray(traj.t)
    pose = _aligned_mean(demos, basis, t, caches.keypoints)
    pins = demo_pins(demos, t, traj.gripper)
    ori = make_sign_continuous(pose[:, 3:])
    pos, ori = pin_poses(t, pose[:, :3], ori, pins)
    if len(demos) > 1:
        tf, pf = t, pose
        if rate_hz is not None and t.shape[0] > 1 and abs((t[1] - t[0]) - dt) > 1e-12:
            # decided on the path at the demos' rate, as learn_skill makes it: the preview shows the skill
            tf = sample_times(0.0, ref_demo.duration, 1.0 / dt)
            pf = _aligned_mean(demos, basis, tf, caches.keypoints)
            grip = gripper_at(basis.times, basis.points, basis.weights, tf)
            share = _plain_mean_share(demos, tf, pf, demo_pins(demos, tf, grip), caches)
        else:
            share = _plain_mean_share(demos, t, pose, pins, caches)
        if share:
            along = _plain_mean_along(quality.time_normalised_mean(demos), tf, pf[:, :3])
            if tf is not t:
                along = np.column_stack([np.interp(t, tf, along[:, k]) for k in range(3)])
            pos = pin_positions(t, (1.0 - share) * pose[:, :3] + share * along, pins)
    return Demo(traj.t, pos, ori, traj.gripper, name="learned skill")


def _mean_pose(
    demos: list[Demo], inverse: list[Callable[[np.ndarray], np.ndarray]], ref: int, t: np.ndarray, cache: KeypointCache
) -> tuple[np.ndarray, np.ndarray]:
    """(len(t), 7) position and orientation and (len(t),) gripper: at each time of the reference, the mean of all
    demos (their 50 ms smoothed series) at the time DTW matched to it.

    Quaternions are averaged on one side: the reference's (sign-continuous) series keeps its own sign, and
    each other demo's quaternion takes the sign of the reference's at the same instant. (Against one fixed
    quaternion instead, a hand that turns past 180° from it flips sign there and the average jumps.)"""
    acc = np.zeros((t.shape[0], 7))
    grip = np.zeros(t.shape[0])
    q_ref: np.ndarray | None = None
    for d in [ref, *(i for i in range(len(demos)) if i != ref)]:
        demo = demos[d]
        ser = cache.series(demo)
        td_all = np.asarray(demo.t) - demo.t[0]
        w = np.clip(inverse[d](t), 0.0, td_all[-1])
        pos = np.column_stack([np.interp(w, td_all, ser.position[:, k]) for k in range(3)])
        q = np.column_stack([np.interp(w, td_all, ser.orientation[:, k]) for k in range(4)])
        if q_ref is None:
            q_ref = q
        else:
            q *= np.where(np.einsum("ij,ij->i", q, q_ref) < 0, -1.0, 1.0)[:, None]
        acc[:, :3] += pos
        acc[:, 3:] += q
        grip += np.interp(w, td_all, np.asarray(demo.gripper, dtype=np.float64))
    acc /= len(demos)
    acc[:, 3:] /= np.linalg.norm(acc[:, 3:], axis=1, keepdims=True)
    return acc, grip / len(demos)


def _aligned_mean(demos: list[Demo], basis: PathBasis, t: np.ndarray, cache: KeypointCache) -> np.ndarray:
    """(len(t), 7) position and orientation of the aligned mean (:func:`_mean_pose`)."""
    return _mean_pose(demos, basis.inverse, basis.ref, t, cache)[0]


def _plain_mean_along(b1: np.ndarray, t: np.ndarray, position: np.ndarray) -> np.ndarray:
    """(len(t), 3) the plain mean ``b1`` (:func:`quality.time_normalised_mean`) walked on the path's own time line:
    at each instant, the plain mean's point DTW matches to ``position`` (len(t), 3) there (its shape, this timing)."""
    from dtaidistance import dtw as dtai

    m = _ALONG_POINTS
    tm = np.linspace(float(t[0]), float(t[-1]), m)
    a = np.column_stack([np.interp(tm, t, position[:, k]) for k in range(3)])
    grid = np.linspace(0.0, b1.shape[0] - 1.0, m)
    b = np.column_stack([np.interp(grid, np.arange(b1.shape[0]), b1[:, k]) for k in range(3)])
    path = np.asarray(dtai.warping_path_fast(np.ascontiguousarray(a), np.ascontiguousarray(b)), dtype=np.int64)
    at = np.bincount(path[:, 0], weights=grid[path[:, 1]], minlength=m) / np.bincount(path[:, 0], minlength=m)
    index = np.interp(t, tm, at)
    return np.column_stack([np.interp(index, np.arange(b1.shape[0]), b1[:, k]) for k in range(3)])


def _plain_mean_share(
    demos: list[Demo],
    t: np.ndarray,
    pose: np.ndarray,
    pins: list[tuple[float, np.ndarray, np.ndarray]],
    caches: LearningCaches,
) -> float:
    """How far the aligned mean ``pose`` (len(t), 7), bent onto ``pins``, is moved toward the plain mean: 0 when its
    mean Fréchet distance to the demos is not larger than the plain mean's, else the first of
    :data:`PLAIN_MEAN_SHARES` that is not farther (or the least far). Remembered per path. Decision 083."""

    def choose() -> float:
        curves = np.stack(caches.guard_curves.get(demos)[0])
        D = curves.shape[0]

        def far(paths: list[np.ndarray]) -> np.ndarray:
            a = np.repeat(np.stack([quality.arc_resample(p) for p in paths]), D, axis=0)
            return quality.frechet_many(a, np.tile(curves, (len(paths), 1, 1))).reshape(len(paths), D).mean(axis=1)

        def bent(share: float) -> np.ndarray:
            return pin_positions(t, (1.0 - share) * pose[:, :3] + share * along, pins)

        b1 = quality.time_normalised_mean(demos)
        along = _plain_mean_along(b1, t, pose[:, :3])
        b1_far, own = far([b1, bent(0.0)])
        if own <= b1_far:
            return 0.0
        fars = far([bent(x) for x in PLAIN_MEAN_SHARES])
        near = [x for x, f in zip(PLAIN_MEAN_SHARES, fars, strict=True) if f <= b1_far]
        best = int(np.argmin(fars))
        return near[0] if near else (PLAIN_MEAN_SHARES[best] if fars[best] < own else 0.0)

    return float(caches.shares.get(_guard_key(demos, t, pose, pins), choose))


def _guard_key(demos: list[Demo], t: np.ndarray, pose: np.ndarray, pins: list) -> tuple:
    h = hashlib.blake2b(digest_size=16)
    for a in (t, pose[:, :3], *(np.r_[p[0], p[1]] for p in pins)):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return (tuple(id(d) for d in demos), h.hexdigest())


# Execution (whole-path IK and timing within the limits) lives in studio.core.execution; re-exported here.
from studio.core.execution import joint_trajectory  # noqa: E402

__all__ = [
    "GRIPPER_LEVEL_TOL",
    "PIN_S",
    "PLAIN_MEAN_SHARES",
    "SMOOTHING",
    "PathBasis",
    "demo_pins",
    "generalize",
    "gripper_at",
    "gripper_steps",
    "joint_trajectory",
    "learned_path",
    "pin_poses",
    "sample_times",
]
