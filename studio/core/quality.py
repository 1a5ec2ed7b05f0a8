"""How good is a learned skill? Measures against the demonstrations, and a verdict in plain words (GUI-free).

Everything here compares **positions** of the gripper (metres), because that is what a teacher sees and what
the figures in the verdict speak of; orientation and the gripper are judged through the grasp/release poses.

Fidelity (:func:`fidelity`):

* curves are compared by shape, not by timing: each series is smoothed over 50 ms (tremor and sensor noise)
  and resampled to :data:`N_POINTS` points evenly spaced along its path;
* **normalised DTW** of two curves: the paper's DTW cost g (Σ of squared distances along the optimal
  alignment, dtaidistance's C warping path) ÷ the alignment's length, i.e. the mean *squared* distance of
  matched points (m²); **G/R** = mean normalised DTW of the learned path to each demo ÷ the demos' mean
  pairwise normalised DTW. A path central to the demonstrations is closer to each of them than they are to
  each other: for n demos that differ by independent noise, their exact mean has G/R = (n − 1)/(2n)
  (0.33 for 3, 0.43 for 7). The figures in metres (:attr:`Fidelity.distance`, "within 4 mm on average")
  are root-mean-square distances, √g; :attr:`Fidelity.rms_ratio` = √(G/R) is the same ratio in those terms
  (0.58 and 0.65 for that exact mean);
* **discrete Fréchet distance** (the leash length; numpy, one anti-diagonal at a time) to each demo, averaged;
  **F/B1** = that ÷ the same for B1, the time-normalised mean of the demos (each resampled over 0…1 of its
  own duration and averaged sample by sample): the simplest generalisation there is, the bar to clear.

Held-out fidelity (:func:`held_out`): learn from all demonstrations but one, measure on the one left out.

Also: start and end error, grasp/release error (the learned path's gripper switches against the demos'
gripper events), corner error (distance of the learned path to each sharp corner every demo shares),
smoothness (jerk of the learned path ÷ the demos', both low-passed), execution (share of samples the IK
tracks, largest Cartesian error; from ``skill.joint_trajectory``), duration, and outlier demos (a demo much
farther from the others than they are from each other, or much less likely under the trained HMM).

:func:`assess` gathers them in a frozen :class:`QualityReport`; :func:`verdict` words it for the teacher.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import uniform_filter1d

from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.types import Demo, Skill

#: Points per curve for the shape comparisons (evenly spaced along the path).
N_POINTS = 600
#: Low-pass applied before any comparison, seconds (tremor and sensor noise are not the path).
SMOOTH_S = 0.05
#: A bend is a sharp corner when the path turns by more than this (radians) within :func:`corner_stride`
#: (on the shape suite this keeps the zigzag's corners and none of the waves' crests or the loops' bottoms).
CORNER_TURN = math.radians(100.0)


# -- curves ------------------------------------------------------------------------------------------------------


def _samples(t: np.ndarray, seconds: float) -> int:
    dt = float(t[-1] - t[0]) / (len(t) - 1) if len(t) > 1 else 1.0
    return max(1, round(seconds / max(dt, 1e-12)))


def smoothed(demo: Demo) -> np.ndarray:
    """(N, 3) positions low-passed by a :data:`SMOOTH_S` moving average."""
    return uniform_filter1d(
        np.asarray(demo.position, dtype=np.float64), _samples(demo.t, SMOOTH_S), axis=0, mode="nearest"
    )


def arc_length(pos: np.ndarray) -> np.ndarray:
    """(N,) cumulative path length of (N, 3) positions, from 0."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1))])


def arc_resample(pos: np.ndarray, n: int = N_POINTS) -> np.ndarray:
    """(n, 3) points evenly spaced along the path through ``pos`` (a still path gives n copies of its point)."""
    pos = np.asarray(pos, dtype=np.float64)
    s = arc_length(pos)
    if s[-1] <= 1e-12:
        return np.repeat(pos[:1], n, axis=0)
    keep = np.concatenate([[True], np.diff(s) > 0])
    grid = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(grid, s[keep], pos[keep, k]) for k in range(3)])


def curve(demo: Demo, n: int = N_POINTS) -> np.ndarray:
    """A demonstration (or a learned trajectory) as the curve the measures compare: smoothed, arc-resampled."""
    return arc_resample(smoothed(demo), n)


