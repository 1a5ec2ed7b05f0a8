"""Timing a joint path within Baxter's joint velocity and acceleration limits (toppra), at the taught pace.

The joint path q(s) from :mod:`studio.core.ik_path` runs at the skill's own pace (ṡ = 1) wherever that is
within the limits; toppra (with the :class:`PaceConstraint` ṡ ≤ 1) slows it along the same path only in the
windows where a limit requires, and between pieces of a path the arm rests and moves in a straight joint-space
line (trapezoidal profile). The result is checked at the output rate and solved again with tighter limits if
needed. Why toppra, and why in windows: docs/decisions/010."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from studio.core.errors import InvalidInput

log = logging.getLogger(__name__)

#: Fraction of each limit the plan may use (the rest absorbs discretisation between toppra's grid points).
LIMIT_MARGIN = 0.97
#: Time (s) added on each side of a stretch that needs slowing down, so toppra has room to slow and resume.
WINDOW_PAD_S = 0.5
#: Largest number of toppra grid points in one window; grid spacing is 10 ms below that.
MAX_GRID = 1500
#: Most samples a timed joint trajectory may have: its arrays and the work of making them grow with it
#: (about 350 bytes a sample at the peak; docs/decisions/051-memory-budget.md).
MAX_TIMED_SAMPLES = 1_500_000
GRID_STEP_S = 0.01
#: Largest deviation (rad) of the joint path from straight chords between grid points.
GRID_TOLERANCE_RAD = 2e-5
#: A joint speed (rad/s) below which the path counts as at rest at its ends.
REST_SPEED = 1e-3


@dataclass(frozen=True, eq=False)
class Timing:
    """A timed joint trajectory.

    Attributes:
        t: (M,) seconds from 0 at ``rate_hz``.
        s: (M,) the skill time each sample executes (constant while the arm changes posture).
        q: (M, 7) joint angles, radians.
        reconfiguring: (M,) True while the arm moves between two pieces of the path (off the path).
        rate_hz: samples per second.
    """

    t: np.ndarray
    s: np.ndarray
    q: np.ndarray
    reconfiguring: np.ndarray
    rate_hz: float

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if self.t.shape[0] else 0.0


def _toppra() -> tuple[ModuleType, ModuleType, ModuleType, type]:
    """toppra, its algorithms and constraints, and its linear constraint base class (imported on first use)."""
    import toppra as ta
    import toppra.algorithm as algo
    import toppra.constraint as constraint
    from toppra.constraint.linear_constraint import LinearConstraint

    return ta, algo, constraint, LinearConstraint


_PACE_CLASS: type | None = None


def pace_constraint(pace: float, dof: int) -> Any:
    """A toppra constraint ṡ ≤ ``pace``: the path may not be run faster than it was taught.

    Returns:
        An instance of a subclass of toppra's ``LinearConstraint`` (toppra has no type annotations).
    """
    global _PACE_CLASS
    if _PACE_CLASS is None:
        base: Any = _toppra()[3]

        class PaceConstraint(base):
            """ṡ² ≤ pace² at every grid point (toppra's canonical linear form, bounds on x = ṡ² only)."""

            def __init__(self, pace: float, dof: int) -> None:
                super().__init__()
                self.pace = float(pace)
                self.dof = int(dof)

            def compute_constraint_params(
                self, path: Any, gridpoints: np.ndarray, *args: Any, **kwargs: Any
            ) -> tuple[None, None, None, None, None, None, np.ndarray]:
                xbound = np.zeros((len(gridpoints), 2))
                xbound[:, 1] = self.pace**2
                return None, None, None, None, None, None, xbound

        _PACE_CLASS = PaceConstraint
    return _PACE_CLASS(pace, dof)


_CONSTRAINTS: dict[tuple[bytes, bytes, float], list[Any]] = {}


def _constraints(vlim: np.ndarray, alim: np.ndarray, pace: float) -> list[Any]:
    """toppra's joint velocity and acceleration constraints and the pace constraint, built once per set of limits
    (they hold no path; building them formats their limits into strings)."""
    key = (vlim.tobytes(), alim.tobytes(), float(pace))
    cons = _CONSTRAINTS.get(key)
    if cons is None:
        constraint = _toppra()[2]
        cons = [
            constraint.JointVelocityConstraint(vlim),
            constraint.JointAccelerationConstraint(alim),
            pace_constraint(pace, vlim.shape[0]),
        ]
        if len(_CONSTRAINTS) >= 64:
            _CONSTRAINTS.clear()
        _CONSTRAINTS[key] = cons
    return cons


@dataclass(frozen=True)
class _Segment:
    """Constant path acceleration from (s0, v0) to (s1, v1); or a posture change (kind = -1)."""

    piece: int
    s0: float
    s1: float
    v0: float
    v1: float

    @property
    def duration(self) -> float:
        ds = self.s1 - self.s0
        if ds <= 0:
            return 0.0
        return 2.0 * ds / max(self.v0 + self.v1, 1e-9)


def _timed_samples(total: float, rate_hz: float) -> int:
    """Samples of a timed trajectory lasting ``total`` s at ``rate_hz``, refused beyond :data:`MAX_TIMED_SAMPLES`."""
    M = max(1, math.ceil(total * rate_hz - 1e-9)) + 1
    if M > MAX_TIMED_SAMPLES:
        raise InvalidInput(
            f"Within its speed limits the robot would need {total / 60:,.0f} minutes to follow this skill, longer "
            f"than the {MAX_TIMED_SAMPLES / rate_hz / 60:,.0f} minutes a skill can be planned for: the learned path "
            "is very long or jittery. Teach it with smoother movements, or in shorter parts."
        )
    return M


def _grid(spl: CubicSpline, a: float, b: float, refine: float) -> np.ndarray:
    """toppra grid points on [a, b]: every :data:`GRID_STEP_S`, denser where the joint path bends.

    As toppra's own ``propose_gridpoints`` does, the spacing Δ keeps the path's deviation from its chords,
    ½ |q''| Δ², below :data:`GRID_TOLERANCE_RAD` (near a singularity joints turn fast for little gripper
    motion, and the limits must hold between grid points too); computed here vectorised, not by bisection.
    """
    fine = np.linspace(a, b, max(3, math.ceil((b - a) * 2000) + 1))
    curv = np.concatenate(  # a chunk at a time: a long path has millions of fine points
        [np.max(np.abs(spl(fine[i : i + 100_000], 2)), axis=1) for i in range(0, fine.shape[0], 100_000)]
    )
    density = np.maximum(1.0 / GRID_STEP_S, np.sqrt(curv / (2.0 * GRID_TOLERANCE_RAD))) / refine
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (density[1:] + density[:-1]) * np.diff(fine))])
    n = int(min(MAX_GRID / refine, max(2.0, math.ceil(cum[-1])))) + 1
    return np.unique(np.concatenate([[a], np.interp(np.linspace(0, cum[-1], n), cum, fine), [b]]))


