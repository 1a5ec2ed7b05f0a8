"""Whole-path inverse kinematics that keeps the path (paper § Robot Execution).

:func:`solve_path` solves the skill's poses as one problem: the start from several seeds (the taught posture
first), damped least squares along knots (:mod:`studio.core.ik_solver`) with a pull away from the joint limits,
smaller steps and restarts that keep the elbow's side where a knot fails, then clearance
(:mod:`studio.core.ik_clearance`) and refinement between knots (:mod:`studio.core.ik_refine`). Where it cannot
follow: :mod:`studio.core.feasibility`. Why not pose by pose: docs/decisions/008."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from studio.core.errors import InvalidInput
from studio.core.ik_clearance import keep_clear
from studio.core.ik_refine import refine
from studio.core.ik_solver import (
    ROTATION_WEIGHT_M,
    PathSolver,
    posture_changes,
    rotation_angle,
)
from studio.core.kinematics import Baxter, matrix_from_quat_wxyz
from studio.core.types import Arm, check_arm, readonly

#: Knot spacing: path length (m; rotation counts ROTATION_WEIGHT_M per radian) or time (s), whichever first.
KNOT_ARC_M = 0.06
KNOT_MAX_DT_S = 1.0
#: A start solution this close (max joint difference, rad) to the given seed is the taught posture.
SEED_POSTURE_RAD = 0.3
#: A knot-to-knot joint change above this (rad) counts as a change of posture (a jump).
JUMP_RAD = 0.6
#: Shortest stretch (s of skill time) worth following on its own between two stretches out of reach or jumps.
MIN_PIECE_S = 0.1
#: Random seeds for other start postures (after the untuck pose, mid-range and the wrist turned over).
START_SEEDS = 16
#: Inside a stretch out of reach, restarts are tried after this much skill time (s), doubling each time.
RESTART_BACKOFF_S = 0.25


def _piece_spline(s: np.ndarray, q: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """A cubic spline through (s, q), constant beyond its ends (one knot: constant)."""
    if s.shape[0] == 1:
        return lambda x: np.broadcast_to(q[0], (*np.shape(x), 7)).copy()
    sp = CubicSpline(s, q, axis=0)
    return lambda x: sp(np.clip(x, s[0], s[-1]))


@dataclass(frozen=True, eq=False)
class PathSolution:
    """Joint-space knots for a Cartesian path.

    Attributes:
        s: (K,) knot times on the skill's time line, seconds, increasing.
        index: (K,) the trajectory sample each knot solves.
        q: (K, 7) joint angles, radians, within the URDF limits.
        reached: (K,) True where the knot is within the acceptance bar (1 mm, 0.01 rad:
            :data:`~studio.core.ik_solver.ACCEPT_POSITION_M`, :data:`~studio.core.ik_solver.ACCEPT_ORIENTATION_RAD`).
        position_error: (K,) metres; orientation_error: (K,) radians.
        recoveries: knots that needed smaller steps or restarts.
        jumps: knots where the arm had to change posture (joint-space jump) to go on.
        starts_tried: start postures tracked before choosing this one.
    """

    s: np.ndarray
    index: np.ndarray
    q: np.ndarray
    reached: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    recoveries: int = 0
    jumps: int = 0
    starts_tried: int = 1

    arc: np.ndarray | None = None

    @property
    def breaks(self) -> np.ndarray:
        """Knot indices j where the arm changes posture between knot j and j + 1 (a joint jump).

        A jump is a joint change larger than :data:`~studio.core.ik_solver.BREAK_RAD` plus
        :data:`~studio.core.ik_solver.BREAK_RAD_PER_M` per metre of path between the two knots (``arc``, rotation
        counted :data:`~studio.core.ik_solver.ROTATION_WEIGHT_M` per radian).
        """
        if self.q.shape[0] < 2:
            return np.zeros(0, dtype=np.int64)
        return np.flatnonzero(posture_changes(self.q, np.zeros(self.q.shape[0]) if self.arc is None else self.arc))

    def pieces(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The stretches the arm can follow: [(s (k,), q (k, 7)), ...], each a continuous joint path.

        Runs of reached knots, split at :attr:`breaks`. Unreached knots are left out: across a stretch out
        of reach the robot moves straight in joint space to where it can follow again (see
        :func:`studio.core.timing.retime`), rather than along jittery closest poses. When no knot is reached,
        the closest poses are the only piece.
        """
        if not self.reached.any():
            keep = np.ones(self.q.shape[0], dtype=bool)
        else:
            keep = np.asarray(self.reached, dtype=bool)
        cut = np.zeros(self.q.shape[0], dtype=bool)  # a new piece starts at this knot
        cut[0] = True
        cut[self.breaks + 1] = True
        cut[1:] |= ~keep[:-1]
        out: list[tuple[np.ndarray, np.ndarray]] = []
        start = None
        for j in range(self.q.shape[0] + 1):
            if j == self.q.shape[0] or cut[j] or not keep[j]:
                if start is not None:
                    out.append((self.s[start:j], self.q[start:j]))
                start = j if (j < self.q.shape[0] and keep[j]) else None
        # A sliver (a few reached knots in another posture at the edge of a stretch out of reach) is not worth
        # two posture changes: the robot goes straight past it.
        long = [p for p in out if p[0][-1] - p[0][0] >= MIN_PIECE_S]
        return long or out[:1]

    def spline(self) -> Callable[[np.ndarray], np.ndarray]:
        """Joints as a function of the skill time: a C² cubic spline per piece, held constant across breaks."""
        splines = [_piece_spline(s, q) for s, q in self.pieces()]
        starts = np.array([p[0][0] for p in self.pieces()])

        def f(s: np.ndarray) -> np.ndarray:
            s = np.asarray(s, dtype=np.float64)
            k = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(splines) - 1)
            out = np.empty((*s.shape, 7))
            for j, sp in enumerate(splines):
                m = k == j
                if m.any():
                    out[m] = sp(s[m])
            return out

        return f


