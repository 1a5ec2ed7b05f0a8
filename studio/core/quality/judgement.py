"""The verdict on a learned skill as data: its level, the headline (how close the path is) and the notes every
registered check finds (:mod:`~studio.core.quality.notes`), and how well each demonstration fits. No words:
:mod:`studio.words` says each kind of finding."""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from studio.core.quality.metrics import OddIn
from studio.core.quality.notes import CHECKS, Finding, tolerance
from studio.core.quality.report import QualityReport

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


@dataclass(frozen=True)
class Close(Finding):
    """Headline: the path stays within ``distance`` m (RMS) of the demonstrations."""

    distance: float


@dataclass(frozen=True)
class Loose(Finding):
    """Headline: ``distance`` m (RMS) from the demonstrations, farther than they are from each other."""

    distance: float


@dataclass(frozen=True)
class CutsCorner(Finding):
    """Headline: the path cuts a shared corner by ``distance`` m at ``time`` s."""

    distance: float
    time: float


@dataclass(frozen=True)
class Strays(Finding):
    """Headline: the path strays ``distance`` m (RMS) from the demonstrations."""

    distance: float


Headline = Close | Loose | CutsCorner | Strays


@dataclass(frozen=True)
class Verdict:
    """The skill's quality: its level, the headline, then one finding per thing to look at
    (:data:`~studio.core.quality.notes.CHECKS`).

    The level is GOOD only when the headline is :class:`Close` and there are no notes.
    """

    level: Level
    headline: Headline
    notes: tuple[Finding, ...] = ()


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
    close = (f.g_over_r <= GOOD_G_OVER_R or f.distance <= tolerance(size, 0.01, 0.0015)) and (
        not math.isfinite(f.f_over_b1) or f.f_over_b1 <= GOOD_F_OVER_B1 or f.frechet <= tolerance(size, 0.02, 0.003)
    )
    poor = f.g_over_r > POOR_G_OVER_R and (not math.isfinite(f.f_over_b1) or f.f_over_b1 > POOR_F_OVER_B1)
    cut = [c for c in r.corners if c.error > tolerance(size, 0.03, 0.003)]
    notes = tuple(note for found in CHECKS for note in found(r))
    if poor:
        return Verdict(Level.POOR, Strays(f.distance), notes)
    if cut:
        worst = max(cut, key=lambda c: c.error)
        return Verdict(Level.FAIR, CutsCorner(worst.error, worst.time), notes)
    if not close:
        return Verdict(Level.FAIR, Loose(f.distance), notes)
    return Verdict(Level.FAIR if notes else Level.GOOD, Close(f.distance), notes)


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
    tol = tolerance(report.size, 0.02, 0.003)
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
