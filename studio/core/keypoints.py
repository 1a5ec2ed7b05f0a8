"""Key-point extraction (paper § Key-point Extraction, the criteria with ε1–ε7 for P and ε8–ε14 for O).

A sample becomes a key-point when a corner, pause or distance test holds for position or orientation; the
first and last samples and both ends of every gripper motion always are. Speeds are per second and
orientation distances rotation angles, so thresholds mean the same at any rate. :func:`precompute` derives the
ε-independent series once per demo; :func:`extract_keypoints` only thresholds and scans. Robust to 1 kHz
noise: docs/decisions/013; the tests' oracle: ``tests/core/oracles.py``."""

from __future__ import annotations

import functools
import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.rotations import make_sign_continuous as _sign_continuous
from studio.core.rotations import relative_axis as _relative_axis
from studio.core.rotations import rotation_angle
from studio.core.types import Demo, KeypointParams, readonly

#: Moving-average window applied to poses before any test, seconds.
SMOOTHING_S = 0.05
#: Half-width of the central difference used for speeds, seconds.
SPEED_HALF_WINDOW_S = 0.02
#: Arc-length stride of the corner test's neighbours: metres of path, radians of rotation.
CORNER_STRIDE_M = 0.03
#: ... but a fifteenth of the demo's size for small gestures (:func:`corner_stride`), never below this.
CORNER_STRIDE_MIN_M = 0.001
CORNER_STRIDE_RAD = 0.08
#: Gripper motion detection: speed above this (percent per second) is motion ...
GRIPPER_SPEED = 20.0
#: ... and a motion counts as an open/close event if the opening changes by more than this (percent).
GRIPPER_MIN_CHANGE = 5.0


@dataclass(frozen=True, eq=False)
class KeypointSeries:
    """Everything the criteria need that does not depend on ε, derived once per demonstration.

    Attributes:
        t: (N,) seconds.
        position: (N, 3) smoothed positions, m.
        orientation: (N, 4) smoothed, sign-continuous unit quaternions w, x, y, z.
        speed: (N,) linear speed of the smoothed position, m/s.
        angular_speed: (N,) rotation speed of the smoothed orientation, rad/s.
        corner_angle: (N,) position corner angle at an arc-length stride, rad in [0, π]; π where undefined.
        corner_angle_o: (N,) the same for orientation (rotation vectors in the tangent space), rad.
        gripper_events: (E,) sorted sample indices at both ends of each gripper motion.
    """

    t: np.ndarray
    position: np.ndarray
    orientation: np.ndarray
    speed: np.ndarray
    angular_speed: np.ndarray
    corner_angle: np.ndarray
    corner_angle_o: np.ndarray
    gripper_events: np.ndarray

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def corner_mask(self, channel: str, threshold: float) -> np.ndarray:
        """(N,) bool, True at corner candidates (:func:`corner_candidates`); the last few are cached, so a
        slider that moves another ε does not recompute them."""
        cache: dict[tuple[str, float], np.ndarray] = self.__dict__.setdefault("_corner_cache", {})
        key = (channel, float(threshold))
        m = cache.get(key)
        if m is None:
            angle = self.corner_angle if channel == "position" else self.corner_angle_o
            m = np.zeros(len(self), dtype=bool)
            m[corner_candidates(angle, threshold)] = True
            m.setflags(write=False)
            # The cache is shared by the slider and training threads; keep every step race-tolerant
            # (two threads may evict the same oldest entry) rather than bring a lock into the core.
            if len(cache) >= 8:
                try:
                    cache.pop(next(iter(cache)), None)
                except (StopIteration, RuntimeError):
                    pass
            cache[key] = m
        return m

    @functools.cached_property
    def position_t(self) -> np.ndarray:
        """(3, N) contiguous copy of :attr:`position` (the fast scan reads it in chunks of columns)."""
        return readonly(self.position.T)

    @functools.cached_property
    def orientation_t(self) -> np.ndarray:
        """(4, N) contiguous copy of :attr:`orientation`."""
        return readonly(self.orientation.T)


# -- vector helpers ----------------------------------------------------------------------------------------------


def _angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    nu, nv = np.linalg.norm(u, axis=-1), np.linalg.norm(v, axis=-1)
    ok = (nu > 0) & (nv > 0)
    c = np.einsum("...i,...i->...", u, v) / np.where(ok, nu * nv, 1.0)
    return np.where(ok, np.arccos(np.clip(c, -1.0, 1.0)), math.pi)


# -- precomputation ------------------------------------------------------------------------------------------------


def _samples(t: np.ndarray, seconds: float) -> int:
    dt = float(t[-1] - t[0]) / (len(t) - 1) if len(t) > 1 else 1.0  # mean sampling interval
    return max(1, round(seconds / dt))