def _window_segments(
    piece: int,
    spl: CubicSpline,
    a: float,
    b: float,
    v_start: float,
    v_end: float,
    vlim: np.ndarray,
    alim: np.ndarray,
    pace: float,
    refine: float,
) -> list[_Segment] | None:
    """toppra on s in [a, b] with ṡ(a) = v_start, ṡ(b) = v_end; None when infeasible."""
    algo = _toppra()[1]
    grid = _grid(spl, a, b, refine)
    n = grid.shape[0]
    path = _SubPath(spl, a, b)
    inst = algo.TOPPRA(_constraints(vlim, alim, pace), path, gridpoints=grid, solver_wrapper="seidel")
    try:
        inst.compute_parameterization(v_start, v_end)
    except Exception:  # toppra raises on some degenerate inputs; treat as "widen the window"
        return None
    data = inst.problem_data
    if data.sd_vec is None or not np.all(np.isfinite(data.sd_vec)) or str(data.return_code.name) != "Ok":
        return None
    sd = np.maximum(np.asarray(data.sd_vec, dtype=np.float64), 0.0)
    return [_Segment(piece, float(grid[i]), float(grid[i + 1]), float(sd[i]), float(sd[i + 1])) for i in range(n - 1)]


class _SubPath:
    """A toppra geometric path: the piece's spline restricted to [a, b] (toppra calls it with s values)."""

    def __init__(self, spl: CubicSpline, a: float, b: float) -> None:
        self._spl, self._d1, self._d2 = spl, spl.derivative(1), spl.derivative(2)
        self.path_interval = np.array([a, b])
        self.dof = int(np.asarray(spl(a)).shape[-1])

    def __call__(self, s: float | np.ndarray, order: int = 0) -> np.ndarray:
        return (self._spl, self._d1, self._d2)[order](s)

    def get_dof(self) -> int:
        return self.dof


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    if not mask.any():
        return []
    e = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(e == 1).tolist(), (np.flatnonzero(e == -1) - 1).tolist(), strict=True))