def knot_indices(t: np.ndarray, position: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Sample indices of the path knots: every ~:data:`KNOT_ARC_M` of motion or :data:`KNOT_MAX_DT_S`."""
    n = t.shape[0]
    if n <= 2:
        return np.arange(n)
    dp = np.linalg.norm(np.diff(position, axis=0), axis=1)
    dr = rotation_angle(R[1:], R[:-1])
    u = np.concatenate([[0.0], np.cumsum(dp + ROTATION_WEIGHT_M * dr)]) / KNOT_ARC_M + (t - t[0]) / KNOT_MAX_DT_S
    cell = np.floor(u).astype(np.int64)
    idx = np.flatnonzero(np.diff(cell) > 0) + 1
    return np.unique(np.concatenate([[0], idx, [n - 1]]))


# -- start postures and restarts (functions of a PathSolver) --------------------------------------------


def _first_start(S: PathSolver, q_seed: np.ndarray) -> np.ndarray | None:
    """The first pose solved from ``q_seed`` itself (the taught posture when the seed is a demo's joints)."""
    q, pe, oe = S.solve(0, q_seed, 200, pull="none")
    return q if S.ok(pe, oe, 5.0) else None


def _wrist_flips(S: PathSolver, q: np.ndarray) -> list[np.ndarray]:
    """Seeds for the same gripper pose with the wrist turned over: w0 and w2 half a turn round, w1 mirrored
    (exact for a spherical wrist, near it for Baxter's); those within the limits."""
    out = []
    for d0 in (math.pi, -math.pi):
        for d2 in (math.pi, -math.pi):
            f = q.copy()
            f[4], f[5], f[6] = q[4] + d0, -q[5], q[6] + d2
            if np.all(f >= S.lo) and np.all(f <= S.hi):
                out.append(f)
    return out


def _other_starts(S: PathSolver, q_seed: np.ndarray, exclude: list[np.ndarray], count: int) -> list[np.ndarray]:
    """Up to ``count`` other solutions of the first pose, farthest from the joint limits first (the wrist
    turned over first of all: a posture that keeps the wrist away from its limits along the whole path is
    often that one)."""
    sols: list[tuple[float, np.ndarray]] = []
    flips = [f for q in exclude for f in _wrist_flips(S, q)]
    seeds = [*flips, S.neutral, S.mid, q_seed, *S.b.random_configuration(S.arm, S.rng, START_SEEDS)]
    near: list[tuple[float, np.ndarray]] = []  # within the acceptance bar only (a pose at the edge of reach)
    for seed in seeds:
        q, pe, oe = S.solve(0, seed, 200, pull="mid")
        if not S.ok(pe, oe, 5.0) and pe < 0.05:  # the pull towards mid-range may hold it off a pose near a limit
            q, pe, oe = S.solve(0, q, 100, pull="none")
        if not S.ok(pe, oe, 5.0):
            if S.accept(pe, oe):
                near.append((pe + 0.1 * oe, q))
            continue
        if any(float(np.max(np.abs(q - s))) < SEED_POSTURE_RAD for s in [*exclude, *(s for _, s in sols)]):
            continue
        x = (q - S.lo) / S.range
        sols.append((-float(np.min(np.minimum(x, 1.0 - x))), q))
        if len(sols) >= 2 * count:
            break
    sols.sort(key=lambda m: m[0])
    near.sort(key=lambda m: m[0])
    return [q for _, q in (sols or near[:1])[:count]]


def _restart(S: PathSolver, i: int, q_prev: np.ndarray) -> np.ndarray | None:
    """A converged solution of sample ``i`` with the elbow on ``q_prev``'s side, nearest to it; or None.

    Seeds: ``q_prev`` pulled half-way to mid-range, mid-range, the untuck pose and six random ones; each
    gets 40 iterations, the three closest to the target that have not converged get 120 more.
    """
    S.restarts += 1
    seeds = [q_prev + 0.5 * (S.mid - q_prev), S.mid, S.neutral]
    seeds += list(S.b.random_configuration(S.arm, S.rng, 6))
    found: list[np.ndarray] = []
    pending: list[tuple[float, np.ndarray]] = []
    for seed in seeds:
        q, pe, oe = S.solve(i, seed, 40, pull="mid")
        if S.ok(pe, oe, 5.0):
            found.append(q)
            if float(np.abs(q - q_prev).max()) < JUMP_RAD and S.same_elbow_side(q, q_prev):
                return q
        elif pe < 0.05:
            pending.append((pe + 0.1 * oe, q))
    pending.sort(key=lambda m: m[0])
    for _, q0 in pending[:3]:
        q, pe, oe = S.solve(i, q0, 120, pull="mid")
        if S.ok(pe, oe, 5.0):
            found.append(q)
    best, best_d = None, math.inf
    for q in found:
        d = float(np.abs(q - q_prev).max())
        if d < best_d and S.same_elbow_side(q, q_prev):
            best, best_d = q, d
    if best is not None:
        S.rescued += 1
    return best


# -- the whole path: tracking the knots, recovery, refinement ------------------------------------------------


def _track(S: PathSolver, idx: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Knot joints (K, 7), reached flags and errors for knots ``idx`` starting from joints ``q0``."""
    K = idx.shape[0]
    Q = np.empty((K, 7))
    pe = np.empty(K)
    oe = np.empty(K)
    Q[0], pe[0], oe[0] = S.solve(int(idx[0]), q0, 50, pull="none")
    ok = np.zeros(K, dtype=bool)
    ok[0] = S.ok(pe[0], oe[0], 5.0)
    t = S.t
    next_restart = -math.inf  # skill time before which no restart is tried (back-off inside lost stretches)
    wait = RESTART_BACKOFF_S
    for j in range(1, K):
        # Smaller steps help where the path is being lost, not inside a stretch already out of reach.
        q, p_, o_, good = S.advance(Q[j - 1], int(idx[j - 1]), int(idx[j]), bisect=bool(ok[j - 1]))
        if good:
            wait = RESTART_BACKOFF_S
        # Restarts when the path is lost; inside a stretch out of reach, ever more rarely (they are costly).
        if not good and (ok[j - 1] or t[idx[j]] >= next_restart):
            S.recoveries += 1
            next_restart = t[idx[j]] + wait
            wait *= 2.0
            cand = _restart(S, int(idx[j]), Q[j - 1])
            if cand is not None and ok[j - 1]:
                S.posture_failures += 1
            if cand is not None:
                q, p_, o_ = S.solve(int(idx[j]), cand, 20, pull="none")
                good = True
                if float(np.max(np.abs(q - Q[j - 1]))) > JUMP_RAD and ok[j - 1]:
                    # Another posture: redo the current reached stretch in it, backwards, if it can.
                    lost = np.flatnonzero(~ok[:j])
                    j0 = int(lost[-1]) + 1 if lost.shape[0] else 0
                    back = _track_back(S, idx[j0 : j + 1], q)
                    if back is not None:
                        Q[j0:j], pe[j0:j], oe[j0:j] = back
                    else:
                        S.jumps += 1
        Q[j], pe[j], oe[j], ok[j] = q, p_, o_, (good and S.ok(p_, o_, 5.0)) or S.accept(p_, o_)
    # Reachable knots just before a reached stretch, lost going forwards in another posture: go backwards.
    for jr in np.flatnonzero(ok[1:] & ~ok[:-1]) + 1:
        q = Q[jr]
        for k in range(int(jr) - 1, -1, -1):
            if ok[k]:
                break
            q, p_, o_, good = S.advance(q, int(idx[k + 1]), int(idx[k]))
            if not good:
                break
            Q[k], pe[k], oe[k], ok[k] = q, p_, o_, True
    return Q, ok, pe, oe


def _track_back(S: PathSolver, idx: np.ndarray, q_last: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Knots idx[:-1] solved backwards from ``q_last`` at idx[-1]; None when a knot fails."""
    n = idx.shape[0] - 1
    Q, pe, oe = np.empty((n, 7)), np.empty(n), np.empty(n)
    q = q_last
    for j in range(n - 1, -1, -1):
        q, p_, o_, good = S.advance(q, int(idx[j + 1]), int(idx[j]))
        if not good:
            return None
        Q[j], pe[j], oe[j] = q, p_, o_
    return Q, pe, oe


def _breaks(Q: np.ndarray, arc: np.ndarray) -> int:
    """How many knot-to-knot joint changes are posture changes (as :attr:`PathSolution.breaks` counts them)."""
    if Q.shape[0] < 2:
        return 0
    return int(np.sum(posture_changes(Q, arc)))


def _score(
    ok: np.ndarray, breaks: int, jumps: int, recoveries: int, Q: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple:
    x = (Q - lo) / (hi - lo)
    margin = float(np.min(np.minimum(x, 1.0 - x)))
    return (int((~ok).sum()), breaks, jumps, recoveries, -margin)


def solve_path(
    t: np.ndarray,
    position: np.ndarray,
    wxyz: np.ndarray,
    arm: Arm,
    q_seed: np.ndarray,
    baxter: Baxter | None = None,
    *,
    max_starts: int = 3,
    avoid: Callable[[np.ndarray], np.ndarray] | None = None,
) -> PathSolution:
    """Joint knots that follow a Cartesian gripper path (the method: docs/decisions/008).

    Args:
        t: (N,) seconds, increasing (the skill's time line).
        position: (N, 3) gripper positions, metres.
        wxyz: (N, 4) gripper orientations, unit quaternions w, x, y, z.
        arm: "left" or "right".
        q_seed: (7,) joint angles near the path's start (the reference demo's first joints, or the neutral pose).
        baxter: the robot model (default :meth:`Baxter.load`).
        max_starts: start postures to try when the first one needs recoveries.
        avoid: joints (K, 7) -> (K,) True where the arm (its upper arm, elbow or forearm: not the gripper, which
            the path decides) touches something; those knots are moved along the arm's self-motion (the posture
            null space) until clear, where one is near (decision 087).

    Returns:
        A :class:`PathSolution`; never raises for unreachable poses (they are marked, see :func:`feasibility`).
    """
    check_arm(arm)
    b = baxter or Baxter.load()
    t = np.asarray(t, dtype=np.float64)
    position = np.asarray(position, dtype=np.float64)
    wxyz = np.asarray(wxyz, dtype=np.float64)
    n = t.shape[0]
    if n == 0 or position.shape != (n, 3) or wxyz.shape != (n, 4):
        raise InvalidInput("The path needs N times, N positions (x, y, z) and N orientations (w, x, y, z).")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(position)) and np.all(np.isfinite(wxyz))):
        raise InvalidInput("The path contains missing or invalid values (NaN or infinity).")
    if n > 1 and np.any(np.diff(t) <= 0):
        raise InvalidInput("The path's time stamps must increase from sample to sample.")
    seed = np.asarray(q_seed, dtype=np.float64)
    if seed.shape != (7,) or not np.all(np.isfinite(seed)):
        raise InvalidInput("The seed joint angles must be 7 finite numbers.")
    R = matrix_from_quat_wxyz(wxyz)
    solver = PathSolver(b, arm, t, position, R)
    idx = knot_indices(t, position, R)
    arc = solver.arc
    first = _first_start(solver, seed)
    starts = [first] if first is not None else []
    best: tuple[Any, ...] | None = None
    fetched = False
    k = 0
    while k < max_starts:
        if k >= len(starts):
            if fetched:
                break
            # The first start needed recoveries (or the seed did not reach the start): try other postures.
            starts += _other_starts(solver, seed, starts, max_starts - len(starts))
            fetched = True
            if k >= len(starts):
                break
        solver.recoveries, solver.jumps, solver.rescued, solver.posture_failures = 0, 0, 0, 0
        Q, ok, pe, oe = _track(solver, idx, starts[k])
        k += 1
        breaks = _breaks(Q, arc[idx])
        score = _score(ok, breaks, solver.jumps, solver.recoveries, Q, solver.lo, solver.hi)
        if best is None or score < best[0]:
            best = (score, Q, ok, pe, oe, solver.recoveries, solver.jumps, k)
        # Another start posture can only help when the path was lost (found again in another posture, or not),
        # or the arm had to change posture on the way (e.g. right after a start from the neutral pose).
        if solver.posture_failures == 0 and solver.jumps == 0 and breaks == 0 and ok.all():
            break
    if best is None:  # the first pose is out of reach: follow as closely as possible from the best effort
        q0, _, _ = solver.solve(0, seed, 200, pull="mid")
        Q, ok, pe, oe = _track(solver, idx, q0)
        best = (None, Q, ok, pe, oe, solver.recoveries, solver.jumps, k + 1)
    assert best is not None
    _, Q, ok, pe, oe, recoveries, jumps, tried = best
    if avoid is not None:
        Q = keep_clear(solver, idx, Q, ok, avoid)
    idx2, Q, ok, pe, oe = refine(solver, idx, Q, ok, pe, oe)
    if avoid is not None and avoid(Q).any():  # knots added between cleared ones may touch again: once more
        Q = keep_clear(solver, idx2, Q, ok, avoid)
        idx2, Q, ok, pe, oe = refine(solver, idx2, Q, ok, pe, oe)
    return PathSolution(
        s=readonly(t[idx2]),
        index=readonly(idx2, dtype=np.int64),
        q=readonly(Q),
        reached=readonly(ok, dtype=bool),
        position_error=readonly(pe),
        orientation_error=readonly(oe),
        recoveries=recoveries,
        jumps=jumps,
        starts_tried=tried,
        arc=readonly(arc[idx2]),
    )


__all__ = [
    "PathSolution",
    "knot_indices",
    "solve_path",
]
