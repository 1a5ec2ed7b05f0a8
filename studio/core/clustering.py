"""k-means codebook over all demonstrations' key-points (paper § Clustering).

Key-points are 8-D (x, y, z, qw, qx, qy, qz, gripper); each group is divided by a physical scale first
(:class:`FeatureScale`) so no unit swamps the others, and quaternions are put in one hemisphere. k defaults to
the mean number of key-points per demonstration (the paper's choice). Clusters are numbered by the mean
normalised time of their members, so the left–right HMM's states inherit the task's order. k-means is a few
lines of numpy (scikit-learn is the test's oracle and ``backend="sklearn"``): docs/decisions/006."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.types import Demo, readonly

#: k-means implementation: "numpy" (this module's Lloyd iterations, default: docs/decisions/006) or
#: "sklearn" (scikit-learn ``KMeans``).
BACKEND = "numpy"
#: Most key-points grouped at once (all demonstrations together) and most clusters: the work and memory of
#: clustering and of the HMM grow with them (docs/decisions/051-memory-budget.md); beyond, refused in words.
MAX_KEYPOINTS = 4_000
MAX_K = 400
#: k-means++ compares at most this many key-points pairwise (a random sample of them beyond it).
SEED_SAMPLE = 2_000


@dataclass(frozen=True)
class FeatureScale:
    """How much of each quantity counts as one unit of distance in clustering and DTW.

    Attributes:
        position: metres per unit.
        orientation: quaternion units per unit (0.1 ≈ 0.2 rad of rotation).
        gripper: percent of opening per unit.
    """

    position: float = 0.05
    orientation: float = 0.1
    gripper: float = 25.0

    def __post_init__(self) -> None:
        for name in ("position", "orientation", "gripper"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v > 0 and np.isfinite(v)):
                raise InvalidInput(f"Feature scale {name} must be a positive number (got {v!r}).")

    @classmethod
    def for_demos(cls, demos: Sequence[Demo]) -> FeatureScale:
        """The scale for these demonstrations: 5 cm of position, or a quarter of their size (median largest
        side of the bounding box) when that is smaller, at least 2 mm — a 3 cm gesture's key-points would
        otherwise all look alike next to the orientation's and the gripper's units."""
        sizes = [d.extent for d in demos if len(d)]
        size = float(np.median(sizes)) if sizes else 0.2
        return cls(position=float(min(0.05, max(0.002, size / 4.0))))

    @property
    def divisors(self) -> np.ndarray:
        """(8,) divisors for x, y, z, qw, qx, qy, qz, gripper."""
        return np.array([self.position] * 3 + [self.orientation] * 4 + [self.gripper])


def align_hemisphere(quats: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Flip quaternions (M, 4) so each has a non-negative dot product with ``reference`` (4,)."""
    s = np.where(quats @ reference < 0, -1.0, 1.0)
    return quats * s[:, None]


