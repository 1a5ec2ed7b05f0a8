"""``learn_skill``: the paper's task-learning stages in order, from demonstrations to a :class:`Skill`.

key-points (keypoints.py) ▸ k-means codebook (clustering.py) ▸ Bakis HMM, Baum–Welch, Viterbi, forward
selection of the reference (hmm.py) ▸ multidimensional DTW of every demo against the reference
(alignment.py) ▸ timed path points without zero-points ▸ the path (generalize.py: the paper's smoothing spline
or the demos averaged along their DTW alignment, the default) ▸ IK (optional). Why: docs/decisions/003, 004."""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import PchipInterpolator

from studio.core import alignment, hmm
from studio.core.caches import LearningCaches
from studio.core.clustering import Clustering, FeatureScale, align_hemisphere, cluster, default_n_clusters
from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.generalize import PathBasis, joint_trajectory, learned_path
from studio.core.kinematics import Baxter
from studio.core.learn_settings import LearnSettings
from studio.core.routes import Routes, routes_of
from studio.core.types import Arm, Demo, Generalization, KeypointParams, Recording, Skill, SkillRoute, check_arm

#: DTW features besides the scaled pose: orientation is weighted down (on a drawn shape the hand's small
#: wobble would steer the alignment as much as the path does) and the unit direction of motion is added
#: (it turns sharply at a corner, so corners align exactly); chosen on the shape suite (docs/decisions/003).
DTW_ORIENTATION_WEIGHT = 0.3
DTW_DIRECTION_WEIGHT = 0.5
_DEFAULT = LearnSettings()


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


def _route_demos(
    demos: list[Demo], route: int | None, split: bool, caches: LearningCaches
) -> tuple[Routes, int, list[Demo]]:
    """(the routes, the one to learn, its demonstrations): all demos when they go one way (or ``split`` is False)."""
    found = routes_of(demos, caches) if split else Routes()
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
    aligned: list[np.ndarray]  # key-point times of each demo on the reference's time line (from its start)
    pairs: np.ndarray  # (P, 2) (state, cluster) of the path points, in the reference's order
    basis: PathBasis  # the timed path points and each demo's warp onto the reference's time line


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
    settings: LearnSettings,
    *,
    keypoints: Sequence[np.ndarray] | None,
    caches: LearningCaches,
) -> _Model:
    n_clusters, seed, spline_through = settings.n_clusters, settings.seed, settings.spline_through
    dtw_features = "paper" if settings.generalization == "paper" else "shape"
    scale = FeatureScale.for_demos(demos)
    # 1. key-points
    if keypoints is None:
        kps = [caches.keypoints.extract(d, params) for d in demos]
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

        mapped = caches.alignments.get(ref_demo, d, key, compute)
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
        aligned=aligned,
        pairs=pairs,
        basis=PathBasis(np.array(tms), np.array(pts), np.array(wts), ref, inverse),
    )


def learn_skill(
    demos: Sequence[Demo],
    settings: LearnSettings = _DEFAULT,
    *,
    arm: Arm | None = None,
    baxter: Baxter | None = None,
    caches: LearningCaches | None = None,
    keypoints: Sequence[np.ndarray] | None = None,
) -> Skill:
    """Learn a skill in the robot's frame from demonstrations (paper § Task Learning).

    Args:
        demos: one or more demonstrations of the same task by the same arm.
        settings: thresholds, k, seed, mode, smoothing and which way (:class:`LearnSettings`; the frames, pauses
            and judging fields are :func:`studio.core.learn.learn`'s).
        arm: if given, also solve IK for ``skill.joint_trajectory``, seeded by the reference demo's joints.
        baxter: the robot model (default :meth:`Baxter.load`).
        caches: what is reused across calls (default: a fresh :class:`LearningCaches`).
        keypoints: precomputed key-point indices per demo (e.g. from the slider's cache).

    Returns:
        The :class:`Skill`; when the demos go several ways (:func:`routes_of`), learned from
        ``settings.route``'s demos (default: the way most demos go), listed in ``skill.routes``.

    Raises:
        NotEnoughData: no demos, a demo with fewer than 2 key-points, more clusters than key-points.
        InvalidInput: malformed input (NaN, mismatched lengths are rejected when the Demo is built).
        IkFailed: with ``arm``, the skill's start is out of reach.
    """
    caches = caches or LearningCaches()
    everyone = demos = _validate(demos)
    found, chosen, demos = _route_demos(demos, settings.route, settings.split_routes, caches)
    params = settings.thresholds(demos)
    if arm is not None:
        check_arm(arm)
    fm = _fit(demos, params, settings, keypoints=keypoints, caches=caches)
    basis = fm.basis
    traj = learned_path(
        demos, basis, generalization=settings.generalization, smoothing=settings.smoothing, caches=caches
    )
    ref_demo = demos[basis.ref]
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
    order = np.argsort(basis.times, kind="stable")
    model = fm.model
    return Skill(
        trajectory=traj,
        keypoints=fm.kps,
        labels=list(fm.cl.labels),
        centroids=fm.cl.centroids,
        centroid_times=centroid_times,
        states=model.states,
        paths=list(model.paths),
        reference=basis.ref,
        zero_points=model.zero_points,
        startprob=model.startprob,
        transmat=model.transmat,
        emissionprob=model.emissionprob,
        loglik=model.loglik,
        path_times=basis.times[order],
        path_points=basis.points[order],
        path_states=fm.pairs[:, 0][order],
        joint_trajectory=jt,
        arm=arm,
        params=params,
        spline_through=settings.spline_through,
        demo_names=tuple(d.name for d in demos),
        generalization=Generalization.of(settings.generalization),
        routes=tuple(SkillRoute(tuple(everyone[i].name for i in r.demos), r.at) for r in found.routes),
        route=chosen,
        route_where=found.where,
    )


