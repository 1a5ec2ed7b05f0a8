"""``learn_skill``: the paper's task-learning stages in order, from demonstrations to a :class:`Skill`.

key-points (keypoints.py) ▸ k-means codebook (clustering.py) ▸ Bakis HMM, Baum–Welch, Viterbi, forward
selection of the reference (hmm.py) ▸ multidimensional DTW of every demo against the reference
(alignment.py) ▸ timed path points without zero-points ▸ smoothing spline (generalize.py) ▸ IK (optional).

Path points ("spline_through"):

* ``"state-means"`` (default): the reference's key-points are taken in order as (Viterbi state, k-means
  cluster) pairs; each pair gives one point, the mean of all demos' key-points with that same state and
  cluster, timed by the mean of their DTW-aligned times. Usually a pair is just a state; keeping the
  cluster too matters when Viterbi lets one state absorb two different key-points of the reference (a
  self-transition) — e.g. the start and the end of a gripper motion at the same pose: one point per state
  would drop one of them, and the gripper would switch half-way to the neighbouring point, centimetres
  away from the grasp;
* ``"centroids"`` (the paper): the k-means centroid of the pair's cluster, timed the same way (not by all
  the cluster's members: a cluster visited twice, as in pick-and-place there and back, has members at two
  different times).

The quality tests (tests/core/test_pipeline.py) measure both on the scripted teacher's demonstrations;
state-means land closer to the demos' start and end poses and to the grasp poses, because a k-means
cluster can mix key-points from different parts of the task that Viterbi keeps apart by their order.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from studio.core import alignment, hmm
from studio.core.clustering import FeatureScale, align_hemisphere, cluster, default_n_clusters
from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.generalize import SMOOTHING, generalize, joint_trajectory
from studio.core.keypoints import KeypointCache, extract_keypoints
from studio.core.kinematics import Baxter
from studio.core.types import ARMS, Demo, KeypointParams, Recording, Skill, check_arm

SPLINE_THROUGH = ("state-means", "centroids")


def demo_from_recording(rec: Recording, arm: str, baxter: Baxter | None = None) -> Demo:
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


def learn_skill(
    demos: Sequence[Demo],
    params: KeypointParams | None = None,
    *,
    n_clusters: int | None = None,
    seed: int = 0,
    arm: str | None = None,
    baxter: Baxter | None = None,
    spline_through: str = "state-means",
    smoothing: float = SMOOTHING,
    scale: FeatureScale | None = None,
    keypoints: Sequence[np.ndarray] | None = None,
    cache: KeypointCache | None = None,
) -> Skill:
    """Learn a skill from demonstrations (paper § Task Learning).

    Args:
        demos: one or more demonstrations of the same task by the same arm.
        params: key-point thresholds (default ``KeypointParams()``).
        n_clusters: k (default: the mean number of key-points per demonstration).
        seed: seed for k-means and hmmlearn.
        arm: if given, also solve IK for ``skill.joint_trajectory``, seeded by the reference demo's joints.
        baxter: the robot model (default :meth:`Baxter.load`).
        spline_through: "state-means" (default) or "centroids" (see module docstring).
        smoothing: spline smoothing (see :mod:`studio.core.generalize`).
        scale: feature scaling for clustering and DTW.
        keypoints: precomputed key-point indices per demo (e.g. from the slider's cache).
        cache: a :class:`KeypointCache` to reuse derived series.

    Returns:
        The :class:`Skill`.

    Raises:
        NotEnoughData: no demos, a demo with fewer than 2 key-points, more clusters than key-points.
        InvalidInput: malformed input (NaN, mismatched lengths are rejected when the Demo is built).
        IkFailed: with ``arm``, the skill's start is out of reach.
    """
    demos = _validate(demos)
    params = params or KeypointParams()
    scale = scale or FeatureScale()
    if spline_through not in SPLINE_THROUGH:
        raise InvalidInput(f'spline_through must be one of {", ".join(SPLINE_THROUGH)} (got "{spline_through}").')
    if arm is not None:
        check_arm(arm)
    # 1. key-points
    if keypoints is None:
        kps = [cache.extract(d, params) if cache else extract_keypoints(d, params) for d in demos]
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
    cl = cluster(demos, kps, k, seed=seed, scale=scale)
    # 3. HMM
    model = hmm.train(cl.labels, k, seed=seed)
    ref = model.reference
    # 4. DTW of every demo against the reference on a common coarse grid
    rate = alignment.common_rate([d.duration for d in demos])
    ref_demo = demos[ref]
    ref_quat = cl.features[0, 3:7] if cl.features.shape[0] else np.array([1.0, 0, 0, 0])
    grids = [alignment.time_grid(d.t[0], d.t[-1], rate) for d in demos]
    series = [
        _scaled(alignment.resample(d.t, d.features, g), scale, ref_quat) for d, g in zip(demos, grids, strict=True)
    ]
    aligned: list[np.ndarray] = []
    for i, d in enumerate(demos):
        tk = d.t[kps[i]]
        if i == ref:
            aligned.append(tk - ref_demo.t[0])
            continue
        _, path = alignment.dtw(series[ref], series[i])
        mapped = alignment.time_map(path, grids[ref], grids[i])
        aligned.append(np.interp(tk, grids[i], mapped) - ref_demo.t[0])
    # 5. timed path points
    times_all = np.concatenate(aligned)
    labels_all = np.concatenate(cl.labels)
    states_all = np.concatenate(model.paths)
    X = cl.features
    centroid_times = np.full(k, np.nan)
    for c in range(k):
        m = labels_all == c
        if m.any():
            centroid_times[c] = times_all[m].mean()
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
    path_states = pairs[:, 0]
    dt = float(np.median(np.diff(ref_demo.t)))
    traj = generalize(
        np.array(tms),
        np.array(pts),
        weights=np.array(wts),
        t_start=0.0,
        t_end=ref_demo.duration,
        rate_hz=1.0 / dt,
        smoothing=smoothing,
        name="learned skill",
    )
    jt = None
    if arm is not None:
        seed_q = ref_demo.q[0] if ref_demo.q is not None else (baxter or Baxter.load()).neutral(arm)
        jt = joint_trajectory(traj, arm, seed_q, baxter)
    order = np.argsort(tms, kind="stable")
    return Skill(
        trajectory=traj,
        keypoints=kps,
        labels=list(cl.labels),
        centroids=cl.centroids,
        centroid_times=centroid_times,
        states=model.states,
        paths=list(model.paths),
        reference=ref,
        zero_points=model.zero_points,
        startprob=model.startprob,
        transmat=model.transmat,
        emissionprob=model.emissionprob,
        loglik=model.loglik,
        path_times=np.array(tms)[order],
        path_points=np.array(pts)[order],
        path_states=path_states[order],
        joint_trajectory=jt,
        arm=arm,
        params=params,
        spline_through=spline_through,
        demo_names=tuple(d.name for d in demos),
    )


def learn_arms(
    recordings: Sequence[Recording],
    params: KeypointParams | None = None,
    *,
    arms: Sequence[str] | None = None,
    n_clusters: int | None = None,
    seed: int = 0,
    baxter: Baxter | None = None,
) -> dict[str, Skill]:
    """One skill per taught arm, each with its joint trajectory.

    Args:
        recordings: the session's recordings.
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
    out: dict[str, Skill] = {}
    for arm in arms:
        check_arm(arm)
        demos = [demo_from_recording(r, arm, b) for r in recordings if arm in r.arms]
        if not demos:
            raise NotEnoughData(f"No demonstration teaches the {arm} arm.")
        out[arm] = learn_skill(demos, params, n_clusters=n_clusters, seed=seed, arm=arm, baxter=b)
    return out


__all__ = ["SPLINE_THROUGH", "demo_from_recording", "learn_arms", "learn_skill"]