def _piece_segments(
    piece: int,
    s: np.ndarray,
    q: np.ndarray,
    vlim: np.ndarray,
    alim: np.ndarray,
    pace: float,
    rest_start: bool,
    rest_end: bool,
    rate_hz: float,
    refine: float = 1.0,
) -> tuple[CubicSpline | None, list[_Segment]]:
    """Segments timing one continuous piece of the path."""
    if s.shape[0] < 2 or s[-1] - s[0] <= 0:
        return None, []
    spl = CubicSpline(s, q, axis=0)
    n = max(2, math.ceil((s[-1] - s[0]) * rate_hz) + 1)
    ss = np.linspace(s[0], s[-1], n)
    d1, d2 = np.abs(spl(ss, 1)), np.abs(spl(ss, 2))
    need = np.maximum(np.max(d1 * pace / vlim, axis=1), np.max(d2 * pace * pace / alim, axis=1))
    bad = need > 1.0
    if rest_start and float(np.max(d1[0])) * pace > REST_SPEED:
        bad[0] = True
    if rest_end and float(np.max(d1[-1])) * pace > REST_SPEED:
        bad[-1] = True
    pad = WINDOW_PAD_S
    for _attempt in range(8):
        # windows: the bad runs padded by `pad` seconds of skill time, merged
        wins: list[list[float]] = []
        for i0, i1 in _runs(bad):
            a, b = max(ss[0], ss[i0] - pad), min(ss[-1], ss[i1] + pad)
            if wins and a <= wins[-1][1]:
                wins[-1][1] = max(wins[-1][1], b)
            else:
                wins.append([a, b])
        segs: list[_Segment] = []
        cursor = float(ss[0])
        failed = False
        for a, b in wins:
            if a > cursor:
                segs.append(_Segment(piece, cursor, a, pace, pace))
            va = 0.0 if (rest_start and a <= ss[0]) else pace
            vb = 0.0 if (rest_end and b >= ss[-1]) else pace
            w = _window_segments(piece, spl, a, b, va, vb, vlim, alim, pace, refine)
            if w is None:
                failed = True
                break
            segs.extend(w)
            cursor = b
        if not failed:
            if cursor < ss[-1]:
                segs.append(_Segment(piece, cursor, float(ss[-1]), pace, pace))
            return spl, segs
        pad *= 2.0
    raise InvalidInput(
        "The robot's speed limits could not be met along this skill; try teaching it more slowly."
    )  # pragma: no cover - a whole-piece window is always feasible from rest to rest


def _trapezoid(dq: np.ndarray, vlim: np.ndarray, alim: np.ndarray) -> tuple[float, float, float]:
    """Rest-to-rest straight-line move of joint change ``dq``: (duration, peak speed, acceleration) in path units."""
    L = float(np.max(np.abs(dq)))
    if L <= 0:
        return 0.0, 0.0, 1.0
    u = np.abs(dq) / L  # per unit of path progress λ ∈ [0, L]
    nz = u > 0
    v = float(np.min(vlim[nz] / u[nz]))
    a = float(np.min(alim[nz] / u[nz]))
    if v * v / a >= L:  # triangle
        v = math.sqrt(a * L)
        return 2.0 * v / a, v, a
    return L / v + v / a, v, a


def _trapezoid_progress(dt: np.ndarray, T: float, v: float, a: float, L: float) -> np.ndarray:
    ta = v / a
    out = np.where(
        dt < ta,
        0.5 * a * dt * dt,
        np.where(dt <= T - ta, 0.5 * a * ta * ta + v * (dt - ta), L - 0.5 * a * (T - dt) ** 2),
    )
    return np.clip(out, 0.0, L)


