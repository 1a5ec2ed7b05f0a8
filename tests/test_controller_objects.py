"""Skills that follow the objects, through the controller without a browser: trained from takes with the objects
in different places (the scripted teacher driving the simulated robot through the recorder), previewed with the
objects somewhere new, said when an object stands where no take put it, and the paper's fixed places as the other
choice."""

from __future__ import annotations

import numpy as np

from studio.controller import Controller, Step
from studio.core.quality import Issue
from studio.panels.train import REMEDIES
from studio.robot_backend.simulated import SimulatedBaxter
from studio.teacher import Place, Places, teach
from studio.words import segment_lines, verdict_lines
from studio.world import preset
from tests.conftest import wait_for


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
    assert "ended in the bottom cup" in result.text
    assert ctl.placed.warnings() == []
    assert "one place only" in ctl.placed.note()
    # Moved 6 cm: said before the run, in words, and the skill still follows the bottom cup.
    bottom = ctl.scene.scene.object("bottom cup")
    ctl.scene.move("bottom cup", (bottom.position[0], bottom.position[1] - 0.06, bottom.position[2]))
    said = ctl.placed.warnings()
    assert len(said) == 1 and said[0].startswith("You never showed me the bottom cup this far to the robot's right")
    assert wait_for(lambda: (r := ctl.scene.task_result()) is not None and "ended in the bottom cup" in r.text)
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
    # The key-point view draws the takes as the skill learns them: each stretch relative to its object, with the
    # objects where they are now (about the last take's places); the paper's fixed places draw them as recorded.
    shown = ctl.demos.for_arm("left")

    def view_in(framed: frozenset) -> bool:
        v = ctl.keypoints.view
        return v is not None and v.in_frames == framed and len(v.demos) == 3

    def moved() -> list[float]:
        view = ctl.keypoints.view
        assert view is not None and "left" in view.centroids
        return [
            float(np.max(np.linalg.norm(it.points - d.position[view.indices["left"][n]], axis=1)))
            for n, (it, (_, d)) in enumerate(zip(view.demos, shown, strict=True))
        ]

    def live_to_block() -> float:
        """How close the live dashed path comes to the block where it stands now (x, y), once it follows the
        current view."""

        def current() -> bool:
            v, p = ctl.keypoints.view, ctl.live.paths.get("left")
            return v is not None and p is not None and p.version == v.version

        assert wait_for(current, 60)
        block = np.asarray(ctl.scene.scene.object("block").position[:2])
        return float(np.min(np.linalg.norm(ctl.live.paths["left"].position[:, :2] - block, axis=1)))

    ctl.view.set_step(Step.KEYPOINTS)
    assert wait_for(lambda: view_in(frozenset({"left"})))
    far = moved()
    assert far[2] < 0.01 and min(far[:2]) > 0.03, far
    near = live_to_block()  # the live path is learned from the takes as drawn: it reaches the block
    ctl.training.set_frames("robot")
    assert wait_for(lambda: view_in(frozenset()))
    assert max(moved()) == 0.0
    assert near < 0.01 and live_to_block() > 2 * near + 0.01, (near, live_to_block())
    ctl.training.set_frames("objects")
    assert wait_for(lambda: view_in(frozenset({"left"})))
    train(ctl)
    skill = ctl.session.skills["left"]
    assert skill.frames is not None and not skill.frames.one_place()
    assert [b.role for b in skill.frames.borders] == ["object:block", "object:pad", "object:block", "start:block"]
    # The verdict: judged against the takes moved with their objects, and each stretch in its own frame.
    assert wait_for(lambda: "left" in ctl.training.verdicts() and not ctl.training.judging)
    judged = ctl.training.verdicts()["left"]
    assert judged.verdict is not None, judged.message
    said = verdict_lines(judged.verdict, REMEDIES)
    assert judged.verdict.headline.issue is Issue.CLOSE, said  # measured in the robot's frame: far (decision 081)
    lines = segment_lines(judged.segments)
    assert [x.split(" (")[0] for x in lines] == [
        "Reaching for the block",
        "Carrying the block to the pad",
        "Going back to the block",
        "Carrying the block to where the block stood",
        "Moving away from the block",
    ]
    assert lines[0].startswith("Reaching for the block (relative to the block): within ") and "— good." in lines[0]
    # Somewhere inside the places shown: no warning, and the preview does the task there.
    set_objects(ctl, "pick-place", Places(Place(-0.03, -0.06, 0.1), Place(0.05, -0.02, 0.0)))
    assert ctl.placed.warnings() == []
    assert wait_for(lambda: (r := ctl.scene.task_result()) is not None and r.ok)
    # Far outside them: said.
    set_objects(ctl, "pick-place", Places(Place(0.0, 0.2, 0.0), Place(0.0, 0.0, 0.0)))
    said = ctl.placed.warnings()
    assert said and "You never showed me the block this far to the robot's left" in said[0]
    assert "Move the" in ctl.placed.suggestion()
