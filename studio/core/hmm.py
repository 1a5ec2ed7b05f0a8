"""Discrete HMM over the codebook (paper § Model Learning using HMM); the only hmmlearn import.

Ns = k states and k symbols. The model starts as the paper's Bakis left–right topology (a_{i,i}, a_{i,i+1},
a_{i,i+2} from the time τ_i spent in state i, b_i from the symbols seen there, π = [1, 0, …]) on a uniform
segmentation of each demo's key-points; Baum–Welch (hmmlearn ``CategoricalHMM``) trains on all demos, Viterbi
decodes each, the forward algorithm picks the most probable as the reference, and states absent from its path
are the zero-points. Choices: docs/decisions/014."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from hmmlearn.hmm import CategoricalHMM

from studio.core.errors import InvalidInput, LearningFailed
from studio.core.types import readonly

#: Uniform share of each emission row at initialisation (keeps out-of-order symbols possible).
EMISSION_FLOOR = 0.01
#: Dirichlet prior − 1 on every allowed parameter (keeps unreached states' rows valid).
PRIOR_EPS = 1e-6


def bakis_init(
    sequences: Sequence[np.ndarray], n_states: int, n_symbols: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Left–right initial model from the codebook's segmentation (docs/decisions/014).

    Args:
        sequences: one int array of symbols (cluster labels, time-ordered codebook) per demonstration.
        n_states: Ns.
        n_symbols: codebook size (default Ns).

    Returns:
        startprob (Ns,), transmat (Ns, Ns) upper-triangular with bandwidth 2, emissionprob (Ns, n_symbols).
    """
    ns = int(n_states)
    nk = ns if n_symbols is None else int(n_symbols)
    if ns < 1:
        raise InvalidInput("The model needs at least one state.")
    steps = np.zeros(ns)  # observation steps spent in each state, summed over demonstrations
    visits = np.zeros(ns)  # number of separate stays in each state
    counts = np.zeros((ns, nk))  # n_i(q_k)
    for seq in sequences:
        seq = np.asarray(seq, dtype=np.int64)
        if seq.size == 0:
            continue
        # initial segmentation: uniform along the sequence (Rabiner's left–right initialisation)
        state = np.minimum((np.arange(seq.size) * ns) // seq.size, ns - 1)
        np.add.at(counts, (state, seq), 1.0)
        np.add.at(steps, state, 1.0)
        starts = np.concatenate([[True], state[1:] != state[:-1]])
        np.add.at(visits, state[starts], 1.0)
    tau = np.where(visits > 0, steps / np.maximum(visits, 1.0), 1.0) + 1.0  # + the step leaving the state
    A = np.zeros((ns, ns))
    for i in range(ns):
        A[i, i] = 1.0 - 1.0 / tau[i]
        if i + 1 < ns:
            A[i, i + 1] = 1.0 / tau[i]
        if i + 2 < ns:
            A[i, i + 2] = 1.0 / (4.0 * tau[i])
        if i == ns - 1:
            A[i, i] = 1.0  # the last state can only stay
        A[i] /= A[i].sum()  # Z
    B = counts / tau[:, None]
    rs = B.sum(axis=1, keepdims=True)
    B = np.where(rs > 0, B / np.maximum(rs, 1e-300), 1.0 / nk)
    B = (1.0 - EMISSION_FLOOR) * B + EMISSION_FLOOR / nk
    pi = np.zeros(ns)
    pi[0] = 1.0
    return pi, A, B


@dataclass(frozen=True, eq=False)
class HmmResult:
    """The trained model and what it says about the demonstrations.

    Attributes:
        startprob, transmat, emissionprob: the trained λ = {π, A, B}.
        init_transmat, init_emissionprob: the Bakis initialisation (for the panel and the tests).
        loglik: (D,) forward-algorithm log-likelihood of each demonstration.
        reference: index of the most probable demonstration.
        paths: Viterbi state sequence of each demonstration.
        states: the reference's Viterbi path.
        zero_points: sorted states absent from ``states``.
        history: log-likelihood of all demonstrations after each Baum–Welch iteration.
    """

    startprob: np.ndarray
    transmat: np.ndarray
    emissionprob: np.ndarray
    init_transmat: np.ndarray
    init_emissionprob: np.ndarray
    loglik: np.ndarray
    reference: int
    paths: list[np.ndarray]
    states: np.ndarray
    zero_points: np.ndarray
    history: np.ndarray


def make_model(
    startprob: np.ndarray,
    transmat: np.ndarray,
    emissionprob: np.ndarray,
    *,
    seed: int = 0,
    n_iter: int = 100,
    tol: float = 1e-4,
    prior_eps: float = PRIOR_EPS,
) -> CategoricalHMM:
    """A hmmlearn CategoricalHMM holding exactly these matrices (``init_params=""``)."""
    ns, nk = emissionprob.shape
    model = CategoricalHMM(
        n_components=ns,
        n_features=nk,
        startprob_prior=np.where(startprob > 0, 1.0 + prior_eps, 1.0),
        transmat_prior=np.where(transmat > 0, 1.0 + prior_eps, 1.0),
        emissionprob_prior=np.where(emissionprob > 0, 1.0 + prior_eps, 1.0),
        algorithm="viterbi",
        random_state=seed,
        n_iter=n_iter,
        tol=tol,
        params="ste",
        init_params="",
        implementation="scaling",
    )
    model.startprob_ = np.array(startprob, dtype=float)
    model.transmat_ = np.array(transmat, dtype=float)
    model.emissionprob_ = np.array(emissionprob, dtype=float)
    return model


def _stack(sequences: Sequence[np.ndarray]) -> tuple[np.ndarray, list[int]]:
    seqs = [np.asarray(s, dtype=np.int64).reshape(-1) for s in sequences]
    return np.concatenate(seqs).reshape(-1, 1), [len(s) for s in seqs]


def forward_loglik(model: CategoricalHMM, seq: np.ndarray) -> float:
    """log P(O | λ) by the forward algorithm."""
    return float(model.score(np.asarray(seq, dtype=np.int64).reshape(-1, 1)))


def viterbi(model: CategoricalHMM, seq: np.ndarray) -> tuple[float, np.ndarray]:
    """Most probable state sequence and its log-probability."""
    lp, path = model.decode(np.asarray(seq, dtype=np.int64).reshape(-1, 1), algorithm="viterbi")
    return float(lp), path.astype(np.int64)


def train(
    sequences: Sequence[np.ndarray],
    n_states: int,
    *,
    seed: int = 0,
    n_iter: int = 100,
    tol: float = 1e-3,
) -> HmmResult:
    """Bakis initialisation, Baum–Welch on all sequences, Viterbi, forward selection of the reference.

    Args:
        sequences: one int symbol array (values in [0, n_states)) per demonstration, each non-empty.
        n_states: Ns = k.
        seed: passed to hmmlearn.

    Raises:
        InvalidInput: no sequences, an empty one, or symbols outside the codebook.
        LearningFailed: the model gives a demonstration zero probability (should not happen).
    """
    if not sequences:
        raise InvalidInput("There are no demonstrations to learn from.")
    for s in sequences:
        s = np.asarray(s)
        if s.size == 0:
            raise InvalidInput("A demonstration has no key-points.")
        if s.min() < 0 or s.max() >= n_states:
            raise InvalidInput(f"Key-point symbols must lie in 0..{n_states - 1}.")
    pi, A, B = bakis_init(sequences, n_states)
    model = make_model(pi, A, B, seed=seed, n_iter=n_iter, tol=tol)
    X, lengths = _stack(sequences)
    model.fit(X, lengths)
    loglik = np.array([forward_loglik(model, s) for s in sequences])
    if not np.all(np.isfinite(loglik)):
        raise LearningFailed(
            "The learned model cannot explain one of the demonstrations. Try fewer clusters or check that "
            "all demonstrations show the same task."
        )
    ref = int(np.argmax(loglik))
    paths = [viterbi(model, s)[1] for s in sequences]
    states = paths[ref]
    zero = np.setdiff1d(np.arange(n_states), states)
    return HmmResult(
        startprob=readonly(model.startprob_),
        transmat=readonly(model.transmat_),
        emissionprob=readonly(model.emissionprob_),
        init_transmat=readonly(A),
        init_emissionprob=readonly(B),
        loglik=readonly(loglik),
        reference=ref,
        paths=[readonly(p, dtype=np.int64) for p in paths],
        states=readonly(states, dtype=np.int64),
        zero_points=readonly(zero, dtype=np.int64),
        history=readonly(list(model.monitor_.history)),
    )


__all__ = [
    "EMISSION_FLOOR",
    "HmmResult",
    "bakis_init",
    "forward_loglik",
    "make_model",
    "train",
    "viterbi",
]
