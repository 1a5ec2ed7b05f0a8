"""Each thing the verdict notes about a skill: a small payload type per kind of :class:`Finding` and the
check that finds it in a :class:`~studio.core.quality.report.QualityReport`, registered with :func:`check`
in the order the notes are told. Facts only: the words are in :mod:`studio.words` (``FINDING_WORDS``)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from studio.core.quality.metrics import GripperMismatch
from studio.core.quality.report import QualityReport
from studio.core.types import SkillRoute

#: Every kind of finding (headlines too), in the order they are defined.
KINDS: list[type[Finding]] = []
#: The checks :func:`~studio.core.quality.judgement.verdict` runs for the notes, in order.
CHECKS: list[Callable[[QualityReport], Iterator[Finding]]] = []


@dataclass(frozen=True)
class Finding:
    """One fact of the verdict; each kind is a subclass with its own figures (metres, seconds)."""

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        KINDS.append(cls)


def check(fn: Callable[[QualityReport], Iterator[Finding]]) -> Callable[[QualityReport], Iterator[Finding]]:
    """Register a check: it yields the notes it finds in a report."""
    CHECKS.append(fn)
    return fn


def tolerance(size: float, share: float, floor: float) -> float:
    """``share`` of the size of what was shown, at least ``floor`` (m)."""
    return max(floor, share * size)


@dataclass(frozen=True)
class Routes(Finding):
    """The demonstrations go several ways; the skill learned ``routes[route]`` (they part most at ``where``, m)."""

    routes: tuple[SkillRoute, ...]
    route: int
    where: tuple[float, float, float]


@check
def _routes(r: QualityReport) -> Iterator[Finding]:
    if r.routes:
        yield Routes(r.routes, r.route, r.route_where)


@dataclass(frozen=True)
class StartOff(Finding):
    """The path starts ``distance`` m from the demonstrations' mean start."""

    distance: float


@dataclass(frozen=True)
class EndOff(Finding):
    """The path ends ``distance`` m from the demonstrations' mean end."""

    distance: float


@check
def _ends(r: QualityReport) -> Iterator[Finding]:
    tol = tolerance(r.size, 0.01, 0.002)
    if r.start_error > tol:
        yield StartOff(r.start_error)
    if r.end_error > tol:
        yield EndOff(r.end_error)


@dataclass(frozen=True)
class GripperUse(Finding):
    """The gripper actions disagree (the demonstrations among themselves, or the skill with them)."""

    mismatch: GripperMismatch


@check
def _gripper_use(r: QualityReport) -> Iterator[Finding]:
    if r.gripper_mismatch is not None:
        yield GripperUse(r.gripper_mismatch)


@dataclass(frozen=True)
class GripperMissed(Finding):
    """A demonstrated gripper ``action`` ("close" or "open") never happens."""

    action: str


@dataclass(frozen=True)
class GripperOff(Finding):
    """A gripper ``action`` happens ``distance`` m from where it was shown, at ``time`` s."""

    action: str
    distance: float
    time: float


@check
def _gripper_actions(r: QualityReport) -> Iterator[Finding]:
    for g in r.gripper:
        if not math.isfinite(g.error):
            yield GripperMissed(g.action)
        elif g.error > 0.01:
            yield GripperOff(g.action, g.error, g.time)


@dataclass(frozen=True)
class Unreachable(Finding):
    """The IK cannot follow ``share`` (0…1) of the path; up to ``distance`` m off, worst at ``time`` s."""

    share: float
    distance: float
    time: float


@dataclass(frozen=True)
class OffPath(Finding):
    """The IK follows all of the path but strays up to ``distance`` m from it, at ``time`` s."""

    distance: float
    time: float


@check
def _execution(r: QualityReport) -> Iterator[Finding]:
    ex = r.execution
    if ex is not None and (ex.tracked < 0.98 or ex.max_error > 0.005):
        miss = 1.0 - ex.tracked
        yield Unreachable(miss, ex.max_error, ex.worst_time) if miss >= 0.005 else OffPath(ex.max_error, ex.worst_time)


@dataclass(frozen=True)
class Slow(Finding):
    """The joints need ``robot`` s, the demonstrations took ``shortest``–``longest`` s."""

    robot: float
    shortest: float
    longest: float


@check
def _slow(r: QualityReport) -> Iterator[Finding]:
    ex = r.execution
    if ex is not None and r.demo_durations and ex.duration > 1.2 * max(r.demo_durations) + 0.2:
        yield Slow(ex.duration, min(r.demo_durations), max(r.demo_durations))


@dataclass(frozen=True)
class MissesHeldOut(Finding):
    """Learned without one demonstration, the path misses it by ``distance`` m on average."""

    distance: float


@check
def _held_out(r: QualityReport) -> Iterator[Finding]:
    h = r.held_out
    if h is not None and math.isfinite(h.g_over_r) and h.g_over_r > 1.0 and h.distance > tolerance(r.size, 0.01, 0.002):
        yield MissesHeldOut(h.distance)


@dataclass(frozen=True)
class OddDemo(Finding):
    """The demonstration ``demo`` differs a lot from the others (``distance`` m from them)."""

    demo: str
    distance: float


@check
def _odd_demos(r: QualityReport) -> Iterator[Finding]:
    for o in r.outliers:
        yield OddDemo(o.name, o.distance)
