"""``learn_skill``: the paper's task-learning stages in order, from demonstrations to a :class:`Skill`.

key-points (keypoints.py) ▸ k-means codebook (clustering.py) ▸ Bakis HMM, Baum–Welch, Viterbi, forward
selection of the reference (hmm.py) ▸ multidimensional DTW of every demo against the reference
(alignment.py) ▸ timed path points without zero-points ▸ the path: the paper's smoothing spline
(generalize.py, ``generalization="paper"``) or the demos averaged along their DTW alignment
(``"aligned-mean"``, the default) ▸ IK (optional). Why these defaults: docs/decisions/003 and 004."""

from __future__ import annotations

import functools
import hashlib
import threading
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.interpolate import PchipInterpolator

from studio.core import alignment, hmm, quality
from studio.core.clustering import Clustering, FeatureScale, align_hemisphere, cluster, default_n_clusters
from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.generalize import (
    SMOOTHING,
    demo_pins,
    generalize,
    gripper_at,
    joint_trajectory,
    pin_poses,
    sample_times,
)
from studio.core.keypoints import KeypointCache
from studio.core.kinematics import Baxter, make_sign_continuous
from studio.core.routes import Routes, find_routes
from studio.core.thresholds import ThresholdSettings
from studio.core.types import (
    ARMS,
    DEFAULT_GENERALIZATION,
    GENERALIZATIONS,
    Arm,
    Demo,
    Generalization,
    KeypointParams,
    Recording,
    Skill,
    SkillRoute,
    check_arm,
)

SPLINE_THROUGH = ("state-means", "centroids")
#: DTW features besides the scaled pose: orientation is weighted down (on a drawn shape the hand's small
#: wobble would steer the alignment as much as the path does) and the unit direction of motion is added
#: (it turns sharply at a corner, so corners align exactly); chosen on the shape suite (docs/decisions/003).
DTW_ORIENTATION_WEIGHT = 0.3
DTW_DIRECTION_WEIGHT = 0.5
#: Points per curve when the plain mean is matched to the aligned mean (:func:`_plain_mean_along`).
_ALONG_POINTS = 400
#: Shares of the plain mean tried when the aligned mean is farther from the demos than it (decision 083).
PLAIN_MEAN_SHARES = (0.25, 0.5, 0.75, 1.0)


def demo_from_recording(rec: Recording, arm: Arm, baxter: Baxter | None = None) -> Demo:
    """One arm of a recording as the paper's 8-D demonstration (forward kinematics of every sample).

    Args:
        rec: the recording (both arms' joints, grippers).
        arm: "left" or "right".
        baxter: the model (default :meth:`Baxter.load`).

    Returns:
        A :class:`Demo` with the gripper pose, opening and the arm's joint angles (q).
    """
    check_arm(arm)
    b = baxter or Baxter.load()
    q = rec.arm_q(arm)
    pos, ori = b.fk_batch(arm, q)
    return Demo(rec.t, pos, ori, rec.arm_gripper(arm), q, name=rec.name)


def _validate(demos: Sequence[Demo]) -> list[Demo]:
    if demos is None or isinstance(demos, Demo):
        raise InvalidInput("Give a list of demonstrations (even for a single one).")
    demos = list(demos)
    if not demos:
        raise NotEnoughData("There are no demonstrations yet: record at least one to learn a skill.")
    for i, d in enumerate(demos):
        if not isinstance(d, Demo):
            raise InvalidInput(f"Item {i + 1} is not a demonstration (got {type(d).__name__}).")
        if len(d) < 2:
            raise NotEnoughData(f"{d.name} has {len(d)} sample(s); record a longer demonstration.")
    return demos


def _scaled(X: np.ndarray, scale: FeatureScale, ref_quat: np.ndarray) -> np.ndarray:
    X = np.array(X, dtype=np.float64)
    X[:, 3:7] = align_hemisphere(X[:, 3:7], ref_quat)
    return X / scale.divisors


