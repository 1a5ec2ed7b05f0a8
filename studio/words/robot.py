"""The robot's execution in plain words: where it cannot follow a skill, and how a run on it went.

The core gives the facts (:class:`~studio.core.feasibility.Feasibility`, :class:`~studio.core.execution.RunVerdict`,
:class:`~studio.core.execution.TrackingReport`); the sentences are here, shared by the controller (why a run
cannot start, how it went) and the Preview panel. Decision 096."""

from __future__ import annotations

import math
from typing import assert_never

from studio.core.execution import RunFailure, RunVerdict, TrackingReport
from studio.core.feasibility import Feasibility, Unreachable, UnreachableSpan
from studio.core.ik_solver import ACCEPT_ORIENTATION_RAD


def _seconds(x: float) -> str:
    return f"{x:.1f}"


def _reach_words(m: float) -> str:
    """How much farther the arm would need to reach: whole centimetres, else whole millimetres (1 mm at least)."""
    if m >= 0.0095:
        return f"{m * 100:.0f} cm"
    return f"{max(m * 1000, 1):.0f} mm"


def _span_words(arm: str, first: UnreachableSpan) -> tuple[str, str]:
    """What goes wrong in the first stretch, and what to do about it."""
    moment = first.t_end - first.t_start < 0.05  # one instant, not a stretch: "at 13.6 s", not "during"
    at = f"{_seconds(first.t_start)} s into the skill"
    stretch = f"{_seconds(first.t_start)}–{_seconds(first.t_end)} s of the skill"
    when = f"at {at}" if moment else f"during {stretch}"
    turn = f"{math.degrees(first.orientation_error):.0f}°"
    if first.reason is Unreachable.POSTURE:
        return (
            f"The {arm} arm has to change its posture {when}: it can reach each of "
            f"{'the poses there' if moment else 'those poses'}, but not in one continuous motion, so the gripper "
            "leaves the taught path there",
            "Teach that part with the arm held the same way throughout.",
        )
    if first.reason is Unreachable.REACH:
        where = f"the pose at {at}" if moment else stretch
        msg = (
            f"The {arm} gripper cannot reach {where}: it would need to be "
            f"{_reach_words(first.position_error)} farther than the arm reaches"
        )
        if first.orientation_error > ACCEPT_ORIENTATION_RAD:
            msg += f" and turned {turn} further"
        return msg, "Teach that part closer to the robot, or with the gripper in a direction the arm can hold."
    return (
        f"The {arm} gripper cannot turn as taught {when}: it would need to turn {turn} further than the wrist allows",
        "Teach that part with the gripper in a direction the arm can hold.",
    )


def feasibility_words(f: Feasibility) -> str:
    """One plain sentence: the arm follows the whole skill, or what goes wrong first, where, by how much, and what to
    do ("The right gripper cannot reach 3.2–4.0 s of the skill: it would need to be 4 cm farther …")."""
    if f.ok:
        return f"The {f.arm} arm can follow the whole skill."
    msg, advice = _span_words(f.arm, f.spans[0])
    if len(f.spans) > 1:
        more = len(f.spans) - 1
        msg += f" (and {more} more stretch{'es' if more > 1 else ''} later)"
    return f"{msg}. {advice}"


def _run_distance(d: float) -> str:
    return f"{max(d, 0.0001) * 1000:.1f} mm" if d < 0.01 else f"{d * 100:.1f} cm"


def run_failure_words(v: RunVerdict) -> list[str]:
    """What failed in a run and by how much, one plain phrase each ([] when the skill works)."""
    out = []
    for failure in v.failures():
        if failure is RunFailure.UNFINISHED:
            out.append(f"the robot did {v.completed * 100:.0f} % of the run")
        elif failure is RunFailure.OFF_TRACK:
            where = "where the plan was at the same moment" if v.same_time else "the planned path"
            out.append(f"its gripper was up to {_run_distance(v.tracking_error)} from {where}")
        elif failure is RunFailure.OFF_END:
            out.append(f"it ended {_run_distance(v.final_error)} from the plan's last pose")
        elif failure is RunFailure.GRIPS:
            out.append(f"it did {v.grips_done} of the {v.grips_planned} gripper actions")
        elif failure is RunFailure.TASK:
            out.append("the objects did not end where you put them")
        else:
            assert_never(failure)
    return out


def tracking_summary(report: TrackingReport) -> str:
    """How closely a run followed its plan, in one plain sentence."""
    return (
        f"The robot ran {round(report.completed * 100)}% of the plan; its gripper stayed within "
        f"{report.max_path_error * 1000:.1f} mm of the planned path ({report.rms_path_error * 1000:.1f} mm on average)."
    )


__all__ = ["feasibility_words", "run_failure_words", "tracking_summary"]
