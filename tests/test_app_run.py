"""The robot's run in the panels, with a server and no browser: Preview's "Run on robot" and its reason, the
stretches the arm cannot follow drawn red where they are, the "Robot's run" status and buttons, and the executed
path drawn on the plan with the "Robot's run" layer. (In Chromium: tests/e2e/test_execution_browser.py.)"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from studio.app import Studio, build_app
from studio.controller import Layer, Step, Topic
from studio.core.execution import joint_trajectory
from studio.panels._charts import EXECUTED_COLOR
from studio.robot_backend.simulated import SimulatedBaxter
from tests.conftest import free_port, quiet_for, wait_for
from tests.viser_client import ViserClient


@pytest.fixture
def app(sessions: Path) -> Iterator[Studio]:
    """The stack-cup example, trained, on a simulated robot 8× faster than real time."""
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions, backend=SimulatedBaxter(time_scale=8))
    a.controller.training.train().result()
    yield a
    a.stop()


@pytest.fixture
def page(app: Studio) -> Iterator[ViserClient]:
    """A tab of the studio (viser's websocket protocol, no browser): the scene as the page receives it."""
    c = ViserClient.tab_of(app)
    assert c.wait_for(lambda _m: c.layer("/demos"), 30)
    yield c
    c.close()


def drawn(page: ViserClient, name: str) -> tuple[np.ndarray, tuple[int, ...], bool] | None:
    """A line node as the page has it: (points, first colour, drawn), None when the page has no such node."""
    node = page.scene().get(name)
    if node is None:
        return None
    pts = np.asarray(node["props"]["points"], dtype=np.float64).reshape(-1, 3)
    color = tuple(int(c) for c in np.asarray(node["props"]["colors"]).reshape(-1, 3)[0])
    return pts, color, name in page.shown(name)


def test_a_skill_the_arm_cannot_follow_is_drawn_red_and_not_run(app: Studio, page: ViserClient) -> None:
    ctl, preview = app.controller, app.panels.preview
    assert not preview.run_btn.disabled and preview.run_reason.content == ""
    assert "The arm can follow all of it." in preview.info.content
    assert drawn(page, "/preview/left/unreachable") is None
    skill = ctl.session.skills["left"]
    tr = skill.trajectory
    bump = np.exp(-(((tr.t - tr.t[0]) - 6.0) ** 2) / (2 * 0.4**2))  # 6 s in, the path goes 60 cm out
    far = dataclasses.replace(tr, position=tr.position + np.outer(bump, [0.6, 0.0, 0.0]))
    assert skill.joint_trajectory is not None
    jt = joint_trajectory(far, "left", skill.joint_trajectory.q[0], ctl.baxter)
    ctl.session.set_skills({"left": dataclasses.replace(skill, trajectory=far, joint_trajectory=jt, frames=None)})
    ctl.events.emit(Topic.SKILL)
    assert "In red: The left gripper cannot reach" in preview.info.content
    assert preview.run_btn.disabled
    assert "does not run a skill it cannot follow" in preview.run_reason.content
    assert page.wait_for(lambda _m: drawn(page, "/preview/left/unreachable"))
    pts, color, _ = drawn(page, "/preview/left/unreachable") or (np.zeros((0, 3)), (), False)
    assert color == (230, 30, 30)
    # drawn where the path goes out of reach: every red point is a point of that stretch of the learned path
    span = ctl.execution.unreachable_paths()["left"][0]
    assert np.min(np.linalg.norm(pts[:, None, :] - span[None, :, :], axis=2), axis=1).max() < 1e-6
    assert pts[:, 0].max() > tr.position[:, 0].max() + 0.3
    ctl.view.set_shown(Layer.LEARNED_PATH, True)
    assert page.wait_for(lambda _m: (drawn(page, "/preview/left/unreachable") or (0, 0, False))[2])
    ctl.view.set_shown(Layer.LEARNED_PATH, False)  # it goes with the learned path
    assert page.wait_for(lambda _m: not (drawn(page, "/preview/left/unreachable") or (0, 0, True))[2])


def test_the_run_is_shown_while_it_runs_and_after(app: Studio, page: ViserClient) -> None:
    ctl, run_panel, preview = app.controller, app.panels.run, app.panels.preview
    ctl.view.set_step(Step.PREVIEW)
    assert 'data-phase="idle"' in run_panel.status.content and not run_panel.stop_btn.visible
    assert run_panel.estop_btn.visible and not run_panel.release_btn.visible
    ctl.execution.run()
    assert 'data-phase="running"' in run_panel.status.content
    assert run_panel.stop_btn.visible and preview.run_btn.disabled and preview.time.disabled
    assert page.wait_for(lambda _m: drawn(page, "/run/left/executed"), 60)  # the executed path grows meanwhile
    assert wait_for(lambda: 'data-phase="done"' in run_panel.status.content, timeout=60)  # every tab is told
    assert wait_for(lambda: 'data-ok="true"' in preview.run_result.content)
    assert not run_panel.stop_btn.visible
    assert run_panel.progress.value == 100.0
    assert 'class="run-result" data-ok="true"' in preview.run_result.content
    assert not preview.run_btn.disabled
    # The executed path, drawn in its colour, lies on the plan (what was computed is what is drawn).
    plan = ctl.execution.plan
    assert plan is not None
    planned = ctl.baxter.fk_batch("left", plan.q[::5, :7])[0]

    def executed() -> tuple[np.ndarray, tuple[int, ...], bool]:
        got = drawn(page, "/run/left/executed")
        assert got is not None
        return got

    # the whole run has reached the page once the drawing ends where the plan ends
    assert page.wait_for(lambda _m: np.linalg.norm(executed()[0][-1] - planned[-1]) < 3e-3)
    pts, color, shown = executed()
    assert color == EXECUTED_COLOR and shown
    assert len(pts) > 500
    assert np.min(np.linalg.norm(pts[::5, None, :] - planned[None, :, :], axis=2), axis=1).max() < 3e-3
    # The "Robot's run" layer hides and shows it.
    ctl.view.set_shown(Layer.EXECUTION, False)
    assert page.wait_for(lambda _m: not executed()[2])
    ctl.view.set_step(Step.TEACH)
    ctl.view.set_step(Step.PREVIEW)
    assert page.wait_for(lambda _m: executed()[2])
    # A new skill: the last run was of the old one, so its drawing and words go.
    ctl.training.train().result()
    assert page.wait_for(lambda _m: drawn(page, "/run/left/executed") is None)
    assert 'data-phase="idle"' in run_panel.status.content and preview.run_result.content == ""


def test_the_status_light_and_the_simulated_robots_faults_in_the_panel(app: Studio) -> None:
    ctl, run_panel = app.controller, app.panels.run
    assert 'data-light="enabled"' in run_panel.light.content and not run_panel.enable_btn.visible
    ctl.execution.robot.cause("Press the robot's e-stop button")
    assert 'data-light="e-stopped"' in run_panel.light.content
    assert "emergency-stop button is pressed" in run_panel.light.content and run_panel.enable_btn.visible
    ctl.execution.robot.cause("Release the robot's e-stop button")
    ctl.execution.robot.enable()
    assert 'data-light="enabled"' in run_panel.light.content and not run_panel.enable_btn.visible
    ctl.execution.robot.cause("Disconnect the robot")
    assert 'data-light="disconnected"' in run_panel.light.content
    assert "Connection to the robot lost" in run_panel.light.content
    ctl.execution.robot.cause("Reconnect the robot")
    assert 'data-light="enabled"' in run_panel.light.content


def test_the_emergency_stop_is_not_queued_behind_another_tabs_presses(
    app: Studio, monkeypatch: pytest.MonkeyPatch
) -> None:
    """300 presses of Rename from another tab (each holding the studio's lock a moment, as a write to disk
    does) wait in viser's shared pool; the Emergency stop pressed after them takes its own path."""
    ctl = app.controller
    sim = ctl.execution.backend
    assert isinstance(sim, SimulatedBaxter)
    done: list[int] = []

    def slow_rename(i: int, name: str) -> None:  # the work of a rename: the lock held while writing
        with ctl.ctx.lock:
            time.sleep(0.02)
        done.append(1)

    monkeypatch.setattr(ctl.demos, "rename", slow_rename)
    ctl.execution.run()
    url = f"ws://127.0.0.1:{app.port}/?key={app.access.key}"
    flood, tab = ViserClient(url), ViserClient(url)
    try:
        flood.set_value("Demo", ctl.demos.names()[0])
        assert wait_for(lambda: app.panels.demos.demo_pick.value == ctl.demos.names()[0])
        tab.wait_gui("Emergency stop")
        for _ in range(300):
            flood.set_value("Demo action", "Rename")
        assert wait_for(lambda: len(done) > 0)
        tab.set_value("Emergency stop", True)
        assert wait_for(lambda: sim.emergency_stopped)
        assert len(done) < 100, f"the emergency stop waited for {len(done)} presses of another tab"
        st = ctl.execution.status
        assert st.estop and st.message.startswith("Emergency stop: the robot halted."), st.message
        # the run is judged once the studio's lock is free again: after the presses that got through, each holding
        # it a moment (on a busy machine each also waits its turn for a core)
        assert quiet_for(lambda: len(done), 1.0, timeout=300)
        assert wait_for(lambda: ctl.execution.status.phase == "emergency-stopped")
        # one tab's presses of one button join the one waiting, and beyond its burst they are ignored (decision 052)
        assert len(done) < 300, len(done)
        assert ctl.execution.status.message.startswith("Emergency stop: the robot halted at ")
    finally:
        flood.close()
        tab.close()