def retime(
    pieces: Sequence[tuple[np.ndarray, np.ndarray]],
    vlim: np.ndarray,
    alim: np.ndarray,
    *,
    rate_hz: float = 1000.0,
    pace: float = 1.0,
    margin: float = LIMIT_MARGIN,
    s_range: tuple[float, float] | None = None,
) -> Timing:
    """Time a joint path, piece by piece, at the taught pace within the limits.

    Args:
        pieces: [(s (k,), q (k, 7)), ...] knots of each continuous piece, s in the skill's seconds, the
            pieces in order. Between two pieces the arm comes to rest and moves straight in joint space to
            the next one, taking at least the skill time between them (so the rest of the skill keeps its
            timing), more if the limits require it.
        vlim, alim: (7,) joint velocity (rad/s) and acceleration (rad/s²) limits.
        rate_hz: output samples per second.
        pace: 1.0 = as taught; 0.5 = at most half as fast.
        margin: fraction of the limits planned for (tightened automatically if the check fails).
        s_range: the skill's whole time span; before the first piece and after the last the arm holds
            still for that long (default: the pieces' span).

    Returns:
        A :class:`Timing` at ``rate_hz`` starting and ending at rest, checked by finite differences.

    Raises:
        InvalidInput: no piece, a non-positive rate or pace, or limits that cannot be met (never seen).
    """
    vlim = np.asarray(vlim, dtype=np.float64)
    alim = np.asarray(alim, dtype=np.float64)
    if not pieces:
        raise InvalidInput("There is no joint path to time.")
    if not (rate_hz > 0 and pace > 0):
        raise InvalidInput("The rate and the pace must be positive.")
    m = float(margin)
    refine = 1.0
    for attempt in range(6):
        timing = _retime_once(pieces, vlim * m, alim * m, rate_hz, pace, refine, s_range)
        ratio = limit_ratio(timing.q, rate_hz, vlim, alim)
        if ratio <= 1.0 + 1e-9:
            return timing
        # Between grid points toppra does not see the limits: a little more margin first (a slight excess, the
        # same grid: half the cost of a finer one), then a finer grid too.
        log.debug("timing exceeded a limit by %.3f; tighter limits%s", ratio, "" if ratio < 1.01 else ", finer grid")
        if ratio >= 1.01 or attempt > 0:
            refine *= 0.5
        m *= min(0.99, 0.995 / ratio) if ratio < 1.2 else 0.99
    raise InvalidInput(
        "The robot's speed and acceleration limits could not be met along this skill; try teaching it more slowly."
    )


