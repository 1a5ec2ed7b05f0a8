"""The quality report: the measures of a learned skill against its demonstrations that the headline and several
notes share, and what was measured, gathered by :func:`assess` in one frozen :class:`QualityReport` (metres,
seconds)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from studio.core.errors import NotEnoughData
from studio.core.quality.curves import curve, extent, spread, time_normalised_mean
from studio.core.quality.holdout import HeldOut
from studio.core.quality.metrics import (
    Corner,
    Execution,
    Fidelity,
    GripperCheck,
    GripperMismatch,
    Outlier,
    corner_checks,
    execution,
    fidelity,
    gripper_checks,
    outliers,
)
from studio.core.types import Demo, Skill, SkillRoute


@dataclass(frozen=True)
class QualityReport:
    """Everything :func:`~studio.core.quality.judgement.verdict` needs, in SI units (metres, seconds).

    Attributes:
        n_demos: number of demonstrations measured against.
        size: extent of what was shown (:func:`extent`), m.
        fidelity: the learned path against the demos.
        held_out: leave-one-demo-out figures, when computed.
        start_error, end_error: distance of the path's first/last point to the demos' mean first/last point, m.
        gripper: shared gripper actions; gripper_mismatch: how the demos' or the skill's gripper actions
            disagree (None when they agree).
        corners: shared sharp corners.
        execution: from the joint trajectory, when there is one.
        duration: length of the learned path, s; demo_durations: each demo's, s.
        outliers: demos that differ a lot from the others.
        mode: the generalisation mode the skill used.
        demo_names: names in order.
        routes: the ways the demonstrations went when more than one (the skill's ``routes``); route: which one
            the skill learned (its demonstrations are ``demo_names``); route_where: (3,) m, where they part most.
        trajectory, skill, demos: what was measured (a check of :mod:`~studio.core.quality.notes` may measure
            more on them); skill is None when only a trajectory was.
    """

    n_demos: int
    size: float
    fidelity: Fidelity
    held_out: HeldOut | None
    start_error: float
    end_error: float
    gripper: tuple[GripperCheck, ...]
    gripper_mismatch: GripperMismatch | None
    corners: tuple[Corner, ...]
    execution: Execution | None
    duration: float
    demo_durations: tuple[float, ...]
    outliers: tuple[Outlier, ...]
    mode: str = ""
    demo_names: tuple[str, ...] = field(default_factory=tuple)
    routes: tuple[SkillRoute, ...] = ()
    route: int = 0
    route_where: tuple[float, float, float] = (0.0, 0.0, 0.0)
    trajectory: Demo | None = field(default=None, repr=False, compare=False)
    skill: Skill | None = field(default=None, repr=False, compare=False)
    demos: tuple[Demo, ...] = field(default=(), repr=False, compare=False)


def assess(
    skill: Skill | Demo,
    demos: Sequence[Demo],
    *,
    held_out_result: HeldOut | None = None,
    loglik: np.ndarray | None = None,
) -> QualityReport:
    """Measure a learned skill (or just its trajectory) against the demonstrations it was learned from.

    Args:
        skill: a :class:`Skill` (its trajectory, key-point counts, likelihoods and joint trajectory are used)
            or a trajectory (:class:`Demo`).
        demos: the demonstrations, in the skill's order.
        held_out_result: :func:`held_out` figures, if computed.
        loglik: per-demo log-likelihood (default: the skill's).

    Returns:
        A :class:`QualityReport`.
    """
    demos = list(demos)
    if not demos:
        raise NotEnoughData("There are no demonstrations to compare the skill with.")
    traj = skill.trajectory if isinstance(skill, Skill) else skill
    size = extent(demos)
    curves = [curve(d) for d in demos]
    r, M = spread(curves)
    path = curve(traj)
    b1 = time_normalised_mean(demos)
    fid = fidelity(path, curves, r=r, b1=b1)
    starts = np.mean([d.position[0] for d in demos], axis=0)
    ends = np.mean([d.position[-1] for d in demos], axis=0)
    checks, mismatch = gripper_checks(traj, demos)
    corners = corner_checks(traj, demos, size)
    ll: np.ndarray | None
    if isinstance(skill, Skill):
        ll = skill.loglik if loglik is None else loglik
        lengths = [len(k) for k in skill.keypoints]
        ex = execution(skill)
        mode = getattr(skill, "generalization", "")
    else:
        ll, lengths, ex, mode = loglik, None, None, ""
    outs = outliers(demos, M, loglik=ll, lengths=lengths, size=size)
    return QualityReport(
        n_demos=len(demos),
        size=size,
        fidelity=fid,
        held_out=held_out_result,
        start_error=float(np.linalg.norm(traj.position[0] - starts)),
        end_error=float(np.linalg.norm(traj.position[-1] - ends)),
        gripper=checks,
        gripper_mismatch=mismatch,
        corners=corners,
        execution=ex,
        duration=traj.duration,
        demo_durations=tuple(d.duration for d in demos),
        outliers=outs,
        mode=mode,
        demo_names=tuple(d.name for d in demos),
        routes=skill.routes if isinstance(skill, Skill) else (),
        route=skill.route if isinstance(skill, Skill) else 0,
        route_where=skill.route_where if isinstance(skill, Skill) else (0.0, 0.0, 0.0),
        trajectory=traj,
        skill=skill if isinstance(skill, Skill) else None,
        demos=tuple(demos),
    )
