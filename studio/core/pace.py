"""The pace of a skill: idle stretches of a demonstration shortened before learning (:func:`without_pauses`,
:func:`remove_pauses`), and a learned joint trajectory timed again at another speed within the robot's joint
limits by the timing stage (:func:`at_speed`, :mod:`studio.core.timing`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from studio.core.errors import InvalidInput
from studio.core.timing import retime
from studio.core.types import Demo, JointTrajectory

#: The hand counts as resting below this speed (m/s) and this turning speed (rad/s), with a gripper that
#: moves less than this (percent per second).
REST_SPEED_M_S = 0.01
REST_TURN_RAD_S = 0.05
REST_GRIPPER_PCT_S = 5.0
#: Speeds are measured over this window (s), so that sensor noise does not count as motion.
WINDOW_S = 0.2
#: A rest longer than this (s) is shortened to this length: the robot still settles, but does not wait.
KEEP_S = 0.4
#: Knots of the joint path per second of skill time handed to the timing stage by :func:`at_speed`.
KNOTS_PER_S = 50.0
#: Slowest and fastest skill speed (× the taught pace).
MIN_SPEED, MAX_SPEED = 0.25, 4.0


def _rates(t: np.ndarray, values: np.ndarray, window: float) -> np.ndarray:
    """(N,) how fast ``values`` (N, d) change around each sample, per second: the distance between their mean
    over the ``window`` seconds before and the ``window`` seconds after, divided by ``window`` (the means
    average sensor noise away)."""
    n = len(t)
    c = np.vstack([np.zeros((1, values.shape[1])), np.cumsum(values, axis=0)])
    lo = np.searchsorted(t, t - window, side="left")
    hi = np.searchsorted(t, t + window, side="right")
    mid = np.arange(n)
    before = (c[mid + 1] - c[lo]) / (mid + 1 - lo)[:, None]
    after = (c[hi] - c[mid]) / np.maximum(hi - mid, 1)[:, None]
    span = (t[np.maximum(hi - 1, mid)] - t[lo]) / 2.0
    return np.linalg.norm(after - before, axis=1) / np.maximum(span, 1e-9)


def resting(demo: Demo, *, window: float = WINDOW_S) -> np.ndarray:
    """(N,) True where the hand rests: slow, hardly turning, the gripper still."""
    t = np.asarray(demo.t, dtype=np.float64)
    if len(t) < 2:
        return np.zeros(len(t), dtype=bool)
    speed = _rates(t, np.asarray(demo.position, dtype=np.float64), window)
    grip = _rates(t, np.asarray(demo.gripper, dtype=np.float64)[:, None], window)
    q = np.asarray(demo.orientation, dtype=np.float64)
    turn = _rates(t, q * np.sign(q[:, :1] + 1e-12), window)  # small angles: the quaternion moves half as far
    return (speed < REST_SPEED_M_S) & (2.0 * turn < REST_TURN_RAD_S) & (grip < REST_GRIPPER_PCT_S)


def without_pauses(demo: Demo, *, keep: float = KEEP_S) -> np.ndarray:
    """(N,) new sample times of ``demo`` in which every rest longer than ``keep`` seconds lasts ``keep``
    seconds (the motion between rests keeps its pace); starts where ``demo.t`` starts, strictly increasing."""
    if keep <= 0:
        raise InvalidInput("The length a pause is shortened to must be positive.")
    t = np.asarray(demo.t, dtype=np.float64)
    if len(t) < 3:
        return t.copy()
    rest = resting(demo)
    dt = np.diff(t)
    idle = rest[:-1] & rest[1:]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], idle.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        total = float(dt[a:b].sum())
        if total > keep:
            dt[a:b] *= keep / total
    return np.concatenate([[t[0]], t[0] + np.cumsum(dt)])


def remove_pauses(demo: Demo, *, keep: float = KEEP_S) -> Demo:
    """``demo`` with its long rests shortened (:func:`without_pauses`); the same samples, other times."""
    return replace(demo, t=without_pauses(demo, keep=keep))


def at_speed(jt: JointTrajectory, speed: float, vlim: np.ndarray, alim: np.ndarray) -> JointTrajectory:
    """``jt`` timed again at ``speed`` × the taught pace (at most: slower where a joint's velocity ``vlim`` or
    acceleration ``alim`` (7,) limit requires it), along the same joint path; at rest at both ends.

    Raises:
        InvalidInput: ``speed`` outside [:data:`MIN_SPEED`, :data:`MAX_SPEED`] or a trajectory without its
            skill time.
    """
    if not MIN_SPEED <= speed <= MAX_SPEED:
        raise InvalidInput(f"The skill's speed must be between {MIN_SPEED:g}× and {MAX_SPEED:g}× the taught pace.")
    if abs(speed - 1.0) < 1e-9 or len(jt.t) < 3:
        return jt
    if jt.skill_time is None:
        raise InvalidInput("This skill was learned by an older studio: train it again to change its speed.")
    s = np.asarray(jt.skill_time, dtype=np.float64)
    q = np.asarray(jt.q, dtype=np.float64)
    pieces = _pieces(s, q)
    if not pieces:
        return jt
    rate = 1.0 / float(np.median(np.diff(jt.t)))
    timing = retime(pieces, vlim, alim, rate_hz=rate, pace=speed, s_range=(float(s[0]), float(s[-1])))
    src = np.clip(np.searchsorted(s, timing.s, side="right") - 1, 0, len(s) - 1)
    return JointTrajectory(
        float(jt.t[0]) + timing.t,
        timing.q,
        np.asarray(jt.position_error)[src],
        np.asarray(jt.orientation_error)[src],
        np.asarray(jt.converged)[src],
        jt.arm,
        None if jt.gripper is None else np.asarray(jt.gripper)[src],
        skill_time=timing.s,
    )


def _pieces(s: np.ndarray, q: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The stretches of (s, q) along which the skill time advances, as knots about 1/:data:`KNOTS_PER_S` s of
    skill time apart (where s stands still the arm holds or changes posture: the timing stage moves it)."""
    moving = np.diff(s) > 1e-9
    out: list[tuple[np.ndarray, np.ndarray]] = []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], moving.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        seg = s[a : b + 1]  # samples a..b: s strictly increasing
        _, first = np.unique(np.floor((seg - seg[0]) * KNOTS_PER_S), return_index=True)
        ks = np.union1d(first, [len(seg) - 1]) + a
        if len(ks) >= 2:
            out.append((s[ks], q[ks]))
    return out
