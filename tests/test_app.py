"""The studio app without a browser: teaching, recording, key-points, training, preview, replay, sessions.

Each test starts a real studio (viser server on a free port, simulated Baxter, real pipeline and session
store) on a copy of the example session and stops it at the end.
"""

from __future__ import annotations

import shutil
import socket
import time
from pathlib import Path

import numpy as np
import pytest

from studio.app import Studio, build_app, exposure_warning, robot_urdf_path
from studio.core.errors import NotEnoughData, SessionFormatError, StudioError
from studio.sessions import SessionStore

ROOT = Path(__file__).resolve().parent.parent


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for(pred, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(0.05)
    return bool(pred())


@pytest.fixture
def sessions(tmp_path: Path) -> Path:
    d = tmp_path / "sessions"
    d.mkdir()
    shutil.copytree(ROOT / "sessions" / "stack-cup", d / "stack-cup")
    return d


@pytest.fixture
def app(sessions: Path):
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    notes: list[tuple[str, str, str]] = []
    original = a.notify

    def record(title: str, body: str, *, kind: str = "error", client=None) -> None:
        notes.append((kind, title, body))
        original(title, body, kind=kind, client=client)

    a.notify = record  # type: ignore[method-assign]
    a.notes = notes  # type: ignore[attr-defined]
    yield a
    a.stop()


def test_light_robot_is_the_default_and_warning_beyond_localhost() -> None:
    assert robot_urdf_path("auto").name == "baxter_light.urdf"
    assert robot_urdf_path("full").name == "baxter.urdf"
    assert exposure_warning("127.0.0.1", 8080) is None
    w = exposure_warning("0.0.0.0", 8080)
    assert w is not None and "anyone" in w
    light = (ROOT / "urdf" / "baxter_light.urdf").read_text()
    assert "package://" not in light and 'filename="meshes/' in light  # self-contained: meshes in urdf/


def test_starts_on_the_session_and_follows_the_robot(app: Studio) -> None:
    assert app.session.name == "stack-cup"
    assert app.url() == f"http://127.0.0.1:{app.port}/?key={app.access.key}"
    assert len(app.demo_names()) == 3
    n0 = app.panels.robot.updates
    q = app.arm_q("left")
    q[3] += 0.2
    app.command_arm("left", q)
    assert wait_for(lambda: app.panels.robot.updates > n0 + 5)
    assert wait_for(lambda: abs(app.arm_q("left")[3] - q[3]) < 1e-3)


def test_gizmo_ik_reachable_and_unreachable(app: Studio) -> None:
    arm = "left"
    pos, wxyz = app.baxter.fk(arm, app.arm_q(arm))
    res = app.move_gripper(arm, pos + np.array([0.0, 0.0, 0.05]), wxyz)
    assert res.converged
    far = app.move_gripper(arm, pos + np.array([3.0, 0.0, 0.0]), wxyz)
    assert not far.converged
    teach = app.panels.teach
    teach._show_reach(arm, far.converged, pos + np.array([3.0, 0.0, 0.0]))
    assert teach.miss_markers[arm].visible and teach.unreachable[arm]


def test_record_stop_saves_to_disk_one_recording_at_a_time(app: Studio, sessions: Path) -> None:
    app.start_recording()
    with pytest.raises(StudioError, match="already running"):
        app.start_recording()
    app.move_joint(0, float(app.robot_q()[0] + 0.2))
    app.set_gripper("left", 0.0)
    assert wait_for(lambda: app.recorder is not None and app.recorder.n_samples > 600)
    app.stop_recording()
    assert app.recorder is None
    assert len(app.demo_names()) == 4
    again = SessionStore(sessions).open("stack-cup")
    assert len(again.recordings) == 4 and len(again.recordings[-1]) > 600
    app.start_recording()
    app.discard_recording()
    assert len(app.demo_names()) == 4


def test_demo_list_hide_rename_trim_delete(app: Studio) -> None:
    app.set_demo_visible(0, False)
    assert [i for i, _ in app.demos_for("left")] == [1, 2]
    app.set_demo_visible(0, True)
    app.rename_demo(1, "slow one")
    assert app.demo_names()[1] == "slow one"
    with pytest.raises(StudioError):
        app.rename_demo(0, "slow one")
    d0 = app.demo_duration(2)
    app.trim_demo(2, 1.0, d0 - 1.0)
    assert app.demo_duration(2) == pytest.approx(d0 - 2.0, abs=0.01)
    app.delete_demo(0)
    assert app.demo_names() == ["slow one", "demo 3"]
    assert len(app.panels.teach._traces) == 2


def test_keypoints_follow_the_sliders_and_k_override(app: Studio) -> None:
    v0 = app.keypoint_view()
    c0 = [d.count for d in v0.demos]
    assert len(c0) == 3 and min(c0) > 2 and v0.k["left"] >= 2
    app.set_param("eps5", 0.03)
    v1 = app.keypoint_view()
    assert sum(d.count for d in v1.demos) > sum(c0)
    app.set_k(5)
    assert app.keypoint_view().k["left"] == 5
    app.reset_params()
    assert [d.count for d in app.keypoint_view().demos] == c0
    app.panels.keypoints.draw(v1)
    assert len(app.panels.keypoints._kp_nodes) == 3
    assert sum(lab.visible for lab in app.panels.keypoints._labels) == v1.k["left"]
    assert 'data-count="' in app.panels.keypoints.counts.content


def test_train_preview_replay_export(app: Studio) -> None:
    app.train().result(timeout=120)
    assert not app.training
    skill = app.skills()["left"]
    assert skill.joint_trajectory is not None
    assert "heatmap" in app.panels.train.heatmap.content
    assert app.panels.train.plots.content.count("position-plot") == 4
    assert app.preview_duration() > 1.0

    app.preview_play(speed=4.0)
    assert wait_for(lambda: (app.preview_position() or 0.0) > 0.5)
    assert "preview" in app.display_label()
    app.preview_pause()
    app.preview_seek(1.0)
    assert app.display is not app.live

    app.replay_demo(1)
    assert wait_for(lambda: (app.replay_position() or 0.0) > 0.2)
    app.replay_seek(3.0)
    app.replay_stop()
    assert app.display is app.live

    name, data = app.joint_trajectory_csv()
    assert name.endswith(".csv") and data.startswith(b"time,left_s0")
    zname, zdata = app.session_zip()
    assert zname == "stack-cup.zip" and zdata[:2] == b"PK"


def test_training_needs_two_demos_in_plain_words(app: Studio) -> None:
    app.new_session("only-one")
    with pytest.raises(NotEnoughData, match="at least two"):
        app.train()
    assert not app.training


def test_corrupt_upload_changes_nothing(app: Studio, sessions: Path) -> None:
    before = sorted(p.name for p in sessions.iterdir())
    with pytest.raises(SessionFormatError):
        app.import_session_zip("bad.zip", b"PK\x03\x04 not a zip at all")
    assert sorted(p.name for p in sessions.iterdir()) == before
    assert app.session.name == "stack-cup"


def test_upload_of_a_downloaded_session_opens_it(app: Studio) -> None:
    _, data = app.session_zip()
    name = app.import_session_zip("stack-cup.zip", data)
    assert name != "stack-cup" and app.session.name == name
    assert len(app.demo_names()) == 3


def test_new_open_duplicate(app: Studio) -> None:
    app.new_session("lesson two")
    assert app.session.name == "lesson two" and app.demo_names() == []
    app.open_session("stack-cup")
    app.duplicate_session("stack-cup copy")
    assert app.session.name == "stack-cup copy" and len(app.demo_names()) == 3
    assert set(app.session_names()) >= {"stack-cup", "lesson two", "stack-cup copy"}


def test_both_arms(app: Studio) -> None:
    app.set_arms(("left", "right"))
    assert all(h.visible for h in app.panels.teach.handles.values())
    app.start_recording()
    assert app.recorder.arms == ("left", "right")
    app.discard_recording()
    app.set_arms(("right",))
    assert not app.panels.teach.handles["left"].visible


def test_too_many_clusters_is_a_plain_notification(app: Studio) -> None:
    app.set_k(500)
    view = app.panels.keypoints.refresh()
    assert view.messages and "left" not in view.k
    assert any(kind == "warning" and title == "Key-points" for kind, title, _ in app.notes)  # type: ignore[attr-defined]
    app.set_k(None)
    assert app.panels.keypoints.refresh().k["left"] >= 2


def test_stopping_the_studio_keeps_a_running_recording(sessions: Path) -> None:
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        a.start_recording()
        assert wait_for(lambda: a.recorder.n_samples > 200)
    finally:
        a.stop()
    assert len(SessionStore(sessions).open("stack-cup").recordings) == 4


def test_light_robot_is_light_and_coloured() -> None:
    import trimesh

    faces, colours = 0, set()
    for glb in (ROOT / "urdf" / "meshes").rglob("*.glb"):
        scene = trimesh.load(str(glb), force="scene")
        for g in scene.geometry.values():
            faces += len(g.faces)
            colours.update(map(tuple, np.unique(g.visual.face_colors[:, :3], axis=0)))
    assert 10_000 < faces < 40_000  # the original meshes have ~410,000 triangles
    assert any(r > 100 and g < 60 for r, g, _ in colours)  # Baxter's red links kept their colour
    assert any(max(c) < 80 for c in colours)  # and the dark joints theirs


def test_charts_are_plain_svg() -> None:
    from studio.panels._charts import downsample_path, heatmap_svg, position_plot_svg, segments

    svg = heatmap_svg(np.eye(4), title="A <b>")
    assert svg.startswith("<svg") and 'data-states="4"' in svg and "&lt;b&gt;" in svg
    t = np.linspace(0, 10, 5000)
    p = np.column_stack([np.sin(t), np.cos(t), t / 10])
    plot = position_plot_svg(t, p, [0, 100, 4999], title="demo", color=(1, 2, 3))
    assert 'data-keypoints="3"' in plot and plot.count("<polyline") == 3
    assert len(downsample_path(p, 600)) <= 601 and segments(p[:3]).shape == (2, 2, 3)


def test_k_override_is_kept_with_the_session(app: Studio, sessions: Path) -> None:
    app.set_k(5)
    app.persist_params()  # what the key-point thread does after each change
    assert SessionStore(sessions).open("stack-cup").n_clusters == 5
    app.new_session("automatic k")
    assert app.k_override is None and app.panels.keypoints.k_auto.value
    app.open_session("stack-cup")
    kp = app.panels.keypoints
    assert app.k_override == 5 and app.keypoint_view().k["left"] == 5
    assert not kp.k_auto.value and kp.k.value == 5 and not kp.k.disabled
    with pytest.raises(StudioError, match="at least 1"):
        app.set_k(0)
    app.reset_params()
    app.persist_params()
    assert SessionStore(sessions).open("stack-cup").n_clusters is None


def test_k_override_comes_back_after_a_restart(sessions: Path) -> None:
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        a.set_k(6)
        a.save_session()
    finally:
        a.stop()
    b = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        assert b.k_override == 6 and b.panels.keypoints.k.value == 6 and not b.panels.keypoints.k_auto.value
    finally:
        b.stop()


def test_buttons_that_cannot_act_now_are_disabled(app: Studio, sessions: Path) -> None:
    teach, files = app.panels.teach, app.panels.sessions
    assert not teach.record_btn.disabled and teach.stop_btn.disabled and teach.discard_btn.disabled
    assert files.export.disabled and not files.upload.disabled and files.replay_time.disabled
    app.start_recording()
    assert teach.record_btn.disabled and not teach.stop_btn.disabled and not teach.discard_btn.disabled
    assert files.upload.disabled
    _, data = app.session_zip()
    before = sorted(p.name for p in sessions.iterdir())
    with pytest.raises(StudioError, match="Stop the recording"):  # a raced click still gets plain words
        app.import_session_zip("copy.zip", data)
    assert sorted(p.name for p in sessions.iterdir()) == before
    app.discard_recording()
    assert not teach.record_btn.disabled and teach.stop_btn.disabled and not files.upload.disabled
    with pytest.raises(StudioError, match="Nothing is being recorded"):
        app.stop_recording()
    app.replay_demo(0)
    assert not files.replay_time.disabled
    app.replay_stop()
    assert files.replay_time.disabled
    app.set_demo_visible(0, False)  # trained from demos 2 and 3 only: the session remembers which
    app.train().result(timeout=120)
    assert not files.export.disabled
    assert app.session.skill_info["left"]["demos"] == app.demo_names()[1:]
    assert SessionStore(sessions).open("stack-cup").skill_info["left"]["demos"] == app.demo_names()[1:]


def test_a_k_outside_the_slider_range_still_opens(sessions: Path) -> None:
    SessionStore(sessions).open("stack-cup").set_n_clusters(500)  # possible from code, not from the slider
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        assert a.k_override == 500 and a.panels.keypoints.k.value == 40
        a.session.set_n_clusters(1)
        a.open_session("stack-cup")
        assert a.k_override == 1 and a.panels.keypoints.k.value == 2
    finally:
        a.stop()


# -- regressions (review of the app layer) -------------------------------------------------------------


def test_sessions_cannot_change_while_training(app: Studio, sessions: Path) -> None:
    _, data = app.session_zip()
    before = sorted(p.name for p in sessions.iterdir())
    fut = app.train()
    assert app.panels.sessions.upload.disabled
    for action in (
        lambda: app.new_session("other"),
        lambda: app.open_session("stack-cup"),
        lambda: app.duplicate_session("copy"),
        lambda: app.import_session_zip("copy.zip", data),
    ):
        with pytest.raises(StudioError, match="Wait for the training to finish"):
            action()
    fut.result(timeout=120)
    assert not app.training and app.session.name == "stack-cup" and not app.panels.sessions.upload.disabled
    assert sorted(p.name for p in sessions.iterdir()) == before
    assert "left" in SessionStore(sessions).open("stack-cup").skills
    assert any(title == "Training finished" for _, title, _ in app.notes)  # type: ignore[attr-defined]


def test_eps_changed_during_training_is_kept(app: Studio, sessions: Path) -> None:
    trained_eps5 = app.params().eps5
    fut = app.train()
    app.set_param("eps5", 0.33)
    app.persist_params()
    fut.result(timeout=120)
    assert app.params().eps5 == 0.33 and app.session.params.eps5 == 0.33
    again = SessionStore(sessions).open("stack-cup")
    assert again.params.eps5 == 0.33
    assert again.skill_info["left"]["params"]["eps5"] == trained_eps5  # the skill remembers what it used


def test_retraining_unloads_the_old_preview(app: Studio) -> None:
    app.train().result(timeout=120)
    app.preview_play(speed=4.0)
    app.preview_pause()
    app.set_demo_visible(0, False)
    app.train().result(timeout=120)
    assert app.playback_kind() is None and app.display is app.live
    app.preview_play()
    assert app._playback is not None
    assert app._playback.recording.duration == pytest.approx(app.preview_duration(), abs=0.02)
    assert "Stop" in app.panels.preview.controls.options  # Stop in Preview: back to the live robot
    app.preview_stop()
    assert app.playback_kind() is None and app.display is app.live


def _loglik_rows(app: Studio) -> list[str]:
    import re

    return re.findall(r'<tr class="loglik-row"><td>(.*?)</td>', app.panels.train.summary.content)


def test_train_panel_rows_stay_matched_to_the_skill(app: Studio) -> None:
    app.train().result(timeout=120)
    assert _loglik_rows(app) == ["demo 1", "demo 2", "demo 3"]
    app.rename_demo(0, "first try")  # the panel follows demo changes, rows keep the skill's order
    assert _loglik_rows(app) == ["demo 1 (renamed or deleted since)", "demo 2", "demo 3"]
    assert app.panels.train.plots.content.count("position-plot") == 3  # demos 2, 3 and the learned path
    app.delete_demo(1)
    assert _loglik_rows(app) == ["demo 1 (renamed or deleted since)", "demo 2 (renamed or deleted since)", "demo 3"]
    assert app.panels.train.plots.content.count("position-plot") == 2
    assert "out of date" in app.panels.train.status.content


def test_arms_cannot_change_while_recording(app: Studio) -> None:
    app.start_recording()
    assert app.panels.robot.arms.disabled
    with pytest.raises(StudioError, match="Stop the recording before changing the arms to teach"):
        app.set_arms(("right",))
    assert app.selected_arms == ("left",) and app.recorder.arms == ("left",)
    app.discard_recording()
    assert not app.panels.robot.arms.disabled
    app.set_arms(("right",))
    assert app.selected_arms == ("right",)


def test_duplicate_is_refused_while_recording_and_checks_the_name_first(app: Studio) -> None:
    app.start_recording()
    with pytest.raises(StudioError, match="Stop the recording"):
        app.duplicate_session("copy")
    app.discard_recording()
    assert "copy" not in app.session_names() and app.session.name == "stack-cup"
    app.new_session("taken")
    app.open_session("stack-cup")
    with pytest.raises(StudioError, match="already exists"):
        app.duplicate_session("taken")
    assert not any(title == "Saved" for _, title, _ in app.notes)  # type: ignore[attr-defined]
    for action in (app.new_session, app.duplicate_session):
        with pytest.raises(StudioError, match="Type a name in 'New name' first"):
            action("  ")
    assert app.session.name == "stack-cup"


def test_unsaved_eps_values_survive_switching_and_stopping(app: Studio, sessions: Path) -> None:
    app.set_param("eps5", 0.41)  # not yet written by the key-point thread
    app.new_session("x")
    assert SessionStore(sessions).open("x").params.eps5 != 0.41
    app.open_session("stack-cup")
    assert app.params().eps5 == 0.41
    app.set_param("eps5", 0.37)
    app.stop()
    assert SessionStore(sessions).open("stack-cup").params.eps5 == 0.37


def test_demos_are_read_from_one_list(app: Studio, monkeypatch: pytest.MonkeyPatch) -> None:
    recs = list(app.session.recordings)
    calls = iter([recs] + [recs[1:]] * 100)  # the first demo is deleted right after the list was read
    monkeypatch.setattr(app, "recordings", lambda: list(next(calls)))
    assert [d.name for _, d in app.demos_for("left")] == [r.name for r in recs]


class _FakeTab:
    def __init__(self) -> None:
        self.titles: list[str] = []

    def add_notification(self, title: str, body: str, **kwargs: object) -> None:
        self.titles.append(title)


def test_a_recovery_is_told_once_not_to_every_new_tab(sessions: Path) -> None:
    from studio.recorder import Recorder
    from studio.robot_backend.simulated import SimulatedBaxter
    from studio.sessions import RECORDING_DIR

    sim = SimulatedBaxter()
    rec = Recorder(sim, sessions / "stack-cup" / RECORDING_DIR, arms="left")
    rec.start()
    sim.step(500)
    rec.flush()
    rec._finish()  # as if the studio had died while recording
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        first, second = _FakeTab(), _FakeTab()
        a._greet(first)  # type: ignore[arg-type]
        a._greet(second)  # type: ignore[arg-type]
        assert first.titles == ["Recovered recordings"] and second.titles == []
        assert len(a.demo_names()) == 4
    finally:
        a.stop()


def test_hidden_demos_stay_hidden_after_a_restart(sessions: Path) -> None:
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        a.set_demo_visible(1, False)
        a.rename_demo(1, "wobbly")
    finally:
        a.stop()
    b = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        assert not b.demo_visible(1) and b.demo_visible(0) and b.demo_visible(2)
        assert [i for i, _ in b.demos_for("left")] == [0, 2]  # training leaves it out
        assert "hidden" in b.panels.teach.demo_list.content  # the list says so
    finally:
        b.stop()


def test_delete_asks_for_a_second_press(app: Studio) -> None:
    names = app.demo_names()
    assert app.delete_demo_confirmed(0, now=100.0) is False  # first press only asks
    assert app.demo_names() == names
    assert any(kind == "warning" and "Press Delete again" in body for kind, _, body in app.notes)  # type: ignore[attr-defined]
    assert app.delete_demo_confirmed(0, now=100.0 + app.DELETE_CONFIRM_S + 1) is False  # too late: asks again
    assert app.demo_names() == names
    assert app.delete_demo_confirmed(1, now=107.0) is False  # another demo: asks for that one
    assert app.delete_demo_confirmed(1, now=108.0) is True
    assert app.demo_names() == [names[0], names[2]]
