"""What the robot touches in the task scene (studio.world.contacts, studio.world.hits), judged against what is
really there: a carry that sags through the table, fingers around the grasped block and cups nesting (allowed),
the left gripper swept into the right arm, a gripper lowered onto the table, a cup left in the way."""

from __future__ import annotations

import numpy as np
import pytest

from studio import teacher
from studio.core.kinematics import Baxter
from studio.storage import SessionStore
from studio.world import preset, simulate
from studio.world.contacts import along, first_contact, touches, touches_at
from studio.world.hits import simulate_hits
from tests.conftest import ROOT

B = Baxter.load()
TABLE_TOP = -0.07


def stream(plan: teacher.TeacherPlan, step: int = 10) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return plan.t[::step], np.asarray(plan.q[::step]), np.asarray(plan.gripper[::step])


@pytest.mark.parametrize("name", ["pick-place", "stack-cup"])
def test_the_bundled_demonstrations_touch_nothing_they_must_not(name: str) -> None:
    """The fingers close around the block and the cup, the cup nests in the bottom cup, the block lands on the pad:
    all allowed; nothing else comes within the margin."""
    session = SessionStore(ROOT / "sessions").open(name)
    for i, rec in enumerate(session.recordings):
        t, q, g = rec.t[::10], rec.q[::10], rec.gripper[::10]
        events = session.objects.events(session.demo_files[i])
        start = next(e.poses for e in events if e.kind == "start")
        run = simulate(t, q, g, session.objects.scene, baxter=B, start=start)
        assert [e.kind for e in run.events if e.kind in ("grasp", "release")], "the demonstration moves an object"
        assert touches(t, q, g, session.objects.scene, run, B) == []


def test_a_carry_that_sags_through_the_table_is_found_as_deep_as_it_goes() -> None:
    scene = preset("pick-place", ("left",))
    t, q, g = stream(teacher.teach("pick-place", 1, arm="left", dip=0.2))
    run = simulate(t, q, g, scene, baxter=B)
    found = touches(t, q, g, scene, run, B)
    block = [x for x in found if x.a.part == "block" and x.b.part == "table"]
    fingers = [x for x in found if x.a.part == "fingers" and x.b.part == "table"]
    assert block and fingers and block[0].a.arm == "left"
    # judged on its own: the carried block's lowest bottom below the table top
    objs = along(t, q, run, B)
    k = objs.names.index("block")
    held = objs.holder[:, k] == 0
    lowest = TABLE_TOP - objs.bottom[k, held, 2, 3].min()
    assert lowest > 0.05
    assert block[0].depth == pytest.approx(lowest, abs=0.005)
    assert block[0].t_start <= t[held][np.argmin(objs.bottom[k, held, 2, 3])] <= block[0].t_end
    assert block[0].carry == "block"


def test_the_left_gripper_swept_into_the_right_arm() -> None:
    """The pad put where the right arm rests: the carry runs the left hand into the right arm's gripper."""
    places = teacher.Places(put=teacher.Place(dy=-0.25))
    scene = preset("pick-place", ("left",), places)
    t, q, g = stream(teacher.teach("pick-place", 2, arm="left", places=places))
    run = simulate(t, q, g, scene, baxter=B)
    found = touches(t, q, g, scene, run, B)
    arms = [x for x in found if x.a.robot and x.b.robot and x.b.arm == "right"]
    assert arms, [(x.a, x.b) for x in found]
    assert all(x.a.arm == "left" for x in arms)
    wrists = next(x for x in arms if x.a.part == "wrist" and x.b.part == "wrist")
    assert wrists.depth > 0.03  # the wrists go centimetres into each other


def test_lowering_a_gripper_onto_the_table_stops_before_it() -> None:
    scene = preset("empty table", ("left",))
    home = np.concatenate([B.neutral("left"), B.neutral("right")])
    from studio.core.posture_ik import reach_pose

    _, w = B.fk("left", home[:7])
    rows, q = [], home[:7]
    for z in np.linspace(0.0, -0.12, 25):  # the gripper point 7 cm above the table down to 5 cm into it
        q = np.asarray(reach_pose(B, "left", np.array([0.7, 0.2, z]), w, q).result.q)
        rows.append(np.concatenate([q, home[7:]]))
    Q = np.array(rows)
    hit = first_contact(Q, np.array([[100.0, 100.0]]), (), scene, B)
    assert hit is not None
    k, x = hit
    assert x.a.part == "fingers" and x.b.part == "table"
    tip_z = B.fk_batch("left", Q[:, :7])[0][:, 2] + 0.0035  # the fingertips reach 3.5 mm past the gripper point
    assert tip_z[k - 1] > TABLE_TOP + 0.005 - 0.0105  # the last free pose is within one step of the margin
    assert tip_z[k - 1] >= TABLE_TOP  # never into the table
    assert touches_at(Q[k - 1 : k], np.array([[100.0, 100.0]]), (), scene, B) == []


def test_fingers_may_close_around_a_block_but_not_sweep_through_it() -> None:
    scene = preset("pick-place", ("left",))
    block = next(o for o in scene.objects if o.name == "block")
    from studio.core.posture_ik import reach_pose
    from studio.world.events import ObjectPose
    from studio.world.geometry import yaw_quat

    pose = ObjectPose(block.name, block.kind, block.size, block.position, yaw_quat(block.yaw), None, "table")
    home = np.concatenate([B.neutral("left"), B.neutral("right")])
    _, w = B.fk("left", home[:7])
    top = block.position[2] + block.size[2]
    around = reach_pose(B, "left", np.array([*block.position[:2], top - 0.01]), w, home[:7]).result
    closed = np.concatenate([around.q, home[7:]])[None]
    assert touches_at(closed, np.array([[0.0, 100.0]]), [pose], scene, B) == []  # closed around it
    beside = reach_pose(B, "left", np.array([block.position[0], block.position[1] + 0.055, top - 0.01]), w, home[:7])
    swept = np.concatenate([beside.result.q, home[7:]])[None]
    found = touches_at(swept, np.array([[100.0, 100.0]]), [pose], scene, B)
    assert [(x.a.part, x.b.part) for x in found] == [("fingers", "block")]


def test_a_cup_in_the_way_is_pushed_or_knocked_over_and_the_block_said_to_go_into_it() -> None:
    places = teacher.Places()
    plan = teacher.teach("pick-place", 3, arm="left", dip=0.1)
    t, q, g = stream(plan)
    scene = preset("pick-place", ("left",), places)
    P = B.fk_batch("left", q[:, :7])[0]
    carry = np.flatnonzero((t > plan.events[0].time) & (t < plan.events[1].time))
    i = int(carry[len(carry) // 2])  # half-way along the carry
    scene = scene.add("cup", (P[i, 0], P[i, 1], TABLE_TOP))
    run, hits, found = simulate_hits(t, q, g, scene, B, new={"cup"})
    first = next(x for x in found if x.b.part == "cup")
    assert first.new and first.carry == "block" and first.depth > 0.005
    assert hits and hits[0].name == "cup" and hits[0].t == pytest.approx(first.at, abs=0.2)
    cup = next(p for p in run.final if p.name == "cup")
    moved = np.hypot(cup.position[0] - P[i, 0], cup.position[1] - P[i, 1])
    assert moved > 0.005 or hits[0].toppled
    assert any(e.kind == "push" and e.object == "cup" for e in run.events)
