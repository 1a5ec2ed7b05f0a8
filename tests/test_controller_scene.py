"""The controller's task scene without a browser: set-up edits saved with the session, a new session on a
preset, takes that keep their object events (the scripted teacher driving the simulated robot through the
recorder), replay and preview moving the objects, trim replaying the objects, and the task result."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from studio.controller import PREVIEW, REPLAY, Controller, Topic
from studio.core.errors import StudioError
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore
from studio.teacher import teach
from studio.world import Scene, simulate


def record_plan(ctl: Controller, sim: SimulatedBaxter, task: str, seed: int) -> int:
    plan = teach(task, seed)
    sim.teleport(plan.q[0], plan.gripper[0])
    sim.step(20)
    ctl.teaching.start_recording()
    sim.run_targets(plan.q, plan.gripper, batch=16)
    ctl.teaching.stop_recording()
    return len(ctl.session.recordings) - 1


def test_an_older_session_opens_on_an_empty_table(rig, sessions: Path) -> None:
    ctl, _ = rig
    assert ctl.scene.scene.preset == "stack-cup" and len(ctl.scene.live.poses()) == 2  # the example's objects
    # The same session as a studio of format 1 wrote it: no scene, no object events.
    old = sessions / "stack-cup old"
    shutil.copytree(sessions / "stack-cup", old)
    raw = json.loads((old / "session.json").read_text())
    raw["version"] = 1
    del raw["scene"]
    for d in raw["demos"]:
        del d["objects"]
    (old / "session.json").write_text(json.dumps(raw))
    ctl.sessions.open("stack-cup old")
    assert ctl.scene.scene == Scene() and ctl.scene.live.poses() == ()
    assert all(ctl.session.objects.events(f) == () for f in ctl.session.demo_files)
    assert len(ctl.session.recordings) == 3


def test_add_move_remove_are_saved_and_refused_while_recording(rig, sessions: Path) -> None:
    ctl, _ = rig
    ctl.sessions.new("objects")  # an empty table
    seen: list[int] = []
    ctl.events.on(Topic.SCENE, lambda: seen.append(len(ctl.scene.scene.objects)))
    cup = ctl.scene.add("cup")
    block = ctl.scene.add("block")
    assert (cup, block) == ("cup", "block") and seen == [1, 2]
    a, b = ctl.scene.scene.objects
    assert np.hypot(a.position[0] - b.position[0], a.position[1] - b.position[1]) >= 0.12  # not on top
    assert a.position[2] == pytest.approx(-0.07)  # on the table
    ctl.scene.move("cup", (0.7, 0.3, 0.2), yaw=0.5)  # let go in the air: it settles on the table
    assert ctl.scene.scene.object("cup").position == pytest.approx((0.7, 0.3, -0.07))
    assert ctl.scene.live.poses()[0].position == pytest.approx((0.7, 0.3, -0.07))
    ctl.scene.remove("block")
    raw = json.loads((sessions / "objects" / "session.json").read_text())
    assert [o["name"] for o in raw["scene"]["objects"]] == ["cup"]
    with pytest.raises(StudioError, match="cup, a block or a pad"):
        ctl.scene.add("piano")
    ctl.teaching.start_recording()
    with pytest.raises(StudioError, match="Stop the recording"):
        ctl.scene.add("pad")
    ctl.teaching.discard_recording()


def test_a_new_session_starts_on_the_chosen_preset(rig, sessions: Path) -> None:
    ctl, _ = rig
    ctl.sessions.new("my blocks", scene="pick-place")
    assert ctl.session.name == "my blocks"
    assert sorted(o.name for o in ctl.scene.scene.objects) == ["block", "pad"]
    assert sorted(p.name for p in ctl.scene.live.poses()) == ["block", "pad"]
    assert SessionStore(sessions).open("my blocks").objects.scene.preset == "pick-place"
    with pytest.raises(StudioError, match="Unknown scene"):
        ctl.sessions.new("other", scene="a kitchen")
    assert "other" not in ctl.sessions.names()


def test_a_take_keeps_its_object_events_and_replay_moves_the_objects(rig, sessions: Path) -> None:
    ctl, sim = rig
    ctl.sessions.new("pp", scene="pick-place")
    i = record_plan(ctl, sim, "pick-place", 0)
    rec = ctl.session.recordings[i]
    events = ctl.session.objects.events(ctl.session.demo_files[i])
    kinds = [(e.kind, e.object) for e in events]
    assert kinds[0] == ("start", None) and kinds[-1] == ("end", None)
    assert [k for k in kinds if k[0] in ("grasp", "release")] == [
        ("grasp", "block"),
        ("release", "block"),
        ("grasp", "block"),
        ("release", "block"),
    ]
    assert 0.0 <= events[1].t <= events[-1].t == pytest.approx(rec.duration)
    # On the recording's clock: replaying the recorded samples gives the same events at the same times.
    again = simulate(rec.t, rec.q, rec.gripper, ctl.scene.scene, start=events[0].poses)
    assert [(e.kind, e.object) for e in again.events] == kinds
    assert [e.t for e in again.events[1:-1]] == pytest.approx([e.t for e in events[1:-1]], abs=0.01)
    first_release = next(e for e in events if e.kind == "release")
    assert first_release.pose("block").on == "pad"
    # Saved with the demonstration.
    stored = SessionStore(sessions).open("pp")
    assert stored.objects.events(stored.demo_files[i]) == events
    # Replay: the objects follow the moment shown, forwards and backwards.
    t_on_pad = first_release.t + 0.3
    ctl.playback.seek(REPLAY, t_on_pad, rec, lambda: rec)
    _, poses = ctl.scene.shown()
    assert poses[1].name == "block" and poses[1].on == "pad"
    ctl.playback.seek(REPLAY, 0.5, rec, lambda: rec)
    _, poses = ctl.scene.shown()
    assert poses[1].position == pytest.approx(events[0].pose("block").position, abs=1e-6)
    ctl.playback.stop(REPLAY)
    key, _ = ctl.scene.shown()
    assert key[0] == id(ctl.scene.live)


def test_each_take_starts_with_the_objects_set_up_and_trim_replays_them(rig) -> None:
    ctl, sim = rig
    ctl.sessions.new("pp", scene="pick-place")
    record_plan(ctl, sim, "pick-place", 0)
    block_after = ctl.scene.live.poses()[1].position  # left where the take ended (back at A, roughly)
    ctl.scene.move("block", (0.55, -0.2, -0.07))  # moved elsewhere: the next take starts from the new set-up
    i = record_plan(ctl, sim, "pick-place", 1)
    ev = ctl.session.objects.events(ctl.session.demo_files[i])
    assert ev[0].pose("block").position == pytest.approx((0.55, -0.2, -0.07))
    assert block_after != ev[0].pose("block").position
    # Trim the first demonstration to start while the block is held: it starts in the gripper.
    events = ctl.session.objects.events(ctl.session.demo_files[0])
    grasp, release = [e for e in events if e.kind in ("grasp", "release")][:2]
    rec = ctl.session.recordings[0]
    ctl.demos.trim(0, (grasp.t + release.t) / 2, rec.duration)
    trimmed = ctl.session.objects.events(ctl.session.demo_files[0])
    assert trimmed[0].t == 0.0 and trimmed[0].pose("block").held_by == "left"
    assert [e.kind for e in trimmed if e.kind in ("grasp", "release")] == ["release", "grasp", "release"]


def test_training_gives_a_task_result_and_the_preview_moves_the_objects(rig) -> None:
    ctl, sim = rig
    ctl.sessions.new("pp", scene="pick-place")
    for seed in (0, 1, 2):
        record_plan(ctl, sim, "pick-place", seed)
    assert ctl.scene.task_result() is None
    results: list[object] = []
    ctl.events.on(Topic.TASK, lambda: results.append(ctl.scene.task_result()))
    ctl.training.train().result()
    result = ctl.scene.task_result()
    assert result is not None
    assert results[-1] is ctl.scene.task_result()
    assert result.ok, result.text
    assert result.text.startswith("The block went onto the pad (") and "ended back where it started" in result.text
    # The preview moves the objects too: halfway through, the block is away from where it started.
    rec = ctl.playback.preview_recording()
    start = ctl.scene.scene.object("block").position
    ctl.playback.seek_preview(rec.duration * 0.45)
    assert ctl.playback.kind == PREVIEW
    _, poses = ctl.scene.shown()
    block = next(p for p in poses if p.name == "block")
    assert np.linalg.norm(np.subtract(block.position, start)) > 0.1
    # Moving the pad away makes the same skill fail, in words.
    ctl.playback.stop(PREVIEW)
    ctl.scene.move("block", (0.6, -0.4, -0.07))
    bad = ctl.scene.task_result()
    assert bad is not None and not bad.ok and "The block was never picked up" in bad.text