def ndtw(a: np.ndarray, b: np.ndarray) -> float:
    """Normalised DTW of two curves (M, 3), (N, 3): the paper's DTW cost g (sum of squared distances along the
    optimal alignment) ÷ the alignment's length — the mean squared distance between matched points, m²."""
    from dtaidistance import dtw as dtai

    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    path = np.asarray(dtai.warping_path_fast(a, b), dtype=np.int64)
    diff = a[path[:, 0]] - b[path[:, 1]]
    return float(np.einsum("ij,ij->", diff, diff) / path.shape[0])


def frechet(a: np.ndarray, b: np.ndarray) -> float:
    """Discrete Fréchet distance of two curves (M, D), (N, D): the shortest leash that walks both forward.

    F(i, j) = max(‖a_i − b_j‖, min(F(i−1, j), F(i−1, j−1), F(i, j−1))), evaluated one anti-diagonal at a
    time (all cells with i + j = d depend only on diagonals d − 1 and d − 2).
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[1] or not len(a) or not len(b):
        raise InvalidInput("Fréchet distance needs two non-empty curves of the same dimension.")
    R, T = a.shape[0], b.shape[0]
    inf = np.inf
    bufs = [np.full(R + 1, inf), np.full(R + 1, inf), np.full(R + 1, inf)]
    bufs[0][0] = 0.0
    brev = b[::-1]
    for d in range(2, R + T + 1):
        prev2, prev1, cur = bufs[(d - 2) % 3], bufs[(d - 1) % 3], bufs[d % 3]
        x0, x1 = max(1, d - T), min(R, d - 1)
        diff = a[x0 - 1 : x1] - brev[T - d + x0 : T - d + x1 + 1]
        local = np.sqrt(np.einsum("ij,ij->i", diff, diff))
        best = np.minimum(np.minimum(prev1[x0 - 1 : x1], prev1[x0 : x1 + 1]), prev2[x0 - 1 : x1])
        cur[x0 : x1 + 1] = np.maximum(local, best)
        cur[x0 - 1] = inf
        if x1 + 1 <= R:
            cur[x1 + 1] = inf
    return float(bufs[(R + T) % 3][R])


def time_normalised_mean(demos: Sequence[Demo], n: int = 2000) -> np.ndarray:
    """B1: (n, 3) the demos' positions, each resampled over 0…1 of its own duration, averaged sample by sample."""
    u = np.linspace(0.0, 1.0, n)
    out = np.zeros((n, 3))
    for d in demos:
        tt = (d.t - d.t[0]) / max(d.duration, 1e-12)
        p = smoothed(d)
        out += np.column_stack([np.interp(u, tt, p[:, k]) for k in range(3)])
    return out / len(demos)


def extent(demos: Sequence[Demo]) -> float:
    """Size of what was shown: the median over demos of the largest side of the position bounding box, m."""
    return float(np.median([d.extent for d in demos]))


# -- results -----------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Fidelity:
    """How close a path is to the demonstrations.

    Attributes:
        distance: root of the mean normalised DTW of the path to the demos, m (the "within … on average" figure).
        spread: root of the demos' mean pairwise normalised DTW (R), m.
        g_over_r: G/R, mean normalised DTW to the demos ÷ the demos' mean pairwise normalised DTW.
        rms_ratio: √(G/R) = distance ÷ spread.
        frechet: mean discrete Fréchet distance of the path to each demo, m.
        frechet_b1: the same for B1 (time-normalised mean of the demos), m.
        f_over_b1: frechet ÷ frechet_b1.
        per_demo: root of the normalised DTW to each demo, m.
    """

    distance: float
    spread: float
    g_over_r: float
    rms_ratio: float
    frechet: float
    frechet_b1: float
    f_over_b1: float
    per_demo: tuple[float, ...]


@dataclass(frozen=True)
class HeldOut:
    """Leave-one-demo-out: a skill learned without demo i, measured on demo i.

    Attributes:
        distance: root of the mean over folds of the normalised DTW to the left-out demo, m.
        g_over_r: that mean ÷ the demos' mean pairwise normalised DTW (G/R held out).
        frechet: mean over folds of the Fréchet distance to the left-out demo, m.
        per_demo: the root normalised DTW of each fold, m (NaN where learning failed).
        failed: folds where learning failed (their demo indices).
    """

    distance: float
    g_over_r: float
    frechet: float
    per_demo: tuple[float, ...]
    failed: tuple[int, ...] = ()


@dataclass(frozen=True)
class Corner:
    """A sharp corner every demonstration shares, and how close the learned path comes to it.

    Attributes:
        position: (3,) mean corner position over the demos, m.
        time: when the learned path passes closest to it, s from the skill's start.
        error: that closest distance, m.
        turn: mean turning angle of the demos there, rad.
    """

    position: tuple[float, float, float]
    time: float
    error: float
    turn: float