def limit_ratio(q: np.ndarray, rate_hz: float, vlim: np.ndarray, alim: np.ndarray) -> float:
    """Largest |velocity| / limit or |acceleration| / limit of samples q (M, d) at ``rate_hz`` (finite differences)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[0] < 2:
        return 0.0
    v = np.abs(np.diff(q, axis=0)) * rate_hz
    r = float(np.max(v / vlim))
    if q.shape[0] >= 3:
        a = np.abs(np.diff(q, 2, axis=0)) * rate_hz * rate_hz
        r = max(r, float(np.max(a / alim)))
    return r


#: A rest-to-rest straight joint move: (q0, q1, duration, peak speed, acceleration, skill time s0, s1).
_Move = tuple[np.ndarray, np.ndarray, float, float, float, float, float]


def _move(
    q0: np.ndarray, q1: np.ndarray, s0: float, s1: float, vlim: np.ndarray, alim: np.ndarray, pace: float
) -> tuple[tuple[str, _Move], float]:
    """A rest-to-rest straight joint move q0 → q1 lasting at least (s1 − s0) / pace (time-scaled trapezoid)."""
    T, v, a = _trapezoid(q1 - q0, vlim, alim)
    T_min = max(0.0, (s1 - s0) / pace)
    if T < T_min:  # slower than the limits allow: stretch the profile in time (v × c, a × c²)
        c = T / T_min if T > 0 else 1.0
        v, a, T = v * c, a * c * c, T_min
    return ("move", (q0, q1, T, v, a, s0, s1)), T


def _retime_once(
    pieces: Sequence[tuple[np.ndarray, np.ndarray]],
    vlim: np.ndarray,
    alim: np.ndarray,
    rate_hz: float,
    pace: float,
    refine: float = 1.0,
    s_range: tuple[float, float] | None = None,
) -> Timing:
    splines: list[CubicSpline | None] = []
    # Timeline items: ("path", _Segment) or ("move", (q0, q1, T, v, a, s0, s1)), with their start times.
    starts: list[float] = []
    items: list[tuple[str, Any]] = []
    now = 0.0
    npieces = len(pieces)
    p_first_s = float(np.asarray(pieces[0][0])[0])
    p_last_s = float(np.asarray(pieces[-1][0])[-1])
    if s_range is not None and s_range[0] < p_first_s - 1e-9:  # hold until the first piece the arm can follow
        q0 = np.asarray(pieces[0][1], dtype=np.float64)[0]
        item, T = _move(q0, q0, float(s_range[0]), p_first_s, vlim, alim, pace)
        starts.append(now)
        items.append(item)
        now += T
    for k, (s, q) in enumerate(pieces):
        s = np.asarray(s, dtype=np.float64)
        q = np.asarray(q, dtype=np.float64)
        spl, segs = _piece_segments(k, s, q, vlim, alim, pace, True, True, rate_hz, refine)
        splines.append(spl)
        for sg in segs:
            starts.append(now)
            items.append(("path", sg))
            now += sg.duration
        if k + 1 < npieces:
            s_next, q_next = np.asarray(pieces[k + 1][0], dtype=np.float64), np.asarray(pieces[k + 1][1])
            item, T = _move(q[-1], q_next[0].astype(np.float64), float(s[-1]), float(s_next[0]), vlim, alim, pace)
            if T > 0:
                starts.append(now)
                items.append(item)
                now += T
    if s_range is not None and s_range[1] > p_last_s + 1e-9:  # hold at the last piece the arm can follow
        q1 = np.asarray(pieces[-1][1], dtype=np.float64)[-1]
        item, T = _move(q1, q1, p_last_s, float(s_range[1]), vlim, alim, pace)
        starts.append(now)
        items.append(item)
        now += T
    total = now
    M = _timed_samples(total, rate_hz)
    t = np.arange(M) / rate_hz
    S = np.empty(M)
    Q = np.empty((M, vlim.shape[0]))
    recon = np.zeros(M, dtype=bool)
    if not items:  # a path that does not move: hold its only pose
        s0, q0 = pieces[0]
        return Timing(
            t[:1], np.asarray(s0, dtype=np.float64)[:1], np.asarray(q0, dtype=np.float64)[:1], recon[:1], rate_hz
        )
    st = np.asarray(starts)
    which = np.clip(np.searchsorted(st, t, side="right") - 1, 0, len(items) - 1)
    # path segments, vectorised
    nseg = len(items)
    is_path = np.zeros(nseg, dtype=bool)
    seg_s0, seg_s1, seg_v0, seg_v1 = np.zeros(nseg), np.zeros(nseg), np.zeros(nseg), np.zeros(nseg)
    seg_piece = np.full(nseg, -1)
    for j, (kind, it) in enumerate(items):
        if kind == "path":
            assert isinstance(it, _Segment)
            is_path[j] = True
            seg_s0[j], seg_s1[j], seg_v0[j], seg_v1[j], seg_piece[j] = it.s0, it.s1, it.v0, it.v1, it.piece
    ds = seg_s1 - seg_s0
    acc = np.where(ds > 0, (seg_v1**2 - seg_v0**2) / (2.0 * np.maximum(ds, 1e-300)), 0.0)
    sel = is_path[which]
    dt = t - st[which]
    s_val = seg_s0[which] + seg_v0[which] * dt + 0.5 * acc[which] * dt * dt
    S[sel] = np.minimum(np.maximum(s_val, seg_s0[which]), seg_s1[which])[sel]
    for k, spl in enumerate(splines):
        mk = sel & (seg_piece[which] == k)
        if mk.any():
            Q[mk] = np.asarray(pieces[k][1], dtype=np.float64)[0] if spl is None else spl(S[mk])
    for jm in np.flatnonzero(~is_path):
        j = int(jm)
        mk = which == j
        if not mk.any():
            continue
        q0, q1, T, v, a, s0, s1 = items[j][1]
        L = float(np.max(np.abs(q1 - q0)))
        if L > 0:
            lam = _trapezoid_progress(t[mk] - st[j], T, v, a, L) / L
        else:
            lam = np.clip((t[mk] - st[j]) / max(T, 1e-300), 0.0, 1.0)
        Q[mk] = q0 + np.outer(lam, q1 - q0)
        S[mk] = s0 + np.clip((t[mk] - st[j]) / max(T, 1e-300), 0.0, 1.0) * (s1 - s0)
        recon[mk] = L > 0
    # the last sample is the path's end, at rest
    S[-1] = float(s_range[1]) if s_range is not None else p_last_s
    Q[-1] = np.asarray(pieces[-1][1], dtype=np.float64)[-1]
    return Timing(t, S, Q, recon, rate_hz)


def pace_ratio(
    f: Callable[[np.ndarray], np.ndarray], s: np.ndarray, vlim: np.ndarray, alim: np.ndarray
) -> float:  # pragma: no cover - diagnostic helper for benchmarks
    """Largest limit ratio of q(s) executed at the taught pace (s sampled uniformly)."""
    q = f(s)
    rate = 1.0 / float(np.median(np.diff(s)))
    return limit_ratio(q, rate, vlim, alim)


__all__ = ["LIMIT_MARGIN", "Timing", "limit_ratio", "pace_constraint", "retime"]