def _stride_neighbours(arc: np.ndarray, stride: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices of the last sample ≥ ``stride`` of arc behind and the first ≥ ``stride`` ahead; validity."""
    n = arc.shape[0]
    prev = np.searchsorted(arc, arc - stride, side="right") - 1
    nxt = np.searchsorted(arc, arc + stride, side="left")
    valid = (arc - stride >= arc[0]) & (prev >= 0) & (nxt < n)
    return np.clip(prev, 0, n - 1), np.clip(nxt, 0, n - 1), valid


def gripper_events(t: np.ndarray, gripper: np.ndarray) -> np.ndarray:
    """Both ends of every gripper motion: the last sample before it moves and the first after it settles.

    Args:
        t: (N,) seconds.
        gripper: (N,) opening percent.

    Returns:
        Sorted unique sample indices (an even number of them, two per open/close event).
    """
    n = t.shape[0]
    if n < 3:
        return np.zeros(0, dtype=np.int64)
    g = uniform_filter1d(gripper.astype(np.float64), _samples(t, 0.02), mode="nearest")
    h = _samples(t, 0.01)
    lo, hi = np.maximum(np.arange(n) - h, 0), np.minimum(np.arange(n) + h, n - 1)
    rate = np.abs(g[hi] - g[lo]) / np.maximum(t[hi] - t[lo], 1e-12)
    moving = rate > GRIPPER_SPEED
    if not moving.any():
        return np.zeros(0, dtype=np.int64)
    edges = np.diff(np.concatenate([[0], moving.view(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # run [s, e)
    # merge motions separated by less than 50 ms (a noisy pause inside one gripper stroke)
    gap = _samples(t, 0.05)
    keep = np.concatenate([[True], starts[1:] - ends[:-1] > gap])
    starts = starts[keep]
    ends = np.concatenate([ends[np.flatnonzero(keep)[1:] - 1], ends[-1:]])
    out: list[int] = []
    for s, e in zip(starts, ends, strict=True):
        a, b = max(s - 1, 0), min(e, n - 1)
        if abs(g[b] - g[a]) > GRIPPER_MIN_CHANGE:
            out.extend((a, b))
    return np.unique(np.asarray(out, dtype=np.int64))


def corner_stride(position: np.ndarray) -> float:
    """Arc-length stride (m) of the position corner test for one demo: :data:`CORNER_STRIDE_M`, or a fifteenth
    of the demo's size (largest side of its bounding box) when that is smaller, but at least
    :data:`CORNER_STRIDE_MIN_M` (a 3 cm stride would span the whole of a 3 cm gesture)."""
    size = float(np.max(np.ptp(position, axis=0))) if len(position) else 0.0
    return float(min(CORNER_STRIDE_M, max(CORNER_STRIDE_MIN_M, size / 15.0)))


def precompute(demo: Demo) -> KeypointSeries:
    """Derive the ε-independent series of one demonstration (smoothing, speeds, corner angles, gripper).

    Args:
        demo: the demonstration (any sampling rate).

    Returns:
        A :class:`KeypointSeries`.
    """
    n = len(demo)
    if n < 2:
        raise NotEnoughData(f"{demo.name} has {n} sample(s); a demonstration needs at least two.")
    t = np.asarray(demo.t)
    w = _samples(t, SMOOTHING_S)
    pos = uniform_filter1d(demo.position, w, axis=0, mode="nearest")
    ori = uniform_filter1d(_sign_continuous(np.asarray(demo.orientation)), w, axis=0, mode="nearest")
    ori /= np.linalg.norm(ori, axis=1, keepdims=True)
    h = _samples(t, SPEED_HALF_WINDOW_S)
    idx = np.arange(n)
    lo, hi = np.maximum(idx - h, 0), np.minimum(idx + h, n - 1)
    span = np.maximum(t[hi] - t[lo], 1e-12)
    speed = np.linalg.norm(pos[hi] - pos[lo], axis=1) / span
    ang_speed = rotation_angle(ori[hi], ori[lo]) / span

    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1))])
    p, q, ok = _stride_neighbours(arc, corner_stride(pos))
    corner = np.where(ok, _angle_between(pos[p] - pos, pos[q] - pos), math.pi)

    arc_o = np.concatenate([[0.0], np.cumsum(rotation_angle(ori[1:], ori[:-1]))])
    p, q, ok = _stride_neighbours(arc_o, CORNER_STRIDE_RAD)
    corner_o = np.where(ok, _angle_between(_relative_axis(ori, ori[p]), _relative_axis(ori, ori[q])), math.pi)

    return KeypointSeries(
        t=readonly(t),
        position=readonly(pos),
        orientation=readonly(ori),
        speed=readonly(speed),
        angular_speed=readonly(ang_speed),
        corner_angle=readonly(corner),
        corner_angle_o=readonly(corner_o),
        gripper_events=readonly(gripper_events(t, np.asarray(demo.gripper)), dtype=np.int64),
    )


# -- the fast path -----------------------------------------------------------------------------------------------


def corner_candidates(angle: np.ndarray, threshold: float) -> np.ndarray:
    """One index per run of consecutive samples with ``angle < threshold``: the run's sharpest sample."""
    members = np.flatnonzero(angle < threshold)
    if members.shape[0] == 0:
        return members.astype(np.int64)
    starts = np.flatnonzero(np.diff(members) > 1) + 1
    starts = np.concatenate([[0], starts])
    vals = angle[members]
    mins = np.minimum.reduceat(vals, starts)
    lengths = np.diff(np.concatenate([starts, [members.shape[0]]]))
    hit = np.flatnonzero(vals == np.repeat(mins, lengths))
    run = np.searchsorted(starts, hit, side="right") - 1
    first = np.concatenate([[True], np.diff(run) > 0])
    return members[hit[first]].astype(np.int64)


_CHUNK = 1024


def _after(t: np.ndarray, tau: int, dur: float) -> int:
    """First index i with t[i] − t[τ] > dur, evaluated exactly as written (the reference's rounding)."""
    n = t.shape[0]
    i = int(np.searchsorted(t, t[tau] + dur, side="right"))
    while i > tau + 1 and t[i - 1] - t[tau] > dur:
        i -= 1
    while i < n and not (t[i] - t[tau] > dur):
        i += 1
    return i


class _Tests:
    """The three tests of one part of the pose (position: ε1–ε7, or orientation: ε8–ε14) from the last key-point
    τ, evaluated on chunks of samples after it.

    Distances are computed with exactly the reference's arithmetic (same operation order, sqrt and acos), so a
    sample lying exactly on a threshold is decided the same way by both implementations.
    """

    def __init__(
        self,
        rows: np.ndarray,
        corner: np.ndarray,
        still: np.ndarray,
        waits: tuple[float, float],
        eps: tuple[float, float, float],
        angle: bool,
    ) -> None:
        self.rows = rows  # (D, N): contiguous rows make chunk arithmetic fast
        self.corner = corner  # (N,) bool: the corner test, thresholded once per call
        self.still = still  # (N,) bool: slower than the pause speed
        self.pause_wait, self.travel_wait = waits  # ε3, ε6 (ε10, ε13)
        self.pause_dist, self.travel_dist, self.radius = eps  # ε4, ε5, ε7 (ε11, ε12, ε14)
        self.angle = angle
        self.n = rows.shape[1]

    def start(self, t: np.ndarray, tau: int) -> None:
        """A new last key-point τ: the time conditions become index bounds."""
        self.ref = self.rows[:, tau]
        self.i_pause, self.i_travel = _after(t, tau, self.pause_wait), _after(t, tau, self.travel_wait)
        # first sample at or after τ that left the radius (d(τ, τ) = 0), n while none did
        self.left = tau if self.radius <= 0 else self.n

    def distance(self, a: int, b: int) -> np.ndarray:
        """Distance of samples [a, b) from τ: metres, or the rotation angle in radians."""
        R, r = self.rows, self.ref
        if self.angle:
            dot = R[0, a:b] * r[0] + R[1, a:b] * r[1] + R[2, a:b] * r[2] + R[3, a:b] * r[3]
            return 2.0 * np.arccos(np.minimum(np.abs(dot), 1.0))
        d0, d1, d2 = R[0, a:b] - r[0], R[1, a:b] - r[1], R[2, a:b] - r[2]
        return np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)

    def keys(self, a: int, b: int) -> np.ndarray:
        """(b − a,) bool: where a test holds — a corner or a pause (both farther than the pause distance from
        τ), or the travel distance reached in time while the path stayed within the radius."""
        d = self.distance(a, b)
        if self.left == self.n:
            out = d >= self.radius
            if out.any():
                self.left = a + int(np.argmax(out))
        m = self.corner[a:b].copy()
        lo = max(self.i_pause, a)
        if lo < b:
            m[lo - a :] |= self.still[lo:b]
        key = m & (d > self.pause_dist)
        lo, hi = max(self.i_travel, a), min(self.left + 1, b)
        if lo < hi:
            key[lo - a : hi - a] |= d[lo - a : hi - a] >= self.travel_dist
        return key


