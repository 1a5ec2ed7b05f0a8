"""Whole-path inverse kinematics that keeps the path, and the feasibility check (paper § Robot Execution).

:func:`solve_path` solves the skill's poses as one problem: the start from several seeds (the taught posture
first), damped least squares along knots with a pull away from the joint limits, smaller steps and restarts
that keep the elbow's side where a knot fails, and refinement between knots until the joint spline holds the
path wherever it is reachable. :func:`feasibility` turns per-sample errors into unreachable time spans and one
plain sentence. Why not pose by pose: docs/decisions/008."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin
from scipy.interpolate import CubicSpline
from scipy.linalg import lapack

from studio.core.errors import InvalidInput
from studio.core.kinematics import Baxter, matrix_from_quat_wxyz
from studio.core.types import Arm, check_arm, readonly

#: A sample is executed faithfully when the gripper is within these of the skill (the acceptance bar).
ACCEPT_POSITION_M = 1e-3
ACCEPT_ORIENTATION_RAD = 1e-2
#: Knots are solved to these tolerances.
SOLVE_POSITION_M = 2e-5
SOLVE_ORIENTATION_RAD = 2e-4
#: The spline between knots must stay within these of the path (else a knot is added).
REFINE_POSITION_M = 1e-4
REFINE_ORIENTATION_RAD = 1e-3
#: Knot spacing: path length (m; rotation counts ROTATION_WEIGHT_M per radian) or time (s), whichever first.
KNOT_ARC_M = 0.06
KNOT_MAX_DT_S = 1.0
ROTATION_WEIGHT_M = 0.2
#: A start solution this close (max joint difference, rad) to the given seed is the taught posture.
SEED_POSTURE_RAD = 0.3
#: A knot-to-knot joint change above this (rad) counts as a change of posture (a jump).
JUMP_RAD = 0.6
#: Joint change between two knots that counts as a posture jump: BREAK_RAD + BREAK_RAD_PER_M × path length.
BREAK_RAD = 0.05
BREAK_RAD_PER_M = 20.0
#: Shortest stretch (s of skill time) worth following on its own between two stretches out of reach or jumps.
MIN_PIECE_S = 0.1
#: Elbow swivel change (rad) beyond which a restart solution is on the other side.
ELBOW_SIDE_RAD = math.pi / 2
#: Random seeds for other start postures (after the untuck pose, mid-range and the wrist turned over).
START_SEEDS = 16
#: Inside a stretch out of reach, restarts are tried after this much skill time (s), doubling each time.
RESTART_BACKOFF_S = 0.25
#: Elbow bend (e1, rad) below which the arm counts as straight: its elbow side is then undefined.
STRAIGHT_ELBOW_RAD = 0.25
#: Fraction of each joint's range, at either end, that the null-space term pushes joints out of.
LIMIT_ZONE = 0.1

_EYE6 = np.eye(6)


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
        reached: (K,) True where the knot is within :data:`ACCEPT_POSITION_M` / :data:`ACCEPT_ORIENTATION_RAD`.
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

        A jump is a joint change larger than :data:`BREAK_RAD` plus :data:`BREAK_RAD_PER_M` per metre of
        path between the two knots (``arc``, rotation counted :data:`ROTATION_WEIGHT_M` per radian).
        """
        if self.q.shape[0] < 2:
            return np.zeros(0, dtype=np.int64)
        arc = np.zeros(self.q.shape[0] - 1) if self.arc is None else np.diff(self.arc)
        return np.flatnonzero(np.max(np.abs(np.diff(self.q, axis=0)), axis=1) > BREAK_RAD + BREAK_RAD_PER_M * arc)

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


@dataclass(frozen=True)
class UnreachableSpan:
    """A stretch of the skill the gripper cannot follow.

    Attributes:
        t_start, t_end: seconds on the skill's time line.
        i_start, i_end: first and last sample index into the Cartesian trajectory (inclusive; for drawing).
        position_error: largest distance (m) between the closest reachable pose and the skill there.
        orientation_error: largest turn (rad) the gripper would still need there.
        reason: "reach" (too far), "turn" (an orientation the wrist cannot hold) or "posture" (each pose is
            reachable, but not by one continuous motion: the arm has to change its posture there).
    """

    t_start: float
    t_end: float
    i_start: int
    i_end: int
    position_error: float
    orientation_error: float
    reason: str = "reach"