class AlignmentCache:
    """DTW time maps between demonstrations, reused while only the thresholds change.

    The alignment of a demo to the reference depends on the two demos, the common DTW rate and the feature
    scale, not on ε: a slider move (or the auto-tune) that keeps the same reference re-uses it. Entries are
    held with weak references to the demos (a deleted demo's maps go with it) and at most :attr:`size` are
    kept. Safe to share between threads (a race only computes one map twice).
    """

    def __init__(self, size: int = 64) -> None:
        self.size = size
        self._maps: dict[tuple, tuple[tuple[weakref.ref, ...], Any]] = {}

    def get(self, ref: Demo, demo: Demo, key: tuple, compute: Callable[[], Any]) -> Any:
        return self.get_set((ref, demo), key, compute)

    def get_set(self, demos: Sequence[Demo], key: tuple, compute: Callable[[], Any]) -> Any:
        """The value for these demos (in this order) and key, computed once while they all live."""
        k = (*(id(d) for d in demos), len(demos), *key)
        hit = self._maps.get(k)
        if hit is not None and len(hit[0]) == len(demos) and all(r() is d for r, d in zip(hit[0], demos, strict=True)):
            return hit[1]
        value = compute()
        if len(self._maps) >= self.size:
            try:
                self._maps.pop(next(iter(self._maps)), None)
            except (StopIteration, RuntimeError):
                pass
        self._maps[k] = (tuple(weakref.ref(d) for d in demos), value)
        return value


_SERIES_CACHE = KeypointCache()
_ALIGN_CACHE = AlignmentCache()
_ROUTES_CACHE = AlignmentCache(16)
#: The plain-mean share chosen per aligned mean (:func:`_plain_mean_share`).
_GUARD_SHARES: dict[tuple, float] = {}
_GUARD_LOCK = threading.Lock()


def routes_of(demos: Sequence[Demo]) -> Routes:
    """Which demonstrations go which way (:func:`studio.core.routes.find_routes`, remembered per set of demos)."""
    demos = list(demos)
    return _ROUTES_CACHE.get_set(demos, ("routes",), lambda: find_routes(demos))


def _route_demos(demos: list[Demo], route: int | None, split: bool = True) -> tuple[Routes, int, list[Demo]]:
    """(the routes, the one to learn, its demonstrations): all demos when they go one way (or ``split`` is False)."""
    found = routes_of(demos) if split else Routes()
    if not found:
        if route not in (None, 0):
            raise InvalidInput("Your demonstrations all go the same way: there is no other way to choose.")
        return found, 0, demos
    r = found.default if route is None else int(route)
    if not 0 <= r < len(found):
        raise InvalidInput(f"Your demonstrations go {len(found)} ways: choose one of them (got way {r + 1}).")
    return found, r, [demos[i] for i in found.routes[r].demos]


@dataclass(frozen=True, eq=False)
class _Model:
    """Everything between the key-points and the generalized path (one learn_skill or preview)."""

    kps: list[np.ndarray]
    k: int
    cl: Clustering
    model: hmm.HmmResult
    ref: int
    aligned: list[np.ndarray]  # key-point times of each demo on the reference's time line (from its start)
    own: list[np.ndarray]  # key-point times of each demo on its own time line (from its start)
    inverse: list[Callable[[np.ndarray], np.ndarray]]  # reference time (from its start) -> demo time (from its start)
    pairs: np.ndarray  # (P, 2) (state, cluster) of the path points, in the reference's order
    times: np.ndarray  # (P,) path point times
    points: np.ndarray  # (P, 8)
    weights: np.ndarray  # (P,)


def _inverse(warp: PchipInterpolator, lo: float, hi: float, tau: np.ndarray) -> np.ndarray:
    return np.asarray(warp(np.clip(tau, lo, hi)), dtype=np.float64)


def _dtw_series(X: np.ndarray, scale: FeatureScale, ref_quat: np.ndarray, dtw_features: str) -> np.ndarray:
    """The DTW features of a resampled (N, 8) series: scaled; for "shape", orientation weighted down and the
    direction of motion added, faded out where the hand is slower than usual (at rest it is only noise)."""
    X = _scaled(X, scale, ref_quat)
    if dtw_features == "paper":
        return X
    X[:, 3:7] *= DTW_ORIENTATION_WEIGHT
    v = np.gradient(X[:, :3], axis=0)
    n = np.linalg.norm(v, axis=1, keepdims=True)
    tan = v / np.maximum(n, 1e-12) * np.minimum(1.0, n / max(float(np.median(n)), 1e-12))
    return np.column_stack([X, DTW_DIRECTION_WEIGHT * tan])


