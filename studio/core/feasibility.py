"""Where the robot cannot follow a skill: unreachable time spans and why (paper § Robot Execution).

:func:`feasibility` turns per-sample errors into :class:`UnreachableSpan` s (when in the skill, how far off, and
:class:`Unreachable`: too far, a turn the wrist cannot make, or a change of posture). Facts only: the sentence
is :func:`studio.words.feasibility_words`. Decision 096."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from studio.core.ik_solver import ACCEPT_ORIENTATION_RAD, ACCEPT_POSITION_M
from studio.core.types import Arm, check_arm


class Unreachable(StrEnum):
    """Why the gripper cannot follow a stretch of the skill."""

    REACH = "reach"  #: too far from the robot
    TURN = "turn"  #: an orientation the wrist cannot hold
    POSTURE = "posture"  #: each pose is reachable, but not in one continuous motion: the arm changes its posture


@dataclass(frozen=True)
class UnreachableSpan:
    """A stretch of the skill the gripper cannot follow.

    Attributes:
        t_start, t_end: seconds on the skill's time line.
        i_start, i_end: first and last sample index into the Cartesian trajectory (inclusive; for drawing).
        position_error: largest distance (m) between the closest reachable pose and the skill there.
        orientation_error: largest turn (rad) the gripper would still need there.
        reason: why (:class:`Unreachable`): too far, a turn the wrist cannot make, or a change of posture.
    """

    t_start: float
    t_end: float
    i_start: int
    i_end: int
    position_error: float
    orientation_error: float
    reason: Unreachable = Unreachable.REACH


@dataclass(frozen=True)
class Feasibility:
    """Whether ``arm`` can execute the whole skill, and where it cannot (``spans``, earliest first)."""

    arm: Arm
    spans: tuple[UnreachableSpan, ...] = field(default_factory=tuple)

    @property
    def ok(self) -> bool:
        return not self.spans


def feasibility(
    t: np.ndarray,
    position_error: np.ndarray,
    orientation_error: np.ndarray,
    arm: Arm,
    *,
    min_gap_s: float = 0.05,
    reachable: Callable[[int], bool] | None = None,
) -> Feasibility:
    """Unreachable time spans of a skill, and why.

    Args:
        t: (N,) the skill's time of each sample (seconds).
        position_error, orientation_error: (N,) how far the closest reachable pose is from the skill.
        arm: "left" or "right".
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
        return Feasibility(arm)
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
        reason = Unreachable.REACH if p_max > ACCEPT_POSITION_M else Unreachable.TURN
        if reachable is not None:
            probes = {a + (z - a) // 4, (a + z) // 2, z - (z - a) // 4}
            if all(reachable(i) for i in sorted(probes)):
                reason = Unreachable.POSTURE
        spans.append(UnreachableSpan(float(t[a]), float(t[z]), a, z, p_max, o_max, reason))
    return Feasibility(arm, tuple(spans))


__all__ = ["Feasibility", "Unreachable", "UnreachableSpan", "feasibility"]