@dataclass(frozen=True)
class Feasibility:
    """Whether the robot can execute the whole skill, and in plain words where it cannot."""

    arm: Arm
    spans: tuple[UnreachableSpan, ...] = field(default_factory=tuple)
    message: str = ""

    @property
    def ok(self) -> bool:
        return not self.spans


def rotation_angle(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Angle (rad) between rotation matrices (…, 3, 3), accurate near zero (‖Ra − Rb‖_F = 2√2 sin(θ/2))."""
    d = np.linalg.norm((np.asarray(Ra) - np.asarray(Rb)).reshape(*np.shape(Ra)[:-2], 9), axis=-1)
    return 2.0 * np.arcsin(np.clip(d / (2.0 * math.sqrt(2.0)), 0.0, 1.0))


def _rotation_error_batch(Rt: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) of Rt · Rᵀ for rotation matrices (N, 3, 3) (angles below π − 1e-3).

    The skew part of Rt · Rᵀ = Σ_k rt_k r_kᵀ is Σ_k r_k × rt_k (columns k), and its trace Σ Rt ∘ R: no
    batched 3 × 3 products, which numpy runs slowly on small matrices.
    """
    v = np.cross(R[:, :, 0], Rt[:, :, 0]) + np.cross(R[:, :, 1], Rt[:, :, 1]) + np.cross(R[:, :, 2], Rt[:, :, 2])
    c = np.clip((np.einsum("nij,nij->n", Rt, R) - 1.0) * 0.5, -1.0, 1.0)
    th = np.arccos(c)
    sn = np.sin(th)
    small = sn < 1e-6
    f = np.where(small, 0.5 + th * th / 12.0, th / (2.0 * np.where(small, 1.0, sn)))
    return v * f[:, None]


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


class _PathSolver:
    """The state of one path solve — the robot model, the targets, a deterministic random generator, counts
    of recoveries — and pose solving: one pose (:meth:`solve`, :meth:`advance`) or many at once
    (:meth:`batch_solve`). Seeding, tracking, recovery and refinement along the path are the functions
    after it."""

    def __init__(self, baxter: Baxter, arm: Arm, t: np.ndarray, position: np.ndarray, R: np.ndarray) -> None:
        self.b = baxter
        self.arm = arm
        self.model, self.fid = baxter._reduced[arm]
        self.data = self.model.createData()
        self.lo = np.array(self.model.lowerPositionLimit, dtype=np.float64)
        self.hi = np.array(self.model.upperPositionLimit, dtype=np.float64)
        self.mid = 0.5 * (self.lo + self.hi)
        self.range = self.hi - self.lo
        self.inv_range = 1.0 / self.range
        self.lo_eps, self.hi_eps = self.lo + 1e-9, self.hi - 1e-9
        self.neutral = baxter.neutral(arm)
        self.t, self.P, self.R = t, position, R
        self.arc = np.concatenate(
            [
                [0.0],
                np.cumsum(
                    np.linalg.norm(np.diff(position, axis=0), axis=1)
                    + ROTATION_WEIGHT_M * rotation_angle(R[1:], R[:-1])
                ),
            ]
        )
        self.rng = np.random.default_rng(20240611)
        self.recoveries = 0
        self.jumps = 0
        self.restarts = 0  # restart searches run
        self.rescued = 0  # of which found a solution
        self.posture_failures = 0  # the path was lost while on it, and found again in another posture

    # -- one pose ----------------------------------------------------------------------------------------
    def solve(
        self,
        i: int,
        q: np.ndarray,
        iterations: int,
        *,
        pull: str = "limits",
        tol_p: float = SOLVE_POSITION_M,
        tol_o: float = SOLVE_ORIENTATION_RAD,
    ) -> tuple[np.ndarray, float, float]:
        """Damped least squares towards sample ``i`` from ``q``; returns the best joints and their errors.

        ``pull``: "limits" pushes joints out of the outer :data:`LIMIT_ZONE` of their range, "mid" pulls
        them towards mid-range, "none" adds nothing; all in the Jacobian's null space. A joint resting on
        a limit that the step would push further out is frozen and the step solved again without it.
        Written for few numpy calls per iteration (this loop is most of the path solve's time).
        """
        model, data, fid = self.model, self.data, self.fid
        lo, hi, lo_e, hi_e = self.lo, self.hi, self.lo_eps, self.hi_eps
        p_t, R_t = self.P[i], self.R[i]
        q = np.minimum(np.maximum(q, lo), hi)
        lam = 1e-4
        best_q, best_cost, best_pe, best_oe = q, math.inf, math.inf, math.inf
        e = np.empty(6)
        lwa = pin.LOCAL_WORLD_ALIGNED
        for it in range(iterations + 1):
            J = pin.computeFrameJacobian(model, data, q, fid, lwa)
            M = pin.updateFramePlacement(model, data, fid)
            e[:3] = p_t - M.translation
            e[3:] = pin.log3(R_t @ M.rotation.T)
            pe = math.sqrt(float(e[:3] @ e[:3]))
            oe = math.sqrt(float(e[3:] @ e[3:]))
            cost = pe + 0.1 * oe
            if cost < best_cost:
                best_q, best_cost, best_pe, best_oe = q, cost, pe, oe
                lam = max(lam * 0.5, 1e-7)
            else:
                lam = min(lam * 8.0, 1.0)
            if (pe <= tol_p and oe <= tol_o) or it == iterations:
                break
            z = None
            if pull == "limits":
                x = (q - lo) * self.inv_range
                if x.min() < LIMIT_ZONE or x.max() > 1.0 - LIMIT_ZONE:
                    z = (np.maximum(LIMIT_ZONE - x, 0.0) - np.maximum(x - (1.0 - LIMIT_ZONE), 0.0)) * self.range * 0.5
            elif pull == "mid":
                z = (self.mid - q) * 0.1
            A = J @ J.T
            A.flat[::7] += lam
            xs = lapack.dposv(A, e)[1]
            dq = J.T @ xs
            if z is not None:
                dq += z - J.T @ lapack.dposv(A, J @ z)[1]
            blocked = ((q <= lo_e) & (dq < 0)) | ((q >= hi_e) & (dq > 0))
            if blocked.any():
                free = np.where(blocked, 0.0, 1.0)
                Jf = J * free
                A = Jf @ Jf.T
                A.flat[::7] += lam
                dq = Jf.T @ lapack.dposv(A, e)[1]
                if z is not None:
                    zf = z * free
                    dq += zf - Jf.T @ lapack.dposv(A, Jf @ zf)[1]
            big = float(np.abs(dq).max())
            if big > 0.4:  # a long step through a curved map overshoots; cap it
                dq *= 0.4 / big
            q = np.minimum(np.maximum(q + dq, lo), hi)
        return best_q, best_pe, best_oe

    @staticmethod
    def ok(pe: float, oe: float, scale: float = 1.0) -> bool:
        return pe <= SOLVE_POSITION_M * scale and oe <= SOLVE_ORIENTATION_RAD * scale

    @staticmethod
    def accept(pe: float, oe: float) -> bool:
        """Within the acceptance bar (1 mm, 0.01 rad): executed faithfully, even if not solved to 20 µm."""
        return pe <= ACCEPT_POSITION_M and oe <= ACCEPT_ORIENTATION_RAD

    # -- one step along the path -------------------------------------------------------------------------
    def advance(
        self, q: np.ndarray, i0: int, i1: int, depth: int = 0, *, bisect: bool = True
    ) -> tuple[np.ndarray, float, float, bool]:
        """From joints ``q`` solving sample ``i0`` to sample ``i1``, bisecting the step when it fails."""
        q1, pe, oe = self.solve(i1, q, 15)
        if self.ok(pe, oe, 5.0):
            return q1, pe, oe, True
        if bisect and depth < 4 and abs(i1 - i0) > 1:
            im = (i0 + i1) // 2
            qm, _, _, okm = self.advance(q, i0, im, depth + 1)
            if okm:
                return self.advance(qm, im, i1, depth + 1)
        return q1, pe, oe, False

    def same_elbow_side(self, qa: np.ndarray, qb: np.ndarray) -> bool:
        """True unless both postures bend the elbow clearly and to sides more than 90° apart."""
        if min(float(qa[3]), float(qb[3])) < STRAIGHT_ELBOW_RAD:  # a straight arm has no elbow side
            return True
        da = self.b.elbow_swivel(self.arm, qa)
        db = self.b.elbow_swivel(self.arm, qb)
        return abs(math.remainder(da - db, 2 * math.pi)) <= ELBOW_SIDE_RAD

    # -- many poses at once (refinement) -----------------------------------------------------------------
    def batch_solve(self, idx: np.ndarray, Q: np.ndarray, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised damped least squares for samples ``idx`` from joints Q (n, 7); returns Q and converged."""
        Q = np.clip(Q, self.lo, self.hi)
        P, Rt = self.P[idx], self.R[idx]
        active = np.ones(idx.shape[0], dtype=bool)
        for _ in range(iterations):
            rot, pos, J = self.b.pose_jacobian_batch(self.arm, Q[active])
            ep = P[active] - pos
            er = _rotation_error_batch(Rt[active], rot)
            done = (np.linalg.norm(ep, axis=1) <= SOLVE_POSITION_M) & (
                np.linalg.norm(er, axis=1) <= SOLVE_ORIENTATION_RAD
            )
            act_idx = np.flatnonzero(active)
            active[act_idx[done]] = False
            keep = ~done
            if not keep.any():
                break
            J, e = J[keep], np.concatenate([ep[keep], er[keep]], axis=1)
            A = J @ np.transpose(J, (0, 2, 1)) + 1e-6 * _EYE6
            x = np.linalg.solve(A, e[:, :, None])
            dq = (np.transpose(J, (0, 2, 1)) @ x)[:, :, 0]
            big = np.max(np.abs(dq), axis=1, keepdims=True)
            dq = dq * np.minimum(1.0, 0.4 / np.maximum(big, 1e-12))
            sel = act_idx[keep]
            Q[sel] = np.clip(Q[sel] + dq, self.lo, self.hi)
        return Q, ~active

    def pose_errors(self, idx: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rot, pos = self.b.rotations_batch(self.arm, Q)
        return np.linalg.norm(pos - self.P[idx], axis=1), rotation_angle(rot, self.R[idx])


# -- start postures and restarts (functions of a _PathSolver) --------------------------------------------


def _first_start(S: _PathSolver, q_seed: np.ndarray) -> np.ndarray | None:
    """The first pose solved from ``q_seed`` itself (the taught posture when the seed is a demo's joints)."""
    q, pe, oe = S.solve(0, q_seed, 200, pull="none")
    return q if S.ok(pe, oe, 5.0) else None


def _wrist_flips(S: _PathSolver, q: np.ndarray) -> list[np.ndarray]:
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


def _other_starts(S: _PathSolver, q_seed: np.ndarray, exclude: list[np.ndarray], count: int) -> list[np.ndarray]:
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


def _restart(S: _PathSolver, i: int, q_prev: np.ndarray) -> np.ndarray | None:
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


def _track(S: _PathSolver, idx: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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


def _track_back(
    S: _PathSolver, idx: np.ndarray, q_last: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
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


def _refine(
    S: _PathSolver, idx: np.ndarray, Q: np.ndarray, ok: np.ndarray, pe: np.ndarray, oe: np.ndarray, rounds: int = 16
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Add knots where the spline strays from the path, and locate where reachable stretches end.

    Between two reached knots, a knot is added mid-way where the spline strays (all new knots solved in
    one batch). Between a reached and an unreached knot, the mid-way sample is solved from the reached
    side, so the edge of a reachable stretch is found to the sample by bisection. Only intervals not yet
    checked are checked again, plus one final check of all of them.
    """
    t = S.t
    verified = np.zeros(max(idx.shape[0] - 1, 0), dtype=bool)
    final_pass = False
    for _ in range(rounds):
        if idx.shape[0] < 2:
            break
        jump = np.max(np.abs(np.diff(Q, axis=0)), axis=1) > BREAK_RAD + BREAK_RAD_PER_M * np.diff(S.arc[idx])
        gap = (np.diff(idx) > 1) & ~jump
        both = ok[:-1] & ok[1:] & gap & ~verified
        edge = (ok[:-1] != ok[1:]) & (np.diff(idx) > 1)
        new_parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        split = np.zeros(verified.shape[0], dtype=bool)
        if both.any():
            spl = CubicSpline(t[idx], Q, axis=0)
            # check samples: ~1 in 4 of each interval's interior samples, at least 3 per interval
            segs = np.flatnonzero(both)
            lens = idx[segs + 1] - idx[segs]
            m = np.clip(lens // 8, 3, None)
            rep = np.repeat(segs, m)
            frac = (np.arange(rep.shape[0]) - np.repeat(np.cumsum(m) - m, m) + 0.5) / np.repeat(m, m)
            chk = np.clip((idx[rep] + frac * (idx[rep + 1] - idx[rep])).astype(np.int64), 0, t.shape[0] - 1)
            perr, oerr = S.pose_errors(chk, np.clip(spl(t[chk]), S.lo, S.hi))
            bad_seg = np.unique(rep[(perr > REFINE_POSITION_M) | (oerr > REFINE_ORIENTATION_RAD)])
            verified[segs] = True
            if bad_seg.shape[0]:
                verified[bad_seg] = False
                split[bad_seg] = True
                new = (idx[bad_seg] + idx[bad_seg + 1]) // 2
                Qn, conv = S.batch_solve(new, spl(t[new]))
                # a knot that lands in another posture (near a singularity the undamped step slides along the
                # arm's self-motion) would cut the path in two: it, too, is solved from the left knot instead
                step = BREAK_RAD + BREAK_RAD_PER_M * (S.arc[new] - S.arc[idx[bad_seg]])
                off = np.max(np.abs(Qn - Q[bad_seg]), axis=1) > step
                for k in np.flatnonzero(~conv | off):  # rare
                    Qn[k], _, _, conv[k] = S.advance(Q[bad_seg[k]], int(idx[bad_seg[k]]), int(new[k]))
                new_parts.append((new, Qn, conv))
        for j in np.flatnonzero(edge):
            a = j if ok[j] else j + 1  # the reached end
            i_new = (int(idx[j]) + int(idx[j + 1])) // 2
            qn, _, _, good = S.advance(Q[a], int(idx[a]), i_new)
            split[j] = True
            new_parts.append((np.array([i_new]), qn[None, :], np.array([good])))
        if not new_parts:
            if final_pass or not verified.any():
                break
            final_pass = True  # inserted knots nudge the spline nearby: check every interval once more
            verified[:] = False
            continue
        final_pass = False
        new = np.concatenate([p[0] for p in new_parts])
        Qn = np.concatenate([p[1] for p in new_parts])
        conv = np.concatenate([p[2] for p in new_parts])
        npe, noe = S.pose_errors(new, Qn)
        # interval flags: a split interval becomes two unchecked ones
        ver_new = np.zeros(new.shape[0], dtype=bool)
        idx = np.concatenate([idx, new])
        order = np.argsort(idx, kind="stable")
        idx = idx[order]
        Q = np.concatenate([Q, Qn])[order]
        # a new knot counts as reached when it is within the acceptance bar (near the edge of the
        # workspace the solver may stop short of 20 µm and still be well within 1 mm)
        ok = np.concatenate([ok, (npe <= ACCEPT_POSITION_M) & (noe <= ACCEPT_ORIENTATION_RAD)])[order]
        pe = np.concatenate([pe, npe])[order]
        oe = np.concatenate([oe, noe])[order]
        # each interval is identified by its left knot: old knots keep their flag unless split
        left_flag = np.concatenate([np.append(verified & ~split, False), ver_new])[order]
        verified = left_flag[:-1]
    return idx, Q, ok, pe, oe


#: Steps (rad) along the arm's self-motion tried to keep a knot's arm clear, and how many each way.
CLEAR_STEP_RAD = 0.12
CLEAR_STEPS = 16


def _self_motion(S: _PathSolver, q: np.ndarray) -> np.ndarray:
    """(7,) unit joint direction that moves the arm without moving the gripper (the Jacobian's null space)."""
    J = pin.computeFrameJacobian(S.model, S.data, q, S.fid, pin.LOCAL_WORLD_ALIGNED)
    n = np.linalg.svd(J)[2][-1]
    return n / np.linalg.norm(n)


def _clear_posture(
    S: _PathSolver, i: int, q: np.ndarray, avoid: Callable[[np.ndarray], np.ndarray], toward: np.ndarray | None = None
) -> np.ndarray | None:
    """The nearest posture along the arm's self-motion from ``q`` that reaches sample ``i`` and is clear (first on
    the side of ``toward``, the knot before's posture)."""
    first = 1.0 if toward is None or float((toward - q) @ _self_motion(S, q)) >= 0.0 else -1.0
    for side in (first, -first):
        cur, way = q.copy(), side * _self_motion(S, q)
        for _ in range(CLEAR_STEPS):
            n = _self_motion(S, cur)
            way = n if float(n @ way) >= 0.0 else -n  # the null space's direction has no sign: keep going one way
            cur, pe, oe = S.solve(i, cur + CLEAR_STEP_RAD * way, 12, pull="none")
            if not S.ok(pe, oe, 5.0):
                break
            if not bool(avoid(cur[None, :])[0]):
                return cur
    return None


def _keep_clear(
    S: _PathSolver, idx: np.ndarray, Q: np.ndarray, ok: np.ndarray, avoid: Callable[[np.ndarray], np.ndarray]
) -> np.ndarray:
    """Knots whose arm touches something, moved along the self-motion until clear: each run of them from its
    first knot's clear posture onwards until the path meets its old posture again, and a few knots before it
    eased into that posture."""
    Q = Q.copy()
    bad = np.asarray(avoid(Q), dtype=bool) & np.asarray(ok, dtype=bool)
    j = 0
    while j < Q.shape[0]:
        if not bad[j]:
            j += 1
            continue
        q = _clear_posture(S, int(idx[j]), Q[j], avoid)
        if q is None:  # no posture helps there: the run stays (said in words, drawn red: studio.world.contacts)
            while j < Q.shape[0] and bad[j]:
                j += 1
            continue
        Q[j] = q
        for b in range(j - 1, max(j - 4, -1), -1):  # ease the knots before into it
            qb, _, _, good = S.advance(Q[b + 1], int(idx[b + 1]), int(idx[b]))
            if not good or avoid(qb[None, :])[0]:
                break
            Q[b] = qb
        k = j + 1
        while k < Q.shape[0]:  # on in the clear posture, until it meets the old path again
            qk, _, _, good = S.advance(Q[k - 1], int(idx[k - 1]), int(idx[k]))
            if not good:
                break
            if avoid(qk[None, :])[0]:
                again = _clear_posture(S, int(idx[k]), qk, avoid, Q[k - 1])
                if again is None:
                    break
                qk = again
            if not bad[k] and float(np.max(np.abs(qk - Q[k]))) < BREAK_RAD:
                break
            Q[k] = qk
            k += 1
        j = k
    return Q


def _breaks(Q: np.ndarray, arc: np.ndarray) -> int:
    """How many knot-to-knot joint changes are posture changes (as :attr:`PathSolution.breaks` counts them)."""
    if Q.shape[0] < 2:
        return 0
    return int(np.sum(np.max(np.abs(np.diff(Q, axis=0)), axis=1) > BREAK_RAD + BREAK_RAD_PER_M * np.diff(arc)))


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
    solver = _PathSolver(b, arm, t, position, R)
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
        Q = _keep_clear(solver, idx, Q, ok, avoid)
    idx2, Q, ok, pe, oe = _refine(solver, idx, Q, ok, pe, oe)
    if avoid is not None and avoid(Q).any():  # knots added between cleared ones may touch again: once more
        Q = _keep_clear(solver, idx2, Q, ok, avoid)
        idx2, Q, ok, pe, oe = _refine(solver, idx2, Q, ok, pe, oe)
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


def _fmt_s(x: float) -> str:
    return f"{x:.1f}"


def _distance_words(m: float) -> str:
    if m >= 0.0095:
        return f"{m * 100:.0f} cm"
    return f"{max(m * 1000, 1):.0f} mm"


def feasibility(
    t: np.ndarray,
    position_error: np.ndarray,
    orientation_error: np.ndarray,
    arm: Arm,
    *,
    min_gap_s: float = 0.05,
    reachable: Callable[[int], bool] | None = None,
) -> Feasibility:
    """Unreachable time spans of a skill and one plain sentence about them.

    Args:
        t: (N,) the skill's time of each sample (seconds).
        position_error, orientation_error: (N,) how far the closest reachable pose is from the skill.
        arm: "left" or "right" (named in the message).
        min_gap_s: spans closer than this are reported as one.
        reachable: optional test "can the arm reach sample i at all" (e.g. by restarts); a span whose
            probed samples are all reachable is a change of posture, not a stretch out of reach.

    Returns:
        A :class:`Feasibility`; ``ok`` when every sample is within 1 mm and 0.01 rad.
    """
    check_arm(arm)
    t = np.asarray(t, dtype=np.float64)
    pe = np.asarray(position_error, dtype=np.float64)
    oe = np.asarray(orientation_error, dtype=np.float64)
    bad = (pe > ACCEPT_POSITION_M) | (oe > ACCEPT_ORIENTATION_RAD)
    if not bad.any():
        return Feasibility(arm, (), f"The {arm} arm can follow the whole skill.")
    edges = np.diff(np.concatenate([[0], bad.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    runs: list[list[int]] = []
    for sa, sz in zip(starts.tolist(), ends.tolist(), strict=True):
        if runs and t[sa] - t[runs[-1][1]] <= min_gap_s:
            runs[-1][1] = sz
        else:
            runs.append([sa, sz])
    spans = []
    for ra, rz in runs:
        a, z = int(ra), int(rz)
        p_max, o_max = float(pe[a : z + 1].max()), float(oe[a : z + 1].max())
        reason = "reach" if p_max > ACCEPT_POSITION_M else "turn"
        if reachable is not None:
            probes = {a + (z - a) // 4, (a + z) // 2, z - (z - a) // 4}
            if all(reachable(i) for i in sorted(probes)):
                reason = "posture"
        spans.append(UnreachableSpan(float(t[a]), float(t[z]), a, z, p_max, o_max, reason))
    return Feasibility(arm, tuple(spans), _feasibility_message(arm, spans))


def _feasibility_message(arm: Arm, spans: list[UnreachableSpan]) -> str:
    first = spans[0]
    moment = first.t_end - first.t_start < 0.05  # one instant, not a stretch: "at 13.6 s", not "during"
    at = f"{_fmt_s(first.t_start)} s into the skill"
    stretch = f"{_fmt_s(first.t_start)}–{_fmt_s(first.t_end)} s of the skill"
    during = f"during {stretch}"
    gripper = f"The {arm} gripper"
    if first.reason == "posture":
        msg = (
            f"The {arm} arm has to change its posture {f'at {at}' if moment else during}: it can reach each of "
            f"{'the poses there' if moment else 'those poses'}, but not in one continuous motion, so the gripper "
            "leaves the taught path there"
        )
        advice = "Teach that part with the arm held the same way throughout."
    elif first.reason == "reach":
        where = f"the pose at {at}" if moment else stretch
        msg = (
            f"{gripper} cannot reach {where}: it would need to be "
            f"{_distance_words(first.position_error)} farther than the arm reaches"
        )
        if first.orientation_error > ACCEPT_ORIENTATION_RAD:
            msg += f" and turned {math.degrees(first.orientation_error):.0f}° further"
        advice = "Teach that part closer to the robot, or with the gripper in a direction the arm can hold."
    else:
        msg = (
            f"{gripper} cannot turn as taught {f'at {at}' if moment else during}: it would need to turn "
            f"{math.degrees(first.orientation_error):.0f}° further than the wrist allows"
        )
        advice = "Teach that part with the gripper in a direction the arm can hold."
    if len(spans) > 1:
        more = len(spans) - 1
        msg += f" (and {more} more stretch{'es' if more > 1 else ''} later)"
    return f"{msg}. {advice}"


def pose_reachable(solver: _PathSolver, i: int, seeds: int = 8) -> bool:
    """Whether any posture reaches sample ``i`` within the acceptance bar (multi-start damped least squares)."""
    cands = [solver.mid, solver.neutral, *solver.b.random_configuration(solver.arm, solver.rng, max(0, seeds - 2))]
    for q0 in cands:
        _, p, o = solver.solve(i, q0, 150, pull="mid", tol_p=ACCEPT_POSITION_M / 10, tol_o=ACCEPT_ORIENTATION_RAD / 10)
        if p <= ACCEPT_POSITION_M and o <= ACCEPT_ORIENTATION_RAD:
            return True
    return False


__all__ = [
    "ACCEPT_ORIENTATION_RAD",
    "ACCEPT_POSITION_M",
    "Feasibility",
    "PathSolution",
    "UnreachableSpan",
    "feasibility",
    "knot_indices",
    "pose_reachable",
    "rotation_angle",
    "solve_path",
]