def _warp_to(
    mapped: np.ndarray, grid: np.ndarray, t0: float, tau: np.ndarray, tau_t0: float
) -> Callable[[np.ndarray], np.ndarray]:
    """The smoothed, monotone inverse of a DTW time map: time on the average's line (from its start) -> demo time
    (from its start)."""
    warp = PchipInterpolator(tau, alignment.smooth_warp(alignment.inverse_time_map(mapped - tau_t0, grid - t0, tau)))
    return functools.partial(_inverse, warp, float(tau[0]), float(tau[-1]))


def _fit(
    demos: list[Demo],
    params: KeypointParams,
    *,
    n_clusters: int | None,
    seed: int,
    scale: FeatureScale,
    spline_through: str,
    keypoints: Sequence[np.ndarray] | None,
    cache: KeypointCache | None,
    align_cache: AlignmentCache | None,
    dtw_features: str = "shape",
) -> _Model:
    # 1. key-points
    if keypoints is None:
        kc = cache or _SERIES_CACHE
        kps = [kc.extract(d, params) for d in demos]
    else:
        if len(keypoints) != len(demos):
            raise InvalidInput("There must be one list of key-points per demonstration.")
        kps = [np.asarray(k, dtype=np.int64) for k in keypoints]
    for d, kp in zip(demos, kps, strict=True):
        if len(kp) < 2:
            raise NotEnoughData(
                f"{d.name} has only {len(kp)} key-point(s); a skill needs at least a start and an end. "
                "Record a longer demonstration or lower the key-point thresholds."
            )
    total = sum(len(kp) for kp in kps)
    k = default_n_clusters(kps) if n_clusters is None else int(n_clusters)
    if k > total:
        raise NotEnoughData(
            f"{k} clusters were asked for but the demonstrations have only {total} key-points in all. "
            f"Choose at most {total} clusters or lower the key-point thresholds."
        )
    # 2. codebook
    cl = cluster(demos, kps, n_clusters, seed=seed, scale=scale)  # automatic k: at most the distinct key-points
    k = cl.n_clusters
    # 3. HMM
    model = hmm.train(cl.labels, k, seed=seed)
    ref = model.reference
    ref_demo = demos[ref]
    # 4. DTW of every demo against the reference on a common grid (maps cached: they do not depend on ε)
    rate = alignment.common_rate([d.duration for d in demos])
    ref_quat = np.asarray(ref_demo.orientation[0], dtype=np.float64)
    grids = [alignment.time_grid(d.t[0], d.t[-1], rate) for d in demos]
    key = (dtw_features, round(rate, 9), *np.round(scale.divisors, 12).tolist())
    ac = align_cache or _ALIGN_CACHE

    def series(i: int) -> np.ndarray:
        return _dtw_series(alignment.resample(demos[i].t, demos[i].features, grids[i]), scale, ref_quat, dtw_features)

    aligned: list[np.ndarray] = []
    inverse: list[Callable[[np.ndarray], np.ndarray]] = []
    for i, d in enumerate(demos):
        tk = d.t[kps[i]]
        if i == ref:
            aligned.append(tk - ref_demo.t[0])
            inverse.append(lambda tau: np.asarray(tau, dtype=np.float64))
            continue

        def compute(i: int = i) -> np.ndarray:
            _, path = alignment.dtw(series(ref), series(i))
            return alignment.time_map(path, grids[ref], grids[i])

        mapped = ac.get(ref_demo, d, key, compute)
        aligned.append(np.interp(tk, grids[i], mapped) - ref_demo.t[0])
        # The demo's time at each step of the reference's grid, smoothed (a DTW staircase would jerk the
        # average), monotone C¹ in between (PCHIP).
        inverse.append(_warp_to(mapped, grids[i], float(d.t[0]), grids[ref] - ref_demo.t[0], float(ref_demo.t[0])))
    # 5. timed path points
    times_all = np.concatenate(aligned)
    labels_all = np.concatenate(cl.labels)
    states_all = np.concatenate(model.paths)
    X = cl.features
    # The reference's key-points in order, as (state, cluster) pairs; consecutive repeats are one point.
    ref_pairs = np.column_stack([model.states, cl.labels[ref]])
    keep = np.concatenate([[True], np.any(ref_pairs[1:] != ref_pairs[:-1], axis=1)])
    pairs = ref_pairs[keep]
    pts, tms, wts = [], [], []
    for s_, c_ in pairs:
        # all demos' key-points that Viterbi put in this state and k-means in this cluster
        m = (states_all == s_) & (labels_all == c_)
        if spline_through == "centroids":
            p = cl.centroids[c_].copy()
        else:
            p = X[m].mean(axis=0)
            p[3:7] /= np.linalg.norm(p[3:7])
        pts.append(p)
        tms.append(times_all[m].mean())
        wts.append(float(m.sum()))
    return _Model(
        kps=kps,
        k=k,
        cl=cl,
        model=model,
        ref=ref,
        aligned=aligned,
        own=[d.t[kp] - d.t[0] for d, kp in zip(demos, kps, strict=True)],
        inverse=inverse,
        pairs=pairs,
        times=np.array(tms),
        points=np.array(pts),
        weights=np.array(wts),
    )


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


