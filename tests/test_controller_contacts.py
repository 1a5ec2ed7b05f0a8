"""Nothing passes through anything (issue 29), through the controller: the teaching keys stop at the table; a skill
whose carry sags through the table is named in words, never called working, never run; a clean skill is not
flagged; a cup put in its way is named; a contact during a run stops it like the emergency stop; demonstrations
recorded through the table are marked. Judged with the collision model's own geometry, independently of the
words."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from studio import teacher
from studio.commands import headless, record_plan, train
from studio.controller import Controller
from studio.core.collision import CollisionModel
from studio.core.errors import StudioError
from studio.core.kinematics import Baxter
from studio.core.obstacles import Obstacle, obstacle_pose
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore
from studio.world import preset
from tests.conftest import RecordingNotifier, run_once, wait_for

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")
TABLE_TOP = -0.07
B = Baxter.load()


def table_clearance(q14: np.ndarray, gripper: np.ndarray) -> float:
    """How far (m) the robot is from the table at ``q14`` (negative: how deep in it), up to 10 cm: an independent
    check with the table alone."""
    table = Obstacle("table", "box", (0.7, 1.5, 0.86), obstacle_pose((0.75, 0.0, TABLE_TOP - 0.43)))
    near = CollisionModel([table], margin=0.1).near(np.asarray(q14)[None], np.asarray(gripper)[None])
    return float(near.distance.min()) if len(near) else 0.1


def table_depth(q14: np.ndarray, gripper: np.ndarray) -> float:
    """How deep (m) the robot is in the table at ``q14`` (0: not in it)."""
    return max(-table_clearance(q14, gripper), 0.0)


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two pick-and-place sessions taught by the scripted teacher, trained once in the run: "sags" carries the
    block 20 cm lower half-way (through the table), "low" 10 cm lower (clear of the table)."""

    def fill(root: Path) -> None:
        st = SessionStore(root)
        for name, dip in (("sags", 0.2), ("low", 0.1)):
            session = st.create(name, arms=("left",))
            session.set_scene(preset("pick-place", ("left",)))
            for i, seed in enumerate((1, 2, 3)):
                plan = teacher.teach("pick-place", seed, arm="left", dip=dip)
                record_plan(session, plan, f"demo {i + 1}", noise_seed=i)
            with headless(st, session) as ctl:
                train(ctl)

    return run_once(tmp_path_factory, "contacts", fill)


def open_rig(store: Path, tmp_path: Path, name: str) -> tuple[Controller, SimulatedBaxter]:
    shutil.copytree(store, tmp_path / "sessions")
    sim = SimulatedBaxter()
    ctl = Controller(store=SessionStore(tmp_path / "sessions"), session=name, backend=sim, notifier=RecordingNotifier())
    ctl.start()
    sim.stop()  # stepped by hand
    assert wait_for(lambda: ctl.scene.task_result() is not None)
    return ctl, sim


@pytest.fixture
def sags(store: Path, tmp_path: Path) -> Iterator[tuple[Controller, SimulatedBaxter]]:
    ctl, sim = open_rig(store, tmp_path, "sags")
    yield ctl, sim
    ctl.close()
    ctl.shutdown()


@pytest.fixture
def low(store: Path, tmp_path: Path) -> Iterator[tuple[Controller, SimulatedBaxter]]:
    ctl, sim = open_rig(store, tmp_path, "low")
    yield ctl, sim
    ctl.close()
    ctl.shutdown()


def test_the_teaching_keys_stop_at_the_table(ctl: Controller) -> None:
    """The "down" key eleven times from 6 cm above the table: the fingers stop short of it, the page says where."""
    from studio.controller.guiding import pointing_down

    g = ctl.guide
    _, now = g.pose("left")
    res = g.move("left", np.array([0.62, 0.3, TABLE_TOP + 0.06]), pointing_down(now))
    assert res.converged
    for _ in range(11):
        g.step("z", -1, "left")  # 1 cm steps
    q = ctl.teaching.target_q("left")
    gap = table_clearance(np.concatenate([q, ctl.teaching.target_q("right")]), ctl.teaching.robot_gripper())
    assert 0.005 <= gap < 0.016  # stopped within a step (1 cm) of the 5 mm margin, never into the table
    assert ctl.teaching.reach_message() == "The left fingers touch the table — lift the gripper first."
    assert wait_for(lambda: np.allclose(ctl.teaching.arm_q("left"), q, atol=1e-3))  # the robot went there
    assert table_depth(ctl.teaching.robot_q(), ctl.teaching.robot_gripper()) == 0.0
    g.step("z", 1, "left")  # lifting is allowed, and the words go
    assert ctl.teaching.reach_message() == ""
    assert B.fk("left", ctl.teaching.target_q("left"))[0][2] > B.fk("left", q)[0][2] + 0.005