@dataclass(frozen=True)
class GripperCheck:
    """A gripper action every demonstration shows, against the learned skill's.

    Attributes:
        action: "close" or "open".
        position: (3,) mean position of the demos' action, m.
        time: when the learned skill does it, s (NaN if it does not).
        error: distance between the learned and the demonstrated positions, m (inf if the skill misses it).
    """

    action: str
    position: tuple[float, float, float]
    time: float
    error: float


@dataclass(frozen=True)
class Outlier:
    """A demonstration the others do not explain.

    Attributes:
        index: position in the demo list.
        name: its name.
        ratio: its mean distance to the others ÷ the others' mean distance to each other (or NaN).
        distance: its root-mean-square DTW distance to the others, m.
        reason: "shape" (far from the others) or "likelihood" (the HMM finds it much less likely).
    """

    index: int
    name: str
    ratio: float
    distance: float
    reason: str


@dataclass(frozen=True)
class Execution:
    """How well the robot's joint trajectory reproduces the learned path.

    Attributes:
        tracked: share of samples where IK reached the pose (0…1).
        max_error: largest Cartesian position error, m.
        worst_time: when it happens, s.
        duration: length of the joint trajectory, s (longer than the path where a joint limit slowed it).
    """

    tracked: float
    max_error: float
    worst_time: float
    duration: float


@dataclass(frozen=True)
class QualityReport:
    """Everything :func:`verdict` needs, in SI units (metres, seconds).

    Attributes:
        n_demos: number of demonstrations measured against.
        size: extent of what was shown (:func:`extent`), m.
        fidelity: the learned path against the demos.
        held_out: leave-one-demo-out figures, when computed.
        start_error, end_error: distance of the path's first/last point to the demos' mean first/last point, m.
        gripper: shared gripper actions; gripper_mismatch: the demos do not agree on their gripper actions,
            or the skill's actions differ from theirs (text for the teacher, empty if fine).
        corners: shared sharp corners.
        smoothness: mean squared jerk of the path ÷ the demos' median (both low-passed); 1 = as smooth.
        execution: from the joint trajectory, when there is one.
        duration: length of the learned path, s; demo_durations: each demo's, s.
        outliers: demos that differ a lot from the others.
        mode: the generalisation mode the skill used.
        demo_names: names in order.
    """

    n_demos: int
    size: float
    fidelity: Fidelity
    held_out: HeldOut | None
    start_error: float
    end_error: float
    gripper: tuple[GripperCheck, ...]
    gripper_mismatch: str
    corners: tuple[Corner, ...]
    smoothness: float
    execution: Execution | None
    duration: float
    demo_durations: tuple[float, ...]
    outliers: tuple[Outlier, ...]
    mode: str = ""
    demo_names: tuple[str, ...] = field(default_factory=tuple)


# -- measures ----------------------------------------------------------------------------------------------------


def spread(curves: Sequence[np.ndarray]) -> tuple[float, np.ndarray]:
    """R, the mean pairwise normalised DTW of curves (m²), and the (D, D) matrix of them (0 on the diagonal)."""
    n = len(curves)
    M = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            M[i, j] = M[j, i] = ndtw(curves[i], curves[j])
    r = float(M[np.triu_indices(n, 1)].mean()) if n > 1 else float("nan")
    return r, M


def fidelity(
    path: np.ndarray,
    demo_curves: Sequence[np.ndarray],
    *,
    r: float | None = None,
    b1_frechet: float | None = None,
    b1: np.ndarray | None = None,
) -> Fidelity:
    """G/R and F/B1 of one path (a curve, :func:`curve`) against the demos' curves.

    ``r`` (the demos' spread) and ``b1_frechet`` (B1's mean Fréchet distance) may be passed when already
    known (the auto-tune scores many paths against the same demos); otherwise ``b1`` (:func:`time_normalised_mean`,
    then made a curve here) is needed for F/B1.
    """
    if not demo_curves:
        raise NotEnoughData("There are no demonstrations to compare the skill with.")
    per = [ndtw(path, c) for c in demo_curves]
    g = float(np.mean(per))
    if r is None:
        r = spread(demo_curves)[0]
    fr = float(np.mean([frechet(path, c) for c in demo_curves]))
    if b1_frechet is None:
        if b1 is None:
            b1_frechet = float("nan")
        else:
            bc = arc_resample(b1, len(path))
            b1_frechet = float(np.mean([frechet(bc, c) for c in demo_curves]))
    return Fidelity(
        distance=math.sqrt(g),
        spread=math.sqrt(r) if r >= 0 else float("nan"),
        g_over_r=g / r if r and r > 0 else float("nan"),
        rms_ratio=math.sqrt(g / r) if r and r > 0 else float("nan"),
        frechet=fr,
        frechet_b1=float(b1_frechet),
        f_over_b1=fr / b1_frechet if b1_frechet and b1_frechet > 0 else float("nan"),
        per_demo=tuple(math.sqrt(x) for x in per),
    )


