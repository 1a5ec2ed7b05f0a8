"""Discrete HMM: the Wikipedia example, the paper's Bakis initialisation, Baum–Welch monotonicity and zeros."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from studio.core import hmm
from studio.core.errors import InvalidInput

# https://en.wikipedia.org/wiki/Viterbi_algorithm#Example : states Healthy, Fever; symbols normal, cold, dizzy
PI = np.array([0.6, 0.4])
A = np.array([[0.7, 0.3], [0.4, 0.6]])
B = np.array([[0.5, 0.4, 0.1], [0.1, 0.3, 0.6]])


def test_wikipedia_viterbi_and_forward():
    model = hmm.make_model(PI, A, B)
    lp, path = hmm.viterbi(model, np.array([0, 1, 2]))
    assert path.tolist() == [0, 0, 1]  # Healthy, Healthy, Fever
    assert np.exp(lp) == pytest.approx(0.01512, rel=1e-9)
    assert np.exp(hmm.forward_loglik(model, np.array([0, 1, 2]))) == pytest.approx(0.03628, rel=1e-9)


def test_bakis_initialisation_follows_the_paper():
    # two demos, 6 key-points each, 3 states: the uniform segmentation puts 2 key-points in each state,
    # so τ_i = 2 steps + the leaving step = 3
    seqs = [np.array([0, 0, 1, 1, 2, 2]), np.array([0, 1, 1, 1, 2, 2])]
    pi, A0, B0 = hmm.bakis_init(seqs, 3)
    assert pi.tolist() == [1.0, 0.0, 0.0]
    tau = 3.0
    row = np.array([1 - 1 / tau, 1 / tau, 1 / (4 * tau)])
    assert A0[0] == pytest.approx(row / row.sum())
    assert A0[1, 1:] == pytest.approx(row[:2] / row[:2].sum()) and A0[1, 0] == 0
    assert A0[2].tolist() == [0.0, 0.0, 1.0]
    assert np.allclose(np.tril(A0, -1), 0) and np.allclose(np.triu(A0, 3), 0)
    # b_i(k) = n_i(q_k) / τ_i, normalised, with a 1 % uniform floor
    counts = np.array([[3, 1, 0], [0, 4, 0], [0, 0, 4]], dtype=float)
    expect = 0.99 * counts / counts.sum(axis=1, keepdims=True) + 0.01 / 3
    assert B0 == pytest.approx(expect)


def _random_sequences(draw_lengths, n_states, seed):
    rng = np.random.default_rng(seed)
    out = []
    for n in draw_lengths:
        base = np.sort(rng.integers(0, n_states, size=n))  # roughly left-to-right, like a time-ordered codebook
        noise = rng.integers(-1, 2, size=n) * (rng.random(n) < 0.2)
        out.append(np.clip(base + noise, 0, n_states - 1))
    return out


@settings(max_examples=15, deadline=None)
@given(st.lists(st.integers(3, 25), min_size=1, max_size=4), st.integers(2, 12), st.integers(0, 10_000))
def test_baum_welch_never_lowers_likelihood_and_keeps_left_right_zeros(lengths, n_states, seed):
    seqs = _random_sequences(lengths, n_states, seed)
    res = hmm.train(seqs, n_states, seed=seed, n_iter=30, tol=0.0)
    h = res.history
    assert np.all(np.diff(h) >= -1e-6 * np.abs(h[1:]) - 1e-9), h
    assert np.all(res.transmat[res.init_transmat == 0] == 0)
    assert res.startprob.tolist() == [1.0] + [0.0] * (n_states - 1)
    assert np.allclose(res.transmat.sum(axis=1), 1) and np.allclose(res.emissionprob.sum(axis=1), 1)
    assert res.reference == int(np.argmax(res.loglik))
    assert set(res.zero_points.tolist()).isdisjoint(res.states.tolist())
    for p in res.paths:
        assert np.all(np.diff(p) >= 0) and np.all(np.diff(p) <= 2)  # left–right, skips of at most one


def test_unreached_states_keep_valid_rows():
    # 10 states but sequences of 3 symbols: most states are never reached; score/decode must still work
    seqs = [np.array([0, 1, 2]), np.array([0, 2, 2])]
    res = hmm.train(seqs, 10)
    model = hmm.make_model(res.startprob, res.transmat, res.emissionprob)
    assert np.isfinite(hmm.forward_loglik(model, np.array([0, 1, 2])))
    assert np.allclose(res.transmat.sum(axis=1), 1)
    assert len(res.zero_points) >= 7


def test_bad_input():
    with pytest.raises(InvalidInput):
        hmm.train([], 3)
    with pytest.raises(InvalidInput):
        hmm.train([np.array([0, 5])], 3)
    with pytest.raises(InvalidInput):
        hmm.train([np.array([], dtype=int)], 3)
