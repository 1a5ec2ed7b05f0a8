"""k-means codebook: feature scaling, time order, the paper's k, hemisphere, errors, and scikit-learn parity."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.cluster import KMeans

from studio.core.clustering import FeatureScale, cluster, cluster_keypoints, default_n_clusters, lloyd
from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.keypoints import extract_keypoints
from studio.core.types import Demo
from tests.core.teacher_demos import demos


def _kps(task):
    ds = demos(task)
    return ds, [extract_keypoints(d) for d in ds]


def test_default_k_is_mean_keypoints_and_clusters_are_time_ordered():
    ds, kps = _kps("pick-place")
    cl = cluster(ds, kps, seed=0)
    assert cl.n_clusters == default_n_clusters(kps) == round(np.mean([len(k) for k in kps]))
    assert np.all(np.diff(cl.mean_time) >= 0)
    assert cl.mean_time[0] < 0.1 and cl.mean_time[-1] > 0.9  # start and end clusters
    assert np.allclose(np.linalg.norm(cl.centroids[:, 3:7], axis=1), 1.0)
    # labels index the centroids and cover every key-point
    assert [len(lab) for lab in cl.labels] == [len(k) for k in kps]
    assert np.array_equal(cluster_keypoints(ds, kps, seed=0), cl.centroids)


def test_gripper_opening_separates_clusters_at_the_same_pose():
    ds, kps = _kps("stack-cup")
    cl = cluster(ds, kps, seed=0)
    X = np.concatenate([d.features[k] for d, k in zip(ds, kps, strict=True)])
    lab = np.concatenate(cl.labels)
    for c in range(cl.n_clusters):  # no cluster mixes an open and a closed gripper
        g = X[lab == c, 7]
        assert g.max() - g.min() < 20


def test_quaternion_sign_does_not_matter():
    ds, kps = _kps("stack-cup")
    flipped = [Demo(d.t, d.position, -d.orientation, d.gripper, name=d.name) if i == 1 else d for i, d in enumerate(ds)]
    a, b = cluster(ds, kps, seed=3), cluster(flipped, kps, seed=3)
    assert all(np.array_equal(x, y) for x, y in zip(a.labels, b.labels, strict=True))


def test_lloyd_matches_scikit_learn_from_the_same_start():
    X = np.random.default_rng(0).normal(size=(90, 8))
    init = X[:12].copy()
    _, labels, inertia = lloyd(X, init)
    km = KMeans(n_clusters=12, init=init, n_init=1, max_iter=100, tol=0.0).fit(X)
    assert inertia == pytest.approx(km.inertia_, rel=1e-9)
    assert np.array_equal(labels, km.labels_)


def test_scaled_inertia_not_worse_than_scikit_learn():
    ds, kps = _kps("pick-place")
    cl = cluster(ds, kps, seed=0)
    Xs = cl.features / FeatureScale().divisors
    km = KMeans(n_clusters=cl.n_clusters, n_init=10, random_state=0).fit(Xs)
    assert cl.inertia <= km.inertia_ * 1.10


def test_errors_are_plain_words():
    ds, kps = _kps("stack-cup")
    total = sum(len(k) for k in kps)
    with pytest.raises(NotEnoughData, match="clusters"):
        cluster(ds, kps, total + 1)
    with pytest.raises(InvalidInput):
        cluster(ds, kps, 0)
    with pytest.raises(NotEnoughData):
        cluster([], [])
    with pytest.raises(InvalidInput):
        FeatureScale(position=0.0)


def test_one_demo_k_equals_its_keypoints():
    ds, kps = _kps("stack-cup")
    cl = cluster(ds[:1], kps[:1])
    assert cl.n_clusters == len(kps[0])
    assert cl.labels[0].tolist() == list(range(len(kps[0])))  # each key-point its own cluster, in order


def test_arm_that_never_moved_gets_a_plain_message():
    n = 500
    still = Demo(
        np.arange(n) / 1000.0, np.tile([0.6, 0.2, 0.1], (n, 1)), np.tile([0, 0, 1.0, 0], (n, 1)), np.full(n, 100.0)
    )
    with pytest.raises(NotEnoughData, match="barely moved"):
        cluster([still], [np.array([0, n - 1])])
    with pytest.raises(NotEnoughData, match="Choose at most 1"):
        cluster([still], [np.array([0, n - 1])], n_clusters=2)


def test_the_sklearn_backend_finds_as_good_a_codebook():
    ds = list(demos("pick-place"))
    kps = [extract_keypoints(d) for d in ds]
    ours = cluster(ds, kps, seed=0, backend="numpy")
    sk = cluster(ds, kps, seed=0, backend="sklearn")
    assert sk.n_clusters == ours.n_clusters
    # two local optima of the same distortion (k-means++ restarts differ): within 10 % of each other
    assert sk.inertia <= ours.inertia * 1.10 and ours.inertia <= sk.inertia * 1.10


def test_the_feature_scale_follows_the_demos_size_computed_once_per_demo() -> None:
    t = np.arange(4) / 10.0
    ori = np.tile([1.0, 0.0, 0.0, 0.0], (4, 1))
    small = Demo(t, np.array([[0, 0, 0], [0.02, 0, 0], [0.02, 0.03, 0], [0, 0.03, 0.01]]), ori, np.zeros(4))
    big = Demo(t, np.array([[0, 0, 0], [0.6, 0, 0], [0.6, 0.2, 0], [0, 0.2, 0]]), ori, np.zeros(4))
    assert small.extent == pytest.approx(0.03) and big.extent == pytest.approx(0.6)
    assert "extent" in vars(small)  # kept with the demo: a slider step does not scan 30,000 samples again
    assert FeatureScale.for_demos([small, small]).position == pytest.approx(0.03 / 4)
    assert FeatureScale.for_demos([big]).position == 0.05
    empty = Demo(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 4)), np.zeros(0))
    assert empty.extent == 0.0 and FeatureScale.for_demos([empty]).position == 0.05


def test_identical_demonstrations_make_one_cluster_per_key_point():
    """Taught by keys and "Go above", three takes repeat the same poses and come back to where they started: k
    falls to the distinct key-points (issue 18) instead of refusing; an asked-for k above them is still refused."""
    n = 300
    s = np.linspace(0.0, 1.0, n)
    out = np.minimum(s, 1.0 - s)[:, None] * np.array([0.4, 0.2, 0.0])  # out and back to the start
    d = Demo(s * 3.0, np.array([0.6, 0.2, 0.1]) + out, np.tile([0, 0, 1.0, 0], (n, 1)), np.full(n, 100.0))
    kp = np.array([0, n // 4, n // 2, 3 * n // 4, n - 1])  # the first and last are the same pose
    cl = cluster([d, d, d], [kp] * 3)
    assert cl.n_clusters == 4
    with pytest.raises(NotEnoughData, match="Choose at most 4"):
        cluster([d, d, d], [kp] * 3, n_clusters=5)