def held_out(
    demos: Sequence[Demo],
    learn: Callable[[list[Demo]], Demo],
    *,
    r: float | None = None,
    folds: Sequence[int] | None = None,
    demo_curves: Sequence[np.ndarray] | None = None,
) -> HeldOut:
    """Leave-one-demo-out fidelity: ``learn(other demos)`` returns a trajectory, measured on the left-out demo.

    Args:
        demos: at least two demonstrations.
        learn: a function from a list of demos to the learned trajectory (a :class:`Demo`); a
            :class:`~studio.core.errors.StudioError` it raises marks the fold as failed.
        r: the demos' spread if known.
        folds: which demos to leave out (default all).
    """
    from studio.core.errors import StudioError

    demos = list(demos)
    if len(demos) < 2:
        raise NotEnoughData("Held-out fidelity needs at least two demonstrations.")
    curves = list(demo_curves) if demo_curves is not None else [curve(d) for d in demos]
    if r is None:
        r = spread(curves)[0]
    idx = list(range(len(demos))) if folds is None else list(folds)
    per, fr, failed = [], [], []
    for i in idx:
        try:
            tr = learn([d for j, d in enumerate(demos) if j != i])
        except StudioError:
            failed.append(i)
            per.append(float("nan"))
            continue
        c = curve(tr)
        per.append(ndtw(c, curves[i]))
        fr.append(frechet(c, curves[i]))
    ok = [p for p in per if math.isfinite(p)]
    g = float(np.mean(ok)) if ok else float("inf")
    return HeldOut(
        distance=math.sqrt(g),
        g_over_r=g / r if r > 0 else float("nan"),
        frechet=float(np.mean(fr)) if fr else float("inf"),
        per_demo=tuple(math.sqrt(p) if math.isfinite(p) else p for p in per),
        failed=tuple(failed),
    )


def corner_stride(size: float) -> float:
    """Arc length (m) over which a bend is measured for the corner measure: a twentieth of the size."""
    return max(size / 20.0, 1e-4)


def find_corners(demo: Demo, size: float) -> list[tuple[int, float]]:
    """Sharp corners of one demo: (sample index, turning angle) at the sharpest sample of each bend."""
    p = smoothed(demo)
    s = arc_length(p)
    stride = corner_stride(size)
    n = len(p)
    prev = np.clip(np.searchsorted(s, s - stride, side="right") - 1, 0, n - 1)
    nxt = np.clip(np.searchsorted(s, s + stride, side="left"), 0, n - 1)
    ok = (s - stride >= 0) & (s + stride <= s[-1])
    u, v = p[prev] - p, p[nxt] - p
    nu, nv = np.linalg.norm(u, axis=1), np.linalg.norm(v, axis=1)
    good = ok & (nu > 0.5 * stride) & (nv > 0.5 * stride)
    cosang = np.einsum("ij,ij->i", u, v) / np.where(good, nu * nv, 1.0)
    ang = np.where(good, np.arccos(np.clip(cosang, -1, 1)), math.pi)
    turn = math.pi - ang
    sharp = turn > CORNER_TURN
    out: list[tuple[int, float]] = []
    i = 0
    idx = np.flatnonzero(sharp)
    if idx.size == 0:
        return out
    # group runs of sharp samples that lie within one stride of arc length
    start = 0
    for k in range(1, idx.size + 1):
        if k == idx.size or s[idx[k]] - s[idx[k - 1]] > stride:
            run = idx[start:k]
            i = int(run[np.argmax(turn[run])])
            out.append((i, float(turn[i])))
            start = k
    return out


