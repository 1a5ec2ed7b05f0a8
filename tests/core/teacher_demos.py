"""Scripted demonstrations shared by the core tests (built once per test session)."""

from __future__ import annotations

from functools import lru_cache

from studio.core.kinematics import Baxter
from studio.core.pipeline import demo_from_recording
from studio.core.types import Demo
from studio.teacher import TeacherPlan, recording_from_plan, teach


@lru_cache(maxsize=16)
def plans(task: str, seeds: tuple[int, ...] = (0, 1, 2)) -> tuple[TeacherPlan, ...]:
    return tuple(teach(task, s) for s in seeds)


@lru_cache(maxsize=16)
def demos(task: str, seeds: tuple[int, ...] = (0, 1, 2)) -> tuple[Demo, ...]:
    b = Baxter.load()
    return tuple(demo_from_recording(recording_from_plan(p), "left", b) for p in plans(task, seeds))
