"""Learned skills' joint trajectories sampled on one time grid: what Preview plays and the CSV export writes.

Both arms share the grid; an arm without a skill holds its rest pose, and an arm whose skill ends earlier
holds its last sample. The gripper is the one that goes with the joint trajectory (``JointTrajectory.gripper``,
on the same, possibly time-stretched, times) or, for skills saved without it, the Cartesian trajectory's.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from studio.core.arms import arm_columns, gripper_column
from studio.core.errors import InvalidInput
from studio.core.types import Arm, Skill

#: Longest trajectory sampled, seconds (the session format's limit on a demonstration, too). A skill longer
#: than this (a hostile file, a time axis stretched ×10⁶) is refused before any grid is allocated.
MAX_SECONDS = 6 * 3600.0
#: Most samples one call may ask for: 6 hours at ~185 Hz (about 0.5 GB of joints and grippers).
MAX_GRID_SAMPLES = 4_000_000


def executable(skills: Mapping[Arm, Skill]) -> dict[Arm, Skill]:
    """The skills that have a joint trajectory (IK was run), by arm."""
    return {a: s for a, s in skills.items() if s.joint_trajectory is not None}


def duration(skills: Mapping[Arm, Skill]) -> float:
    """Seconds until the longest joint trajectory ends (0 without any).

    Raises:
        InvalidInput: a trajectory lasts longer than :data:`MAX_SECONDS` (or its times are not numbers).
    """
    ends = [float(jt.t[-1] - jt.t[0]) for s in skills.values() if (jt := s.joint_trajectory) is not None]
    end = max(ends, default=0.0)
    if not 0.0 <= end <= MAX_SECONDS:
        raise InvalidInput(
            f"The learned trajectory lasts {end / 3600:,.0f} hours, longer than the {MAX_SECONDS / 3600:.0f} hours "
            "the studio plays or exports; learn the skill again."
        )
    return end


def _interp(t_src: np.ndarray, values: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Linear interpolation of (M,) or (M, d) ``values`` at ``t_new``, holding the last value after the end."""
    t_new = np.minimum(t_new, t_src[-1])
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1:
        return np.interp(t_new, t_src, values)
    return np.column_stack([np.interp(t_new, t_src, values[:, j]) for j in range(values.shape[1])])


def _joints(t_src: np.ndarray, q: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Joint samples at ``t_new`` (held after the end): the samples themselves when the times coincide, else a
    C² cubic spline through them, so the velocities and accelerations the timing kept within the limits stay
    within them (a straight line between rows would bend sharply at every sample)."""
    q = np.asarray(q, dtype=np.float64)
    m = t_src.shape[0]
    if m <= len(t_new) and np.allclose(t_new[:m], t_src, rtol=0.0, atol=1e-9):
        return np.vstack([q, np.tile(q[-1], (len(t_new) - m, 1))])
    if m < 2:
        return np.tile(q[0], (len(t_new), 1))
    from scipy.interpolate import CubicSpline

    return np.asarray(CubicSpline(t_src, q, axis=0)(np.minimum(t_new, t_src[-1])))


def native_rate(skills: Mapping[Arm, Skill], default: float = 100.0) -> float:
    """Samples per second of the joint trajectories as timed (the highest when the arms differ)."""
    rates = [
        1.0 / float(np.median(np.diff(jt.t)))
        for s in skills.values()
        if (jt := s.joint_trajectory) is not None and len(jt.t) > 1
    ]
    return max(rates, default=default)


def sample_joints(
    skills: Mapping[Arm, Skill], t: np.ndarray, rest_q: np.ndarray, rest_gripper: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Joints (N, 14) rad and grippers (N, 2) percent of ``skills`` at times ``t`` (N,) s from their start.

    Args:
        skills: arm -> Skill; those without a joint trajectory are ignored (that arm rests).
        rest_q: (14,) joints of the arms without a skill; rest_gripper: (2,) their grippers, percent.
    """
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1 or len(t) > MAX_GRID_SAMPLES:
        raise InvalidInput(f"Cannot sample a trajectory at {t.size:,} times; at most {MAX_GRID_SAMPLES:,} at once.")
    q = np.tile(np.asarray(rest_q, dtype=np.float64), (len(t), 1))
    g = np.tile(np.asarray(rest_gripper, dtype=np.float64), (len(t), 1))
    for arm, sk in executable(skills).items():
        jt = sk.joint_trajectory
        assert jt is not None
        ts = np.asarray(jt.t, dtype=np.float64) - float(jt.t[0])
        q[:, arm_columns(arm)] = _joints(ts, jt.q, t)
        if jt.gripper is not None:
            gt, gv = ts, np.asarray(jt.gripper)
        else:
            tr = sk.trajectory
            gt, gv = np.asarray(tr.t, dtype=np.float64) - float(tr.t[0]), np.asarray(tr.gripper)
        g[:, gripper_column(arm)] = _interp(gt, gv, t)
    return q, np.clip(g, 0.0, 100.0)