def shared_corners(demos: Sequence[Demo], size: float | None = None) -> list[tuple[np.ndarray, float]]:
    """Sharp corners every demo has (matched by position within a quarter of the size, in order).

    Returns:
        [(mean position (3,), mean turning angle)] in the order of the first demo.
    """
    size = extent(demos) if size is None else size
    per = [find_corners(d, size) for d in demos]
    if not per or not per[0]:
        return []
    out = []
    tol = 0.25 * size
    for i0, a0 in per[0]:
        p0 = smoothed(demos[0])[i0]
        pts, angs = [p0], [a0]
        for d, cs in zip(demos[1:], per[1:], strict=True):
            if not cs:
                break
            pd = smoothed(d)
            cand = [(float(np.linalg.norm(pd[i] - p0)), i, a) for i, a in cs]
            dist, i, a = min(cand)
            if dist > tol:
                break
            pts.append(pd[i])
            angs.append(a)
        else:
            out.append((np.mean(pts, axis=0), float(np.mean(angs))))
    return out


def _xyz(p: np.ndarray) -> tuple[float, float, float]:
    return (float(p[0]), float(p[1]), float(p[2]))


def _gripper_actions(demo: Demo) -> list[tuple[str, np.ndarray, float]]:
    from studio.core.keypoints import gripper_events

    ev = gripper_events(np.asarray(demo.t), np.asarray(demo.gripper))
    out = []
    g = np.asarray(demo.gripper)
    for a, b in zip(ev[0::2], ev[1::2], strict=True):
        action = "close" if g[b] < g[a] else "open"
        out.append((action, (demo.position[a] + demo.position[b]) / 2.0, float(demo.t[a] - demo.t[0])))
    return out


def _skill_switches(traj: Demo) -> list[tuple[str, int]]:
    g = np.asarray(traj.gripper)
    i = np.flatnonzero(np.abs(np.diff(g)) > 1.0)
    return [("close" if g[j + 1] < g[j] else "open", int(j) + 1) for j in i]


def gripper_checks(traj: Demo, demos: Sequence[Demo]) -> tuple[tuple[GripperCheck, ...], str]:
    """The demos' shared gripper actions against the learned trajectory's switches (see :class:`GripperCheck`)."""
    acts = [_gripper_actions(d) for d in demos]
    seqs = {tuple(a for a, _, _ in x) for x in acts}
    if len(seqs) > 1:
        return (), "Your demonstrations do not use the gripper the same way (not the same closes and opens)."
    ref = acts[0]
    if not ref:
        sw = _skill_switches(traj)
        return (), ("The skill moves the gripper though your demonstrations do not." if sw else "")
    sw = _skill_switches(traj)
    checks = []
    mismatch = ""
    if [a for a, _ in sw] != [a for a, _, _ in ref]:
        mismatch = f"The skill does not use the gripper as you did ({len(sw)} gripper actions instead of {len(ref)})."
    for n, (action, _, _) in enumerate(ref):
        pos = np.mean([x[n][1] for x in acts], axis=0)
        same = [j for a, j in sw if a == action]
        # the n-th action of this kind in the skill, if any
        k = sum(1 for a, _, _ in ref[:n] if a == action)
        if k < len(same):
            j = same[k]
            checks.append(
                GripperCheck(
                    action, _xyz(pos), float(traj.t[j] - traj.t[0]), float(np.linalg.norm(traj.position[j] - pos))
                )
            )
        else:
            checks.append(GripperCheck(action, _xyz(pos), float("nan"), float("inf")))
    return tuple(checks), mismatch


def corner_checks(traj: Demo, demos: Sequence[Demo], size: float) -> tuple[Corner, ...]:
    """Distance of the learned path to each shared corner and when it passes closest."""
    out = []
    p = np.asarray(traj.position)
    for pos, turn in shared_corners(demos, size):
        d = np.linalg.norm(p - pos, axis=1)
        i = int(np.argmin(d))
        out.append(Corner(_xyz(pos), float(traj.t[i] - traj.t[0]), float(d[i]), turn))
    return tuple(out)


def mean_squared_jerk(demo: Demo) -> float:
    """Mean squared jerk of the path low-passed over 0.1 s and resampled at 50 Hz, normalised by duration⁵ and
    path length² (dimensionless, so a fast and a slow demo of one shape compare)."""
    t = np.asarray(demo.t)
    if demo.duration <= 0.2:
        return float("nan")
    p = uniform_filter1d(np.asarray(demo.position, dtype=np.float64), _samples(t, 0.1), axis=0, mode="nearest")
    grid = np.arange(t[0], t[-1], 0.02)
    if grid.shape[0] < 8:
        return float("nan")
    q = np.column_stack([np.interp(grid, t, p[:, k]) for k in range(3)])
    j = np.diff(q, n=3, axis=0) / 0.02**3
    length = float(arc_length(q)[-1])
    if length <= 1e-9:
        return 0.0
    dur = float(grid[-1] - grid[0])
    return float(np.mean(np.sum(j * j, axis=1)) * dur**5 / length**2 / dur)