def learn_path(
    demos: Sequence[Demo],
    settings: LearnSettings = _DEFAULT,
    *,
    caches: LearningCaches | None = None,
    keypoints: Sequence[np.ndarray] | None = None,
    rate_hz: float = 50.0,
) -> Demo:
    """The generalized trajectory only, sampled at ``rate_hz`` (no IK, no :class:`Skill`): what the auto-tune
    scores, held-out judging learns and the live preview draws. Same stages and results as :func:`learn_skill`
    at a lower rate (``keypoints``: the key-point indices per demo for ``settings.params``, when already
    extracted)."""
    caches = caches or LearningCaches()
    everyone = _validate(demos)
    found, _, demos = _route_demos(everyone, settings.route, True, caches)
    if keypoints is not None and found:
        if len(keypoints) != len(everyone):
            raise InvalidInput("There must be one list of key-points per demonstration.")
        keep = {id(d) for d in demos}
        keypoints = [k for d, k in zip(everyone, keypoints, strict=True) if id(d) in keep]
    fm = _fit(demos, settings.thresholds(demos), settings, keypoints=keypoints, caches=caches)
    return learned_path(
        demos,
        fm.basis,
        generalization=settings.generalization,
        smoothing=settings.smoothing,
        caches=caches,
        rate_hz=rate_hz,
    )


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


def preview_path(
    demos: Sequence[Demo],
    settings: LearnSettings,
    *,
    caches: LearningCaches | None = None,
    keypoints: Sequence[np.ndarray] | None = None,
    rate_hz: float = 50.0,
) -> PreviewPath:
    """Re-extract key-points, re-cluster, re-train the HMM and regenerate the path for the live preview.

    Pass the owner's :class:`LearningCaches` (DTW maps are reused across calls since they do not depend on ε;
    speed: bench/bench_quality.py). Never raises for thresholds that find too few key-points: the message says
    what to do instead. ``keypoints``: the key-point indices per demo for ``settings.params`` when already
    extracted (the slider's view has them); ``settings.route``: the way to draw (a way that no longer exists
    is the default again).
    """
    from studio.core import quality
    from studio.core.errors import StudioError

    caches = caches or LearningCaches()
    demos = _validate(demos)
    params = settings.thresholds(demos)
    if keypoints is None:
        kps = [caches.keypoints.extract(d, params) for d in demos]
    else:
        kps = [np.asarray(k) for k in keypoints]
    found = routes_of(demos, caches)
    route = settings.route
    way = found.default if found and (route is None or not 0 <= route < len(found)) else int(route or 0)
    ways = tuple(SkillRoute(tuple(demos[i].name for i in r.demos), r.at) for r in found.routes)
    try:
        traj = learn_path(
            demos,
            replace(settings, params=params, route=way if found else None),
            caches=caches,
            keypoints=kps,
            rate_hz=rate_hz,
        )
    except StudioError as exc:
        return PreviewPath(np.zeros(0), np.zeros((0, 3)), kps, 0, float("nan"), float("nan"), str(exc), ways, way)
    used = kps
    if found:
        demos = [demos[i] for i in found.routes[way].demos]
        used = [kps[i] for i in found.routes[way].demos]
    curves, r = caches.preview_curves.get(demos)
    c = quality.curve(traj, 300)
    g = float(np.mean([quality.ndtw(c, x) for x in curves]))
    n_clusters = settings.n_clusters
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


__all__ = [
    "DTW_DIRECTION_WEIGHT",
    "DTW_ORIENTATION_WEIGHT",
    "PreviewPath",
    "demo_from_recording",
    "learn_path",
    "learn_skill",
    "preview_path",
]
