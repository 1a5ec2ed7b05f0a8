"""Where a demonstration really starts and ends: the idle time before and after the teacher moved."""

from __future__ import annotations

import numpy as np

from studio.core.arms import arm_columns, gripper_column
from studio.core.types import Recording


def idle_bounds(
    rec: Recording, *, threshold: float = 0.01, gripper_threshold: float = 1.0, margin: float = 0.2
) -> tuple[float, float]:
    """Times (t0, t1) between which the taught arm(s) move: the idle start and end are outside.

    The arm is idle while every joint of the taught arms stays within ``threshold`` rad of its pose at the
    start (or at the end) and the gripper within ``gripper_threshold`` percent. Robust to sensor noise of a
    few milliradians (displacement, not speed, is tested). ``margin`` seconds of idle are kept on each side.
    """
    n = len(rec)
    if n < 2:
        return float(rec.t[0]), float(rec.t[-1])
    q = np.concatenate([rec.q[:, arm_columns(a)] for a in rec.arms], axis=1)
    g = rec.gripper[:, [gripper_column(a) for a in rec.arms]]
    w = max(1, min(n, int(0.1 * n / max(rec.duration, 1e-9))))  # a 100 ms reference window

    def first_move(qq: np.ndarray, gg: np.ndarray) -> int:
        ref_q = np.median(qq[:w], axis=0)
        ref_g = np.median(gg[:w], axis=0)
        moved = np.any(np.abs(qq - ref_q) > threshold, axis=1) | np.any(np.abs(gg - ref_g) > gripper_threshold, axis=1)
        return int(np.argmax(moved)) if moved.any() else n

    i0 = first_move(q, g)
    if i0 >= n:  # never moves: nothing to cut
        return float(rec.t[0]), float(rec.t[-1])
    i1 = n - 1 - first_move(q[::-1], g[::-1])
    t0 = max(float(rec.t[0]), float(rec.t[i0]) - margin)
    t1 = min(float(rec.t[-1]), float(rec.t[i1]) + margin)
    return t0, t1
