"""The task scene without a GUI: presets, editing, grasp/carry/release rules, events, and the task result in
plain words, from real runs of the scripted teacher (studio/teacher.py) through the world."""

from __future__ import annotations

import itertools
import json
import re

import numpy as np
import pytest

from studio import teacher
from studio.core.errors import InvalidInput, SessionFormatError
from studio.core.kinematics import Baxter
from studio.core.types import ARMS
from studio.robot_backend.simulated import SimulatedBaxter
from studio.teacher import TASKS, recording_from_plan, teach
from studio.world import (
    CUP_GRASP_HEIGHT,
    DEFAULT_SIZE,
    FLOOR_Z,
    NEST_STEP,
    PRESETS,
    START,
    TABLE_CENTER,
    TABLE_SIZE,
    TABLE_TOP_Z,
    Placement,
    Scene,
    World,
    WorldEvent,
    events_from_dict,
    events_to_dict,
    preset,
    read_goal,
    session_goal,
    simulate,
    task_result,
)


def run_plan(plan, scene: Scene, noise: bool = True):
    rec = recording_from_plan(plan, noise=noise)
    return simulate(rec.t, rec.q, rec.gripper, scene)


@pytest.fixture
def teacher_variant(monkeypatch: pytest.MonkeyPatch):
    """Change where the scripted teacher acts (its task constants), with teach()'s cache cleared around it."""

    def change(**values) -> None:
        teach.cache_clear()
        for k, v in values.items():
            monkeypatch.setattr(teacher, k, v)
            monkeypatch.setattr(teacher.tasks, k, v)  # where the key-frames read them

    yield change
    monkeypatch.undo()
    teach.cache_clear()


def goal_of(task: str, arm: str = "left", seeds=(0, 1, 2)):
    """The goal of the task set-up, matched to demonstrations of the scripted teacher, and its scene."""
    scene = preset(task, ("left", "right") if arm == "both" else (arm,))
    events = [run_plan(teach(task, s, arm=arm), scene).events for s in seeds]
    return session_goal(scene.preset, scene.goal, scene.names(), events), scene


# -- the scene -------------------------------------------------------------------------------------------------


def test_presets_put_the_objects_where_the_teacher_acts() -> None:
    assert PRESETS == ("empty table", "stack-cup", "pick-place")
    empty = preset("empty table")
    assert empty.table is not None and empty.objects == ()
    cups = preset("stack-cup")
    assert sorted(o.kind for o in cups.objects) == ["cup", "cup"]
    handed, bottom = cups.object("cup"), cups.object("bottom cup")
    assert handed.held_out and bottom.position[2] == TABLE_TOP_Z
    assert handed.position[:2] == teacher.STACK_CUP_HANDOVER[:2]
    pp = preset("pick-place")
    assert sorted(o.kind for o in pp.objects) == ["block", "pad"]
    assert pp.object("block").position[:2] == teacher.PICK_PLACE_A[:2]
    assert pp.object("pad").position[:2] == teacher.PICK_PLACE_B[:2]
    both = preset("pick-place", ("left", "right"))
    assert both.names() == ["pad", "block (left)", "block (right)"]  # one pad between the arms' B points
    assert both.object("block (right)").position[1] == pytest.approx(-teacher.PICK_PLACE_A[1])
    # Everything is within reach of the gripper that acts on it: IK reaches 2 cm above each object with the
    # gripper pointing down.
    b = Baxter.load()
    rng = np.random.default_rng(0)
    for sc in (preset("stack-cup", ("left", "right")), both):
        for o in sc.objects:
            arms = [a for a in ARMS if a in o.name] or list(ARMS)
            for arm in arms:
                top = np.asarray(o.position) + np.array([0.0, 0.0, o.size[2] + 0.02])
                seeds = [b.neutral(arm), *b.random_configuration(arm, rng, 20)]
                assert any(
                    b.ik(arm, top, np.array([0.0, 0.0, 1.0, 0.0]), s, max_iterations=200).converged for s in seeds
                ), (o.name, arm)
    with pytest.raises(InvalidInput, match="Unknown scene"):
        preset("kitchen")


