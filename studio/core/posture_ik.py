"""IK for guiding the gripper by hand: one pose, solved so the arm never ends trapped at its joint limits.

:func:`reach_pose` solves from the arm's joints with a pull towards a rest posture and out of the ends of each
joint's range (both in the Jacobian's null space), inside the limits less a margin; when that solution is not
reached or sits near a limit it also solves from other starts (the rest posture, the wrist turned over,
mid-range) and keeps the best. Whether a pose is within reach does not depend on where the arm is.
Why: docs/decisions/070."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from studio.core.errors import InvalidInput
from studio.core.kinematics import Baxter, IkResult
from studio.core.rotations import matrix_from_quat_wxyz
from studio.core.types import Arm, check_arm, readonly

#: Every solution stays this far (rad) inside each joint's limits: a joint never rests on a limit.
LIMIT_MARGIN_RAD = math.radians(2.0)
#: Fraction of a joint's range, at either end, that the null-space term pushes joints out of.
LIMIT_ZONE = 0.08
#: A solution with a joint closer than this (fraction of its range) to a limit makes the other starts run
#: (the elbow's straight end excepted: a straight arm is how the gripper reaches far, and it bends back freely).
NEAR_LIMIT = 0.04
#: Share of the way to the rest posture taken each iteration (in the null space only).
REST_GAIN = 0.05
#: Reached: the gripper within these of the target.
REACH_POSITION_M = 1e-3
REACH_ORIENTATION_RAD = 1e-2
#: Solve to these (tighter than "reached", so a reached pose is also a good one).
SOLVE_POSITION_M = 1e-4
SOLVE_ORIENTATION_RAD = 1e-3
#: Largest joint step of one iteration, rad.
MAX_STEP_RAD = 0.3
#: Shoulder (s1 joint) to gripper point with the arm stretched, m: beyond it no start can reach.
_STRETCH_SLACK_M = 0.02


@dataclass(frozen=True)
class Reached:
    """What :func:`reach_pose` found: the joints to send and whether the target is within reach.

    Attributes:
        result: the solution (``result.converged``: within :data:`REACH_POSITION_M` and
            :data:`REACH_ORIENTATION_RAD`).
        start: which start it came from ("arm", "rest", "wrist turned", "mid-range", "unwound").
        tried: how many starts were solved.
    """

    result: IkResult
    start: str
    tried: int


class _Solver:
    """One arm's reduced model, limits and reach (shared; each solve brings its thread's pinocchio data)."""

    def __init__(self, baxter: Baxter, arm: Arm) -> None:
        self.model, self.fid = baxter._reduced[arm]
        lo = np.array(self.model.lowerPositionLimit, dtype=np.float64)
        hi = np.array(self.model.upperPositionLimit, dtype=np.float64)
        self.lo, self.hi = lo + LIMIT_MARGIN_RAD, hi - LIMIT_MARGIN_RAD
        self.range = hi - lo
        self.full_lo = lo
        self.mid = 0.5 * (lo + hi)
        self.shoulder = _joint_origin(baxter, arm, 1)
        self.reach_m = _stretched_reach(baxter, arm, self.shoulder) + _STRETCH_SLACK_M

    def margins(self, q: np.ndarray) -> np.ndarray:
        """(7,) distance of each joint to its nearer limit, as a fraction of its range (the straight elbow's
        end not counted)."""
        x = (q - self.full_lo) / self.range
        lower = x.copy()
        lower[3] = 1.0  # e1 at its lower end is a straight elbow, not a trap
        return np.minimum(lower, 1.0 - x)

    def solve(
        self, data: pin.Data, p_t: np.ndarray, R_t: np.ndarray, q: np.ndarray, rest: np.ndarray, iterations: int
    ) -> tuple[np.ndarray, float, float, int]:
        """Damped least squares from ``q`` with the null-space pull; returns the best joints, their errors and the
        iterations used."""
        model, fid = self.model, self.fid
        lo, hi = self.lo, self.hi
        q = np.minimum(np.maximum(q, lo), hi)
        lam = 1e-4
        best_q, best_cost, best_pe, best_oe = q, math.inf, math.inf, math.inf
        e = np.empty(6)
        settled = 0
        for it in range(iterations + 1):
            J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
            M = pin.updateFramePlacement(model, data, fid)
            e[:3] = p_t - M.translation
            e[3:] = pin.log3(R_t @ M.rotation.T)
            pe = math.sqrt(float(e[:3] @ e[:3]))
            oe = math.sqrt(float(e[3:] @ e[3:]))
            cost = pe + 0.1 * oe
            if cost < best_cost - 1e-12 or (pe <= SOLVE_POSITION_M and oe <= SOLVE_ORIENTATION_RAD):
                best_q, best_cost, best_pe, best_oe = q, min(cost, best_cost), pe, oe
                lam = max(lam * 0.5, 1e-7)
            else:
                lam = min(lam * 8.0, 1.0)
            if it == iterations:
                break
            x = (q - self.full_lo) / self.range
            z = REST_GAIN * (rest - q)
            z += (np.maximum(LIMIT_ZONE - x, 0.0) - np.maximum(x - (1.0 - LIMIT_ZONE), 0.0)) * self.range * 0.5
            A = J @ J.T
            A.flat[::7] += lam
            dq = J.T @ lapack.dposv(A, e)[1]
            dz = z - J.T @ lapack.dposv(A, J @ z)[1]
            done = pe <= SOLVE_POSITION_M and oe <= SOLVE_ORIENTATION_RAD
            if done:
                settled += 1
                if settled > 3 or float(np.abs(dz).max()) < 1e-3:
                    break  # reached, and the posture has (nearly) stopped moving
            dq += dz
            blocked = ((q <= lo + 1e-9) & (dq < 0)) | ((q >= hi - 1e-9) & (dq > 0))
            if blocked.any():  # a joint on its (margin) limit that the step pushes further: freeze it
                free = np.where(blocked, 0.0, 1.0)
                Jf = J * free
                A = Jf @ Jf.T
                A.flat[::7] += lam
                zf = z * free
                dq = Jf.T @ lapack.dposv(A, e)[1] + zf - Jf.T @ lapack.dposv(A, Jf @ zf)[1]
            big = float(np.abs(dq).max())
            if big > MAX_STEP_RAD:
                dq *= MAX_STEP_RAD / big
            q = np.minimum(np.maximum(q + dq, lo), hi)
        return best_q, best_pe, best_oe, it


def _joint_origin(baxter: Baxter, arm: Arm, index: int) -> np.ndarray:
    """World position of joint ``index``'s origin (s0 = 0 … w2 = 6); s0 and s1 do not move with the arm."""
    model, _ = baxter._reduced[arm]
    data = model.createData()
    pin.forwardKinematics(model, data, np.zeros(model.nq))
    return np.array(data.oMi[index + 1].translation)


