"""Clearance for the whole-path IK: knots whose arm touches something moved along the arm's self-motion.

:func:`keep_clear` moves each run of touching knots along the Jacobian's null space (the gripper stays on the
path, the elbow swings) to the nearest clear posture, eases the knots before into it and follows the path in it
until the old posture is clear again. What touches is the caller's (``avoid``); decisions 087 and 096."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from studio.core.ik_solver import BREAK_RAD, PathSolver

#: Steps (rad) along the arm's self-motion tried to keep a knot's arm clear, and how many each way.
CLEAR_STEP_RAD = 0.12
CLEAR_STEPS = 16


def _self_motion(S: PathSolver, q: np.ndarray) -> np.ndarray:
    """(7,) unit joint direction that moves the arm without moving the gripper (the Jacobian's null space)."""
    J = pin.computeFrameJacobian(S.model, S.data, q, S.fid, pin.LOCAL_WORLD_ALIGNED)
    n = np.linalg.svd(J)[2][-1]
    return n / np.linalg.norm(n)


def _clear_posture(
    S: PathSolver, i: int, q: np.ndarray, avoid: Callable[[np.ndarray], np.ndarray], toward: np.ndarray | None = None
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


def keep_clear(
    S: PathSolver, idx: np.ndarray, Q: np.ndarray, ok: np.ndarray, avoid: Callable[[np.ndarray], np.ndarray]
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


__all__ = ["CLEAR_STEPS", "CLEAR_STEP_RAD", "keep_clear"]