def _aligned_mean(demos: list[Demo], fm: _Model, t: np.ndarray, cache: KeypointCache) -> np.ndarray:
    """(len(t), 7) position and orientation of the aligned mean (:func:`_mean_pose`)."""
    return _mean_pose(demos, fm.inverse, fm.ref, t, cache)[0]


def _trajectory(
    demos: list[Demo],
    fm: _Model,
    *,
    generalization: str,
    smoothing: float,
    cache: KeypointCache,
    rate_hz: float | None = None,
) -> Demo:
    ref_demo = demos[fm.ref]
    dt = float(np.median(np.diff(ref_demo.t)))
    traj = generalize(
        fm.times,
        fm.points,
        weights=fm.weights,
        t_start=0.0,
        t_end=ref_demo.duration,
        rate_hz=rate_hz or 1.0 / dt,
        smoothing=smoothing,
        name="learned skill",
    )
    if generalization == "paper":
        return traj
    t = np.asarray(traj.t)
    pose = _aligned_mean(demos, fm, t, cache)
    pins = demo_pins(demos, t, traj.gripper)
    ori = make_sign_continuous(pose[:, 3:])
    pos, ori = pin_poses(t, pose[:, :3], ori, pins)
    if len(demos) > 1:
        tf, pf = t, pose
        if rate_hz is not None and t.shape[0] > 1 and abs((t[1] - t[0]) - dt) > 1e-12:
            # decided on the path at the demos' rate, as learn_skill makes it: the preview shows the skill
            tf = sample_times(0.0, ref_demo.duration, 1.0 / dt)
            pf = _aligned_mean(demos, fm, tf, cache)
            share = _plain_mean_share(
                demos, tf, pf, demo_pins(demos, tf, gripper_at(fm.times, fm.points, fm.weights, tf))
            )
        else:
            share = _plain_mean_share(demos, t, pose, pins)
        if share:
            along = _plain_mean_along(quality.time_normalised_mean(demos), tf, pf[:, :3])
            if tf is not t:
                along = np.column_stack([np.interp(t, tf, along[:, k]) for k in range(3)])
            pos = pin_poses(t, (1.0 - share) * pose[:, :3] + share * along, ori, pins)[0]
    return Demo(traj.t, pos, ori, traj.gripper, name="learned skill")


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
    demos: list[Demo], t: np.ndarray, pose: np.ndarray, pins: list[tuple[float, np.ndarray, np.ndarray]]
) -> float:
    """How far the aligned mean ``pose`` (len(t), 7), bent onto ``pins``, is moved toward the plain mean: 0 when its
    mean Fréchet distance to the demos is not larger than the plain mean's, else the first of
    :data:`PLAIN_MEAN_SHARES` that is not farther (or the least far). Remembered per path. Decision 083."""
    key = _guard_key(demos, t, pose, pins)
    with _GUARD_LOCK:
        share = _GUARD_SHARES.get(key)
    if share is not None:
        return share
    curves = np.stack(_GUARD_CURVES.get(demos)[0])
    D = curves.shape[0]

    def far(paths: list[np.ndarray]) -> np.ndarray:
        a = np.repeat(np.stack([quality.arc_resample(p) for p in paths]), D, axis=0)
        return quality.frechet_many(a, np.tile(curves, (len(paths), 1, 1))).reshape(len(paths), D).mean(axis=1)

    def bent(share: float) -> np.ndarray:
        return pin_poses(t, (1.0 - share) * pose[:, :3] + share * along, pose[:, 3:], pins)[0]

    b1 = quality.time_normalised_mean(demos)
    along = _plain_mean_along(b1, t, pose[:, :3])
    b1_far, own = far([b1, bent(0.0)])
    share = 0.0
    if own > b1_far:
        fars = far([bent(x) for x in PLAIN_MEAN_SHARES])
        near = [x for x, f in zip(PLAIN_MEAN_SHARES, fars, strict=True) if f <= b1_far]
        best = int(np.argmin(fars))
        share = near[0] if near else (PLAIN_MEAN_SHARES[best] if fars[best] < own else 0.0)
    with _GUARD_LOCK:
        _GUARD_SHARES[key] = share
        while len(_GUARD_SHARES) > 64:
            _GUARD_SHARES.pop(next(iter(_GUARD_SHARES)))
    return share


