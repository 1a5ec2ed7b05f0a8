"""Measures of a learned path against the demonstrations, in metres and seconds: fidelity (G/R, F/B1),
shared sharp corners, gripper actions, outlier demos and how well the IK tracks the path."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from studio.core.errors import NotEnoughData
from studio.core.quality.curves import arc_length, arc_resample, extent, frechet_pairs, ndtw, smoothed, spread
from studio.core.types import Demo, Skill

#: A bend is a sharp corner when the path turns by more than this (radians) within :func:`corner_stride`
#: (on the shape suite this keeps the zigzag's corners and none of the waves' crests or the loops' bottoms).
CORNER_TURN = math.radians(100.0)


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


class OddIn(StrEnum):
    """Why a demonstration is an outlier."""

    SHAPE = "shape"  #: far from the others
    LIKELIHOOD = "likelihood"  #: the trained HMM finds it much less likely than the others


@dataclass(frozen=True)
class Outlier:
    """A demonstration the others do not explain.

    Attributes:
        index: position in the demo list.
        name: its name.
        ratio: its mean distance to the others ÷ the others' mean distance to each other (or NaN).
        distance: its root-mean-square DTW distance to the others, m.
        reason: why (:class:`OddIn`).
    """

    index: int
    name: str
    ratio: float
    distance: float
    reason: OddIn


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
    fr = float(np.mean(frechet_pairs([(path, c) for c in demo_curves])))
    if b1_frechet is None:
        if b1 is None:
            b1_frechet = float("nan")
        else:
            bc = arc_resample(b1, len(path))
            b1_frechet = float(np.mean(frechet_pairs([(bc, c) for c in demo_curves])))
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


def demo_actions(demo: Demo) -> list[tuple[str, np.ndarray, float]]:
    """The demo's grasps and releases in order: ("close" or "open", where (3,) m, when s from its start)."""
    return _gripper_actions(demo)


def task_error(traj: Demo, actions: Sequence[tuple[str, np.ndarray, float]]) -> float:
    """Root-mean-square distance (m) from where the path closes and opens the gripper to where one demo did
    (:func:`demo_actions`): 0 when neither does, inf when the path closes and opens it differently."""
    sw = _skill_switches(traj)
    if [a for a, _ in sw] != [a for a, _, _ in actions]:
        return math.inf
    if not sw:
        return 0.0
    err = [float(np.sum((traj.position[j] - p) ** 2)) for (_, j), (_, p, _) in zip(sw, actions, strict=True)]
    return math.sqrt(float(np.mean(err)))


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
    """The path's gripper actions in order, (action, sample where it completes): steps of the same direction in a
    row are one action (a close taken in two steps, e.g. where two segments of a skill meet, is one grasp)."""
    g = np.asarray(traj.gripper)
    out: list[tuple[str, int]] = []
    for j in np.flatnonzero(np.abs(np.diff(g)) > 1.0):
        action = "close" if g[j + 1] < g[j] else "open"
        if out and out[-1][0] == action:
            out[-1] = (action, int(j) + 1)
        else:
            out.append((action, int(j) + 1))
    return out


class Disagreement(StrEnum):
    """How the gripper actions fail to agree (see :class:`GripperMismatch`)."""

    DEMOS_DIFFER = "demos differ"  #: the demonstrations do not close and open the gripper the same way
    UNTAUGHT = "untaught"  #: the skill moves the gripper though no demonstration does
    SKILL_DIFFERS = "skill differs"  #: the skill's closes and opens are not the demonstrations'


@dataclass(frozen=True)
class GripperMismatch:
    """The gripper actions do not agree.

    Attributes:
        kind: what disagrees.
        skill_actions: how many times the skill closes or opens the gripper.
        demo_actions: how many times the (first) demonstration does.
    """

    kind: Disagreement
    skill_actions: int
    demo_actions: int


def gripper_checks(traj: Demo, demos: Sequence[Demo]) -> tuple[tuple[GripperCheck, ...], GripperMismatch | None]:
    """The demos' shared gripper actions against the learned trajectory's switches (see :class:`GripperCheck`),
    and how they disagree (None when they agree)."""
    acts = [_gripper_actions(d) for d in demos]
    seqs = {tuple(a for a, _, _ in x) for x in acts}
    ref = acts[0]
    sw = _skill_switches(traj)
    if len(seqs) > 1:
        return (), GripperMismatch(Disagreement.DEMOS_DIFFER, len(sw), len(ref))
    if not ref:
        return (), (GripperMismatch(Disagreement.UNTAUGHT, len(sw), 0) if sw else None)
    checks = []
    mismatch = None
    if [a for a, _ in sw] != [a for a, _, _ in ref]:
        mismatch = GripperMismatch(Disagreement.SKILL_DIFFERS, len(sw), len(ref))
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
            out.append(Outlier(i, demos[i].name, ratio, mine, OddIn.SHAPE))
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
                        OddIn.LIKELIHOOD,
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
