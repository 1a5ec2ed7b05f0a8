"""Skills that follow the objects, through the controller without a browser: trained from takes with the objects
in different places (the scripted teacher driving the simulated robot through the recorder), previewed with the
objects somewhere new, said when an object stands where no take put it, and the paper's fixed places as the other
choice."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from studio.controller import Controller
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore
from studio.teacher import Place, Places, teach
from studio.world import preset
from tests.conftest import RecordingNotifier, wait_for


@pytest.fixture
def rig(sessions: Path) -> Iterator[tuple[Controller, SimulatedBaxter]]:
    sim = SimulatedBaxter()
    c = Controller(store=SessionStore(sessions), session="stack-cup", backend=sim, notifier=RecordingNotifier())
    c.start()
    sim.stop()  # manual steps from here on
    yield c, sim
    c.close()
    c.shutdown()


def set_objects(ctl: Controller, task: str, places: Places) -> None:
    for o in preset(task, ("left",), places).objects:
        ctl.scene.move(o.name, o.position, o.yaw)


def record(ctl: Controller, sim: SimulatedBaxter, task: str, seed: int, places: Places) -> None:
    set_objects(ctl, task, places)
    plan = teach(task, seed, places=places)
    sim.teleport(plan.q[0], plan.gripper[0])
    sim.step(20)
    ctl.teaching.start_recording()
    sim.run_targets(plan.q, plan.gripper, batch=16)
    ctl.teaching.stop_recording()


def train(ctl: Controller) -> None:
    ctl.training.train().result(timeout=120)
    assert wait_for(lambda: ctl.scene.task_result() is not None)


def test_a_skill_taught_in_one_place_works_there_and_says_it_has_seen_no_other(rig) -> None:
    ctl, _ = rig
    assert ctl.training.frames == "objects"  # the default (the example session has no skill yet)
    train(ctl)
    skill = ctl.session.skills["left"]
    assert skill.frames is not None and [b.role for b in skill.frames.borders] == ["object:cup", "object:bottom cup"]
    result = ctl.scene.task_result()
    assert result is not None and result.ok, result.text
    assert "ended on the bottom cup" in result.text
    assert ctl.placed.warnings() == []
    assert "one place only" in ctl.placed.note()
    # Moved 6 cm: said before the run, in words, and the skill still follows the bottom cup.
    bottom = ctl.scene.scene.object("bottom cup")
    ctl.scene.move("bottom cup", (bottom.position[0], bottom.position[1] - 0.06, bottom.position[2]))
    said = ctl.placed.warnings()
    assert len(said) == 1 and said[0].startswith("You never showed me the bottom cup this far to the robot's right")
    assert wait_for(lambda: (r := ctl.scene.task_result()) is not None and "ended on the bottom cup" in r.text)
    result = ctl.scene.task_result()
    assert result is not None and result.ok, result.text
    placed = ctl.placed.get()["left"]
    assert placed.joint_trajectory is not None and bool(np.all(placed.joint_trajectory.converged))


def test_the_papers_fixed_places_stay_a_choice(rig) -> None:
    ctl, _ = rig
    ctl.training.set_frames("robot")
    train(ctl)
    assert ctl.session.skills["left"].frames is None
    first = ctl.scene.task_result()
    assert first is not None and first.ok
    bottom = ctl.scene.scene.object("bottom cup")
    ctl.scene.move("bottom cup", (bottom.position[0], bottom.position[1] - 0.06, bottom.position[2]))
    assert wait_for(lambda: (r := ctl.scene.task_result()) is not None and not r.ok)
    # fixed places know no region, but say which object stands elsewhere than when you taught
    (said,) = ctl.placed.warnings()
    assert said.startswith("The bottom cup is 6 cm from where it stood when you taught; your skill repeats")


def test_takes_in_different_places_teach_a_skill_that_follows_the_objects(rig) -> None:
    ctl, sim = rig
    ctl.sessions.new("moving blocks", scene="pick-place")
    spots = [
        Places(Place(0.0, 0.0, 0.0), Place(0.0, 0.0, 0.0)),
        Places(Place(-0.1, -0.08, 0.4), Place(0.06, -0.1, -0.3)),
        Places(Place(0.08, -0.12, -0.3), Place(0.1, 0.05, 0.3)),
    ]
    for i, places in enumerate(spots):
        record(ctl, sim, "pick-place", i + 1, places)
    assert len(ctl.session.recordings) == 3
    train(ctl)
    skill = ctl.session.skills["left"]
    assert skill.frames is not None and not skill.frames.one_place()
    assert [b.role for b in skill.frames.borders] == ["object:block", "object:pad", "object:block", "start:block"]
    # Somewhere inside the places shown: no warning, and the preview does the task there.
    set_objects(ctl, "pick-place", Places(Place(-0.03, -0.06, 0.1), Place(0.05, -0.02, 0.0)))
    assert ctl.placed.warnings() == []
    assert wait_for(lambda: (r := ctl.scene.task_result()) is not None and r.ok)
    # Far outside them: said.
    set_objects(ctl, "pick-place", Places(Place(0.0, 0.2, 0.0), Place(0.0, 0.0, 0.0)))
    said = ctl.placed.warnings()
    assert said and "You never showed me the block this far to the robot's left" in said[0]
    assert "Move the" in ctl.placed.suggestion()