def test_the_joint_sliders_stop_at_the_table(ctl: Controller) -> None:
    from studio.controller.guiding import pointing_down

    _, now = ctl.guide.pose("left")
    ctl.guide.move("left", np.array([0.62, 0.3, TABLE_TOP + 0.06]), pointing_down(now))
    q = ctl.teaching.target_q("left")
    ctl.teaching.move_joint(1, float(q[1]) + 0.4)  # the shoulder down: the gripper into the table
    after = ctl.teaching.target_q("left")
    assert after[1] < q[1] + 0.4 - 1e-6
    assert table_depth(np.concatenate([after, ctl.teaching.target_q("right")]), ctl.teaching.robot_gripper()) == 0.0
    assert "touch the table" in ctl.teaching.reach_message()


def test_a_carry_through_the_table_is_named_never_works_and_never_runs(sags) -> None:
    ctl, sim = sags
    found = ctl.scene.skill_touches()
    through = [x for x in found if x.b.part == "table" and x.a.part == "block"]
    assert through and through[0].depth > 0.05
    # judged independently: the fingers at the skill's lowest point are in the table
    rec = ctl.playback.preview_recording()
    z = B.fk_batch("left", rec.q[:, :7])[0][:, 2]
    assert table_depth(rec.q[int(np.argmin(z))], rec.gripper[int(np.argmin(z))]) > 0.02
    task = ctl.scene.task_result()
    assert task is not None and not task.ok and "works" not in task.text
    assert "the block would go" in task.text and "into the table" in task.text
    why = ctl.execution.why_not()
    assert "into the table" in why and "does not run a skill that would hit something" in why
    with pytest.raises(StudioError, match="into the table"):
        ctl.execution.run()
    assert not ctl.execution.running and sim.progress().state == "idle"
    paths = ctl.scene.contact_paths()
    assert paths["left"] and all(len(p) > 1 for p in paths["left"])
    lowest = min(float(p[:, 2].min()) for p in paths["left"])
    assert lowest == pytest.approx(float(z.min()), abs=0.01)  # the red stretch is where the gripper goes lowest
    # the demonstrations themselves were recorded through the table (the scripted teacher has no guard)
    assert "went" in ctl.scene.demo_contact(0) and "into the table" in ctl.scene.demo_contact(0)


def test_a_clean_skill_is_not_flagged_and_a_new_cup_in_its_way_is_named(low) -> None:
    ctl, _ = low
    assert ctl.scene.skill_touches() == ()
    task = ctl.scene.task_result()
    assert task is not None and task.ok and task.text.startswith("The block went onto the pad")
    assert ctl.execution.why_not() == ""
    assert ctl.scene.demo_contact(0) == ""
    rec = ctl.playback.preview_recording()
    P = B.fk_batch("left", rec.q[:, :7])[0]
    carry = np.flatnonzero(rec.gripper[:, 0] < 50)  # the gripper closed: carrying the block
    first = carry[: int(np.argmax(np.diff(carry) > 1)) or len(carry)]
    i = int(first[len(first) // 2])
    name = ctl.scene.add("cup")
    ctl.scene.move(name, (P[i, 0], P[i, 1], TABLE_TOP))
    task = ctl.scene.task_result()
    assert task is not None and not task.ok and "works" not in task.text
    assert task.text.startswith("The new cup is in the way of the carry of the block at ")
    why = ctl.execution.why_not()
    assert why.startswith("The new cup is in the way") and "would hit something" in why
    with pytest.raises(StudioError, match="new cup"):
        ctl.execution.run()


def test_a_contact_during_a_run_stops_it_like_the_emergency_stop(low) -> None:
    """A cup in the way that the check before the run missed (its words left out here): the robot is stopped at
    the contact, in words, and the cup is pushed or knocked over."""
    ctl, sim = low
    rec = ctl.playback.preview_recording()
    P = B.fk_batch("left", rec.q[:, :7])[0]
    carry = np.flatnonzero(rec.gripper[:, 0] < 50)
    first = carry[: int(np.argmax(np.diff(carry) > 1)) or len(carry)]
    i = int(first[len(first) // 2])
    name = ctl.scene.add("cup")
    ctl.scene.move(name, (P[i, 0], P[i, 1], TABLE_TOP))
    assert ctl.execution.why_not().startswith("The new cup")
    ctl.execution.contacts = lambda: ""  # as if the check before the run had missed it
    ctl.execution.run()
    while sim.progress().active:
        sim.step(20)
    assert wait_for(lambda: not ctl.execution.running)
    st = ctl.execution.status
    assert st.estop and st.phase == "emergency-stopped" and st.ok is False
    assert st.message.startswith("The robot was stopped at ") and "the cup" in st.message
    assert "Release emergency stop" in st.message
    assert st.fraction < 0.6
    assert "and was stopped" in st.result and "works" not in st.result
    pushed = [e for e in ctl.scene.live.events if e.kind == "push" and e.object == name]
    assert pushed
    with pytest.raises(StudioError, match="emergency stop"):
        ctl.execution.run()
