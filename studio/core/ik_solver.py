"""Pose solving for the whole-path IK: damped least squares towards one sample of a path or many at once.

:class:`PathSolver` holds one path solve's state (the arm's model, the targets, a seeded random generator, the
counts of recoveries) and solves one pose (:meth:`~PathSolver.solve`, :meth:`~PathSolver.advance`) or a batch
(:meth:`~PathSolver.batch_solve`). :func:`pose_reachable` asks whether any posture reaches a sample. The path
built on it: :mod:`studio.core.ik_path`; decisions 008 and 096."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from studio.core.kinematics import Baxter
from studio.core.types import Arm

#: A sample is executed faithfully when the gripper is within these of the skill (the acceptance bar).
ACCEPT_POSITION_M = 1e-3
ACCEPT_ORIENTATION_RAD = 1e-2
#: Knots are solved to these tolerances.
SOLVE_POSITION_M = 2e-5
SOLVE_ORIENTATION_RAD = 2e-4
#: Path length counts this many metres per radian the gripper turns.
ROTATION_WEIGHT_M = 0.2
#: Joint change between two knots that counts as a posture jump: BREAK_RAD + BREAK_RAD_PER_M × path length.
BREAK_RAD = 0.05
BREAK_RAD_PER_M = 20.0
#: Elbow swivel change (rad) beyond which a restart solution is on the other side.
ELBOW_SIDE_RAD = math.pi / 2
#: Elbow bend (e1, rad) below which the arm counts as straight: its elbow side is then undefined.
STRAIGHT_ELBOW_RAD = 0.25
#: Fraction of each joint's range, at either end, that the null-space term pushes joints out of.
LIMIT_ZONE = 0.1

_EYE6 = np.eye(6)


def posture_changes(Q: np.ndarray, arc: np.ndarray) -> np.ndarray:
    """(K - 1,) True where the joints change posture between knots j and j + 1 of joints Q (K, 7) at path lengths
    ``arc`` (K,): a joint change above :data:`BREAK_RAD` plus :data:`BREAK_RAD_PER_M` per metre of path."""
    return np.max(np.abs(np.diff(Q, axis=0)), axis=1) > BREAK_RAD + BREAK_RAD_PER_M * np.diff(arc)


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


class PathSolver:
    """The state of one path solve — the robot model, the targets, a deterministic random generator, counts
    of recoveries — and pose solving: one pose (:meth:`solve`, :meth:`advance`) or many at once
    (:meth:`batch_solve`). Seeding, tracking and recovery along the path: :mod:`studio.core.ik_path`."""

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


def pose_reachable(solver: PathSolver, i: int, seeds: int = 8) -> bool:
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
    "PathSolver",
    "pose_reachable",
    "posture_changes",
    "rotation_angle",
]
