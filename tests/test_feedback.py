"""Feedback at the grasp and after a change: a close in words (held, missed by how much, how much closer),
the task of each set-up, objects that stand elsewhere than when the demonstrations started, and the controller
telling them (the latest grasp of the live world, "Saving…" after Stop, a moved object for a fixed-places skill)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from studio.controller import Controller, Topic
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore
from studio.teacher import teach
from studio.words import count_words, grasp_words, moved_words, task_words
from studio.world import GRASP_XY_TOL, ObjectPose, Scene, WorldEvent, grasp_note, preset
from studio.world.moved import moved_objects
from tests.conftest import RecordingNotifier

CUP = ObjectPose("cup", "cup", (0.07, 0.07, 0.095), (0.7, 0.1, -0.2), (1.0, 0.0, 0.0, 0.0))


def miss_at(p: tuple[float, float, float], *poses: ObjectPose) -> WorldEvent:
    return WorldEvent(1.0, "miss", "left", None, p, poses or (CUP,))


def test_a_grasp_says_what_the_gripper_holds() -> None:
    note = grasp_note(WorldEvent(1.0, "grasp", "left", "cup", (0.7, 0.1, -0.14), (CUP,)))
    assert note is not None and note.held == "cup"
    assert grasp_words(note) == "Holding the cup."


def test_a_miss_three_cm_to_the_side_says_by_how_much_and_how_much_closer() -> None:
    note = grasp_note(miss_at((0.73, 0.1, -0.14)))  # 3 cm from the axis, at a holding height
    assert note is not None and note.held is None and note.near == "cup"
    assert note.distance == pytest.approx(0.03) and note.closer == pytest.approx(0.03 - GRASP_XY_TOL)
    assert note.height == 0.0
    assert note.toward == pytest.approx((-(0.03 - GRASP_XY_TOL), 0.0))
    assert grasp_words(note).startswith("Missed the cup by 3 cm — move 1 cm toward the robot,")


@pytest.mark.parametrize(
    ("gripper", "way"),
    [
        ((0.7, 0.1 - 0.06, -0.14), "move 3.5 cm to the robot's left"),  # the cup is to the robot's left
        ((0.7, 0.1 + 0.045, -0.14), "move 2 cm to the robot's right"),
        ((0.7 - 0.045, 0.1, -0.14), "move 2 cm away from the robot"),
        ((0.7 + 0.04, 0.1 - 0.04, -0.14), "toward the robot and 2.2 cm to its left"),
    ],
)
def test_a_miss_says_which_way_in_the_rooms_terms(gripper: tuple[float, float, float], way: str) -> None:
    note = grasp_note(miss_at(gripper))
    assert note is not None and note.near == "cup"
    assert np.hypot(*note.toward) == pytest.approx(note.closer)  # the move asked for is the one that reaches it
    words = grasp_words(note)
    assert way in words and "closer" not in words, words


def test_a_miss_above_the_cup_says_lower_it() -> None:
    note = grasp_note(miss_at((0.7, 0.1, -0.2 + 0.095 + 0.015 + 0.05)))  # 5 cm above the band it holds in
    assert note is not None and note.closer == 0.0 and note.height == pytest.approx(0.05)
    assert grasp_words(note) == "Missed the cup: the gripper is 5 cm too high — lower it 5 cm, then close it again."


def test_a_miss_picks_the_nearest_free_object_and_skips_held_and_flat_ones() -> None:
    far = ObjectPose("block", "block", (0.05, 0.05, 0.05), (0.9, 0.1, -0.2), (1.0, 0.0, 0.0, 0.0))
    held = ObjectPose("held", "cup", (0.07, 0.07, 0.095), (0.7, 0.1, -0.2), (1.0, 0.0, 0.0, 0.0), held_by="right")
    pad = ObjectPose("pad", "pad", (0.12, 0.12, 0.004), (0.7, 0.1, -0.2), (1.0, 0.0, 0.0, 0.0))
    note = grasp_note(miss_at((0.75, 0.1, -0.15), far, held, pad))
    assert note is not None and note.near == "block"
    nothing = grasp_note(miss_at((0.7, 0.1, -0.15), held, pad))
    assert nothing is not None and nothing.near is None and "nothing" in grasp_words(nothing)
    assert grasp_note(WorldEvent(0.0, "start", None, None, None, (CUP,))) is None


def test_each_set_up_has_a_task_in_words() -> None:
    assert task_words("stack-cup").startswith("Take the cup I hand you") and "into the other cup" in task_words(
        "stack-cup"
    )
    assert "block" in task_words("pick-place")
    assert task_words(None) == task_words("my own") != task_words("empty table")


def test_counts_say_one_or_many() -> None:
    assert count_words(1, "demonstration") == "1 demonstration"
    assert count_words(3, "demonstration") == "3 demonstrations"
    assert count_words(0, "key-point") == "0 key-points"


def test_moved_objects_are_measured_from_where_the_demonstrations_started() -> None:
    scene = preset("stack-cup")
    start = tuple(
        ObjectPose(o.name, o.kind, o.size, o.position, (1.0, 0.0, 0.0, 0.0), on="table") for o in scene.objects
    )
    assert moved_objects([start, start], scene) == []
    bottom = scene.objects[0]
    moved = scene.move(bottom.name, (bottom.position[0] + 0.115, bottom.position[1], bottom.position[2]))
    (name, d), *rest = moved_objects([start, start], moved)
    assert name == bottom.name and d == pytest.approx(0.115, abs=1e-6) and rest == []
    assert moved_words(name, d).startswith(
        f"The {name} is 12 cm from where it stood when you taught; your skill repeats"
    )
    assert moved_objects([], moved) == [] and moved_objects([start], Scene()) == []


# -- the controller ----------------------------------------------------------------------------------------
def test_the_live_world_tells_the_latest_grasp_until_the_gripper_opens(rig) -> None:
    """ "Holding the cup." is true while the gripper holds it: through Stop and Home, and no longer once the
    gripper opens."""
    ctl, sim = rig
    assert ctl.scene.last_grip() is None
    plan = teach("stack-cup", 0)
    opened = plan.event_poses("open")[0].time
    n = int(np.searchsorted(plan.t, opened - 0.3))  # carried to the stack, the gripper still closed
    sim.teleport(plan.q[0], plan.gripper[0])
    sim.step(20)
    ctl.teaching.start_recording()
    sim.run_targets(plan.q[:n], plan.gripper[:n], batch=16)
    grip = ctl.scene.last_grip()
    assert grip is not None and grip[0].kind == "grasp"
    ev, note = grip
    assert grasp_words(note) == f"Holding the {ev.object}." and ctl.scene.last_grip()[0] is ev
    ctl.teaching.stop_recording()  # Stop: it still holds the cup, and says so
    assert ctl.scene.last_grip() is not None and ctl.scene.live.held("left") == ["cup"]
    ctl.guide.home()  # Home: the arm goes home with the cup
    sim.step(3000)
    assert ctl.scene.last_grip() is not None and ctl.scene.live.held("left") == ["cup"]
    ctl.teaching.set_gripper("left", 100.0)  # Open: it lets go, and no longer says it holds it
    sim.step(1000)
    assert ctl.scene.live.held("left") == []
    assert ctl.scene.last_grip() is None
    assert [e.kind for e in ctl.scene.live.events if e.kind in ("grasp", "release")] == ["grasp", "release"]


def test_stop_says_saving_until_the_take_is_kept(rig) -> None:
    ctl, sim = rig
    seen: list[tuple[bool, bool]] = []
    ctl.events.on(Topic.RECORDING, lambda: seen.append((ctl.teaching.recording, ctl.teaching.saving)))
    ctl.teaching.start_recording(by="tab-1")
    sim.step(200)
    ctl.teaching.start_recording(by="tab-1")  # a double click on Record: the take goes on, no error
    with pytest.raises(Exception, match="in another browser tab"):
        ctl.teaching.start_recording(by="tab-2")
    ctl.teaching.stop_recording()
    assert seen == [(True, False), (False, True), (False, False)]
    assert not ctl.teaching.saving


def test_a_fixed_places_skill_names_the_object_that_moved(rig) -> None:
    ctl, _ = rig
    ctl.training.set_frames("robot")
    ctl.training.train().result()
    assert ctl.session.skills and all(s.frames is None for s in ctl.session.skills.values())
    assert not any("repeats the taught motion" in w for w in ctl.placed.warnings())
    bottom = next(o for o in ctl.scene.scene.objects if o.name.startswith("bottom"))
    ctl.scene.move(bottom.name, (bottom.position[0] + 0.115, bottom.position[1], bottom.position[2]))
    said = [w for w in ctl.placed.warnings() if "repeats the taught motion" in w]
    assert len(said) == 1 and said[0].startswith(f"The {bottom.name} is 1")
    ctl.training.set_frames("objects")
    ctl.training.train().result()  # a skill that follows the objects: never "repeats the taught motion"
    assert all(s.frames is not None for s in ctl.session.skills.values())
    assert not any("repeats the taught motion" in w for w in ctl.placed.warnings())
    assert np.isfinite(bottom.position[0])


def test_a_discarded_take_can_be_brought_back_with_its_objects(rig) -> None:
    ctl, sim = rig
    n = len(ctl.session.recordings)
    plan = teach("stack-cup", 1)
    sim.teleport(plan.q[0], plan.gripper[0])
    sim.step(20)
    ctl.teaching.start_recording()
    sim.run_targets(plan.q, plan.gripper, batch=16)
    assert ctl.teaching.discard_recording() is True
    assert len(ctl.session.recordings) == n and ctl.undo.what.startswith('"demo')
    ctl.undo.undo()
    assert len(ctl.session.recordings) == n + 1
    events = ctl.session.objects.events(ctl.session.demo_files[-1])
    assert [e.kind for e in events if e.kind in ("grasp", "release")] == ["grasp", "release"]


def test_suggest_names_a_threshold_of_the_teacher_it_replaced(rig) -> None:
    ctl, _ = rig
    ctl.keypoints.set_param("eps5", 0.5)  # travel distance far too long: hardly a key-point
    ctl.suggest.workers = 1
    ctl.suggest.start().result()
    st = ctl.suggest.state
    assert st.result is not None and st.result.changed, st.summary
    assert st.replaced == ("eps5",) and st.can_undo
    said = ("instead of", "the same number of key-points", "do exactly as well as yours")
    assert any(w in st.summary for w in said), st.summary
    ctl.suggest.undo()
    assert ctl.suggest.state.replaced == () and ctl.keypoints.params().eps5 == pytest.approx(0.5)


def test_a_bundled_example_stays_as_it_is_and_a_named_copy_changes(sessions: Path) -> None:
    from studio.storage import ReadOnly

    manifest = (sessions / "stack-cup" / "session.json").read_bytes()
    sim = SimulatedBaxter()
    store = SessionStore(sessions, examples=("stack-cup",))
    ctl = Controller(store=store, session="stack-cup", backend=sim, notifier=RecordingNotifier())
    ctl.start()
    sim.stop()
    try:
        assert ctl.session.read_only
        with pytest.raises(ReadOnly, match="Duplicate"):
            ctl.teaching.start_recording()
        assert not ctl.teaching.recording
        with pytest.raises(ReadOnly):
            ctl.training.train()
        bottom = ctl.scene.scene.object("bottom cup")
        with pytest.raises(ReadOnly):
            ctl.scene.move("bottom cup", (bottom.position[0] + 0.1, bottom.position[1], bottom.position[2]))
        with pytest.raises(ReadOnly):
            ctl.demos.delete(0)
        with pytest.raises(ReadOnly):
            ctl.sessions.save()
        ctl.keypoints.set_param("eps5", 0.05)  # tried in memory; never written into the example
        ctl.keypoints.persist(force=True)
        ctl.sessions.duplicate("my stack-cup")  # the copy the teacher names is theirs to change
        assert ctl.session.name == "my stack-cup" and not ctl.session.read_only
        ctl.scene.move("bottom cup", (bottom.position[0] + 0.1, bottom.position[1], bottom.position[2]))
        ctl.teaching.start_recording()
        sim.step(100)
        ctl.teaching.stop_recording()
        assert len(ctl.session.recordings) == 4
        ctl.sessions.open("stack-cup")
        assert ctl.session.read_only and len(ctl.session.recordings) == 3
    finally:
        ctl.close()
        ctl.shutdown()
    assert (sessions / "stack-cup" / "session.json").read_bytes() == manifest


def test_a_preview_of_before_the_objects_moved_is_unloaded(rig) -> None:
    from studio.controller import PREVIEW

    ctl, _ = rig
    ctl.training.train().result()
    ctl.playback.play_preview()
    assert ctl.playback.kind == PREVIEW
    bottom = ctl.scene.scene.object("bottom cup")
    ctl.scene.move("bottom cup", (bottom.position[0] + 0.05, bottom.position[1], bottom.position[2]))
    assert ctl.playback.kind is None and ctl.display.is_live