def test_add_move_remove_objects() -> None:
    s = preset("empty table")
    s = s.add("cup", (0.7, 0.3, 0.4))  # let go in the air: it settles on the table
    assert s.object("cup").position == (0.7, 0.3, TABLE_TOP_Z)
    s = s.add("cup", (0.7, 0.3, 0.4))  # on top of the first: nests into it
    assert s.names() == ["cup", "cup 2"]
    assert s.object("cup 2").position[2] == pytest.approx(TABLE_TOP_Z + NEST_STEP)
    s = s.add("block", (0.6, -0.2, 0.0), 0.3, name="red block")
    s = s.add("pad", (0.5, 0.0, 0.0))
    s = s.move("red block", (0.5, 0.0, 0.3))  # onto the pad
    assert s.object("red block").position[2] == pytest.approx(TABLE_TOP_Z + DEFAULT_SIZE["pad"][2])
    assert s.object("red block").yaw == pytest.approx(0.3)
    s = s.move("red block", (0.5, 0.0, 0.3), settle=False)  # a gizmo drag can leave it where it is
    assert s.object("red block").position[2] == 0.3
    s = s.remove("cup")
    assert s.names() == ["cup 2", "red block", "pad"]
    s = s.move("cup 2", (1.6, 0.0, 0.2))  # beyond the table: on the floor
    assert s.object("cup 2").position[2] == pytest.approx(-0.93)
    for bad in (
        lambda: s.add("teapot", (0.5, 0, 0)),
        lambda: s.add("cup", (np.nan, 0, 0)),
        lambda: s.add("cup", (9.0, 0, 0)),
        lambda: s.add("cup", (0.5, 0.0)),
        lambda: s.add("cup", (0.5, 0, 0), name="pad"),
        lambda: s.add("block", (0.5, 0, 0), size=(0.0, 0.05, 0.05)),
        lambda: s.move("ghost", (0.5, 0, 0)),
        lambda: s.remove("ghost"),
    ):
        with pytest.raises(InvalidInput):
            bad()


def test_scene_and_events_round_trip_through_json() -> None:
    scene = preset("stack-cup", ("left", "right")).add("block", (0.5, -0.1, 0.0), 0.2)
    again = Scene.from_dict(json.loads(json.dumps(scene.to_dict())))
    assert again == scene
    assert Scene.from_dict(None) == Scene()  # an older session: an empty table
    with pytest.raises(SessionFormatError, match="newer"):
        Scene.from_dict({**scene.to_dict(), "version": 99})
    with pytest.raises(SessionFormatError, match="damaged"):
        Scene.from_dict({"version": 1, "objects": [{"name": "x", "kind": "cup"}]})
    with pytest.raises(SessionFormatError):
        Scene.from_dict(
            {"version": 1, "objects": [{"name": "x", "kind": "cup", "size": [1, 1, "a"], "position": [0, 0, 0]}]}
        )

    run = run_plan(teach("pick-place", 0), preset("pick-place"))
    d = json.loads(json.dumps(events_to_dict(run.events)))
    assert d["version"] == 1
    back = events_from_dict(d)
    assert tuple(back) == run.events
    assert all(isinstance(e, WorldEvent) for e in back)
    assert events_from_dict(None) == []
    with pytest.raises(SessionFormatError, match="newer"):
        events_from_dict({"version": 7, "events": []})
    with pytest.raises(SessionFormatError, match="damaged"):
        events_from_dict({"version": 1, "events": [{"t": 0.0, "kind": "explode"}]})
    with pytest.raises(SessionFormatError, match="damaged"):
        events_from_dict({"version": 1, "events": [{"t": "NaN", "kind": "start", "poses": []}]})


