"""The panels' honest words with a server: the task of the set-up, Undo after Discard, the last run marked out of
date after a change, the Run on robot warning, the skill speed, one skill length and Keep its pauses, the session box
that names the open session, an empty "New name" after New, "1 demonstration", and a restart that reopens the
last session."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from studio.app import Studio, build_app
from studio.controller import Topic
from studio.robot_backend.simulated import SimulatedBaxter
from tests.conftest import free_port, wait_for


@pytest.fixture
def fast_app(sessions: Path) -> Iterator[Studio]:
    """The studio on the "stack-cup" example whose simulated robot runs 8× faster than real time (for a run
    whose subject is not its timing)."""
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions, backend=SimulatedBaxter(time_scale=8))
    yield a
    a.stop()


def test_the_task_and_the_stand_under_the_cup_held_out(app: Studio) -> None:
    panel = app.panels.task
    assert "Take the cup I hand you" in panel.task.content
    ctl = app.controller
    held = [p for p in ctl.scene.live.poses() if p.on == "hand"]
    assert len(held) == 1
    assert wait_for(lambda: len(panel.stands()) == 1)  # drawn at the pose pump
    (stand,) = panel.stands()
    assert stand == pytest.approx(held[0].position)
    ctl.scene.use_preset("pick-place")
    assert "block" in panel.task.content
    assert wait_for(lambda: panel.stands() == [])


def test_discard_then_undo(app: Studio) -> None:
    ctl = app.controller
    panel = app.panels.task
    assert panel.undo.disabled and "Nothing to undo" in panel.undo_text.content  # a fixed slot
    n = len(ctl.session.recordings)
    ctl.teaching.start_recording()
    assert wait_for(lambda: ctl.teaching.recorder is not None and ctl.teaching.recorder.n_samples > 50)
    ctl.teaching.discard_recording()
    assert not panel.undo.disabled and "Thrown away" in panel.undo_text.content
    ctl.undo.undo()
    assert len(ctl.session.recordings) == n + 1 and panel.undo.disabled and panel.undo.visible


def test_the_last_run_goes_out_of_date_when_the_objects_move(fast_app: Studio) -> None:
    app = fast_app
    ctl = app.controller
    ctl.training.set_frames("robot")
    ctl.training.train().result()
    ctl.placed.set_speed(3.0)  # the robot runs it in a third of the time
    ctl.execution.run()
    assert wait_for(lambda: not ctl.execution.running, timeout=240), ctl.execution.status
    st = ctl.execution.status
    assert st.phase == "done" and not st.stale
    preview = app.panels.preview
    assert 'data-stale="false"' in preview.run_result.content
    bottom = ctl.scene.scene.object("bottom cup")
    ctl.scene.move("bottom cup", (bottom.position[0] + 0.115, bottom.position[1], bottom.position[2]))
    assert ctl.execution.status.stale
    assert wait_for(lambda: 'data-stale="true"' in preview.run_result.content)
    assert "Out of date:" in preview.run_result.content and "On the robot: the skill does" not in (
        preview.run_result.content
    )
    # the preview misses now: Run on robot warns (and stays possible), the moved cup is named
    result = ctl.scene.task_result()
    assert result is not None and not result.ok
    assert wait_for(lambda: "would do the same" in preview.run_reason.content)
    assert not preview.run_btn.disabled
    assert "The bottom cup is 12 cm from where it stood when you taught" in preview.reach.content


def test_skill_speed_keep_pauses_and_one_skill_length(app: Studio) -> None:
    ctl = app.controller
    ctl.training.train().result()
    preview, train = app.panels.preview, app.panels.train
    taught = ctl.playback.preview_duration()
    assert preview.skill_speed.value == "1× (as taught)" and not preview.skill_speed.disabled
    ctl.placed.set_speed(2.0)
    assert wait_for(lambda: preview.skill_speed.value == "2×")
    m = re.search(r"Learned path \(([\d.]+) s\)", preview.info.content)
    assert m and float(m.group(1)) < taught * 0.8
    # one length everywhere: Train's result line and its chart say what Preview plays
    length = ctl.placed.duration()
    assert m and float(m.group(1)) == round(length, 1)
    assert wait_for(lambda: f"The skill lasts **{length:.1f} s**" in train.status.content), train.status.content
    assert f"learned path (left, {length:.1f} s)" in train.plots.content
    # the demonstration list says the pauses it shortened; the chosen one can keep them
    demos = app.panels.demos
    assert demos.demo_pauses.value is False and not ctl.demos.keeps_pauses(0)
    row = re.search(r'data-demo="0"[^>]*>.*?</div>', demos.demo_list.content)
    assert row and re.search(r"[\d.]+ s of [\d.]+ s recorded", row.group(0)), demos.demo_list.content
    demos.demo_pick.value = ctl.demos.names()[0]  # type: ignore[misc]
    ctl.demos.set_keep_pauses(0, True)
    assert ctl.demos.keeps_pauses(0) and ctl.session.skills_stale
    assert wait_for(lambda: demos.demo_pauses.value is True)
    ctl.demos.set_keep_pauses(0, False)
    assert wait_for(lambda: demos.demo_pauses.value is False) and not ctl.demos.keeps_pauses(0)


def test_one_demonstration_is_said_in_the_singular(app: Studio) -> None:
    ctl, panel = app.controller, app.panels.sessions
    ctl.sessions.new("mine", scene="empty table")
    assert panel.current.content.endswith("· 0 demonstrations")
    ctl.teaching.start_recording()
    assert wait_for(lambda: ctl.teaching.recorder is not None and ctl.teaching.recorder.n_samples > 50)
    ctl.teaching.stop_recording()
    assert wait_for(lambda: panel.current.content.endswith("· 1 demonstration"))


def test_a_restart_reopens_the_last_session(sessions: Path) -> None:
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        a.controller.sessions.duplicate("mine")
    finally:
        a.stop()
    b = build_app(port=free_port(), session=None, sessions_dir=sessions)
    try:
        assert b.controller.session.name == "mine"
    finally:
        b.stop()


def test_the_studio_opens_its_bundled_examples_read_only(sessions: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import studio.app

    monkeypatch.setattr(studio.app, "DEFAULT_ROOT", sessions)  # this folder is the studio's own
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        assert a.controller.session.read_only
        assert "an example, kept as it is" in a.panels.sessions.current.content
        a.controller.sessions.duplicate("mine")
        assert not a.controller.session.read_only
        assert "kept as it is" not in a.panels.sessions.current.content
    finally:
        a.stop()


def test_the_position_plot_legend_sits_above_the_curves() -> None:
    import numpy as np

    from studio.panels._charts import position_plot_svg

    t = np.linspace(0.0, 2.0, 50)
    pos = np.column_stack([t, np.full_like(t, 1.0), -t])  # a curve reaching the plot's top right corner
    svg = position_plot_svg(t, pos, [10], title="demo 1 (left)", color=(0, 0, 200))
    legend = re.search(r'<text class="legend" x="[\d.]+" y="([\d.]+)"', svg)
    top = re.search(r'<rect x="[\d.]+" y="([\d.]+)"', svg)
    assert legend and top and float(legend.group(1)) < float(top.group(1))  # on the title line, not in the plot


def test_stop_says_saving_in_the_panel_until_the_take_is_kept(app: Studio) -> None:
    ctl, teach = app.controller, app.panels.teach
    said: list[str] = []
    ctl.events.on(Topic.RECORDING, lambda: said.append(str(teach.rec_status.content)))
    ctl.teaching.start_recording()
    assert wait_for(lambda: ctl.teaching.recorder is not None and ctl.teaching.recorder.n_samples > 50)
    assert wait_for(lambda: "● Recording" in str(teach.rec_status.content))
    ctl.teaching.stop_recording()
    assert said[-2:] == ["Saving the demonstration…", "Not recording."]
    assert teach.record_btn.disabled is False
