"""Scripted demonstrations shared by the core tests (built once per test session)."""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

from studio.core.kinematics import Baxter
from studio.core.learn_settings import LearnSettings
from studio.core.pipeline import demo_from_recording
from studio.core.types import ARMS, Arm, Demo, Recording, Skill
from studio.teacher import TeacherPlan, recording_from_plan, teach


@lru_cache(maxsize=16)
def plans(task: str, seeds: tuple[int, ...] = (0, 1, 2)) -> tuple[TeacherPlan, ...]:
    return tuple(teach(task, s) for s in seeds)


@lru_cache(maxsize=16)
def demos(task: str, seeds: tuple[int, ...] = (0, 1, 2)) -> tuple[Demo, ...]:
    b = Baxter.load()
    return tuple(demo_from_recording(recording_from_plan(p), "left", b) for p in plans(task, seeds))


def skills_of(
    recordings: Sequence[Recording],
    settings: LearnSettings | None = None,
    baxter: Baxter | None = None,
    arms: Sequence[Arm] = ARMS,
) -> dict[Arm, Skill]:
    """One skill per arm of ``arms`` taught in ``recordings`` (with its joint trajectory), each learned by the
    core's use case from the recordings that teach that arm."""
    from studio.core.learn import learn

    b = baxter or Baxter.load()
    out: dict[Arm, Skill] = {}
    for arm in arms:
        arm_demos = [demo_from_recording(r, arm, b) for r in recordings if arm in r.arms]
        if arm_demos:
            out[arm] = learn(arm_demos, None, settings or LearnSettings(), arm=arm, baxter=b).skill
    return out