# -- the rules -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("arm", ["left", "right", "both"])
def test_scripted_demos_do_the_task_in_the_world(task: str, arm: str) -> None:
    arms = ("left", "right") if arm == "both" else (arm,)
    scene = preset(task, arms)
    run = run_plan(teach(task, 0, arm=arm), scene)
    kinds = [e.kind for e in run.events]
    assert kinds[0] == "start" and kinds[-1] == "end"
    assert "miss" not in kinds
    final = {p.name: p for p in run.final}
    for a in arms:
        tag = f" ({a})" if len(arms) > 1 else ""
        acts = [(e.kind, e.object) for e in run.events if e.arm == a]
        if task == "stack-cup":
            assert acts == [("grasp", f"cup{tag}"), ("release", f"cup{tag}")]
            cup = final[f"cup{tag}"]
            assert cup.on == f"bottom cup{tag}" and cup.held_by is None
            assert cup.position[2] == pytest.approx(TABLE_TOP_Z + NEST_STEP)
        else:
            assert acts == [("grasp", f"block{tag}"), ("release", f"block{tag}")] * 2
            # the first release puts it on the pad at B; it ends back at A on the table
            first = next(e for e in run.events if e.kind == "release" and e.arm == a)
            assert first.pose(f"block{tag}").on == "pad"
            block = final[f"block{tag}"]
            start = scene.object(f"block{tag}").position
            assert block.on == "table" and np.hypot(block.position[0] - start[0], block.position[1] - start[1]) < 0.02
            assert abs(block.yaw - scene.object(f"block{tag}").yaw) < 0.2  # it comes back turned about as it was


def test_an_object_moves_with_the_gripper_while_held() -> None:
    plan = teach("pick-place", 1)
    rec = recording_from_plan(plan, noise=False)
    world = World(preset("pick-place"))
    b = world.baxter
    grasp = plan.event_poses("close")[0].time
    i0 = int(np.searchsorted(rec.t, grasp + 1.0))
    world.feed(rec.t[:i0], rec.q[:i0], rec.gripper[:i0])
    assert world.held("left") == ["block"]
    for i in (i0 + 500, i0 + 2000):  # carried: fixed offset from the gripper point
        world.feed(rec.t[i0:i], rec.q[i0:i], rec.gripper[i0:i])
        i0 = i
        p, _ = b.fk("left", rec.q[i - 1, :7])
        pose = next(x for x in world.poses() if x.name == "block")
        assert pose.held_by == "left" and pose.on is None
        assert np.linalg.norm(np.asarray(pose.position) + np.array([0.0, 0.0, 0.04]) - p) < 0.01
    v = world.version
    world.feed(rec.t[i0 : i0 + 20], rec.q[i0 : i0 + 20], rec.gripper[i0 : i0 + 20])
    assert world.version > v  # the drawing knows it moved


