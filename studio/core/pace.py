"""The pace of a skill: a take becomes a demonstration from its first motion to its last with its long still
stretches shortened (:func:`take_clock`, :class:`TakeClock`; :func:`without_pauses`), and a learned joint
trajectory timed again at another speed within the robot's joint limits (:func:`at_speed`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from studio.core.errors import InvalidInput
from studio.core.frames import DemoObjects
from studio.core.timing import retime
from studio.core.types import Demo, JointTrajectory

#: The hand counts as still below this speed (m/s) and this turning speed (rad/s), with a gripper that
#: moves less than this (percent per second); a slow careful drag (5 mm/s) is motion (decision 094).
REST_SPEED_M_S = 0.0025
REST_TURN_RAD_S = 0.01
REST_GRIPPER_PCT_S = 2.0
#: Speeds are measured over this window (s), so that sensor noise does not count as motion.
WINDOW_S = 0.25
#: A still stretch at least this long (s) is a pause; it is shortened to :data:`KEEP_S`.
PAUSE_S = 1.0
#: What is left of a pause (s): the robot still settles, but does not wait.
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
    mid = np.arange(n)
    a, b = np.searchsorted(t, t[0] + window), np.searchsorted(t, t[-1] - window, side="right") - 1
    if a < b:  # near the ends, the nearest sample with whole windows on both sides speaks for them
        mid = np.clip(mid, a, b)
    lo = np.searchsorted(t, t[mid] - window, side="left")
    hi = np.searchsorted(t, t[mid] + window, side="right")
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


def _still(demos: Sequence[Demo]) -> np.ndarray:
    """(N,) True where every arm of one take is still (its hand, its turn and its gripper; what it carries
    moves only with it)."""
    out = resting(demos[0])
    for d in demos[1:]:
        out = out & resting(d)
    return out


def _stretches(still: np.ndarray, t: np.ndarray, a: int, b: int, longer: float) -> list[tuple[int, int]]:
    """(i, j) sample spans within ``a``…``b`` where consecutive samples are still for at least ``longer`` s."""
    idle = still[a:b] & still[a + 1 : b + 1]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], idle.astype(np.int8), [0]])))
    return [(a + i, a + j) for i, j in zip(edges[::2], edges[1::2], strict=True) if t[a + j] - t[a + i] >= longer]


@dataclass(frozen=True)
class TakeClock:
    """How a take becomes a demonstration: its samples ``first``…``last`` (first to last motion), at times ``t``
    (from 0) in which each pause (``pauses``: start and end on the take's clock) lasts :data:`KEEP_S`, unless
    the teacher keeps them (``kept``)."""

    first: int
    last: int
    source: np.ndarray  # (n,) the take's times of samples first…last
    t: np.ndarray  # (n,) their times in the demonstration, from 0
    pauses: tuple[tuple[float, float], ...]
    kept: bool
    start: float  # the take's first time
    take: float  # the take's length (s)

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    @property
    def removed(self) -> float:
        """Seconds of pauses left out (0 when they are kept)."""
        return 0.0 if self.kept else sum(max(0.0, b - a - KEEP_S) for a, b in self.pauses)

    @property
    def still_ends(self) -> float:
        """Seconds of stillness before the first motion and after the last."""
        return max(0.0, self.take - float(self.source[-1] - self.source[0]))

    def at(self, t: float) -> float:
        """The demonstration's time of the take's moment ``t`` (clipped to its first and last motion)."""
        return float(np.interp(t, self.source, self.t))

    def demo(self, d: Demo) -> Demo:
        """``d`` (one arm of the take, every sample) as taught: first to last motion, pauses shortened."""
        sl = slice(self.first, self.last + 1)
        q = None if d.q is None else d.q[sl]
        return replace(
            d, t=self.t.copy(), position=d.position[sl], orientation=d.orientation[sl], gripper=d.gripper[sl], q=q
        )

    def objects(self, o: DemoObjects) -> DemoObjects:
        """The take's objects (contacts timed from the take's start) with each grasp and release at its moment
        in the demonstration."""
        return replace(o, contacts=tuple(replace(c, t=self.at(c.t + self.start)) for c in o.contacts))


def take_clock(demos: Sequence[Demo], *, keep: bool = False) -> TakeClock:
    """The :class:`TakeClock` of one take from its arms' ``demos`` (the same samples): from the first sample
    where an arm moves to the last; every still stretch of at least :data:`PAUSE_S` between is a pause,
    shortened to :data:`KEEP_S` unless ``keep``. A take that never moves stays whole."""
    t = np.asarray(demos[0].t, dtype=np.float64)
    n = len(t)
    take = float(t[-1] - t[0]) if n else 0.0
    still = _still(demos) if n >= 2 else np.zeros(n, dtype=bool)
    moving = np.flatnonzero(~still)
    first, last = (int(moving[0]), int(moving[-1])) if len(moving) else (0, max(n - 1, 0))
    if len(moving):  # a moment of stillness kept at each end, as at a pause: the motion starts and ends at rest
        first = int(np.searchsorted(t, t[first] - KEEP_S))
        last = int(np.searchsorted(t, t[last] + KEEP_S, side="right")) - 1
    if last - first < 1:
        first, last = 0, max(n - 1, 0)
    src = t[first : last + 1]
    spans = _stretches(still, t, first, last, PAUSE_S) if len(moving) and n >= 2 else []
    dt = np.diff(src)
    if not keep:
        for i, j in spans:
            dt[i - first : j - first] *= KEEP_S / float(t[j] - t[i])
    new = np.concatenate([[0.0], np.cumsum(dt)])
    pauses = tuple((float(t[i]), float(t[j])) for i, j in spans)
    return TakeClock(first, last, src.copy(), new, pauses, keep, float(t[0]) if n else 0.0, take)


def without_pauses(demo: Demo, *, keep: float = KEEP_S) -> np.ndarray:
    """(N,) new sample times of ``demo`` in which every pause (still for at least :data:`PAUSE_S`) lasts
    ``keep`` seconds (the motion between keeps its pace); starts where ``demo.t`` starts, strictly increasing."""
    if keep <= 0:
        raise InvalidInput("The length a pause is shortened to must be positive.")
    t = np.asarray(demo.t, dtype=np.float64)
    if len(t) < 3:
        return t.copy()
    dt = np.diff(t)
    for a, b in _stretches(resting(demo), t, 0, len(t) - 1, max(PAUSE_S, keep)):
        dt[a:b] *= keep / float(t[b] - t[a])
    return np.concatenate([[t[0]], t[0] + np.cumsum(dt)])


def remove_pauses(demo: Demo, *, keep: float = KEEP_S) -> Demo:
    """``demo`` with its pauses shortened (:func:`without_pauses`); the same samples, other times."""
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