def outliers(
    demos: Sequence[Demo],
    matrix: np.ndarray,
    *,
    loglik: np.ndarray | None = None,
    lengths: Sequence[int] | None = None,
    size: float | None = None,
) -> tuple[Outlier, ...]:
    """Demos the others do not explain.

    Shape: with ≥ 3 demos, demo i is an outlier when its mean RMS DTW distance to the others is more than 2.5×
    the others' mean distance to each other and more than max(4 mm, 10 % of the size).
    Likelihood: the trained HMM's log-likelihood per key-point of demo i is more than 3 nats below the median.
    """
    n = len(demos)
    out: list[Outlier] = []
    if n < 3:
        return ()
    matrix = np.sqrt(np.asarray(matrix, dtype=float))  # root-mean-square distances, m
    size = extent(demos) if size is None else size
    floor = max(0.004, 0.10 * size)
    for i in range(n):
        others = [j for j in range(n) if j != i]
        mine = float(np.mean(matrix[i, others]))
        rest = matrix[np.ix_(others, others)]
        base = float(rest[np.triu_indices(len(others), 1)].mean())
        ratio = mine / base if base > 0 else float("inf")
        if ratio > 2.5 and mine > floor:
            out.append(Outlier(i, demos[i].name, ratio, mine, "shape"))
    if loglik is not None and lengths is not None and len(loglik) == n:
        per = np.asarray(loglik, dtype=float) / np.maximum(np.asarray(lengths, dtype=float), 1.0)
        med = float(np.median(per))
        for i in range(n):
            if per[i] < med - 3.0 and not any(o.index == i for o in out):
                out.append(
                    Outlier(
                        i,
                        demos[i].name,
                        float("nan"),
                        float(np.mean(matrix[i, [j for j in range(n) if j != i]])),
                        "likelihood",
                    )
                )
    # the most different first
    return tuple(sorted(out, key=lambda o: -o.distance))


def execution(skill: Skill) -> Execution | None:
    """Tracking of the skill's joint trajectory (None when it has none)."""
    jt = skill.joint_trajectory
    if jt is None or len(jt) == 0:
        return None
    pe = np.asarray(jt.position_error)
    i = int(np.argmax(pe))
    return Execution(
        tracked=float(np.mean(jt.converged)),
        max_error=float(pe[i]),
        worst_time=float(jt.t[i] - jt.t[0]),
        duration=float(jt.t[-1] - jt.t[0]),
    )


def assess(
    skill: Skill | Demo,
    demos: Sequence[Demo],
    *,
    held_out_result: HeldOut | None = None,
    loglik: np.ndarray | None = None,
) -> QualityReport:
    """Measure a learned skill (or just its trajectory) against the demonstrations it was learned from.

    Args:
        skill: a :class:`Skill` (its trajectory, key-point counts, likelihoods and joint trajectory are used)
            or a trajectory (:class:`Demo`).
        demos: the demonstrations, in the skill's order.
        held_out_result: :func:`held_out` figures, if computed.
        loglik: per-demo log-likelihood (default: the skill's).

    Returns:
        A :class:`QualityReport`. About 0.1–0.3 s for 3–7 demos.
    """
    demos = list(demos)
    if not demos:
        raise NotEnoughData("There are no demonstrations to compare the skill with.")
    traj = skill.trajectory if isinstance(skill, Skill) else skill
    size = extent(demos)
    curves = [curve(d) for d in demos]
    r, M = spread(curves)
    path = curve(traj)
    b1 = time_normalised_mean(demos)
    fid = fidelity(path, curves, r=r, b1=b1)
    starts = np.mean([d.position[0] for d in demos], axis=0)
    ends = np.mean([d.position[-1] for d in demos], axis=0)
    checks, mismatch = gripper_checks(traj, demos)
    corners = corner_checks(traj, demos, size)
    jd = [mean_squared_jerk(d) for d in demos]
    jd = [x for x in jd if math.isfinite(x) and x > 0]
    js = mean_squared_jerk(traj)
    smooth = js / float(np.median(jd)) if jd and math.isfinite(js) else float("nan")
    ll: np.ndarray | None
    if isinstance(skill, Skill):
        ll = skill.loglik if loglik is None else loglik
        lengths = [len(k) for k in skill.keypoints]
        ex = execution(skill)
        mode = getattr(skill, "generalization", "")
    else:
        ll, lengths, ex, mode = loglik, None, None, ""
    outs = outliers(demos, M, loglik=ll, lengths=lengths, size=size)
    return QualityReport(
        n_demos=len(demos),
        size=size,
        fidelity=fid,
        held_out=held_out_result,
        start_error=float(np.linalg.norm(traj.position[0] - starts)),
        end_error=float(np.linalg.norm(traj.position[-1] - ends)),
        gripper=checks,
        gripper_mismatch=mismatch,
        corners=corners,
        smoothness=smooth,
        execution=ex,
        duration=traj.duration,
        demo_durations=tuple(d.duration for d in demos),
        outliers=outs,
        mode=mode,
        demo_names=tuple(d.name for d in demos),
    )