def keypoint_features(
    demos: Sequence[Demo], keypoints: Sequence[np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stack the key-points of all demos.

    Returns:
        X (M, 8) unscaled 8-D vectors (quaternions in one hemisphere), demo index (M,), normalised time (M,).
    """
    if len(demos) != len(keypoints):
        raise InvalidInput("There must be one list of key-points per demonstration.")
    rows, owner, u = [], [], []
    for d, (demo, kp) in enumerate(zip(demos, keypoints, strict=True)):
        kp = np.asarray(kp, dtype=np.int64)
        rows.append(np.column_stack([demo.position[kp], demo.orientation[kp], demo.gripper[kp]]))
        owner.append(np.full(kp.shape[0], d))
        dur = demo.duration if demo.duration > 0 else 1.0
        u.append((demo.t[kp] - demo.t[0]) / dur)
    X = np.concatenate(rows) if rows else np.zeros((0, 8))
    if X.shape[0]:
        ref = X[0, 3:7]
        X[:, 3:7] = align_hemisphere(X[:, 3:7], ref)
        mean = X[:, 3:7].mean(axis=0)
        if np.linalg.norm(mean) > 1e-6:
            X[:, 3:7] = align_hemisphere(X[:, 3:7], mean / np.linalg.norm(mean))
    return X, np.concatenate(owner) if owner else np.zeros(0, int), np.concatenate(u) if u else np.zeros(0)


@dataclass(frozen=True, eq=False)
class Clustering:
    """The codebook.

    Attributes:
        centroids: (k, 8) unscaled centroids (unit quaternions), ordered by mean normalised time.
        labels: one (K_d,) int array per demo: the cluster (= codebook symbol) of each key-point.
        mean_time: (k,) mean normalised time of each cluster's members.
        features: (M, 8) all key-points' 8-D vectors in the order of ``labels`` concatenated.
        scale: the feature scale used.
        inertia: k-means distortion in scaled units.
    """

    centroids: np.ndarray
    labels: list[np.ndarray]
    mean_time: np.ndarray
    features: np.ndarray
    scale: FeatureScale
    inertia: float

    @property
    def n_clusters(self) -> int:
        return int(self.centroids.shape[0])


def _sq_dist(X: np.ndarray, C: np.ndarray) -> np.ndarray:
    # einsum, not X @ C.T: OpenBLAS starts its threads even for these tiny products (docs/decisions/006)
    d = np.sum(X * X, axis=1)[:, None] + np.sum(C * C, axis=1)[None, :] - 2.0 * np.einsum("ik,jk->ij", X, C)
    return np.maximum(d, 0.0)


def kmeans_plusplus(
    X: np.ndarray, k: int, rng: np.random.Generator, n_local_trials: int | None = None, D: np.ndarray | None = None
) -> np.ndarray:
    """k-means++ seeding (Arthur & Vassilvitskii, greedy variant as in scikit-learn): (k, D) centres.

    ``D`` is the (M, M) matrix of squared distances between the points if already computed.
    """
    m = X.shape[0]
    trials = n_local_trials or 2 + int(np.log(k))
    D = _sq_dist(X, X) if D is None else D
    chosen = [int(rng.integers(m))]
    closest = D[chosen[0]].copy()
    for _ in range(1, k):
        pot = closest.sum()
        if pot <= 0:
            rest = np.setdiff1d(np.arange(m), chosen)
            chosen.extend(rng.choice(rest, k - len(chosen), replace=False).tolist())
            break
        cand = np.minimum(np.searchsorted(np.cumsum(closest), rng.random(trials) * pot), m - 1)
        d = np.minimum(closest[None, :], D[cand])
        best = int(np.argmin(d.sum(axis=1)))
        chosen.append(int(cand[best]))
        closest = d[best]
    return X[np.array(chosen[:k])].copy()


def lloyd(X: np.ndarray, centers: np.ndarray, max_iter: int = 100) -> tuple[np.ndarray, np.ndarray, float]:
    """Lloyd iterations from ``centers`` until the assignment stops changing.

    An emptied cluster is re-seeded with the point farthest from its centre (as scikit-learn does), so
    exactly k clusters come out whenever there are at least k distinct points.

    Returns:
        centres (k, D), labels (M,), inertia (sum of squared distances).
    """
    C = np.array(centers, dtype=np.float64, copy=True)
    k = C.shape[0]
    labels = np.full(X.shape[0], -1)
    for _ in range(max_iter):
        d = _sq_dist(X, C)
        new = np.argmin(d, axis=1)
        counts = np.bincount(new, minlength=k)
        for c in np.flatnonzero(counts == 0):
            far = int(np.argmax(d[np.arange(X.shape[0]), new]))
            new[far] = c
            d[far] = 0.0
            counts = np.bincount(new, minlength=k)
        if np.array_equal(new, labels):
            break
        labels = new
        for dim in range(X.shape[1]):
            C[:, dim] = np.bincount(labels, weights=X[:, dim], minlength=k) / np.maximum(counts, 1)
    inertia = float(np.sum((X - C[labels]) ** 2))
    return C, labels, inertia


def _sklearn_kmeans(
    Xs: np.ndarray, k: int, quantiles: np.ndarray, *, seed: int, n_init: int
) -> tuple[float, np.ndarray, np.ndarray]:
    """scikit-learn ``KMeans``: one fit from the time-quantile centres, one with ``n_init − 1`` k-means++ starts;
    the lower distortion wins. OpenMP/BLAS limited to one thread (tiny inputs; thread start-up and contention
    with the other cores' work cost more than they give)."""
    from sklearn.cluster import KMeans
    from sklearn.cluster import kmeans_plusplus as kmeans_plusplus_sklearn
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        a = KMeans(n_clusters=k, init=quantiles, n_init=1, algorithm="lloyd", random_state=seed).fit(Xs)
        best = (float(a.inertia_), a.labels_, a.cluster_centers_)
        for i in range(n_init - 1):
            seeds, _ = kmeans_plusplus_sklearn(Xs, k, random_state=seed + i)
            b = KMeans(n_clusters=k, init=seeds, n_init=1, algorithm="lloyd", random_state=seed).fit(Xs)
            if float(b.inertia_) < best[0] - 1e-12:
                best = (float(b.inertia_), b.labels_, b.cluster_centers_)
    return best


def default_n_clusters(keypoints: Sequence[np.ndarray]) -> int:
    """The paper's k: the mean number of key-points per demonstration, rounded."""
    return max(1, round(float(np.mean([len(k) for k in keypoints]))))


def cluster(
    demos: Sequence[Demo],
    keypoints: Sequence[np.ndarray],
    n_clusters: int | None = None,
    *,
    seed: int = 0,
    scale: FeatureScale | None = None,
    n_init: int = 4,
    backend: str | None = None,
) -> Clustering:
    """k-means over all key-points; clusters numbered by mean normalised time.

    The first start is "time quantiles" (all key-points sorted by normalised time and cut into k groups),
    which already respects the task's order; ``n_init − 1`` k-means++ starts follow; the lowest distortion
    wins. Deterministic for a given ``seed``.

    Raises:
        NotEnoughData: no key-points, or more clusters than distinct key-points.
        InvalidInput: k below 1.
    """
    scale = scale or FeatureScale.for_demos(demos)
    m = sum(len(kp) for kp in keypoints)
    if m > MAX_KEYPOINTS:
        raise InvalidInput(
            f"The demonstrations have {m:,} key-points together; at most {MAX_KEYPOINTS:,} can be grouped into a "
            "skill (a demonstration usually has tens: these are noisy or very long recordings, or the key-point "
            "thresholds are very fine). Use larger key-point thresholds, or trim or hide the longest demonstrations."
        )
    X, _, u = keypoint_features(demos, keypoints)
    if m == 0:
        raise NotEnoughData("There are no key-points to group: record at least one demonstration.")
    k = default_n_clusters(keypoints) if n_clusters is None else int(n_clusters)
    if k < 1:
        raise InvalidInput(f"The number of clusters must be at least 1 (got {k}).")
    if k > MAX_K:
        raise InvalidInput(
            f"{k:,} clusters are more than a skill can be learned with (at most {MAX_K:,}). "
            + (
                "The demonstrations have that many key-points each: use larger key-point thresholds."
                if n_clusters is None
                else "Choose fewer clusters."
            )
        )
    Xs = X / scale.divisors
    n_distinct = np.unique(np.round(Xs, 9), axis=0).shape[0]
    if k > n_distinct >= 2 and n_clusters is None:
        k = n_distinct  # the demonstrations repeat the same key-points (taught by keys or "Go above"): one each
    if k > n_distinct and n_clusters is None:
        raise NotEnoughData(
            f"The demonstrations have only {n_distinct} different key-point(s): the arm barely moved. Record "
            "demonstrations that move the arm through the task, or lower the key-point thresholds."
        )
    if k > n_distinct:
        raise NotEnoughData(
            f"Cannot make {k} clusters from {n_distinct} different key-points. Choose at most {n_distinct} "
            "clusters, record more demonstrations, or lower the key-point thresholds to find more key-points."
        )
    order = np.argsort(u, kind="stable")
    groups = np.array_split(order, k)
    quantiles = np.stack([Xs[g].mean(axis=0) for g in groups])
    if (backend or BACKEND) == "sklearn":
        inertia, labels, centers = _sklearn_kmeans(Xs, k, quantiles, seed=seed, n_init=n_init)
    else:
        inits = [quantiles]
        rng = np.random.default_rng(seed)
        sample = Xs if m <= SEED_SAMPLE else Xs[np.sort(rng.choice(m, SEED_SAMPLE, replace=False))]
        D = _sq_dist(sample, sample)
        for _ in range(max(0, n_init - 1)):
            inits.append(kmeans_plusplus(sample, k, rng, D=D))
        best: tuple[float, np.ndarray, np.ndarray] | None = None
        for init in inits:
            centers, labels_, inertia = lloyd(Xs, init)
            if best is None or inertia < best[0] - 1e-12:
                best = (inertia, labels_, centers)
        assert best is not None
        inertia, labels, centers = best
    labels = labels.astype(np.int64)
    counts = np.bincount(labels, minlength=k)
    mean_u = np.bincount(labels, weights=u, minlength=k) / np.maximum(counts, 1)
    mean_u[counts == 0] = np.inf
    rank = np.argsort(mean_u, kind="stable")
    relabel = np.empty(k, dtype=np.int64)
    relabel[rank] = np.arange(k)
    labels = relabel[labels]
    cent = np.zeros((k, 8))
    for c in range(k):
        members = X[labels == c]
        cent[c] = members.mean(axis=0) if members.shape[0] else centers[rank[c]] * scale.divisors
    cent[:, 3:7] /= np.linalg.norm(cent[:, 3:7], axis=1, keepdims=True)
    split = np.cumsum([len(kp) for kp in keypoints])[:-1]
    return Clustering(
        centroids=readonly(cent),
        labels=[readonly(lab, dtype=np.int64) for lab in np.split(labels, split)],
        mean_time=readonly(mean_u[rank]),
        features=readonly(X),
        scale=scale,
        inertia=float(inertia),
    )


def cluster_keypoints(
    demos: Sequence[Demo],
    keypoints: Sequence[np.ndarray],
    n_clusters: int | None = None,
    *,
    seed: int = 0,
    scale: FeatureScale | None = None,
) -> np.ndarray:
    """(k, 8) centroids ordered by mean normalised time (see :func:`cluster` for labels and details)."""
    return cluster(demos, keypoints, n_clusters, seed=seed, scale=scale).centroids


__all__ = [
    "Clustering",
    "FeatureScale",
    "align_hemisphere",
    "cluster",
    "cluster_keypoints",
    "default_n_clusters",
    "keypoint_features",
    "kmeans_plusplus",
    "lloyd",
]