def _stretched_reach(baxter: Baxter, arm: Arm, shoulder: np.ndarray) -> float:
    """Farthest the gripper point gets from the shoulder: sampled over postures with the elbow straight."""
    rng = np.random.default_rng(7)
    lo, hi = baxter.lower_limits(arm), baxter.upper_limits(arm)
    Q = rng.uniform(lo, hi, size=(4000, 7))
    Q[:, 3] = lo[3]
    P, _ = baxter.fk_batch(arm, Q)
    return float(np.linalg.norm(P - shoulder, axis=1).max())


_SOLVERS: dict[tuple[int, str], _Solver] = {}


def _solver(baxter: Baxter, arm: Arm) -> _Solver:
    key = (id(baxter), arm)
    s = _SOLVERS.get(key)
    if s is None:
        s = _SOLVERS[key] = _Solver(baxter, arm)
    return s


def _wrist_turned(q: np.ndarray) -> np.ndarray:
    """The same gripper pose (near enough to seed from) with the wrist turned over: w0 and w2 half a turn
    round, w1 mirrored; the half turn taken towards the middle of each range."""
    f = q.copy()
    f[4] = q[4] - math.copysign(math.pi, q[4])
    f[5] = -q[5]
    f[6] = q[6] - math.copysign(math.pi, q[6])
    return f


def _reached(pe: float, oe: float) -> bool:
    return pe <= REACH_POSITION_M and oe <= REACH_ORIENTATION_RAD


