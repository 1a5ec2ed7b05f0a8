"""Knot refinement for the whole-path IK: knots added until the joint spline holds the path where it is reachable.

:func:`refine` checks each stretch between two reached knots against the path and adds a knot mid-way where the
spline strays; between a reached and an unreached knot it bisects to the sample where reach ends. The knots
come from :mod:`studio.core.ik_path`; decisions 008 and 096."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from studio.core.ik_solver import (
    ACCEPT_ORIENTATION_RAD,
    ACCEPT_POSITION_M,
    BREAK_RAD,
    BREAK_RAD_PER_M,
    PathSolver,
    posture_changes,
)

#: The spline between knots must stay within these of the path (else a knot is added).
REFINE_POSITION_M = 1e-4
REFINE_ORIENTATION_RAD = 1e-3


def refine(
    S: PathSolver, idx: np.ndarray, Q: np.ndarray, ok: np.ndarray, pe: np.ndarray, oe: np.ndarray, rounds: int = 16
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
        jump = posture_changes(Q, S.arc[idx])
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


__all__ = ["REFINE_ORIENTATION_RAD", "REFINE_POSITION_M", "refine"]
