"""The verdict on a learned skill as data: its level, the headline and each thing to look at, with the knob
that would help (:class:`Remedy`), and how well each demonstration fits. No words: each audience words it
(:mod:`studio.words`, with the studio's controls or ``studio learn``'s options)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from studio.core.quality.metrics import GripperMismatch, OddIn
from studio.core.quality.report import QualityReport
from studio.core.types import SkillRoute

NAN = float("nan")

#: Verdict limits (see :func:`verdict`).
GOOD_G_OVER_R = 0.6
GOOD_F_OVER_B1 = 1.25
POOR_G_OVER_R = 1.0
POOR_F_OVER_B1 = 2.0


class Level(StrEnum):
    """How good the skill is."""

    GOOD = "good"
    FAIR = "fair"
    POOR = "poor"


class Remedy(StrEnum):
    """The knob that would help; the audience says how to reach it (a control, a command-line option)."""

    MORE_KEYPOINTS = "more key-points"  #: search the thresholds, or more detail (more key-points)
    SHARPER_CORNERS = "sharper corners"  #: search the thresholds, or a lower corner-sharpness threshold
    MORE_DEMOS = "more demonstrations"  #: record one or two more
    REDO_DEMO = "redo the demonstration"  #: re-record or hide it
    WITHIN_REACH = "within reach"  #: teach closer to the robot, the gripper in a direction the arm can hold
    CHOOSE_ROUTE = "choose the way"  #: choose which way the skill learns


class Issue(StrEnum):
    """What a :class:`Finding` is about (headlines first, then the notes)."""

    CLOSE = "close"  #: headline: the path stays close to the demos (distance)
    LOOSE = "loose"  #: headline: farther from the demos than they are from each other (distance)
    CUTS_CORNER = "cuts corner"  #: headline: a shared corner is cut (distance, time)
    STRAYS = "strays"  #: headline: far from the demos (distance)
    START_OFF = "start off"  #: starts away from the demos' start (distance)
    END_OFF = "end off"  #: ends away from the demos' end (distance)
    GRIPPER_MISMATCH = "gripper mismatch"  #: the gripper actions disagree (mismatch)
    GRIPPER_MISSED = "gripper missed"  #: a demonstrated gripper action never happens (action)
    GRIPPER_OFF = "gripper off"  #: a gripper action happens elsewhere (action, distance, time)
    UNREACHABLE = "unreachable"  #: the IK cannot follow part of the path (share, distance, time)
    OFF_PATH = "off path"  #: the IK follows it all but strays from it (distance, time)
    SLOW = "slow"  #: the joints need longer than the demos took (time, durations)
    HELD_OUT = "held out"  #: learned without one demo, it misses that one (distance)
    OUTLIER = "outlier"  #: a demo differs a lot from the others (demo)
    ROUTES = "routes"  #: the demos go several ways; the skill learned one of them (routes, route, where)


@dataclass(frozen=True)
class Finding:
    """One fact of the verdict, with the figures its :class:`Issue` names (metres, seconds; NaN when unused).

    Attributes:
        issue: what it is about.
        remedy: the knob that would help, if any.
        distance: m; time: s from the skill's start; share: 0…1 of the path.
        action: "close" or "open" (gripper issues); demo: a demonstration's name (outliers).
        mismatch: how the gripper actions disagree (GRIPPER_MISMATCH).
        durations: the robot's duration, the shortest and the longest demo's, s (SLOW).
        routes, route, where: the ways the demos went, the one learned and where they part most (ROUTES).
    """

    issue: Issue
    remedy: Remedy | None = None
    distance: float = NAN
    time: float = NAN
    share: float = NAN
    action: str = ""
    demo: str = ""
    mismatch: GripperMismatch | None = None
    durations: tuple[float, float, float] = (NAN, NAN, NAN)
    routes: tuple[SkillRoute, ...] = ()
    route: int = 0
    where: tuple[float, float, float] = (NAN, NAN, NAN)


@dataclass(frozen=True)
class Verdict:
    """The skill's quality: its level, the headline, then one finding per thing to look at.

    The level is GOOD only when the headline is CLOSE and there are no notes.
    """

    level: Level
    headline: Finding
    notes: tuple[Finding, ...] = ()


def _tolerance(size: float, share: float, floor: float) -> float:
    return max(floor, share * size)


def _notes(r: QualityReport) -> list[Finding]:
    size = r.size
    notes: list[Finding] = []
    if r.routes:
        notes.append(Finding(Issue.ROUTES, Remedy.CHOOSE_ROUTE, routes=r.routes, route=r.route, where=r.route_where))
    tol_end = _tolerance(size, 0.01, 0.002)
    if r.start_error > tol_end:
        notes.append(Finding(Issue.START_OFF, distance=r.start_error))
    if r.end_error > tol_end:
        notes.append(Finding(Issue.END_OFF, distance=r.end_error))
    if r.gripper_mismatch is not None:
        notes.append(Finding(Issue.GRIPPER_MISMATCH, mismatch=r.gripper_mismatch))
    for g in r.gripper:
        if not math.isfinite(g.error):
            notes.append(Finding(Issue.GRIPPER_MISSED, Remedy.MORE_KEYPOINTS, action=g.action))
        elif g.error > 0.01:
            notes.append(
                Finding(Issue.GRIPPER_OFF, Remedy.MORE_KEYPOINTS, distance=g.error, time=g.time, action=g.action)
            )
    ex = r.execution
    if ex is not None and (ex.tracked < 0.98 or ex.max_error > 0.005):
        miss = 1.0 - ex.tracked
        issue = Issue.UNREACHABLE if miss >= 0.005 else Issue.OFF_PATH
        notes.append(Finding(issue, Remedy.WITHIN_REACH, distance=ex.max_error, time=ex.worst_time, share=miss))
    if ex is not None and r.demo_durations and ex.duration > 1.2 * max(r.demo_durations) + 0.2:
        notes.append(
            Finding(Issue.SLOW, time=ex.duration, durations=(ex.duration, min(r.demo_durations), max(r.demo_durations)))
        )
    h = r.held_out
    if h is not None and math.isfinite(h.g_over_r) and h.g_over_r > 1.0 and h.distance > _tolerance(size, 0.01, 0.002):
        notes.append(Finding(Issue.HELD_OUT, Remedy.MORE_DEMOS, distance=h.distance))
    notes.extend(Finding(Issue.OUTLIER, Remedy.REDO_DEMO, distance=o.distance, demo=o.name) for o in r.outliers)
    return notes


def verdict(report: QualityReport) -> Verdict:
    """Judge a :class:`QualityReport`.

    The path is *close* when G/R ≤ 0.6 (or the RMS distance is within 1.5 mm / 1 % of the size) and F/B1 ≤ 1.25
    (or the Fréchet distance is within 3 mm / 2 % of the size); *poor* when G/R > 1 and F/B1 > 2. A shared
    corner is *cut* when the path passes farther than max(3 mm, 3 % of the size) from it; start and end count
    from max(2 mm, 1 % of the size), a grasp or release from 1 cm, execution when IK tracks less than 98 % of
    the samples or strays more than 5 mm. The level is GOOD only if nothing else needs a note.
    """
    r = report
    f = r.fidelity
    size = r.size
    close = (f.g_over_r <= GOOD_G_OVER_R or f.distance <= _tolerance(size, 0.01, 0.0015)) and (
        not math.isfinite(f.f_over_b1) or f.f_over_b1 <= GOOD_F_OVER_B1 or f.frechet <= _tolerance(size, 0.02, 0.003)
    )
    poor = f.g_over_r > POOR_G_OVER_R and (not math.isfinite(f.f_over_b1) or f.f_over_b1 > POOR_F_OVER_B1)
    cut = [c for c in r.corners if c.error > _tolerance(size, 0.03, 0.003)]
    notes = tuple(_notes(r))
    if poor:
        return Verdict(Level.POOR, Finding(Issue.STRAYS, Remedy.MORE_KEYPOINTS, distance=f.distance), notes)
    if cut:
        worst = max(cut, key=lambda c: c.error)
        head = Finding(Issue.CUTS_CORNER, Remedy.SHARPER_CORNERS, distance=worst.error, time=worst.time)
        return Verdict(Level.FAIR, head, notes)
    if not close:
        return Verdict(Level.FAIR, Finding(Issue.LOOSE, Remedy.MORE_KEYPOINTS, distance=f.distance), notes)
    return Verdict(Level.FAIR if notes else Level.GOOD, Finding(Issue.CLOSE, distance=f.distance), notes)


class Misfit(StrEnum):
    """Why a demonstration fits the skill poorly."""

    SHAPE = "shape"  #: it differs a lot from the others
    LIKELIHOOD = "likelihood"  #: the skill's model finds it much less likely than the others
    FAR = "far"  #: the learned path stays far from it, far more than from the others


@dataclass(frozen=True)
class DemoFit:
    """How well one demonstration fits the learned skill.

    Attributes:
        index: position in the skill's demo list; name: its name.
        well: it fits well (``why`` is None).
        distance: root-mean-square distance of the learned path to it, m.
        why: why it fits poorly (None when it fits well).
    """

    index: int
    name: str
    well: bool
    distance: float
    why: Misfit | None = None


def demo_fits(report: QualityReport) -> tuple[DemoFit, ...]:
    """Per demonstration: well or poorly (in place of the paper's raw HMM log-likelihoods).

    A demo fits poorly when it is an outlier (:func:`~studio.core.quality.metrics.outliers`: far from the
    others, or much less likely under the HMM), or when the learned path stays more than twice as far from it as
    from the typical demo and farther than max(3 mm, 2 % of the size).
    """
    per = report.fidelity.per_demo
    if not per:
        return ()
    typical = float(np.median(per))
    tol = _tolerance(report.size, 0.02, 0.003)
    outs = {o.index: o for o in report.outliers}
    names = report.demo_names or tuple(f"demo {i + 1}" for i in range(len(per)))
    out = []
    for i, d in enumerate(per):
        why: Misfit | None = None
        if i in outs:
            why = Misfit.SHAPE if outs[i].reason is OddIn.SHAPE else Misfit.LIKELIHOOD
        elif d > 2.0 * typical and d > tol:
            why = Misfit.FAR
        out.append(DemoFit(i, names[i] if i < len(names) else f"demo {i + 1}", why is None, float(d), why))
    return tuple(out)
