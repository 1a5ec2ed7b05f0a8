"""The pace of the skill in the controller: "Remove pauses" learns from demonstrations with their long rests
shortened, and the skill speed retimes what Preview, the task result and Run on robot play."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from studio.controller import Controller, Topic
from studio.core.errors import StudioError
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore
from tests.conftest import RecordingNotifier


@pytest.fixture
def ctl(sessions: Path) -> Iterator[Controller]:
    sim = SimulatedBaxter()
    c = Controller(store=SessionStore(sessions), session="stack-cup", backend=sim, notifier=RecordingNotifier())
    c.start()
    sim.stop()
    yield c
    c.close()
    c.shutdown()


def test_removing_pauses_makes_a_shorter_skill_that_still_does_the_task(ctl: Controller) -> None:
    ctl.training.train().result()
    taught = ctl.playback.preview_duration()
    result = ctl.scene.task_result()
    assert result is not None and result.ok
    told: list[bool] = []
    ctl.events.on(Topic.TRAINING, lambda: told.append(ctl.training.remove_pauses))
    ctl.training.set_remove_pauses(True)
    assert told == [True]
    ctl.training.train().result()
    brisk = ctl.playback.preview_duration()
    assert brisk < taught * 0.9, (brisk, taught)  # the scripted teacher rests at each grasp and release
    result = ctl.scene.task_result()
    assert result is not None
    assert result.ok, result.text


def test_the_skill_speed_retimes_preview_and_run_within_the_limits(ctl: Controller) -> None:
    ctl.training.train().result()
    taught = ctl.playback.preview_duration()
    skills: list[int] = []
    ctl.events.on(Topic.SKILL, lambda: skills.append(1))
    ctl.placed.set_speed(2.0)
    assert skills == [1]
    fast = ctl.playback.preview_duration()
    assert taught / 2 - 0.5 <= fast < taught * 0.8
    assert all(f.ok for f in ctl.execution.feasibility().values())
    result = ctl.scene.task_result()
    assert result is not None
    assert result.ok, result.text
    ctl.placed.set_speed(0.5)
    assert ctl.playback.preview_duration() == pytest.approx(2 * taught, rel=0.05)
    ctl.placed.set_speed(1.0)
    assert ctl.playback.preview_duration() == pytest.approx(taught)
    with pytest.raises(StudioError):
        ctl.placed.set_speed(20.0)