# -- the verdict -------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Verdict:
    """The skill's quality in plain words.

    Attributes:
        level: "good", "fair" or "poor".
        lines: the headline first ("Good: …", "Fair: …" or "Poor: …"), then one line per thing to look at.
    """

    level: str
    lines: tuple[str, ...]

    @property
    def text(self) -> str:
        return "\n".join(self.lines)


def length_words(metres: float) -> str:
    """A distance as a person says it: "4 mm", "2.5 cm", "1.2 m"."""
    m = abs(float(metres))
    if m < 0.0095:
        return f"{m * 1000:.0f} mm" if m >= 0.00095 else f"{max(m * 1000, 0.1):.1f} mm"
    if m < 1.0:
        cm = m * 100
        return f"{cm:.0f} cm" if cm >= 9.95 else f"{cm:.1f} cm".replace(".0 cm", " cm")
    return f"{m:.1f} m"


#: Verdict limits (see :func:`verdict`).
GOOD_G_OVER_R = 0.6
GOOD_F_OVER_B1 = 1.25
POOR_G_OVER_R = 1.0
POOR_F_OVER_B1 = 2.0


def _tolerance(size: float, share: float, floor: float) -> float:
    return max(floor, share * size)


def verdict(report: QualityReport) -> Verdict:
    """Word a :class:`QualityReport` for the teacher (GUI-free; the Train panel and ``studio learn`` show it).

    The path is *close* when G/R ≤ 0.6 (or the RMS distance is within 1.5 mm / 1 % of the size) and F/B1 ≤ 1.25
    (or the Fréchet distance is within 3 mm / 2 % of the size); *poor* when G/R > 1 and F/B1 > 2. A shared
    corner is *cut* when the path passes farther than max(3 mm, 3 % of the size) from it; start and end count
    from max(2 mm, 1 % of the size), a grasp or release from 1 cm, execution when IK tracks less than 98 % of
    the samples or strays more than 5 mm. The headline is "Good" only if nothing else needs a line.
    """
    r = report
    f = r.fidelity
    size = r.size
    notes: list[str] = []
    close = (f.g_over_r <= GOOD_G_OVER_R or f.distance <= _tolerance(size, 0.01, 0.0015)) and (
        not math.isfinite(f.f_over_b1) or f.f_over_b1 <= GOOD_F_OVER_B1 or f.frechet <= _tolerance(size, 0.02, 0.003)
    )
    poor = f.g_over_r > POOR_G_OVER_R and (not math.isfinite(f.f_over_b1) or f.f_over_b1 > POOR_F_OVER_B1)
    cut = [c for c in r.corners if c.error > _tolerance(size, 0.03, 0.003)]
    worst_corner = max(cut, key=lambda c: c.error) if cut else None
    tol_end = _tolerance(size, 0.01, 0.002)
    if r.start_error > tol_end:
        notes.append(f"It starts {length_words(r.start_error)} away from where your demonstrations start.")
    if r.end_error > tol_end:
        notes.append(f"It ends {length_words(r.end_error)} away from where your demonstrations end.")
    if r.gripper_mismatch:
        notes.append(r.gripper_mismatch)
    past = {"close": "closed", "open": "opened"}
    verb = {"close": "closes", "open": "opens"}
    for g in r.gripper:
        if not math.isfinite(g.error):
            notes.append(
                f"It never {verb[g.action][:-1]}s the gripper where you {past[g.action]} it — press Suggest, or move "
                "Detail towards more key-points."
            )
        elif g.error > 0.01:
            notes.append(
                f"It {verb[g.action]} the gripper {length_words(g.error)} away from where you {past[g.action]} it "
                f"(at {g.time:.1f} s) — press Suggest, or move Detail towards more key-points."
            )
    ex = r.execution
    if ex is not None and (ex.tracked < 0.98 or ex.max_error > 0.005):
        miss = 100 * (1 - ex.tracked)
        what = (
            f"cannot follow {miss:.0f} % of it (up to {length_words(ex.max_error)} off at {ex.worst_time:.1f} s)"
            if miss >= 0.5
            else f"strays up to {length_words(ex.max_error)} from it (at {ex.worst_time:.1f} s)"
        )
        notes.append(
            f"The robot {what} — teach it closer to the robot, with the gripper in a direction the arm can hold."
        )
    if ex is not None and r.demo_durations and ex.duration > 1.2 * max(r.demo_durations) + 0.2:
        notes.append(
            f"The robot needs {ex.duration:.1f} s for it (your demonstrations took "
            f"{min(r.demo_durations):.1f}–{max(r.demo_durations):.1f} s): its joints cannot move that fast."
        )
    h = r.held_out
    if h is not None and math.isfinite(h.g_over_r) and h.g_over_r > 1.0 and h.distance > _tolerance(size, 0.01, 0.002):
        notes.append(
            f"Learned without one of your demonstrations, it misses that one by {length_words(h.distance)} on "
            "average: record one or two more demonstrations."
        )
    for o in r.outliers:
        notes.append(f"{o.name} differs a lot from the others — re-record or hide it.")
    d = length_words(f.distance)
    if poor:
        head = (
            f"Poor: the skill strays from your demonstrations ({d} on average) — press Suggest, or move Detail "
            "towards more key-points."
        )
        level = "poor"
    elif worst_corner is not None:
        head = (
            f"Fair: it cuts the corner at {worst_corner.time:.1f} s by {length_words(worst_corner.error)} — press "
            "Suggest, or lower Corner sharpness."
        )
        level = "fair"
    elif not close:
        head = (
            f"Fair: the skill stays within {d} of your demonstrations on average, but they are closer to each other "
            "than that — press Suggest, or move Detail towards more key-points."
        )
        level = "fair"
    elif notes:
        head = f"Fair: the skill follows your demonstrations closely (within {d} on average), but:"
        level = "fair"
    else:
        head = f"Good: the skill follows your demonstrations closely (within {d} on average)."
        level = "good"
    return Verdict(level, (head, *notes))