def test_grasping_the_bottom_of_a_stack_carries_the_top_and_a_drop_off_the_table_hits_the_floor() -> None:
    b = Baxter.load()
    scene = preset("empty table").add("cup", (0.75, 0.30, 0.0)).add("cup", (0.75, 0.30, 0.2))
    down = np.array([0.0, 0.0, 1.0, 0.0])  # gripper pointing down (as the teacher holds it)
    rng = np.random.default_rng(1)

    def q_at(p):
        for seed in [b.neutral("left"), *b.random_configuration("left", rng, 30)]:
            res = b.ik("left", np.asarray(p), down, seed, max_iterations=200)
            if res.converged:
                return np.concatenate([res.q, b.neutral("right")])
        raise AssertionError(f"cannot reach {p}")

    at_rim = q_at((0.75, 0.30, TABLE_TOP_Z + NEST_STEP + 0.05))  # inside the top cup: that one is grasped
    up = q_at((0.75, 0.30, 0.25))
    t = np.arange(6) * 0.5
    q = np.array([up, at_rim, at_rim, up, up, up])
    g = np.array([[100, 100], [100, 100], [0, 100], [0, 100], [100, 100], [100, 100]], dtype=float)
    run = simulate(t, q, g, scene)
    grasp = next(e for e in run.events if e.kind == "grasp")
    assert grasp.object == "cup 2"
    final = {p.name: p for p in run.final}
    assert final["cup 2"].on == "cup" and final["cup 2"].position[2] == pytest.approx(TABLE_TOP_Z + NEST_STEP)

    # grasp the bottom cup (gripper point low, inside only the bottom cup's range): both move together
    low = q_at((0.75, 0.30, TABLE_TOP_Z + 0.005))
    off = q_at((0.32, 0.50, 0.20))  # between the robot and the table's near edge (x = 0.40)
    q = np.array([up, low, low, up, off, off])
    g = np.array([[100, 100], [100, 100], [0, 100], [0, 100], [0, 100], [100, 100]], dtype=float)
    run = simulate(np.arange(6) * 0.5, q, g, scene)
    assert [e.object for e in run.events if e.kind in ("grasp", "release")] == ["cup", "cup"]
    final = {p.name: p for p in run.final}
    assert final["cup"].on == "floor" and final["cup"].position[2] == pytest.approx(-0.93)
    assert final["cup 2"].on == "cup" and final["cup 2"].position[2] == pytest.approx(-0.93 + NEST_STEP)
    assert np.allclose(final["cup 2"].position[:2], final["cup"].position[:2], atol=1e-6)


def test_the_same_stream_gives_the_same_events_live_or_at_once() -> None:
    plan = teach("stack-cup", 2)
    scene = preset("stack-cup")
    a = run_plan(plan, scene)
    assert run_plan(plan, scene).events == a.events  # deterministic
    # Live: the world listens to the simulated robot driven through the plan (batches of 20 samples).
    robot = SimulatedBaxter(q0=plan.q[0], gripper0=plan.gripper[0], sensor_noise=2.5e-4, seed=3)
    world = World(scene)
    unsubscribe = robot.subscribe(world.on_batch)
    world.snapshot("start", 0.0)
    robot.run_targets(np.asarray(plan.q), np.asarray(plan.gripper))
    unsubscribe()
    world.snapshot("end")
    live = world.events
    assert [(e.kind, e.object) for e in live] == [(e.kind, e.object) for e in a.events]
    for x, y in zip(live, a.events, strict=True):
        assert abs(x.t - y.t) < 0.1
        for p, r in zip(x.poses, y.poses, strict=True):
            assert np.linalg.norm(np.subtract(p.position, r.position)) < 0.005
    assert robot.listener_errors == 0
    # A marked part of the event list is what one recording keeps.
    m = world.mark()
    world.snapshot("end")
    assert [e.kind for e in world.events_since(m)] == ["end"]


def test_bad_streams_are_refused_or_skipped() -> None:
    scene = preset("pick-place")
    with pytest.raises(InvalidInput, match="nothing to play"):
        simulate(np.zeros(0), np.zeros((0, 14)), np.zeros((0, 2)), scene)
    with pytest.raises(InvalidInput, match="14 joint angles"):
        simulate(np.zeros(3), np.zeros((3, 7)), np.zeros((3, 2)), scene)
    plan = teach("pick-place", 0)
    rec = recording_from_plan(plan)
    q = np.array(rec.q)
    q[5000:5100] = np.nan  # a damaged stretch (not at a grasp): skipped, the rest plays as before
    run = simulate(rec.t, q, rec.gripper, scene)
    assert [(e.kind, e.object) for e in run.events] == [(e.kind, e.object) for e in run_plan(plan, scene).events]
    world = World(scene)
    assert world.feed(np.array([0.0]), np.full((1, 14), np.nan), np.zeros((1, 2))) == []


