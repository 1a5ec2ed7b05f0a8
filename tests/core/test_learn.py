"""The use case "learn and judge a skill" (studio.core.learn): frames, the reason for fixed places, the verdict."""

from __future__ import annotations

import numpy as np
import pytest

from studio.core.errors import Cancelled
from studio.core.learn import TaughtObjects, judge, learn, learn_and_judge
from studio.core.learn_settings import LearnSettings
from tests.core.test_segments import taught


def test_learn_and_judge_follows_the_objects_and_judges_each_stretch_in_its_frame():
    demos, objs, _ = taught("pick-place")
    objects = TaughtObjects(tuple(objs))
    out = learn_and_judge(demos, objects)
    assert out.skill.frames is not None and out.note == ""
    j = out.judgement
    assert j is not None and j.verdict is not None
    assert len(j.segments) == len(out.skill.frames.borders) + 1  # one fit per stretch between grasps and releases
    assert len(j.fits) == len(demos)
    # its two halves give the same skill and the same verdict
    alone = learn(demos, objects)
    np.testing.assert_array_equal(alone.skill.trajectory.position, out.skill.trajectory.position)
    again = judge(alone.skill, demos, objects)
    assert again.verdict.level == j.verdict.level
    assert again.report.held_out is not None and j.report.held_out is not None
    assert again.report.held_out.per_demo == j.report.held_out.per_demo
    # a verdict nobody wants any more (the studio stops) stops before its next held-out fold
    asked: list[int] = []

    def stopping() -> bool:
        asked.append(1)
        return len(asked) > 1

    with pytest.raises(Cancelled):
        judge(alone.skill, demos, objects, stopping=stopping)
    assert len(asked) == 2


def test_fixed_places_when_asked_or_when_the_objects_do_not_allow_it_with_the_reason():
    demos, objs, _ = taught("pick-place")
    robot = learn_and_judge(demos, TaughtObjects(tuple(objs)), LearnSettings(frames="robot"))
    assert robot.skill.frames is None and robot.note == ""  # asked for: nothing to explain
    assert robot.judgement is not None and robot.judgement.segments == () and robot.judgement.choices == ()
    with pytest.raises(Cancelled):  # judged in the robot's frame, it stops as well
        judge(robot.skill, demos, stopping=lambda: True)
    why = "One demonstration has no objects."
    fixed = learn(demos, TaughtObjects(why_not=why))
    assert fixed.skill.frames is None and fixed.note == why
    np.testing.assert_array_equal(fixed.skill.trajectory.position, robot.skill.trajectory.position)