def _guard_key(demos: list[Demo], t: np.ndarray, pose: np.ndarray, pins: list) -> tuple:
    h = hashlib.blake2b(digest_size=16)
    for a in (t, pose[:, :3], *(np.r_[p[0], p[1]] for p in pins)):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return (tuple(id(d) for d in demos), h.hexdigest())


def learn_skill(
    demos: Sequence[Demo],
    params: KeypointParams | None = None,
    *,
    n_clusters: int | None = None,
    seed: int = 0,
    arm: Arm | None = None,
    baxter: Baxter | None = None,
    spline_through: str = "state-means",
    generalization: str = DEFAULT_GENERALIZATION,
    smoothing: float = SMOOTHING,
    scale: FeatureScale | None = None,
    keypoints: Sequence[np.ndarray] | None = None,
    cache: KeypointCache | None = None,
    align_cache: AlignmentCache | None = None,
    route: int | None = None,
    split_routes: bool = True,
) -> Skill:
    """Learn a skill from demonstrations (paper § Task Learning).

    Args:
        demos: one or more demonstrations of the same task by the same arm.
        params: key-point thresholds (default: automatic for these demos, :func:`studio.core.thresholds.auto_params`).
        n_clusters: k (default: the mean number of key-points per demonstration).
        seed: seed for k-means and hmmlearn.
        arm: if given, also solve IK for ``skill.joint_trajectory``, seeded by the reference demo's joints.
        baxter: the robot model (default :meth:`Baxter.load`).
        spline_through: paper mode's path points, "state-means" (default) or "centroids" (docs/decisions/004).
        generalization: "aligned-mean" (default) or "paper" (docs/decisions/003).
        smoothing: spline smoothing (see :mod:`studio.core.generalize`).
        scale: feature scaling for clustering and DTW (default :meth:`FeatureScale.for_demos`).
        keypoints: precomputed key-point indices per demo (e.g. from the slider's cache).
        cache: a :class:`KeypointCache` to reuse derived series.
        align_cache: an :class:`AlignmentCache` to reuse DTW maps (default: a process-wide one).
        route: when the demos go several ways (:func:`routes_of`), which one to learn (index into
            ``skill.routes``; default: the way most demos go). The skill learns from that way's demos only.
        split_routes: False learns from every demo even when they go several ways (a part of an object-relative
            skill, whose parts must keep every demo).

    Returns:
        The :class:`Skill`.

    Raises:
        NotEnoughData: no demos, a demo with fewer than 2 key-points, more clusters than key-points.
        InvalidInput: malformed input (NaN, mismatched lengths are rejected when the Demo is built).
        IkFailed: with ``arm``, the skill's start is out of reach.
    """
    everyone = demos = _validate(demos)
    found, chosen, demos = _route_demos(demos, route, split_routes)
    if params is None:
        from studio.core.thresholds import auto_params

        params = auto_params(demos)
    scale = scale or FeatureScale.for_demos(demos)
    if spline_through not in SPLINE_THROUGH:
        raise InvalidInput(f'spline_through must be one of {", ".join(SPLINE_THROUGH)} (got "{spline_through}").')
    if generalization not in GENERALIZATIONS:
        raise InvalidInput(f'generalization must be one of {", ".join(GENERALIZATIONS)} (got "{generalization}").')
    if arm is not None:
        check_arm(arm)
    kc = cache or _SERIES_CACHE
    fm = _fit(
        demos,
        params,
        n_clusters=n_clusters,
        seed=seed,
        scale=scale,
        spline_through=spline_through,
        keypoints=keypoints,
        cache=kc,
        align_cache=align_cache,
        dtw_features="paper" if generalization == "paper" else "shape",
    )
    traj = _trajectory(demos, fm, generalization=generalization, smoothing=smoothing, cache=kc)
    ref_demo = demos[fm.ref]
    jt = None
    if arm is not None:
        seed_q = ref_demo.q[0] if ref_demo.q is not None else (baxter or Baxter.load()).neutral(arm)
        jt = joint_trajectory(traj, arm, seed_q, baxter)
    k = fm.k
    labels_all = np.concatenate(fm.cl.labels)
    times_all = np.concatenate(fm.aligned)
    centroid_times = np.full(k, np.nan)
    for c in range(k):
        m = labels_all == c
        if m.any():
            centroid_times[c] = times_all[m].mean()
    order = np.argsort(fm.times, kind="stable")
    model = fm.model
    return Skill(
        trajectory=traj,
        keypoints=fm.kps,
        labels=list(fm.cl.labels),
        centroids=fm.cl.centroids,
        centroid_times=centroid_times,
        states=model.states,
        paths=list(model.paths),
        reference=fm.ref,
        zero_points=model.zero_points,
        startprob=model.startprob,
        transmat=model.transmat,
        emissionprob=model.emissionprob,
        loglik=model.loglik,
        path_times=fm.times[order],
        path_points=fm.points[order],
        path_states=fm.pairs[:, 0][order],
        joint_trajectory=jt,
        arm=arm,
        params=params,
        spline_through=spline_through,
        demo_names=tuple(d.name for d in demos),
        generalization=Generalization.of(generalization),
        routes=tuple(SkillRoute(tuple(everyone[i].name for i in r.demos), r.at) for r in found.routes),
        route=chosen,
        route_where=found.where,
    )