# -- the task result -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("task", TASKS)
def test_result_a_good_run_works(task: str) -> None:
    goal, scene = goal_of(task)
    assert goal.source == "set-up" and goal.objects == (["cup"] if task == "stack-cup" else ["block"])
    res = task_result(run_plan(teach(task, 7), scene), goal)
    assert res.ok, res.text
    if task == "stack-cup":
        assert re.fullmatch(r"The cup ended in the bottom cup, [\d.]+ cm from its centre\.", res.text), res.text
    else:  # the scripted teacher brings the block back: the goal's pad, then where it started
        assert re.fullmatch(
            r"The block went onto the pad \([\d.]+ cm from its centre\), then ended back where it started, "
            r"([\d.]+ cm|less than 1 mm) from it\.",
            res.text,
        ), res.text
    assert res.objects[0].distance is not None and res.objects[0].distance < 0.02


def test_result_both_arms() -> None:
    goal, scene = goal_of("stack-cup", "both", seeds=(0, 1))
    assert sorted(goal.objects) == ["cup (left)", "cup (right)"]
    assert {goal.arm(n) for n in goal.objects} == {"left", "right"}
    res = task_result(run_plan(teach("stack-cup", 5, arm="both"), scene), goal)
    assert res.ok and res.text.count("ended in the bottom cup") == 2, res.text


def test_result_never_picked_up_the_gripper_closed_above_it(teacher_variant) -> None:
    goal, scene = goal_of("pick-place")
    a = teacher.PICK_PLACE_A
    teacher_variant(PICK_PLACE_A=(a[0], a[1], a[2] + 0.04))  # the teacher closes 4 cm higher at A
    res = task_result(run_plan(teach("pick-place", 7), scene), goal)
    assert not res.ok and res.objects[0].verdict == "never picked up"
    assert res.text == "The block was never picked up: the gripper closed 3 cm above it.", res.text


def test_result_never_picked_up_the_gripper_closed_beside_it(teacher_variant) -> None:
    goal, scene = goal_of("stack-cup")
    h = teacher.STACK_CUP_HANDOVER
    teacher_variant(STACK_CUP_HANDOVER=(h[0], h[1] - 0.06, h[2]))
    res = task_result(run_plan(teach("stack-cup", 7), scene), goal)
    assert res.objects[0].verdict == "never picked up"
    assert res.text.startswith("The cup was never picked up: the gripper closed 6 cm to the robot's right of it")


def test_result_never_picked_up_the_gripper_never_closed() -> None:
    goal, scene = goal_of("pick-place")
    plan = teach("pick-place", 7)
    rec = recording_from_plan(plan)
    run = simulate(rec.t, rec.q, np.full_like(rec.gripper, 88.0), scene)  # a skill that keeps the gripper open
    res = task_result(run, goal)
    assert res.text == "The block was never picked up: the gripper never closed."


def test_result_not_picked_up_the_second_time(teacher_variant) -> None:
    goal, scene = goal_of("pick-place")
    # The teacher puts the block down at B but, the second time, reaches 5 cm beyond it.
    plan = teach("pick-place", 7)
    rec = recording_from_plan(plan)
    g = np.array(rec.gripper)
    second_close = plan.event_poses("close")[1].time
    g[rec.t >= second_close - 0.2, 0] = 88.0  # ...and never closes again
    res = task_result(simulate(rec.t, rec.q, g, scene), goal)
    assert res.text == "The block was not picked up the second time: the gripper did not close again."


def test_result_still_held_at_the_end() -> None:
    goal, scene = goal_of("stack-cup")
    plan = teach("stack-cup", 7)
    rec = recording_from_plan(plan)
    g = np.array(rec.gripper)
    g[rec.t >= plan.event_poses("open")[0].time - 0.1, 0] = teacher.GRIP_WIDTH["stack-cup"]  # never lets go
    res = task_result(simulate(rec.t, rec.q, g, scene), goal)
    assert res.objects[0].verdict == "still held"
    assert res.text == "The cup was still in the gripper at the end: the gripper never opened."


