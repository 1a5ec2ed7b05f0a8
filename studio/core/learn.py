"""The use case "learn and judge a skill": :func:`learn_and_judge` takes one arm's demonstrations, their objects
and one :class:`~studio.core.learn_settings.LearnSettings` and returns the skill with its verdict. Inside:
object frames or the robot's frame, which way, the verdict (held out, in the frames the skill follows).
:func:`learn` and :func:`judge` are its two halves (the studio shows a skill before its verdict). Call chain:
docs/decisions/095."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

from studio.core import quality
from studio.core.caches import LearningCaches
from studio.core.errors import Cancelled, StudioError
from studio.core.frames import DemoObjects, ObjectAt
from studio.core.kinematics import Baxter
from studio.core.learn_settings import LearnSettings
from studio.core.pipeline import learn_path, learn_skill
from studio.core.quality import DemoFit, QualityReport, Verdict
from studio.core.routes import routes_of
from studio.core.segment_view import SegmentFit, demos_in_frames, segment_fits, taught_placement
from studio.core.segments import FrameChoice, choose_frames, learn_relative, place_skill
from studio.core.thresholds import ThresholdSettings
from studio.core.types import Arm, Demo, Skill

_DEFAULT = LearnSettings()


@dataclass(frozen=True)
class TaughtObjects:
    """The objects of one arm's demonstrations, for a skill that follows them.

    Attributes:
        demos: per demonstration (in the same order), its objects and the arm's contacts; empty when the skill
            cannot follow them (then ``why_not`` says why, in plain words).
        rules: the frame each release follows by its meaning (:func:`studio.core.segments.plan`).
        now: where the objects stand now, where the learned skill is placed (default: as at the first
            demonstration's start).
    """

    demos: tuple[DemoObjects, ...] = ()
    why_not: str = ""
    rules: Mapping[int, str] | None = None
    now: tuple[ObjectAt, ...] | None = None


@dataclass(frozen=True)
class Judgement:
    """How good a skill is: the report against its demonstrations, the verdict, how well each demonstration
    fits and, for a skill that follows the objects, how closely each stretch follows the demonstrations in its
    frame and how the frame of each grasp and release was chosen."""

    report: QualityReport
    verdict: Verdict
    fits: tuple[DemoFit, ...] = ()
    segments: tuple[SegmentFit, ...] = ()
    choices: tuple[FrameChoice, ...] = ()


@dataclass(frozen=True)
class LearnedSkill:
    """A learned skill, its judgement (None until judged) and, when it was asked to follow the objects but
    follows fixed places, why (``note``, plain words)."""

    skill: Skill
    judgement: Judgement | None = None
    note: str = ""


def learn_and_judge(
    demos: Sequence[Demo],
    objects: TaughtObjects | None = None,
    settings: LearnSettings = _DEFAULT,
    *,
    arm: Arm | None = None,
    baxter: Baxter | None = None,
    caches: LearningCaches | None = None,
) -> LearnedSkill:
    """Learn one arm's skill from ``demos`` (:func:`learn`) and judge it against them (:func:`judge`)."""
    caches = caches or LearningCaches()
    learned = learn(demos, objects, settings, arm=arm, baxter=baxter, caches=caches)
    judged = judge(learned.skill, demos, objects, settings, arm=arm, baxter=baxter, caches=caches)
    return replace(learned, judgement=judged)


def learn(
    demos: Sequence[Demo],
    objects: TaughtObjects | None = None,
    settings: LearnSettings = _DEFAULT,
    *,
    arm: Arm | None = None,
    baxter: Baxter | None = None,
    caches: LearningCaches | None = None,
) -> LearnedSkill:
    """Learn one arm's skill: in the frames of the objects it acts on when ``settings.frames`` is "objects" and
    ``objects`` allow it (:func:`studio.core.segments.learn_relative`), else in the robot's frame from the way
    ``settings.route`` (:func:`studio.core.pipeline.learn_skill`); with ``arm``, its joint trajectory too.

    ``demos`` are the demonstrations as taught (first to last motion, pauses shortened:
    :class:`studio.core.pace.TakeClock`), and ``objects`` their contacts on that clock.

    Raises:
        StudioError: too few demonstrations or key-points, an unknown way, the start out of reach (in words).
    """
    demos = list(demos)
    if isinstance(settings.params, ThresholdSettings):
        settings = replace(settings, params=settings.params.resolve(demos))
    wanted = objects if objects is not None and settings.frames == "objects" else None
    objs = wanted.demos if wanted is not None else ()
    if wanted is not None and objs:
        skill = learn_relative(demos, objs, settings, now=wanted.now, arm=arm, baxter=baxter, rules=wanted.rules)
        return LearnedSkill(skill)
    caches = caches or LearningCaches()
    route = settings.route
    if route is not None and route >= len(routes_of(demos, caches)):
        route = None  # the demonstrations changed since that way was chosen
    skill = learn_skill(demos, replace(settings, route=route), arm=arm, baxter=baxter, caches=caches)
    return LearnedSkill(skill, note=wanted.why_not if wanted is not None else "")


def judge(
    skill: Skill,
    demos: Sequence[Demo],
    objects: TaughtObjects | None = None,
    settings: LearnSettings = _DEFAULT,
    *,
    arm: Arm | None = None,
    baxter: Baxter | None = None,
    caches: LearningCaches | None = None,
    stopping: Callable[[], bool] | None = None,
) -> Judgement:
    """How good ``skill`` is against the demonstrations it learned from (in the skill's order, as taught):
    held out (at most ``settings.folds`` demos left out in turn, learned again the same way; with the skill's
    k when ``settings.n_clusters`` was chosen by hand), the report and its verdict.

    A skill that follows the objects is judged where the demonstrations had them (the one nearest the middle
    of their places, never where the objects stand now): its path placed there against the demonstrations
    moved there, each stretch with its object, and each stretch measured in its own frame. When the objects do
    not allow that (one is missing, the arm cannot follow it there) it is judged in the robot's frame.

    ``stopping()`` true (the caller no longer wants the verdict) raises :class:`Cancelled` before the next
    held-out fold.
    """
    caches = caches or LearningCaches()
    demos = list(demos)
    objs = objects.demos if objects is not None and skill.frames is not None else ()
    if objs:
        rules = objects.rules if objects is not None else None
        framed = _judge_in_frames(skill, demos, objs, rules, settings.folds, arm, baxter, stopping)
        if framed is not None:
            return framed
    return _judge_in_robot_frame(skill, demos, settings, caches, stopping)


def _go_on(stopping: Callable[[], bool] | None) -> None:
    """Raise :class:`Cancelled` when the caller no longer wants the result."""
    if stopping is not None and stopping():
        raise Cancelled


def _judge_in_robot_frame(
    skill: Skill,
    demos: list[Demo],
    settings: LearnSettings,
    caches: LearningCaches,
    stopping: Callable[[], bool] | None,
) -> Judgement:
    held = None
    if len(demos) >= 2:
        k = skill.n_clusters if settings.n_clusters is not None else None

        def learn_without(dd: list[Demo]) -> Demo:
            _go_on(stopping)
            kk = None if k is None else min(k, sum(len(x) for x in skill.keypoints))
            again = LearnSettings(params=skill.params, n_clusters=kk, generalization=skill.generalization)
            return learn_path(dd, again, caches=caches)

        try:
            held = quality.held_out(demos, learn_without, folds=list(range(min(len(demos), settings.folds))))
        except StudioError:
            held = None
    report = quality.assess(skill, demos, held_out_result=held)
    return Judgement(report, quality.verdict(report), quality.demo_fits(report))


def _judge_in_frames(
    skill: Skill,
    demos: list[Demo],
    objs: tuple[DemoObjects, ...],
    rules: Mapping[int, str] | None,
    folds: int,
    arm: Arm | None,
    baxter: Baxter | None,
    stopping: Callable[[], bool] | None,
) -> Judgement | None:
    assert skill.frames is not None
    _, choices, _ = choose_frames(objs, rules)
    now = taught_placement(objs)
    moved = demos_in_frames(demos, objs, now, skill.frames)
    if moved is None:
        return None
    try:  # where the demonstrations had the objects: the arm's reach is judged there too
        placed = place_skill(skill, now, arm=arm, baxter=baxter)
    except StudioError:  # an object the skill needs is missing from them, or the arm cannot follow it there
        return None
    again = LearnSettings(params=skill.params, generalization=skill.generalization)

    def learn_without(dd: list[Demo]) -> Demo:
        _go_on(stopping)
        keep = [i for i, m in enumerate(moved) if any(m is d for d in dd)]
        parts = [demos[i] for i in keep]
        return learn_relative(parts, [objs[i] for i in keep], again, now=now, rules=rules).trajectory

    held = quality.held_out(moved, learn_without, folds=list(range(min(len(moved), folds))))
    report = quality.assess(placed, moved, held_out_result=held)
    fits = quality.demo_fits(report)
    return Judgement(report, quality.verdict(report), fits, segment_fits(skill.frames, demos, objs), choices)


__all__ = ["Judgement", "LearnedSkill", "TaughtObjects", "judge", "learn", "learn_and_judge"]