@dataclass(frozen=True)
class DemoFit:
    """How well one demonstration fits the learned skill, for the per-demo list in the Train panel.

    Attributes:
        index: position in the skill's demo list; name: its name.
        well: True ("fits the skill: well") or False ("poorly").
        distance: root-mean-square distance of the learned path to it, m.
        note: why it fits poorly, in plain words ("" when it fits well).
    """

    index: int
    name: str
    well: bool
    distance: float
    note: str = ""


#: The one line that explains the per-demo list.
FIT_EXPLANATION = (
    "How closely the learned path follows each demonstration. One that fits poorly pulls the skill away from "
    "the others: re-record it or hide it."
)


def demo_fits(report: QualityReport) -> tuple[DemoFit, ...]:
    """Per demonstration: "well" or "poorly" (replaces the raw log-likelihoods of the paper's HMM for a teacher).

    A demo fits poorly when it is an outlier (:func:`outliers`: far from the others, or much less likely under
    the HMM), or when the learned path stays more than twice as far from it as from the typical demo and
    farther than max(3 mm, 2 % of the size).
    """
    per = report.fidelity.per_demo
    if not per:
        return ()
    typical = float(np.median(per))
    tol = _tolerance(report.size, 0.02, 0.003)
    outs = {o.index: o for o in report.outliers}
    names = report.demo_names or tuple(f"demo {i + 1}" for i in range(len(per)))
    out = []
    for i, d in enumerate(per):
        note = ""
        if i in outs:
            o = outs[i]
            note = (
                "It differs a lot from the others."
                if o.reason == "shape"
                else "The skill's model finds it much less likely than the others."
            )
        elif d > 2.0 * typical and d > tol:
            note = f"The learned path stays {length_words(d)} from it on average, far more than from the others."
        out.append(DemoFit(i, names[i] if i < len(names) else f"demo {i + 1}", not note, float(d), note))
    return tuple(out)


__all__ = [
    "FIT_EXPLANATION",
    "N_POINTS",
    "Corner",
    "DemoFit",
    "Execution",
    "Fidelity",
    "GripperCheck",
    "HeldOut",
    "Outlier",
    "QualityReport",
    "Verdict",
    "arc_resample",
    "assess",
    "corner_checks",
    "curve",
    "demo_fits",
    "execution",
    "extent",
    "fidelity",
    "find_corners",
    "frechet",
    "gripper_checks",
    "held_out",
    "length_words",
    "mean_squared_jerk",
    "ndtw",
    "outliers",
    "shared_corners",
    "spread",
    "time_normalised_mean",
    "verdict",
]