def learn_path(
    demos: Sequence[Demo],
    params: KeypointParams | None = None,
    *,
    n_clusters: int | None = None,
    seed: int = 0,
    generalization: str = DEFAULT_GENERALIZATION,
    rate_hz: float = 50.0,
    cache: KeypointCache | None = None,
    align_cache: AlignmentCache | None = None,
    keypoints: Sequence[np.ndarray] | None = None,
    route: int | None = None,
) -> Demo:
    """The generalized trajectory only, sampled at ``rate_hz`` (no IK, no :class:`Skill`): what the auto-tune
    scores and the live preview draws. Same stages and results as :func:`learn_skill` at a lower rate
    (``keypoints``: the key-point indices per demo for ``params``, when already extracted; ``route``: as for
    :func:`learn_skill`)."""
    everyone = _validate(demos)
    found, _, demos = _route_demos(everyone, route)
    if keypoints is not None and found:
        if len(keypoints) != len(everyone):
            raise InvalidInput("There must be one list of key-points per demonstration.")
        keep = {id(d) for d in demos}
        keypoints = [k for d, k in zip(everyone, keypoints, strict=True) if id(d) in keep]
    if params is None:
        from studio.core.thresholds import auto_params

        params = auto_params(demos)
    if generalization not in GENERALIZATIONS:
        raise InvalidInput(f'generalization must be one of {", ".join(GENERALIZATIONS)} (got "{generalization}").')
    kc = cache or _SERIES_CACHE
    fm = _fit(
        demos,
        params,
        n_clusters=n_clusters,
        seed=seed,
        scale=FeatureScale.for_demos(demos),
        spline_through="state-means",
        keypoints=keypoints,
        cache=kc,
        align_cache=align_cache,
        dtw_features="paper" if generalization == "paper" else "shape",
    )
    return _trajectory(demos, fm, generalization=generalization, smoothing=SMOOTHING, cache=kc, rate_hz=rate_hz)


