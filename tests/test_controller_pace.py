"""The pace of the skill in the controller: each take is learned from its first motion to its last with its
pauses shortened (unless the teacher keeps them), and the skill speed retimes what Preview, the task result and
Run on robot play."""

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


def test_pauses_are_shortened_by_default_and_a_take_can_keep_them(ctl: Controller) -> None:
    ctl.training.train().result()
    brisk = ctl.placed.duration()
    assert ctl.playback.preview_duration() == brisk  # one length: what Preview plays
    result = ctl.scene.task_result()
    assert result is not None and result.ok, result
    clocks = [d.clock for d in ctl.demos.summaries()]
    assert all(c is not None for c in clocks)
    shortened = sum(c.removed + c.still_ends for c in clocks if c is not None)
    assert shortened > 1.0, clocks  # the scripted teacher rests at its start, grasps and releases
    for c, d in zip(clocks, ctl.demos.summaries(), strict=True):
        assert c is not None and c.duration < d.duration
    told: list[int] = []
    ctl.events.on(Topic.DEMOS, lambda: told.append(1))
    for i in range(len(clocks)):
        ctl.demos.set_keep_pauses(i, True)
    assert told and ctl.session.skills_stale
    assert all(d.clock is not None and d.clock.kept and d.clock.removed == 0 for d in ctl.demos.summaries())
    ctl.training.train().result()
    removed = sum(c.removed for c in clocks if c is not None)
    assert ctl.placed.duration() >= brisk + (0.3 * removed if removed > 1.0 else 0.0), (removed, brisk)
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