def test_result_dropped_early() -> None:
    goal, scene = goal_of("stack-cup")
    plan = teach("stack-cup", 7)
    rec = recording_from_plan(plan)
    close, opened = plan.event_poses("close")[0].time, plan.event_poses("open")[0].time
    g = np.array(rec.gripper)
    early = close + 0.45 * (opened - close)  # opens half-way while carrying the cup to the stack
    g[rec.t >= early, 0] = teacher.OPEN_WIDTH["stack-cup"]
    res = task_result(simulate(rec.t, rec.q, g, scene), goal)
    assert res.objects[0].verdict == "dropped early", res.text
    assert res.text.startswith("The cup was dropped early: it landed beside the bottom cup, ")
    assert res.text.endswith(
        "from its centre, because the gripper opened before it got there — the skill did not do the task."
    ), res.text
    assert res.objects[0].distance is not None and res.objects[0].distance > 0.05


def test_result_released_in_the_wrong_place(teacher_variant) -> None:
    goal, scene = goal_of("pick-place")
    b = teacher.PICK_PLACE_B
    teacher_variant(PICK_PLACE_B=(b[0], b[1] + 0.07, b[2]))  # puts the block down 7 cm to the robot's left
    res = task_result(run_plan(teach("pick-place", 7), scene), goal)
    assert res.objects[0].verdict == "wrong place"
    assert re.fullmatch(
        r"The block was released in the wrong place the first time: it landed beside the pad, \d cm from its "
        r"centre — the skill did not do the task\.",
        res.text,
    ), res.text


def test_result_ended_elsewhere_and_nothing_to_check() -> None:
    goal, scene = goal_of("stack-cup")
    # The scene changed after teaching: the bottom cup is elsewhere, so the cup falls onto the table.
    moved = scene.move("bottom cup", (0.60, -0.20, 0.0))
    res = task_result(run_plan(teach("stack-cup", 7), moved), goal)
    assert res.objects[0].verdict == "wrong place"
    assert re.fullmatch(
        r"The cup ended beside the bottom cup, \d+ cm from its centre — the skill did not do the task\.", res.text
    ), res.text
    empty = read_goal([run_plan(teach("stack-cup", 0), preset("empty table")).events, []])
    assert empty.placements == () and empty.source == ""
    res = task_result(run_plan(teach("stack-cup", 7), scene), empty)
    assert not res.ok and res.text.startswith("There is nothing to check")


def test_demos_that_disagree_are_left_out_with_a_note() -> None:
    scene = preset("pick-place")
    plan = teach("pick-place", 2)
    rec = recording_from_plan(plan)
    g = np.array(rec.gripper)
    g[rec.t >= plan.event_poses("close")[1].time - 0.2, 0] = 88.0  # this demo picks the block up only once
    events = [run_plan(teach("pick-place", s), scene).events for s in (0, 1)]
    events.append(simulate(rec.t, rec.q, g, scene).events)
    goal = read_goal(events)
    assert [p.onto for p in goal.of("block")] == ["pad", START]
    assert goal.notes == ("2 of 3 demonstrations put the block down twice; the others are left out of the goal.",)


