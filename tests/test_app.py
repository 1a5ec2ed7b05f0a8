"""The studio app without a browser: the viser server, the panels and what they show, over the controller.

Each test starts a real studio (viser server on a free port, simulated Baxter, real pipeline and session
store) on a copy of the example session and stops it at the end. The controller's own behaviour is tested
without a server in test_controller.py.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from studio.app import Studio, build_app, exposure_warning, robot_urdf_path
from studio.controller import PREVIEW, Step, Topic
from studio.core.errors import StudioError
from studio.core.types import Arm
from studio.panels.keypoints import LABEL_GAP, MAX_LABELS
from studio.recorder import Recorder
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import RECORDING_DIR, SessionStore
from tests.conftest import ROOT, RecordingNotifier, free_port, wait_for
from tests.viser_client import ViserClient


@pytest.fixture
def page(app: Studio) -> Iterator[ViserClient]:
    """A tab of the studio (viser's websocket protocol, no browser): the scene as the page receives it."""
    c = ViserClient.tab_of(app)
    assert c.wait_for(lambda _m: c.layer("/keypoints/left") and c.layer("/demos"), 30)
    yield c
    c.close()


def points(node: dict) -> np.ndarray:
    """A drawn point cloud's or line segments' points as the page received them, one row per point."""
    return np.asarray(node["props"]["points"], dtype=float).reshape(-1, 3)


def notes(app: Studio) -> list[tuple[str, str, str]]:
    notifier = app.controller.notifier
    assert isinstance(notifier, RecordingNotifier)
    return notifier.notes


def test_light_robot_is_the_default_and_warning_beyond_localhost() -> None:
    assert robot_urdf_path("auto").name == "baxter_light.urdf"
    assert robot_urdf_path("full").name == "baxter.urdf"
    assert exposure_warning("127.0.0.1", 8080) is None
    w = exposure_warning("0.0.0.0", 8080)
    assert w is not None and "anyone" in w
    light = (ROOT / "urdf" / "baxter_light.urdf").read_text()
    assert "package://" not in light and 'filename="meshes/' in light  # self-contained: meshes in urdf/


def test_starts_on_the_session_and_follows_the_robot(app: Studio) -> None:
    ctl = app.controller
    assert ctl.session.name == "stack-cup"
    assert app.url() == f"http://127.0.0.1:{app.port}/?key={app.access.key}"
    assert len(ctl.demos.names()) == 3
    n0 = app.panels.robot.updates
    q = ctl.teaching.arm_q("left")
    q[3] += 0.2
    ctl.teaching.command_arm("left", q)
    assert wait_for(lambda: app.panels.robot.updates > n0 + 5)
    assert wait_for(lambda: abs(ctl.teaching.arm_q("left")[3] - q[3]) < 1e-3)


def test_unreachable_handle_is_marked_and_told(app: Studio) -> None:
    ctl, teach, robot = app.controller, app.panels.teach, app.panels.robot
    arm: Arm = "left"
    pos, wxyz = ctl.baxter.fk(arm, ctl.teaching.arm_q(arm))
    far = ctl.teaching.move_gripper(arm, pos + np.array([3.0, 0.0, 0.0]), wxyz)
    assert not far.converged
    assert teach.miss_markers[arm].visible and teach.miss_labels[arm].visible
    assert np.allclose(teach.miss_markers[arm].position, pos + np.array([3.0, 0.0, 0.0]))
    assert wait_for(lambda: "cannot reach" in robot.status.content)
    back, back_wxyz = ctl.baxter.fk(arm, far.q)  # where the arm stopped: within reach again
    near = ctl.teaching.move_gripper(arm, back, back_wxyz)
    assert near.converged and not teach.miss_markers[arm].visible
    assert wait_for(lambda: "cannot reach" not in robot.status.content)


def test_an_out_of_reach_drag_says_where_the_gripper_stopped(app: Studio, page: ViserClient) -> None:
    """The gripper stops at the closest pose it reaches; the words say how far short and, when its height changed
    (a later key moves from there), by how much and where it is now."""
    ctl = app.controller
    handle = lambda: page.scene()["/teach/left_handle"]  # noqa: E731
    assert page.wait_for(lambda _m: handle()["visible"] and handle()["position"] is not None)
    start = np.array(handle()["position"], dtype=float)
    target = (float(start[0] + 0.9), float(start[1]), float(start[2] + 0.4))  # far in front of it and high
    page.drag("/teach/left_handle", target)
    assert wait_for(lambda: any(title == "Out of reach" for _, title, _ in notes(app)))
    body = next(b for _, title, b in notes(app) if title == "Out of reach")
    reached = ctl.guide.pose("left")[0]
    up = reached[2] - target[2]
    assert abs(up) > 0.01  # the arm could not keep the handle's height
    short = np.hypot(target[0] - reached[0], target[1] - reached[1])
    assert re.search(rf"{short * 100:.0f} cm short of it", body), body
    assert f"{'higher' if up > 0 else 'lower'} than the handle" in body, body
    assert f"now {reached[2] * 100:.1f} cm high (z), the handle was at {target[2] * 100:.1f} cm" in body, body


def test_demo_edits_redraw_the_traces(app: Studio, page: ViserClient) -> None:
    demos = app.controller.demos
    demos.set_visible(0, False)
    assert page.wait_for(lambda _m: sum(page.layer("/demos").values()) == 2)
    assert "hidden" in app.panels.demos.demo_list.content
    demos.set_visible(0, True)
    assert page.wait_for(lambda _m: sum(page.layer("/demos").values()) == 3)
    demos.delete(0)
    assert page.wait_for(lambda _m: len(page.layer("/demos")) == 2)


def test_a_renamed_demo_stays_chosen_and_a_delete_chooses_the_last(app: Studio, page: ViserClient) -> None:
    """The chosen demonstration once jumped to the last one when it was renamed (a Trim pressed next trimmed
    another demonstration than the one just renamed), and the replay's to the first."""
    panel, demos = app.panels.demos, app.controller.demos
    first = demos.names()[0]
    page.set_value("Demo", first)
    assert wait_for(lambda: panel.demo_name.value == first)
    page.set_value("Name", "pour, first try")
    assert wait_for(lambda: panel.demo_name.value == "pour, first try")
    page.set_value("Demo action", "Rename")
    assert wait_for(lambda: demos.names()[0] == "pour, first try")
    assert wait_for(lambda: panel.demo_pick.value == "pour, first try"), panel.demo_pick.value  # the list redrawn
    assert panel.demo_name.value == "pour, first try"
    replay = app.panels.sessions.replay_pick  # the replay's list follows the rename too
    assert wait_for(lambda: replay.value == "pour, first try"), replay.value
    page.set_value("Demo action", "Delete")
    assert wait_for(lambda: len(demos.names()) == 2)
    assert wait_for(lambda: panel.demo_pick.value == demos.names()[-1]), panel.demo_pick.value
    assert wait_for(lambda: replay.value == demos.names()[0]), replay.value


def test_keypoints_are_drawn(app: Studio, page: ViserClient) -> None:
    kp = app.controller.keypoints
    kp.set_param("eps5", 0.03)
    v1 = kp.compute()
    app.panels.keypoints.draw(v1)
    counts = [d.count for d in v1.demos]

    def drawn_counts() -> list[int]:
        return [len(points(page.scene()[f"/keypoints/left/demo{i}"])) for i in range(3)]

    assert page.wait_for(lambda _m: drawn_counts() == counts)
    assert not any(page.layer("/keypoints/labels").values())  # Teach shows no cluster centres
    app.controller.view.set_step("Key-points")
    assert page.wait_for(lambda _m: any(page.layer("/keypoints/labels").values()))
    labels = page.scene()
    shown = [np.asarray(labels[n]["position"]) for n, on in page.layer("/keypoints/labels").items() if on]
    assert 0 < len(shown) <= min(v1.k["left"], MAX_LABELS)  # numbers that would pile up are left out
    gaps = [np.linalg.norm(a - b) for i, a in enumerate(shown) for b in shown[i + 1 :]]
    assert min(gaps, default=1.0) >= LABEL_GAP - 1e-3  # (positions travel as float32)
    assert all(on for n, on in page.layer("/keypoints/left").items() if "/demo" in n)
    assert 'data-count="' in app.panels.keypoints.counts.content


def test_train_panel_and_preview_after_training(app: Studio) -> None:
    ctl = app.controller
    ctl.training.train().result(timeout=120)
    assert "heatmap" in app.panels.train.heatmap.content
    assert app.panels.train.plots.content.count("position-plot") == 4
    ctl.playback.play_preview(speed=4.0)
    assert wait_for(lambda: (ctl.playback.position(PREVIEW) or 0.0) > 0.5)
    assert wait_for(lambda: "preview" in app.panels.robot.status.content)
    assert "Stop" in app.panels.preview.controls.options  # Stop in Preview: back to the live robot
    ctl.playback.stop(PREVIEW)
    assert ctl.display.is_live


def test_both_arms(app: Studio) -> None:
    ctl = app.controller
    ctl.teaching.set_arms(("left", "right"))
    assert all(h.visible for h in app.panels.teach.handles.values())
    ctl.teaching.start_recording()
    recorder = ctl.teaching.recorder
    assert recorder is not None and recorder.arms == ("left", "right")
    ctl.teaching.discard_recording()
    ctl.teaching.set_arms(("right",))
    assert not app.panels.teach.handles["left"].visible


def test_stopping_the_studio_keeps_a_running_recording(sessions: Path) -> None:
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        a.controller.teaching.start_recording()
        assert wait_for(lambda: (r := a.controller.teaching.recorder) is not None and r.n_samples > 200)
    finally:
        a.stop()
    assert len(SessionStore(sessions).open("stack-cup").recordings) == 4


def test_light_robot_is_light_and_coloured() -> None:
    import trimesh

    faces, colours = 0, set[tuple[int, ...]]()
    for glb in (ROOT / "urdf" / "meshes").rglob("*.glb"):
        scene = trimesh.load(str(glb), force="scene")
        assert isinstance(scene, trimesh.Scene)
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
    ctl, kp = app.controller, app.panels.keypoints
    ctl.keypoints.set_k(5)
    ctl.keypoints.persist()  # what the key-point thread does after each change
    assert SessionStore(sessions).open("stack-cup").n_clusters == 5
    ctl.sessions.new("automatic k")
    assert ctl.keypoints.k is None and kp.k_auto.value
    ctl.sessions.open("stack-cup")
    assert ctl.keypoints.k == 5 and ctl.keypoints.compute().k["left"] == 5
    assert not kp.k_auto.value and kp.k.value == 5 and not kp.k.disabled
    with pytest.raises(StudioError, match="at least 1"):
        ctl.keypoints.set_k(0)
    ctl.keypoints.reset()
    ctl.keypoints.persist()
    assert SessionStore(sessions).open("stack-cup").n_clusters is None


def test_k_override_comes_back_after_a_restart(sessions: Path) -> None:
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        a.controller.keypoints.set_k(6)
        a.controller.sessions.save()
    finally:
        a.stop()
    b = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        kp = b.panels.keypoints
        assert b.controller.keypoints.k == 6 and kp.k.value == 6 and not kp.k_auto.value
    finally:
        b.stop()


def test_buttons_that_cannot_act_now_are_disabled(app: Studio, sessions: Path) -> None:
    ctl = app.controller
    teach, files = app.panels.teach, app.panels.sessions
    assert not teach.record_btn.disabled and teach.stop_btn.disabled and teach.discard_btn.disabled
    assert files.export.disabled and not files.upload.disabled and files.replay_time.disabled
    ctl.teaching.start_recording()
    assert teach.record_btn.disabled and not teach.stop_btn.disabled and not teach.discard_btn.disabled
    assert files.upload.disabled
    _, data = ctl.sessions.zip()
    before = sorted(p.name for p in sessions.iterdir())
    with pytest.raises(StudioError, match="Stop the recording"):  # a raced click still gets plain words
        ctl.sessions.import_zip("copy.zip", data)
    assert sorted(p.name for p in sessions.iterdir()) == before
    ctl.teaching.discard_recording()
    assert not teach.record_btn.disabled and teach.stop_btn.disabled and not files.upload.disabled
    with pytest.raises(StudioError, match="Nothing is being recorded"):
        ctl.teaching.stop_recording()
    ctl.playback.play_demo(0)
    assert not files.replay_time.disabled
    ctl.playback.stop("replay")
    assert files.replay_time.disabled
    ctl.demos.set_visible(0, False)  # trained from demos 2 and 3 only: the session remembers which
    ctl.training.train().result(timeout=120)
    assert not files.export.disabled
    assert list(ctl.session.skill_info["left"].demos) == ctl.demos.names()[1:]
    assert list(SessionStore(sessions).open("stack-cup").skill_info["left"].demos) == ctl.demos.names()[1:]


def test_a_k_outside_the_slider_range_still_opens(sessions: Path) -> None:
    SessionStore(sessions).open("stack-cup").set_n_clusters(500)  # possible from code, not from the slider
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        assert a.controller.keypoints.k == 500 and a.panels.keypoints.k.value == 40
        a.controller.session.set_n_clusters(1)
        a.controller.sessions.open("stack-cup")
        assert a.controller.keypoints.k == 1 and a.panels.keypoints.k.value == 2
    finally:
        a.stop()


# -- regressions (review of the app layer) -------------------------------------------------------------


def test_sessions_cannot_change_while_training(app: Studio, sessions: Path) -> None:
    ctl = app.controller
    _, data = ctl.sessions.zip()
    before = sorted(p.name for p in sessions.iterdir())
    fut = ctl.training.train()
    assert app.panels.sessions.upload.disabled
    for action in (
        lambda: ctl.sessions.new("other"),
        lambda: ctl.sessions.open("stack-cup"),
        lambda: ctl.sessions.duplicate("copy"),
        lambda: ctl.sessions.import_zip("copy.zip", data),
    ):
        with pytest.raises(StudioError, match="Wait for the training to finish"):
            action()
    fut.result(timeout=120)
    assert not ctl.training.busy and ctl.session.name == "stack-cup" and not app.panels.sessions.upload.disabled
    assert sorted(p.name for p in sessions.iterdir()) == before
    assert "left" in SessionStore(sessions).open("stack-cup").skills
    assert any(title == "Training finished" for _, title, _ in notes(app))


def _loglik_rows(app: Studio) -> list[str]:
    """The per-demo rows of the Train panel ("fits the skill: well / poorly"), in the skill's order."""
    return re.findall(r'<tr class="fit-row" data-well="[01]?"><td>(.*?)</td>', app.panels.train.summary.content)


def test_train_panel_rows_stay_matched_to_the_skill(app: Studio) -> None:
    ctl = app.controller
    ctl.training.train().result(timeout=120)
    assert _loglik_rows(app) == ["demo 1", "demo 2", "demo 3"]
    ctl.demos.rename(0, "first try")  # the panel follows demo changes, rows keep the skill's order
    assert _loglik_rows(app) == ["demo 1 (renamed or deleted since)", "demo 2", "demo 3"]
    assert app.panels.train.plots.content.count("position-plot") == 3  # demos 2, 3 and the learned path
    ctl.demos.delete(1)
    assert _loglik_rows(app) == ["demo 1 (renamed or deleted since)", "demo 2 (renamed or deleted since)", "demo 3"]
    assert app.panels.train.plots.content.count("position-plot") == 2
    assert "out of date" in app.panels.train.status.content


def test_arms_cannot_change_while_recording(app: Studio) -> None:
    ctl = app.controller
    ctl.teaching.start_recording()
    assert app.panels.robot.arms.disabled
    with pytest.raises(StudioError, match="Stop the recording before changing the arms to teach"):
        ctl.teaching.set_arms(("right",))
    recorder = ctl.teaching.recorder
    assert ctl.teaching.selected_arms == ("left",) and recorder is not None and recorder.arms == ("left",)
    ctl.teaching.discard_recording()
    assert not app.panels.robot.arms.disabled
    ctl.teaching.set_arms(("right",))
    assert ctl.teaching.selected_arms == ("right",)


def test_unsaved_eps_values_survive_switching_and_stopping(app: Studio, sessions: Path) -> None:
    ctl = app.controller
    ctl.keypoints.set_param("eps5", 0.41)  # not yet written by the key-point thread
    ctl.sessions.new("x")
    assert SessionStore(sessions).open("x").params.eps5 != 0.41
    ctl.sessions.open("stack-cup")
    assert ctl.keypoints.params().eps5 == 0.41
    ctl.keypoints.set_param("eps5", 0.37)
    app.stop()
    assert SessionStore(sessions).open("stack-cup").params.eps5 == 0.37


class _FakeTab:
    def __init__(self) -> None:
        self.titles: list[str] = []

    def add_notification(self, title: str, body: str, **kwargs: object) -> None:
        self.titles.append(title)


def test_a_recovery_is_told_once_not_to_every_new_tab(sessions: Path) -> None:
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
        assert len(a.controller.demos.names()) == 4
    finally:
        a.stop()


def test_hidden_demos_stay_hidden_after_a_restart(sessions: Path) -> None:
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        a.controller.demos.set_visible(1, False)
        a.controller.demos.rename(1, "wobbly")
    finally:
        a.stop()
    b = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    try:
        demos = b.controller.demos
        assert not demos.visible(1) and demos.visible(0) and demos.visible(2)
        assert [i for i, _ in demos.for_arm("left")] == [0, 2]  # training leaves it out
        assert "hidden" in b.panels.demos.demo_list.content  # the list says so
    finally:
        b.stop()


# -- the key-points and train panels: automatic thresholds, units, Suggest, verdict, live path ---------------


def test_the_clusters_box_shows_the_k_in_use(app: Studio) -> None:
    kp, ctl = app.panels.keypoints, app.controller
    view = ctl.keypoints.refresh()
    assert ctl.keypoints.k is None and kp.k.disabled and kp.k_auto.value
    assert kp.k.value == view.k["left"] != 12  # not the slider's default while the text says another number
    assert f'data-k="{view.k["left"]}"' in kp.counts.content


def test_sliders_show_real_units_and_whose_values_they_are(app: Studio, page: ViserClient) -> None:
    import math

    from studio.core.thresholds import auto_params

    kp, ctl = app.panels.keypoints, app.controller
    auto = auto_params([d for _, d in ctl.demos.for_arm("left")])
    s1, s5, s12 = kp.sliders["eps1"], kp.sliders["eps5"], kp.sliders["eps12"]
    assert s1.label == "Corner sharpness, °" and s1.min == 180 and s1.max == 360
    assert s1.value == pytest.approx(math.degrees(auto.eps1), abs=0.1)  # stored in radians, shown in degrees
    assert s12.value == pytest.approx(math.degrees(auto.eps12), abs=0.1)
    assert s5.label == "Travel distance, cm" and s5.value == pytest.approx(100 * auto.eps5, abs=0.05)
    assert "follows your demonstrations" in kp.thresholds.whose.content and kp.thresholds.make_auto.disabled
    page.set_value("Travel distance, cm", 4.5)  # the teacher drags it
    # the label first, then the line saying whose values they are: both waited for (the panel sets them in turn)
    assert wait_for(
        lambda: s5.label == "Travel distance, cm · yours" and 'data-yours="1"' in kp.thresholds.whose.content
    )
    assert ctl.keypoints.params().eps5 == pytest.approx(0.045)
    assert kp.thresholds.yours.value == s5.label.split(" ·")[0]
    ctl.keypoints.set_detail(-2.0)  # Detail moves the automatic ones, the teacher's stays
    assert kp.detail.value == -2.0 and s5.value == 4.5 and ctl.keypoints.params().eps7 > auto.eps7
    page.set_value("Make it automatic", True)
    assert wait_for(lambda: ctl.keypoints.settings().is_auto("eps5") and s5.label == "Travel distance, cm")
    assert s5.value == pytest.approx(100 * ctl.keypoints.params().eps5, abs=0.05)


def test_a_slider_the_teacher_just_moved_is_not_put_back_by_a_view_computed_before(app: Studio) -> None:
    kp, ctl = app.panels.keypoints, app.controller
    ctl.keypoints.refresh()
    s5 = kp.thresholds.sliders["eps5"]
    auto5 = float(s5.value)
    s5.value = auto5 + 0.5  # type: ignore[misc]  # the teacher's move reached the slider; its callback has not run yet
    kp.thresholds.sync()  # a key-point view computed before the move is shown meanwhile
    assert s5.value == pytest.approx(auto5 + 0.5)
    ctl.keypoints.set_param("eps5", (auto5 + 0.5) / 100)  # the callback
    kp.thresholds.sync(every=True)
    assert s5.value == pytest.approx(auto5 + 0.5)


def test_train_panel_says_how_good_the_skill_is(app: Studio, page: ViserClient) -> None:
    ctl, train = app.controller, app.panels.train
    ctl.training.train().result(timeout=120)
    assert wait_for(lambda: 'data-level="good"' in train.verdict.content, 120)
    assert "Good: the skill follows your demonstrations closely (within " in train.verdict.content
    assert train.summary.content.count('class="fit-row" data-well="1"') == 3  # each demo fits well
    assert "How closely the learned path follows each demonstration." in train.summary.content
    assert "log-likelihood" not in train.summary.content
    assert 'data-mode="aligned-mean"' in train.summary.content and "Follow the demonstrations" in train.summary.content
    assert re.search(r"Zero-points [^:]*: (none|states? \d)", train.summary.content)
    assert "to state →" in train.heatmap.content and "time, s" in train.plots.content
    page.set_value("Path", train.mode.options[1])  # the curious choose the paper's spline
    assert wait_for(lambda: ctl.training.generalization == "paper")


def test_suggest_controls_show_progress_and_undo(app: Studio) -> None:
    ctl, sc = app.controller, app.panels.keypoints.suggest
    ctl.suggest.workers = 1
    seen: list[tuple[bool, bool]] = []
    ctl.events.on(Topic.SUGGEST, lambda: seen.append((sc.progress.visible, sc.stop.visible)))
    assert not sc.undo.visible and not sc.progress.visible
    ctl.keypoints.set_param("eps5", 0.3)  # far too few key-points: Suggest has something better to offer
    ctl.suggest.start().result(timeout=120)
    assert (True, True) in seen  # the progress bar and Stop while it searched
    assert not sc.progress.visible and sc.undo.visible and "misses it by" in sc.text.content
    ctl.suggest.undo()
    assert not sc.undo.visible and "Undone" in sc.text.content


def test_live_path_is_drawn_dashed_with_the_key_points_layer(app: Studio, page: ViserClient) -> None:
    from studio.controller import Layer

    ctl, kp = app.controller, app.panels.keypoints
    live = "/keypoints/left/live-path"
    ctl.view.set_step(Step.KEYPOINTS)
    assert page.wait_for(lambda _m: page.layer("/keypoints/left").get(live), 60)
    assert points(page.scene()[live]).shape == (120, 3)  # 60 dashes, two ends each
    assert "The learned path would stay within" in kp.live_text.content
    ctl.view.set_shown(Layer.KEYPOINTS, False)  # the key-points and the live path (the centres stay)
    assert page.wait_for(
        lambda _m: not any(on for n, on in page.layer("/keypoints/left").items() if not n.endswith("/centroids"))
    )
    ctl.view.set_shown(Layer.CENTROIDS, False)
    assert page.wait_for(lambda _m: not any(page.layer("/keypoints/labels").values()))
    ctl.view.set_step(Step.TRAIN)
    assert page.wait_for(lambda _m: not page.layer("/keypoints/left").get(live))


def test_markers_go_with_their_live_path_and_never_wait_for_a_failed_one(
    app: Studio, page: ViserClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    import studio.core.pipeline as pipeline

    ctl = app.controller
    ctl.view.set_step(Step.KEYPOINTS)
    assert wait_for(lambda: "left" in ctl.live.paths, 60)
    ctl.keypoints.set_param("eps5", 0.02)  # many more key-points

    def drawn() -> list[int]:
        return [len(points(page.scene()[f"/keypoints/left/demo{i}"])) for i in range(3)]

    assert wait_for(lambda: ctl.keypoints.view is not None and ctl.keypoints.view.params["left"].eps5 == 0.02)
    view = ctl.keypoints.view
    assert view is not None
    version = view.version
    assert wait_for(lambda: ctl.live.paths["left"].version == version, 60)
    counts = [d.count for d in view.demos]
    assert page.wait_for(lambda _m: drawn() == counts)  # the markers with their path

    def broken(*args: object, **kwargs: object) -> object:
        raise RuntimeError("no path today")

    monkeypatch.setattr(pipeline, "preview_path", broken)
    ctl.keypoints.set_param("eps5", 0.2)
    assert wait_for(lambda: ctl.live.paths == {})  # the failure was told; no path …
    view = ctl.keypoints.view
    assert view is not None  # … and the markers still came
    counts = [d.count for d in view.demos]
    assert page.wait_for(lambda _m: drawn() == counts)
    # told right after the paths were emptied (the failure leaves the follower, then it is reported)
    assert wait_for(lambda: any(title == "Could not draw the learned path" for _, title, _ in notes(app)))


def test_centroid_numbers_never_pile_up() -> None:
    from studio.panels.keypoints import spaced

    line = np.column_stack([np.linspace(0.0, 0.6, 40), np.zeros(40), np.zeros(40)])  # 40 centres, 1.5 cm apart
    room = spaced(line, LABEL_GAP)
    kept = line[np.asarray(room)]
    assert 2 <= len(kept) <= MAX_LABELS and room[0]
    assert np.min(np.diff(kept[:, 0])) >= LABEL_GAP - 1e-9
    few = line[::8]  # 5 centres, 12 cm apart: every one is numbered
    assert all(spaced(few, LABEL_GAP))