def reach_pose(
    baxter: Baxter,
    arm: Arm,
    position: np.ndarray,
    wxyz: np.ndarray,
    q_seed: np.ndarray,
    *,
    rest: np.ndarray | None = None,
    iterations: int = 60,
) -> Reached:
    """Joints that put the gripper at a pose, near ``q_seed`` and kept away from the joint limits.

    Args:
        baxter: the model.
        arm: "left" or "right".
        position: (3,) target gripper position, m.
        wxyz: (4,) target orientation, quaternion w, x, y, z.
        q_seed: (7,) the arm's joints now, rad.
        rest: (7,) the posture pulled towards in the null space (default: :meth:`Baxter.neutral`).
        iterations: damped least-squares iterations per start.

    Returns:
        :class:`Reached`. A target out of reach from every start ends at the closest pose found from the
        arm's own joints (or a start clearly closer), still inside the limits less :data:`LIMIT_MARGIN_RAD`.
    """
    check_arm(arm)
    p = np.asarray(position, dtype=np.float64)
    w = np.asarray(wxyz, dtype=np.float64)
    seed = np.asarray(q_seed, dtype=np.float64)
    if p.shape != (3,) or w.shape != (4,) or seed.shape != (7,):
        raise InvalidInput("A gripper target needs a position (x, y, z), an orientation (w, x, y, z) and 7 joints.")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(w)) and np.all(np.isfinite(seed))):
        raise InvalidInput("The gripper target contains missing or invalid values (NaN or infinity).")
    nrm = float(np.linalg.norm(w))
    if nrm < 1e-9:
        raise InvalidInput("The target orientation must be a non-zero quaternion (w, x, y, z).")
    S = _solver(baxter, arm)
    R_t = matrix_from_quat_wxyz(w / nrm)
    rest_q = np.clip(baxter.neutral(arm) if rest is None else np.asarray(rest, dtype=np.float64), S.lo, S.hi)

    data = baxter._reduced_data(arm)  # this thread's own
    q0, pe0, oe0, used = S.solve(data, p, R_t, seed, rest_q, iterations)
    own = ("arm", q0, pe0, oe0)
    if _reached(pe0, oe0) and S.margins(q0).min() >= NEAR_LIMIT:
        return _result(own, 1, used)
    if float(np.linalg.norm(p - S.shoulder)) > S.reach_m:
        return _result(own, 1, used)  # beyond the stretched arm: no start reaches it
    unwound = seed.copy()
    unwound[[0, 2, 4, 6]] = rest_q[[0, 2, 4, 6]]
    starts = [
        ("rest", rest_q),
        ("wrist turned", _wrist_turned(rest_q)),
        ("unwound", unwound),
        ("mid-range", S.mid),
        ("wrist turned", _wrist_turned(seed)),
    ]
    found = [own]
    for name, q_start in starts:
        q, pe, oe, n = S.solve(data, p, R_t, q_start, rest_q, iterations)
        found.append((name, q, pe, oe))
        used += n
    return _result(_pick(S, seed, found), len(found), used)


def _pick(
    S: _Solver, seed: np.ndarray, found: list[tuple[str, np.ndarray, float, float]]
) -> tuple[str, np.ndarray, float, float]:
    """Of the reached solutions: clear of the limits first, then nearest the arm's joints. None reached: the
    arm's own closest pose, unless another start gets more than a centimetre closer."""
    reached = [f for f in found if _reached(f[2], f[3])]
    if reached:

        def key(f: tuple[str, np.ndarray, float, float]) -> tuple[float, float]:
            clear = min(float(S.margins(f[1]).min()), NEAR_LIMIT)
            return (-clear, float(np.abs(f[1] - seed).max()))

        return min(reached, key=key)
    own = found[0]
    best = min(found, key=lambda f: f[2] + 0.1 * f[3])
    return best if best[2] + 0.1 * best[3] < own[2] + 0.1 * own[3] - 0.01 else own


def _result(f: tuple[str, np.ndarray, float, float], tried: int, iterations: int) -> Reached:
    name, q, pe, oe = f
    ok = _reached(pe, oe)
    res = IkResult(q=readonly(q), converged=ok, position_error=pe, orientation_error=oe, iterations=iterations)
    return Reached(res, name, tried)


__all__ = ["LIMIT_MARGIN_RAD", "Reached", "reach_pose"]