def test_a_replay_starts_from_the_recorded_poses_even_mid_grasp() -> None:
    """A demonstration replayed from its "start" event: here one that starts while the gripper holds the block."""
    plan = teach("pick-place", 1)
    rec = recording_from_plan(plan)
    scene = preset("pick-place")
    full = simulate(rec.t, rec.q, rec.gripper, scene)
    first_close = plan.event_poses("close")[0].time
    i = int(np.searchsorted(rec.t, first_close + 2.0))  # carrying the block from A to B
    world = World(scene)
    world.feed(rec.t[:i], rec.q[:i], rec.gripper[:i])
    start = world.snapshot("start").poses
    assert next(p for p in start if p.name == "block").held_by == "left"
    tail = simulate(rec.t[i:], rec.q[i:], rec.gripper[i:], preset("empty table"), start=start)
    later = [(e.kind, e.object) for e in full.events if e.t > rec.t[i] and e.kind != "end"]
    assert [(e.kind, e.object) for e in tail.events if e.kind not in ("start", "end")] == later
    for p, r in zip(tail.final, full.final, strict=True):
        # (the grip is taken again from the first replayed sample: encoder noise moves it by < 2 mm)
        assert p.name == r.name and np.linalg.norm(np.subtract(p.position, r.position)) < 2e-3
    # The live world with a recorded path judges a run as simulate() does.
    goal = read_goal(
        [
            simulate(r.t, r.q, r.gripper, scene).events
            for r in (recording_from_plan(teach("pick-place", s)) for s in (0, 2))
        ]
    )
    live = World(scene, record_path=True)
    live.snapshot("start", float(rec.t[0]))
    for k in range(0, len(rec.t), 15):
        live.feed(rec.t[k : k + 15], rec.q[k : k + 15], rec.gripper[k : k + 15])
    live.snapshot("end")
    run = live.run()
    assert run.events == full.events
    assert abs(len(run.path_t) - len(full.path_t)) <= 2
    assert task_result(run, goal) == task_result(full, goal)


def test_result_moved_again_after_it_was_put_down() -> None:
    # Demonstrations that carry the block from A to the pad and stop there (the first half of pick-place) ...
    scene = preset("pick-place")
    demos = []
    for s in (0, 1, 2):
        plan = teach("pick-place", s)
        rec = recording_from_plan(plan)
        n = int(np.searchsorted(rec.t, plan.event_poses("open")[0].time + 2.0))
        demos.append(simulate(rec.t[:n], rec.q[:n], rec.gripper[:n], scene).events)
    goal = session_goal(scene.preset, scene.goal, scene.names(), demos)
    assert goal.placements == (Placement("block", "pad", goal.placements[0].spot),)
    # ... and a run that does the whole task: put on the pad, then picked up again and taken back to A.
    res = task_result(run_plan(teach("pick-place", 7), scene), goal)
    assert res.objects[0].verdict == "moved"
    assert re.fullmatch(
        r"The block ended beside the pad, \d+ cm from its centre: it was picked up again afterwards — the skill did "
        r"not do the task\.",
        res.text,
    ), res.text


def test_distances_in_plain_words() -> None:
    from studio.world import format_distance

    assert [format_distance(d) for d in (0.0004, 0.006, -0.03, 0.25, 1.24)] == [
        "less than 1 mm",
        "0.6 cm",
        "3 cm",
        "25 cm",
        "1.2 m",
    ]


# -- the world's own claims (issue 27) ---------------------------------------------------------------------------
DOWN = np.array([0.0, 0.0, 1.0, 0.0])  # gripper pointing down (as the teacher holds it)


def stream_through(points, closes: int, opens: int, step_m: float = 0.01):
    """A joint stream (t, q, gripper) whose left gripper goes straight through ``points`` (IK every ``step_m``
    along each straight stretch, 20 ms apart), closing on arriving at point ``closes`` and opening at ``opens``."""
    b = Baxter.load()
    rng = np.random.default_rng(1)
    q_prev = b.neutral("left")
    qs, gs = [], []
    closed = False
    for i, (a, c) in enumerate(itertools.pairwise(points)):
        a, c = np.asarray(a, dtype=float), np.asarray(c, dtype=float)
        n = max(1, int(np.ceil(np.linalg.norm(c - a) / step_m)))
        for u in np.linspace(0.0, 1.0, n + 1)[(1 if i else 0) :]:
            for seed in [q_prev, b.neutral("left"), *b.random_configuration("left", rng, 20)]:
                res = b.ik("left", a + u * (c - a), DOWN, seed, max_iterations=200)
                if res.converged:
                    break
            assert res.converged, f"cannot reach {a + u * (c - a)}"
            q_prev = res.q
            qs.append(np.concatenate([res.q, b.neutral("right")]))
            gs.append([0.0 if closed else 100.0, 100.0])
        if i + 1 == closes:
            closed = True
        if i + 1 == opens:
            closed = False
        for _ in range(10):  # a pause at each point: the gripper closes or opens there
            qs.append(qs[-1])
            gs.append([0.0 if closed else 100.0, 100.0])
    q = np.array(qs)
    return np.arange(len(q)) * 0.02, q, np.array(gs, dtype=float)


