"""A plan being executed by the simulated Baxter: its targets at the simulator's rate, the progress along it
(slowed down to rest along the path by a controlled stop) and the progress report.

The simulator (:mod:`studio.robot_backend.simulated`) has :meth:`PlanFollower.produce` make its next
samples: the arms follow the plan's targets (:meth:`PlanFollower.next_targets`) within their limits
(:func:`~studio.robot_backend.motion.follow`), and once they are at rest the run ends ("done" at the plan's
end, "stopped" after a controlled stop, :meth:`PlanFollower.settle`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from studio.core.errors import InvalidInput, StudioError
from studio.robot_backend.base import ExecutionProgress, JointStateBatch
from studio.robot_backend.motion import SimArms

if TYPE_CHECKING:  # pragma: no cover
    from studio.core.execution import ExecutionPlan

#: A plan must start within this (rad, every joint) of where the arms are.
PLAN_START_TOLERANCE = 0.01


def plan_targets(plan: ExecutionPlan, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The plan's joint (M, 14) and gripper (M, 2) targets at ``rate_hz`` (resampled if it has another rate).

    Raises:
        InvalidInput: the plan does not give 14 joint and 2 gripper targets per sample.
    """
    q = np.asarray(plan.q, dtype=np.float64)
    g = np.asarray(plan.gripper, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 14 or g.shape != (q.shape[0], 2) or not len(q):
        raise InvalidInput("The plan must give 14 joint targets and 2 gripper targets per sample.")
    if abs(float(plan.rate_hz) - rate_hz) > 1e-9:
        t_src = np.asarray(plan.t, dtype=np.float64) - float(plan.t[0])
        t_new = np.arange(math.floor(t_src[-1] * rate_hz + 1e-9) + 1) / rate_hz
        q = np.column_stack([np.interp(t_new, t_src, q[:, j]) for j in range(14)])
        k = np.clip(np.searchsorted(t_src, t_new + 1e-9, side="right") - 1, 0, len(t_src) - 1)
        g = g[k]
    return q, np.clip(g, 0.0, 100.0)


class PlanFollower:
    """Progress along one plan's targets, sample by sample.

    Args:
        q, g: joint (M, 14) and gripper (M, 2) targets at the simulator's rate (:func:`plan_targets`).
        rate_hz: the simulator's rate.
        started_at: time stamp (s) of the first sample that executes the plan.
    """

    def __init__(self, q: np.ndarray, g: np.ndarray, rate_hz: float, started_at: float) -> None:
        self.q, self.g = q, g
        self.dt = 1.0 / rate_hz
        self.rate_hz = rate_hz
        # progress of the latest sample: the first sample produced from now on is the plan's sample 0
        self._p, self._r, self._dr = -1.0, 1.0, 0.0
        self.progress = ExecutionProgress(
            "running", 0.0, (len(q) - 1) * self.dt, started_at, "The robot is running the skill."
        )

    def check_start(self, q_now: np.ndarray) -> None:
        """Refuse a plan that does not start where the arms are (they moved since it was planned)."""
        off = float(np.max(np.abs(self.q[0] - q_now)))
        if off > PLAN_START_TOLERANCE:
            raise StudioError(
                f"The robot moved since the run was planned (by {math.degrees(off):.0f}° at one joint); "
                "press Run again to plan from where it is now."
            )

    @property
    def finished(self) -> bool:
        return self.progress.state in ("done", "stopped")

    def slow_down(self, t_stop: float) -> None:
        """Controlled stop: the progress rate falls from 1 to 0 in ``t_stop`` seconds (idempotent)."""
        if self.progress.state == "stopping":
            return
        self._dr = 1.0 / (t_stop * self.rate_hz)
        p = self.progress
        self.progress = ExecutionProgress("stopping", p.t, p.duration, p.started_at, "The robot is stopping.")

    def next_targets(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Joint (n, 14) and gripper (n, 2) targets of the next ``n`` samples; advances the progress."""
        last = self.q.shape[0] - 1
        if self._dr == 0.0:
            prog = self._p + np.arange(1, n + 1, dtype=np.float64)
            rates = np.ones(n)
        else:
            rates = np.maximum(self._r - self._dr * np.arange(1, n + 1), 0.0)
            prog = self._p + np.cumsum(rates)
        prog = np.clip(prog, 0.0, last)
        i0 = np.floor(prog).astype(np.int64)
        i1 = np.minimum(i0 + 1, last)
        w = (prog - i0)[:, None]
        self._p, self._r = float(prog[-1]), float(rates[-1])
        return self.q[i0] * (1 - w) + self.q[i1] * w, self.g[np.round(prog).astype(np.int64)]

    def produce(self, arms: SimArms, n: int) -> JointStateBatch:
        """The next ``n`` samples of ``arms`` following the plan within their limits; once at rest at the end
        (or stopped), they hold there and the plan is :attr:`finished`."""
        q, g = arms.along(*self.next_targets(n))
        self.settle(at_rest=bool(np.max(np.abs(arms.v)) < 1e-6))
        if self.finished:
            arms.qt, arms.gt = q[-1].copy(), g[-1].copy()
        return arms.emit(q, g, velocity_known=not self.finished)

    def settle(self, at_rest: bool) -> ExecutionProgress:
        """The progress after the samples just produced; "done" or "stopped" once the arms are at rest there."""
        p = self.progress
        t_plan = max(self._p, 0.0) * self.dt
        state, msg = p.state, p.message
        if self._p >= self.q.shape[0] - 1 and at_rest:
            state, msg = "done", "The robot finished the skill."
        elif state == "stopping" and self._r <= 0.0 and at_rest:
            state, msg = "stopped", f"The robot stopped at {t_plan:.1f} s of {p.duration:.1f} s."
        self.progress = ExecutionProgress(state, t_plan, p.duration, p.started_at, msg)
        return self.progress


def halted(progress: ExecutionProgress) -> ExecutionProgress:
    """``progress`` after an emergency stop."""
    return ExecutionProgress(
        "emergency-stopped",
        progress.t,
        progress.duration,
        progress.started_at,
        "Emergency stop: the robot halted. Release the emergency stop to move it again.",
    )


__all__ = ["PLAN_START_TOLERANCE", "PlanFollower", "halted", "plan_targets"]