def _next_keypoint(pos: _Tests, ori: _Tests, tau: int, ub: int, chunk: int) -> int:
    """The first sample after τ and before ``ub`` where a position or orientation test holds (else ``ub``).

    Chunks grow ×2 while nothing is found; orientation only needs checking before the position candidate.
    """
    a = tau + 1
    while a < ub:
        b = min(a + chunk, ub)
        key = pos.keys(a, b)
        k = int(np.argmax(key))
        if key[k]:
            b = a + k
        if b > a:
            key_o = ori.keys(a, b)
            ko = int(np.argmax(key_o))
            if key_o[ko]:
                return a + ko
        if key[k]:
            return a + k
        a = b
        chunk *= 2
    return ub


def extract_from_series(s: KeypointSeries, params: KeypointParams) -> np.ndarray:
    """The fast path: key-point indices from precomputed series (the tests: :func:`extract_keypoints`).

    Per call, the ε-dependent masks (corners, stillness) are thresholded once over the whole demonstration;
    the sequential part then evaluates all six tests together on chunks of samples after the last key-point
    τ (distances from τ, the time conditions as index bounds, "stayed within ε7" as the index of the first
    sample that left the ball) and jumps to the first sample where any test holds (:class:`_Tests`).
    """
    p = params
    n = len(s)
    t = s.t
    two_pi = 2.0 * math.pi
    pos = _Tests(
        s.position_t,
        s.corner_mask("position", two_pi - p.eps1),
        s.speed < p.eps2,
        (p.eps3, p.eps6),
        (p.eps4, p.eps5, p.eps7),
        angle=False,
    )
    ori = _Tests(
        s.orientation_t,
        s.corner_mask("orientation", two_pi - p.eps8),
        s.angular_speed < p.eps9,
        (p.eps10, p.eps13),
        (p.eps11, p.eps12, p.eps14),
        angle=True,
    )
    out = [0]
    tau = 0
    chunk = _CHUNK
    gev = s.gripper_events
    while tau < n - 1:
        pos.start(t, tau)
        ori.start(t, tau)
        # the next gripper event is a key-point for sure: nothing after it needs looking at
        g = int(np.searchsorted(gev, tau, side="right"))
        ub = min(int(gev[g]), n - 1) if g < gev.shape[0] else n - 1
        found = _next_keypoint(pos, ori, tau, ub, chunk)
        if found >= n - 1:
            break
        chunk = max(_CHUNK // 4, min(_CHUNK, 2 * (found - tau)))
        out.append(found)
        tau = found
    if n > 1:
        out.append(n - 1)
    return np.asarray(out, dtype=np.int64)


def extract_keypoints(
    demo: Demo, params: KeypointParams | None = None, *, series: KeypointSeries | None = None
) -> np.ndarray:
    """Key-points of one demonstration (paper § Key-point Extraction).

    A sample is a key-point if, for position (orientation), one of three tests holds:

    1. corner: the angle between the directions to its neighbours (at an arc-length stride on the smoothed
       path) is below 2π − ε1 (ε8), and the pose is more than ε4 (ε11) from the last key-point;
    2. pause: the speed is below ε2 (ε9), more than ε3 (ε10) s after the last key-point, and the pose is more
       than ε4 (ε11) from it;
    3. distance: the pose is at least ε5 (ε12) from the last key-point, more than ε6 (ε13) s after it, and
       every sample since stayed within ε7 (ε14) of it (the first exit from that ball).

    Args:
        demo: the demonstration.
        params: the fourteen thresholds; defaults to ``KeypointParams()``.
        series: :func:`precompute` (demo) if already available (the slider fast path).

    Returns:
        (K,) sorted unique int sample indices into ``demo``; always includes 0, N − 1 and both ends of
        every gripper motion.
    """
    params = params or KeypointParams()
    s = series if series is not None else precompute(demo)
    if len(s) != len(demo):
        raise InvalidInput(f"The precomputed series does not belong to {demo.name} (different number of samples).")
    return extract_from_series(s, params)


class KeypointCache:
    """Per-demonstration :class:`KeypointSeries`, computed once and reused for every ε change.

    Demonstrations are held weakly (a deleted demo's series goes with it). Thread-safe enough for one
    writer: a race only computes a series twice.
    """

    def __init__(self) -> None:
        self._series: weakref.WeakKeyDictionary[Demo, KeypointSeries] = weakref.WeakKeyDictionary()

    def series(self, demo: Demo) -> KeypointSeries:
        s = self._series.get(demo)
        if s is None:
            s = self._series[demo] = precompute(demo)
        return s

    def extract(self, demo: Demo, params: KeypointParams | None = None) -> np.ndarray:
        return extract_from_series(self.series(demo), params or KeypointParams())

    def extract_all(self, demos: Sequence[Demo], params: KeypointParams | None = None) -> list[np.ndarray]:
        return [self.extract(d, params) for d in demos]


__all__ = [
    "CORNER_STRIDE_M",
    "CORNER_STRIDE_MIN_M",
    "CORNER_STRIDE_RAD",
    "KeypointCache",
    "KeypointSeries",
    "corner_candidates",
    "corner_stride",
    "extract_from_series",
    "extract_keypoints",
    "gripper_events",
    "precompute",
    "rotation_angle",
]