def test_a_cup_goes_into_another_only_through_its_opening() -> None:
    """A cup has walls: lowered from above it goes in; slid in sideways below the other cup's rim, it meets the
    wall, and it ends beside that cup, not in it."""
    scene = preset("empty table").add("cup", (0.75, 0.30, 0.0), name="bottom cup").add("cup", (0.60, 0.30, 0.0))
    grip_z = TABLE_TOP_Z + CUP_GRASP_HEIGHT
    nest_z = TABLE_TOP_Z + NEST_STEP + CUP_GRASP_HEIGHT + 0.005
    from_above = [
        (0.60, 0.30, 0.15),
        (0.60, 0.30, grip_z),
        (0.60, 0.30, 0.15),
        (0.75, 0.30, 0.15),
        (0.75, 0.30, nest_z),
    ]
    t, q, g = stream_through([*from_above, (0.75, 0.30, 0.15)], closes=1, opens=4)
    nested = next(p for p in simulate(t, q, g, scene).final if p.name == "cup")
    assert nested.on == "bottom cup" and nested.position[2] == pytest.approx(TABLE_TOP_Z + NEST_STEP)
    low = TABLE_TOP_Z + 0.03 + CUP_GRASP_HEIGHT  # the carried cup's bottom 3 cm above the table: below the rim
    sideways = [(0.60, 0.30, 0.15), (0.60, 0.30, grip_z), (0.60, 0.30, low), (0.75, 0.30, low), (0.75, 0.30, 0.15)]
    t, q, g = stream_through(sideways, closes=1, opens=3)
    release = next(e for e in simulate(t, q, g, scene).events if e.kind == "release")
    cup = release.pose("cup")
    assert cup is not None and cup.on == "table", cup
    bottom = scene.object("bottom cup").position
    assert np.hypot(cup.position[0] - bottom[0], cup.position[1] - bottom[1]) >= 0.07 - 1e-9  # beside it


def test_an_object_whose_centre_is_beyond_the_tables_edge_falls() -> None:
    """Nothing standing on the table holds up what is beyond its edge; an object left in the air comes down."""
    edge = TABLE_CENTER[0] + TABLE_SIZE[0] / 2
    scene = preset("empty table").add("pad", (edge - 0.02, 0.0, 0.0))  # the pad sticks out 4 cm
    on_pad = scene.add("block", (edge - 0.03, 0.0, 0.1))  # centre over the pad, on the table side: on the pad
    assert on_pad.object("block").position[2] == pytest.approx(TABLE_TOP_Z + 0.004)
    beyond = scene.add("block", (edge + 0.02, 0.0, 0.1))  # centre over the pad's overhang: falls
    assert beyond.object("block").position[2] == pytest.approx(FLOOR_Z)
    # The pad moved away from under the block: the block comes down onto the table.
    moved = on_pad.move("pad", (0.6, 0.4, 0.0))
    assert moved.object("block").position[2] == pytest.approx(TABLE_TOP_Z)
    # A saved scene whose block stands half over the edge (as an older studio could leave it): the world drops it.
    raw = preset("empty table").add("block", (0.7, 0.0, 0.0)).to_dict()
    raw["objects"][0]["position"] = [edge + 0.01, 0.0, TABLE_TOP_Z]
    world = World(Scene.from_dict(raw))
    (block,) = world.poses()
    assert block.on == "floor" and block.position[2] == pytest.approx(FLOOR_Z)