@dataclass(frozen=True, eq=False)
class PreviewPath:
    """The learned path while a slider moves (thin and dashed in the browser) and its fidelity figure.

    Attributes:
        t: (M,) seconds on the reference demo's time line.
        position: (M, 3) metres.
        keypoints: the key-point indices per demo for these thresholds.
        n_clusters: k used.
        g_over_r: in-sample fidelity G/R against the shown demos (NaN with one demo).
        distance: root-mean-square distance to the demos, m (the "within … on average" figure).
        message: plain words when no path could be made (too few key-points, …), else "".
        routes: the ways the demos go when more than one; the path follows ``routes[route]`` and the figures
            are against that way's demos.
    """

    t: np.ndarray
    position: np.ndarray
    keypoints: list[np.ndarray]
    n_clusters: int
    g_over_r: float
    distance: float
    message: str = ""
    routes: tuple[SkillRoute, ...] = ()
    route: int = 0


class _DemoCurves:
    """The demos' comparison curves (``n`` points) and spread, computed once per set of demos (the slider moves
    ε only)."""

    def __init__(self, n: int, spread: bool = True) -> None:
        self._n, self._spread = n, spread
        self._entry: tuple[tuple, tuple, tuple[list[np.ndarray], float]] | None = None

    def get(self, demos: Sequence[Demo]) -> tuple[list[np.ndarray], float]:
        from studio.core import quality

        key = tuple(id(d) for d in demos)
        entry = self._entry
        if entry is not None and key == entry[0] and all(r() is d for r, d in zip(entry[1], demos, strict=True)):
            return entry[2]
        curves = [quality.curve(d, self._n) for d in demos]
        r = quality.spread(curves)[0] if self._spread and len(curves) > 1 else float("nan")
        self._entry = (key, tuple(weakref.ref(d) for d in demos), (curves, r))
        return curves, r


_PREVIEW_CURVES = _DemoCurves(300)
_GUARD_CURVES = _DemoCurves(quality.N_POINTS, spread=False)


def preview_path(
    demos: Sequence[Demo],
    params: KeypointParams,
    *,
    n_clusters: int | None = None,
    generalization: str = DEFAULT_GENERALIZATION,
    cache: KeypointCache | None = None,
    align_cache: AlignmentCache | None = None,
    rate_hz: float = 50.0,
    keypoints: Sequence[np.ndarray] | None = None,
    route: int | None = None,
) -> PreviewPath:
    """Re-extract key-points, re-cluster, re-train the HMM and regenerate the path for the live preview.

    Pass the slider's :class:`KeypointCache` (DTW maps are cached across calls since they do not depend on ε;
    speed: bench/bench_quality.py). Never raises for thresholds that find too few key-points: the message says
    what to do instead. ``keypoints``: the key-point indices per demo for ``params`` when already extracted
    (the slider's view has them).
    """
    from studio.core import quality
    from studio.core.errors import StudioError

    demos = _validate(demos)
    kc = cache or _SERIES_CACHE
    kps = [kc.extract(d, params) for d in demos] if keypoints is None else [np.asarray(k) for k in keypoints]
    found = routes_of(demos)
    way = found.default if found and (route is None or not 0 <= route < len(found)) else int(route or 0)
    ways = tuple(SkillRoute(tuple(demos[i].name for i in r.demos), r.at) for r in found.routes)
    try:
        traj = learn_path(
            demos,
            params,
            n_clusters=n_clusters,
            generalization=generalization,
            rate_hz=rate_hz,
            cache=kc,
            align_cache=align_cache,
            keypoints=kps,
            route=way if found else None,
        )
    except StudioError as exc:
        return PreviewPath(np.zeros(0), np.zeros((0, 3)), kps, 0, float("nan"), float("nan"), str(exc), ways, way)
    used = kps
    if found:
        demos = [demos[i] for i in found.routes[way].demos]
        used = [kps[i] for i in found.routes[way].demos]
    curves, r = _PREVIEW_CURVES.get(demos)
    c = quality.curve(traj, 300)
    g = float(np.mean([quality.ndtw(c, x) for x in curves]))
    k = default_n_clusters(used) if n_clusters is None else int(n_clusters)
    return PreviewPath(
        t=np.asarray(traj.t),
        position=np.asarray(traj.position),
        keypoints=kps,
        n_clusters=k,
        g_over_r=g / r if r and r > 0 else float("nan"),
        distance=float(np.sqrt(g)),
        routes=ways,
        route=way,
    )


