"""Skills that follow the objects, through the controller without a browser: trained from takes with the objects
in different places (the scripted teacher driving the simulated robot through the recorder), previewed with the
objects somewhere new, said when an object stands where no take put it, and the paper's fixed places as the other
choice."""

from __future__ import annotations

import re

import numpy as np
import pytest

from studio.controller import Controller, Step
from studio.core.quality.judgement import Close
from studio.robot_backend.simulated import SimulatedBaxter
from studio.teacher import Place, Places, teach
from studio.words import frame_lines, segment_lines
from studio.words.quality import STUDIO_REMEDIES, verdict_lines
from studio.world import preset, simulate
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
    said = verdict_lines(judged.verdict, STUDIO_REMEDIES)
    assert isinstance(judged.verdict.headline, Close), said  # measured in the robot's frame: far (decision 081)
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


# -- issue 27: the skill judged by the task's goal, taught at one place ----------------------------------------------
def record_once(ctl: Controller, sim: SimulatedBaxter, seed: int, hand: Places) -> None:
    """A newcomer's take of pick-place: the block onto the pad, then home (``hand``: where the hand acts; the
    objects stay where the scene has them)."""
    plan = teach("pick-place", seed, places=hand, once=True)
    sim.teleport(plan.q[0], plan.gripper[0])
    sim.step(20)
    ctl.teaching.start_recording()
    sim.run_targets(plan.q, plan.gripper, batch=16)
    ctl.teaching.stop_recording()


def where_the_block_ended(ctl: Controller) -> tuple[str | None, float]:
    """What the preview really does with the block: the joints Play plays, through the world (forward kinematics);
    what it ended on and how far (m) from the pad's centre."""
    rec = ctl.playback.preview_recording()
    run = simulate(rec.t, rec.q, rec.gripper, ctl.scene.scene, baxter=ctl.baxter)
    block = next(p for p in run.final if p.name == "block")
    pad = next(p for p in run.final if p.name == "pad")
    return block.on, float(np.hypot(block.position[0] - pad.position[0], block.position[1] - pad.position[1]))


def test_taught_at_one_place_the_preview_never_claims_the_task_when_the_block_is_not_on_the_pad(rig) -> None:
    """Three takes at one placement, one of which let the block go 7 cm from the pad's centre: the release
    follows the pad (said in Train), and wherever the block or the pad is moved, no preview claims the task
    while the block did not end on the pad; the words say where it ended."""
    ctl, sim = rig
    ctl.sessions.new("one place", scene="pick-place")
    for seed, hand in ((1, Places()), (2, Places(put=Place(0.07, 0.0, 0.0))), (3, Places())):
        record_once(ctl, sim, seed, hand)
    goal = ctl.scene.goal()
    assert goal.source == "set-up" and [(p.object, p.onto) for p in goal.placements] == [("block", "pad")]
    train(ctl)
    skill = ctl.session.skills["left"]
    assert skill.frames is not None and [b.role for b in skill.frames.borders] == ["object:block", "object:pad"]
    assert wait_for(lambda: "left" in ctl.training.verdicts() and not ctl.training.judging)
    said = frame_lines(ctl.training.verdicts()["left"].choices)
    assert said == (
        "Every demonstration had the block in the same place: I will follow the block for the grasp and the pad for "
        "the release. Show me one more with the block somewhere else to be sure.",
    )
    assert ctl.placed.suggestion().startswith("Move the block somewhere else")  # the same object as above
    block, pad = ctl.scene.scene.object("block"), ctl.scene.scene.object("pad")
    moves = [("block", 0.0, 0.08), ("block", -0.1, 0.15), ("block", 0.0, 0.37), ("pad", 0.05, 0.1)]
    claims = []
    for name, dx, dy in moves:
        o = block if name == "block" else pad
        ctl.scene.move(name, (o.position[0] + dx, o.position[1] + dy, o.position[2]))
        result = ctl.scene.task_result()
        assert result is not None
        on, d = where_the_block_ended(ctl)
        claims.append((name, dy, result.ok, on, round(d, 3)))
        assert result.ok == (on == "pad"), (result.text, on, d)
        if result.ok:
            assert re.fullmatch(r"The block ended on the pad, [\d.]+ cm from its centre\.", result.text), result.text
            assert d < 0.05
        else:
            assert "did not do the task" in result.text or "never picked up" in result.text, result.text
        ctl.scene.move(name, o.position, o.yaw)
    assert sum(c[2] for c in claims) >= 2, claims  # the block moved within reach, and the pad moved: done
    # Run on the robot with the block moved: the words agree with where the block really ended (the live world,
    # driven by the robot's joint states).
    ctl.scene.move("block", (block.position[0], block.position[1] + 0.08, block.position[2]))
    ok, text, on = run_on_robot(ctl, sim)
    assert ok and on == "pad" and text.endswith("— the skill works."), text
    # The paper's fixed places with the pad moved: the run misses, and says so.
    ctl.scene.move("block", block.position, block.yaw)
    ctl.training.set_frames("robot")
    train(ctl)
    ctl.scene.move("pad", (pad.position[0] + 0.05, pad.position[1] + 0.1, pad.position[2]))
    result = ctl.scene.task_result()
    assert result is not None and not result.ok and where_the_block_ended(ctl)[0] != "pad", result.text
    ok, text, on = run_on_robot(ctl, sim)
    assert not ok and on != "pad" and "the skill works" not in text and "did not do the task" in text, text


def run_on_robot(ctl: Controller, sim: SimulatedBaxter) -> tuple[bool, str, str | None]:
    """Run on robot (the simulated robot stepped to the end): whether the run says it works, its words, and what
    the block really ended on."""
    ctl.execution.run()
    while sim.progress().active:
        sim.step(200)
    assert wait_for(lambda: not ctl.execution.running, 60)
    st = ctl.execution.status
    block = next(p for p in ctl.scene.live.poses() if p.name == "block")
    return bool(st.ok), st.result, block.on


def test_good_stays_good_when_only_an_object_moved(rig) -> None:
    """The verdict judges the skill against the demonstrations where they had the objects, not today's scene."""
    ctl, _ = rig
    train(ctl)

    def verdict() -> tuple[str, float]:
        assert wait_for(lambda: "left" in ctl.training.verdicts() and not ctl.training.judging, 120)
        v = ctl.training.verdicts()["left"].verdict
        assert v is not None
        return str(v.level), float(v.headline.distance)

    before = verdict()
    bottom = ctl.scene.scene.object("bottom cup")
    ctl.scene.move("bottom cup", (bottom.position[0] - 0.12, bottom.position[1] - 0.1, bottom.position[2]))
    ctl.training.judge().result(timeout=120)
    assert verdict() == before
    train(ctl)  # learned again with the cup elsewhere: judged where the demonstrations had it, as before
    again = verdict()
    assert again[0] == before[0] and again[1] == pytest.approx(before[1], abs=0.002)