def judge_skill(
    skill: Skill, demos: Sequence[Demo], *, fixed_k: bool = False, folds: int = 3
) -> tuple[quality.QualityReport, quality.Verdict]:
    """How good a learned skill is, measured against the demonstrations it learned from (in the skill's order):
    the :class:`~studio.core.quality.QualityReport` with held-out fidelity (at most ``folds`` demos left out in
    turn, learned with the skill's thresholds and mode; with ``fixed_k`` the skill's k, else the default) and
    its :func:`~studio.core.quality.verdict`.
    """
    from studio.core.errors import StudioError

    demos = list(demos)
    held = None
    if len(demos) >= 2:
        k = skill.n_clusters if fixed_k else None

        def learn(dd: list[Demo]) -> Demo:
            kk = None if k is None else min(k, sum(len(x) for x in skill.keypoints))
            return learn_path(dd, skill.params, n_clusters=kk, generalization=skill.generalization)

        try:
            held = quality.held_out(demos, learn, folds=list(range(min(len(demos), folds))))
        except StudioError:
            held = None
    report = quality.assess(skill, demos, held_out_result=held)
    return report, quality.verdict(report)


def learn_arms(
    recordings: Sequence[Recording],
    params: KeypointParams | ThresholdSettings | None = None,
    *,
    arms: Sequence[str] | None = None,
    n_clusters: int | None = None,
    seed: int = 0,
    baxter: Baxter | None = None,
    generalization: str = DEFAULT_GENERALIZATION,
) -> dict[Arm, Skill]:
    """One skill per taught arm, each with its joint trajectory.

    Args:
        recordings: the session's recordings.
        params: fixed thresholds, or :class:`~studio.core.thresholds.ThresholdSettings` resolved for each
            arm's demonstrations (default: automatic).
        arms: the arms to learn (default: every arm taught in at least one recording).

    Returns:
        {arm: Skill} for each arm, learned from the recordings in which that arm was taught.
    """
    recordings = list(recordings)
    if not recordings:
        raise NotEnoughData("There are no demonstrations yet: record at least one to learn a skill.")
    b = baxter or Baxter.load()
    if arms is None:
        arms = [a for a in ARMS if any(a in r.arms for r in recordings)]
    out: dict[Arm, Skill] = {}
    for name in arms:
        arm = check_arm(name)
        demos = [demo_from_recording(r, arm, b) for r in recordings if arm in r.arms]
        if not demos:
            raise NotEnoughData(f"No demonstration teaches the {arm} arm.")
        p = params.resolve(demos) if isinstance(params, ThresholdSettings) else params
        out[arm] = learn_skill(
            demos, p, n_clusters=n_clusters, seed=seed, arm=arm, baxter=b, generalization=generalization
        )
    return out


__all__ = [
    "DEFAULT_GENERALIZATION",
    "GENERALIZATIONS",
    "SPLINE_THROUGH",
    "AlignmentCache",
    "PreviewPath",
    "demo_from_recording",
    "judge_skill",
    "learn_arms",
    "learn_path",
    "learn_skill",
    "preview_path",
]
