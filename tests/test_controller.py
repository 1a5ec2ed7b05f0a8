"""The studio's controller without a browser or a viser server: teaching, recording, demos, key-points,
training, preview, replay and sessions, on a copy of the example session with a simulated Baxter."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest

import studio.core.learn as learn
from studio.controller import PREVIEW, REPLAY, Controller, Topic
from studio.core.errors import NotEnoughData, SessionFormatError, StudioError
from studio.core.quality.judgement import Close
from studio.core.quality.notes import OddDemo
from studio.core.types import Arm
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore
from tests.conftest import RecordingNotifier, trained_copy, wait_for


def notes(ctl: Controller) -> list[tuple[str, str, str]]:
    notifier = ctl.notifier
    assert isinstance(notifier, RecordingNotifier)
    return notifier.notes


def test_opens_the_session_and_follows_the_robot(ctl: Controller) -> None:
    assert ctl.session.name == "stack-cup"
    assert len(ctl.demos.names()) == 3
    q = ctl.teaching.arm_q("left")
    q[3] += 0.2
    ctl.teaching.command_arm("left", q)
    assert wait_for(lambda: abs(ctl.teaching.arm_q("left")[3] - q[3]) < 1e-3)


def test_gizmo_ik_reachable_and_unreachable(ctl: Controller) -> None:
    arm: Arm = "left"
    seen: list[str] = []
    ctl.events.on(Topic.REACH, lambda: seen.append(ctl.teaching.reach_message()))
    pos, wxyz = ctl.baxter.fk(arm, ctl.teaching.arm_q(arm))
    res = ctl.teaching.move_gripper(arm, pos + np.array([0.0, 0.0, 0.05]), wxyz)
    assert res.converged and not ctl.teaching.unreachable(arm) and ctl.teaching.reach_message() == ""
    far = ctl.teaching.move_gripper(arm, pos + np.array([3.0, 0.0, 0.0]), wxyz)
    assert not far.converged and ctl.teaching.unreachable(arm)
    assert ctl.teaching.reach[arm].target == pytest.approx(tuple(pos + np.array([3.0, 0.0, 0.0])))
    assert "cannot reach" in ctl.teaching.reach_message() and "cannot reach" in seen[-1]


def test_record_stop_saves_to_disk_one_recording_at_a_time(ctl: Controller, sessions: Path) -> None:
    teaching = ctl.teaching
    teaching.start_recording()
    with pytest.raises(StudioError, match="already running"):
        teaching.start_recording()
    teaching.move_joint(0, float(teaching.robot_q()[0] + 0.2))
    teaching.set_gripper("left", 0.0)
    assert wait_for(lambda: teaching.recorder is not None and teaching.recorder.n_samples > 600)
    teaching.stop_recording()
    assert teaching.recorder is None and not teaching.recording
    assert len(ctl.demos.names()) == 4
    again = SessionStore(sessions).open("stack-cup")
    assert len(again.recordings) == 4 and len(again.recordings[-1]) > 600
    teaching.start_recording()
    teaching.discard_recording()
    assert len(ctl.demos.names()) == 4


def test_demo_list_hide_rename_trim_delete(ctl: Controller) -> None:
    demos = ctl.demos
    demos.set_visible(0, False)
    assert [i for i, _ in demos.for_arm("left")] == [1, 2]
    assert [d.visible for d in demos.summaries()] == [False, True, True]
    demos.set_visible(0, True)
    demos.rename(1, "slow one")
    assert demos.names()[1] == "slow one"
    with pytest.raises(StudioError):
        demos.rename(0, "slow one")
    d0 = demos.duration(2)
    demos.trim(2, 1.0, d0 - 1.0)
    assert demos.duration(2) == pytest.approx(d0 - 2.0, abs=0.01)
    demos.delete(0)
    assert demos.names() == ["slow one", "demo 3"]


def test_keypoints_follow_the_thresholds_and_k(ctl: Controller) -> None:
    kp = ctl.keypoints
    v0 = kp.compute()
    c0 = [d.count for d in v0.demos]
    assert len(c0) == 3 and min(c0) > 2 and v0.k["left"] >= 2
    kp.set_param("eps5", 0.03)
    v1 = kp.compute()
    assert sum(d.count for d in v1.demos) > sum(c0)
    kp.set_k(5)
    assert kp.compute().k["left"] == 5
    kp.reset()
    assert [d.count for d in kp.compute().demos] == c0


def test_the_keypoint_thread_serves_the_newest_request(ctl: Controller) -> None:
    views: list[int] = []

    def drawn() -> None:
        view = ctl.keypoints.view
        assert view is not None
        views.append(sum(d.count for d in view.demos))

    ctl.events.on(Topic.KEYPOINTS, drawn)
    ctl.keypoints.set_param("eps5", 0.03)
    assert wait_for(lambda: bool(views) and views[-1] == sum(d.count for d in ctl.keypoints.compute().demos))


def test_train_preview_replay_export(ctl: Controller) -> None:
    ctl.training.train().result(timeout=120)
    assert not ctl.training.busy
    skill = ctl.training.skills()["left"]
    assert skill.joint_trajectory is not None
    assert [u.name for u in ctl.training.skill_demos("left")] == ["demo 1", "demo 2", "demo 3"]
    playback = ctl.playback
    assert playback.preview_duration() > 1.0

    playback.play_preview(speed=4.0)
    assert wait_for(lambda: (playback.position(PREVIEW) or 0.0) > 0.5)
    assert "preview" in playback.label()
    playback.pause(PREVIEW)
    playback.seek_preview(1.0)
    assert not ctl.display.is_live

    playback.play_demo(1)
    assert wait_for(lambda: (playback.position(REPLAY) or 0.0) > 0.2)
    playback.seek(REPLAY, 3.0)
    playback.stop(REPLAY)
    assert ctl.display.is_live

    name, data = ctl.sessions.trajectory_csv()
    assert name.endswith(".csv") and data.startswith(b"time,left_s0")
    zname, zdata = ctl.sessions.zip()
    assert zname == "stack-cup.zip" and zdata[:2] == b"PK"


def test_replay_seek_needs_play_first(ctl: Controller) -> None:
    with pytest.raises(StudioError, match="Press Play first"):
        ctl.playback.seek(REPLAY, 1.0)
    assert ctl.playback.kind is None


def test_the_controller_says_each_audience_s_way_to_a_control(ctl: Controller) -> None:
    from studio.words.controls import CLI_CONTROLS

    ctl.sessions.new("nothing learned")
    with pytest.raises(StudioError, match="no learned skill to preview yet: press Train first"):
        ctl.playback.preview_recording()
    ctl.ctx.controls = CLI_CONTROLS  # as `studio learn`'s headless controller says it
    with pytest.raises(StudioError, match="no learned skill to preview yet: run `studio learn` first"):
        ctl.playback.preview_recording()


def test_training_needs_two_demos_in_plain_words(ctl: Controller) -> None:
    ctl.sessions.new("only-one")
    with pytest.raises(NotEnoughData, match="at least two"):
        ctl.training.train()
    assert not ctl.training.busy


def test_corrupt_upload_changes_nothing(ctl: Controller, sessions: Path) -> None:
    before = sorted(p.name for p in sessions.iterdir())
    with pytest.raises(SessionFormatError):
        ctl.sessions.import_zip("bad.zip", b"PK\x03\x04 not a zip at all")
    assert sorted(p.name for p in sessions.iterdir()) == before
    assert ctl.session.name == "stack-cup"


def test_upload_of_a_downloaded_session_opens_it(ctl: Controller) -> None:
    _, data = ctl.sessions.zip()
    name = ctl.sessions.import_zip("stack-cup.zip", data)
    assert name != "stack-cup" and ctl.session.name == name
    assert len(ctl.demos.names()) == 3


def test_new_open_duplicate(ctl: Controller) -> None:
    ctl.sessions.new("lesson two")
    assert ctl.session.name == "lesson two" and ctl.demos.names() == []
    ctl.sessions.open("stack-cup")
    ctl.sessions.duplicate("stack-cup copy")
    assert ctl.session.name == "stack-cup copy" and len(ctl.demos.names()) == 3
    assert set(ctl.sessions.names()) >= {"stack-cup", "lesson two", "stack-cup copy"}


def test_too_many_clusters_is_a_plain_notification(ctl: Controller) -> None:
    ctl.keypoints.set_k(500)
    view = ctl.keypoints.refresh()
    assert view.messages and "left" not in view.k
    assert any(kind == "warning" and title == "Key-points" for kind, title, _ in notes(ctl))
    ctl.keypoints.set_k(None)
    assert ctl.keypoints.refresh().k["left"] >= 2


def test_eps_changed_during_training_is_kept(ctl: Controller, sessions: Path) -> None:
    trained_eps5 = ctl.keypoints.params().eps5
    fut = ctl.training.train()
    ctl.keypoints.set_param("eps5", 0.33)
    ctl.keypoints.persist()
    fut.result(timeout=120)
    assert ctl.keypoints.params().eps5 == 0.33 and ctl.session.params.eps5 == 0.33
    again = SessionStore(sessions).open("stack-cup")
    assert again.params.eps5 == 0.33
    assert again.skill_info["left"].params["eps5"] == trained_eps5  # the skill remembers what it used


def test_retraining_unloads_the_old_preview(ctl: Controller) -> None:
    ctl.training.train().result(timeout=120)
    ctl.playback.play_preview(speed=4.0)
    ctl.playback.pause(PREVIEW)
    ctl.demos.set_visible(0, False)
    ctl.training.train().result(timeout=120)
    assert ctl.playback.kind is None and ctl.display.is_live
    ctl.playback.play_preview()
    loaded = ctl.playback.loaded
    assert loaded is not None
    assert loaded.recording.duration == pytest.approx(ctl.playback.preview_duration(), abs=0.02)
    ctl.playback.stop(PREVIEW)
    assert ctl.playback.kind is None and ctl.display.is_live


def test_duplicate_is_refused_while_recording_and_checks_the_name_first(ctl: Controller) -> None:
    ctl.teaching.start_recording()
    with pytest.raises(StudioError, match="Stop the recording"):
        ctl.sessions.duplicate("copy")
    ctl.teaching.discard_recording()
    assert "copy" not in ctl.sessions.names() and ctl.session.name == "stack-cup"
    ctl.sessions.new("taken")
    ctl.sessions.open("stack-cup")
    with pytest.raises(StudioError, match="already exists"):
        ctl.sessions.duplicate("taken")
    assert not any(title == "Saved" for _, title, _ in notes(ctl))
    for action in (ctl.sessions.new, ctl.sessions.duplicate):
        with pytest.raises(StudioError, match="Type a name in 'New name' first"):
            action("  ")
    assert ctl.session.name == "stack-cup"


def test_arms_cannot_change_while_recording(ctl: Controller) -> None:
    ctl.teaching.start_recording()
    with pytest.raises(StudioError, match="Stop the recording before changing the arms to teach"):
        ctl.teaching.set_arms(("right",))
    recorder = ctl.teaching.recorder
    assert ctl.teaching.selected_arms == ("left",) and recorder is not None and recorder.arms == ("left",)
    ctl.teaching.discard_recording()
    ctl.teaching.set_arms(("right",))
    assert ctl.teaching.selected_arms == ("right",) and ctl.session.arms == ("right",)
    with pytest.raises(StudioError, match="at least one arm"):
        ctl.teaching.set_arms(())


def test_demos_are_read_from_one_list(ctl: Controller, monkeypatch: pytest.MonkeyPatch) -> None:
    recs = list(ctl.session.recordings)
    calls = iter([recs] + [recs[1:]] * 100)  # the first demo is deleted right after the list was read
    monkeypatch.setattr(ctl.demos, "recordings", lambda: list(next(calls)))
    assert [d.name for _, d in ctl.demos.for_arm("left")] == [r.name for r in recs]


def test_delete_at_once_with_undo(ctl: Controller) -> None:
    demos = ctl.demos
    names = demos.names()
    ctl.demos.set_visible(1, False)
    demos.delete(1)  # at once: no second press
    assert demos.names() == [names[0], names[2]]
    assert any("Press Undo" in body for _, _, body in notes(ctl))
    assert names[1] in ctl.undo.what
    ctl.undo.undo()  # back, as the last demonstration, still hidden
    assert demos.names() == [names[0], names[2], names[1]] and not demos.visible(2)
    assert ctl.undo.what == ""
    with pytest.raises(StudioError, match="nothing to bring back"):
        ctl.undo.undo()


def test_events_reach_every_view_even_after_a_broken_one(ctl: Controller) -> None:
    seen: list[str] = []

    def broken() -> None:
        raise RuntimeError("a view that fails")

    ctl.events.on(Topic.DEMOS, broken)
    off = ctl.events.on(Topic.DEMOS, lambda: seen.append("demos"))
    ctl.demos.set_visible(0, False)
    assert seen == ["demos"]
    off()
    ctl.demos.set_visible(0, True)
    assert seen == ["demos"]


# -- thresholds that follow the demonstrations, Suggest, the verdict, the live path (issue 11) -----------------


def test_the_first_train_uses_thresholds_that_follow_the_demos(ctl: Controller, sessions: Path) -> None:
    from studio.core.thresholds import ThresholdSettings, auto_params

    demos = [d for _, d in ctl.demos.for_arm("left")]
    assert ctl.keypoints.settings() == ThresholdSettings()  # the example session: every threshold automatic
    assert ctl.keypoints.params() == auto_params(demos)
    ctl.training.train().result(timeout=120)
    assert ctl.training.skills()["left"].params == auto_params(demos)
    assert SessionStore(sessions).open("stack-cup").skill_info["left"].params["eps5"] == auto_params(demos).eps5


def test_teachers_values_are_kept_and_detail_moves_the_others(ctl: Controller, sessions: Path) -> None:
    auto = ctl.keypoints.params()
    seen: list[str] = []
    ctl.events.on(Topic.THRESHOLDS, lambda: seen.append("thresholds"))
    ctl.keypoints.set_param("eps5", 0.033)
    assert not ctl.keypoints.settings().is_auto("eps5") and ctl.keypoints.params().eps5 == 0.033
    assert seen == []  # a slider's own move is not announced to the sliders
    ctl.keypoints.set_detail(2.0)  # more key-points: the automatic distances shrink, the teacher's value stays
    more = ctl.keypoints.params()
    assert more.eps5 == 0.033 and more.eps7 < auto.eps7 and more.eps4 < auto.eps4 and seen == ["thresholds"]
    ctl.keypoints.persist()
    again = SessionStore(sessions).open("stack-cup")
    assert again.thresholds.detail == 2.0 and dict(again.thresholds.teacher) == {"eps5": 0.033}
    assert again.params.eps5 == 0.033 and again.params.eps7 == pytest.approx(more.eps7)
    ctl.keypoints.set_auto("eps5")
    assert ctl.keypoints.params().eps5 < auto.eps5 and ctl.keypoints.settings().is_auto("eps5")
    ctl.keypoints.set_param("eps2", 0.02)
    ctl.keypoints.all_auto()
    assert ctl.keypoints.settings().teacher == {} and ctl.keypoints.settings().detail == 2.0
    ctl.keypoints.reset()
    assert ctl.keypoints.params() == auto and ctl.keypoints.k is None


def test_thresholds_are_written_once_they_rest(ctl: Controller, sessions: Path) -> None:
    ctl.keypoints.set_param("eps5", 0.05)
    assert SessionStore(sessions).open("stack-cup").params.eps5 != 0.05  # not per slider step
    assert wait_for(lambda: SessionStore(sessions).open("stack-cup").params.eps5 == 0.05)


def test_suggest_applies_one_change_that_can_be_undone(ctl: Controller) -> None:
    ctl.suggest.workers = 1
    ctl.keypoints.set_param("eps5", 0.4)  # a far too coarse travel distance: 2–3 key-points per demo
    ctl.keypoints.set_k(3)
    states: list[tuple[bool, float]] = []
    ctl.events.on(Topic.SUGGEST, lambda: states.append((ctl.suggest.state.running, ctl.suggest.state.fraction)))
    ctl.suggest.start().result(timeout=120)
    assert states[0] == (True, 0.0) and not states[-1][0] and states[-1][1] == 1.0
    assert any(running and 0 < f < 1 for running, f in states)  # progress was told on the way
    st = ctl.suggest.state
    assert st.can_undo and st.summary.startswith("Suggested: ") and "misses it by" in st.summary
    assert ctl.keypoints.settings().teacher == {} and ctl.keypoints.params().eps5 < 0.4
    ctl.suggest.undo()
    assert ctl.keypoints.params().eps5 == 0.4 and ctl.keypoints.k == 3 and not ctl.suggest.state.can_undo
    with pytest.raises(StudioError, match="no suggestion to undo"):
        ctl.suggest.undo()


def test_suggest_can_be_stopped_and_changes_nothing(ctl: Controller) -> None:
    ctl.suggest.workers = 1
    ctl.keypoints.set_param("eps5", 0.4)
    ctl.suggest.cancel()
    fut = ctl.suggest.start()
    assert wait_for(lambda: ctl.suggest.state.fraction > 0 or not ctl.suggest.state.running, 60)
    ctl.suggest.cancel()
    fut.result(timeout=60)
    assert not ctl.suggest.state.running and not ctl.suggest.state.can_undo
    assert "stopped" in ctl.suggest.state.summary and ctl.keypoints.params().eps5 == 0.4


def test_suggest_needs_two_demos(ctl: Controller) -> None:
    ctl.demos.set_visible(0, False)
    ctl.demos.set_visible(1, False)
    with pytest.raises(NotEnoughData, match="at least two"):
        ctl.suggest.start()


def test_training_is_judged_in_plain_words(ctl: Controller) -> None:
    verdicts: list[int] = []
    ctl.events.on(Topic.VERDICT, lambda: verdicts.append(len(ctl.training.verdicts())))
    ctl.training.train().result(timeout=120)
    assert wait_for(lambda: "left" in ctl.training.verdicts() and not ctl.training.judging, 120)
    v = ctl.training.verdicts()["left"]
    assert v.verdict is not None and v.verdict.level == "good" and isinstance(v.verdict.headline, Close)
    assert [f.name for f in v.fits] == ["demo 1", "demo 2", "demo 3"] and all(f.well for f in v.fits)
    assert verdicts[0] == 0 and verdicts[-1] == 1
    ctl.demos.rename(0, "renamed")  # the skill stays; its judgement says what it cannot judge any more
    ctl.training.judge().result(timeout=120)
    assert "renamed or deleted" in ctl.training.verdicts()["left"].message


def test_an_odd_demonstration_is_named(ctl: Controller) -> None:
    from studio.storage import DEFAULT_ROOT

    pick = SessionStore(DEFAULT_ROOT).open("pick-place", recover=False).recordings[0]
    ctl.session.add_recording(pick, name="demo 4")  # a pick-place take among the stack-cup ones
    ctl.events.emit(Topic.DEMOS)
    ctl.training.train().result(timeout=180)
    assert wait_for(lambda: "left" in ctl.training.verdicts() and not ctl.training.judging, 180)
    v = ctl.training.verdicts()["left"]
    assert v.verdict is not None and "demo 4" in [f.demo for f in v.verdict.notes if isinstance(f, OddDemo)]
    assert [f.well for f in v.fits] == [True, True, True, False]


def test_paper_mode_can_be_chosen(ctl: Controller, sessions: Path) -> None:
    assert ctl.training.generalization == "aligned-mean"
    ctl.training.set_generalization("paper")
    ctl.training.train().result(timeout=120)
    assert ctl.training.skills()["left"].generalization == "paper"
    assert SessionStore(sessions).open("stack-cup").generalization == "paper"
    with pytest.raises(StudioError, match="Unknown way"):
        ctl.training.set_generalization("spline")


def test_the_live_path_follows_the_thresholds_in_the_key_points_step(ctl: Controller) -> None:
    from studio.controller import Step

    paths: list[int] = []
    ctl.events.on(Topic.LIVE_PATH, lambda: paths.append(len(ctl.live.paths)))
    ctl.keypoints.refresh()
    assert ctl.live.paths == {}  # nobody looks (the Teach step): nothing is computed
    ctl.view.set_step(Step.KEYPOINTS)
    assert wait_for(lambda: "left" in ctl.live.paths, 60)
    first = ctl.live.paths["left"]
    assert len(first.position) > 10 and 0 < first.distance < 0.05 and "within" in first.words
    ctl.keypoints.set_param("eps5", 0.4)
    assert wait_for(lambda: ctl.live.paths["left"].version > first.version, 60)
    view = ctl.keypoints.view
    assert view is not None and ctl.live.paths["left"].k == view.k["left"]


def test_the_verdict_being_judged_stops_when_the_studio_stops(
    trained_examples: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Opening a trained session judges its skill on the work thread; stopping the studio meanwhile ends that
    job before its next held-out fold, silently (its verdict would be shown nowhere)."""
    real, folds = learn.learn_relative, []
    started, stopped = threading.Event(), threading.Event()

    def fold(*args, **kwargs):  # the first held-out fold waits until the studio has stopped
        folds.append(1)
        started.set()
        assert stopped.wait(30)
        return real(*args, **kwargs)

    monkeypatch.setattr(learn, "learn_relative", fold)
    sessions = trained_copy(trained_examples, "pick-place", tmp_path / "sessions")
    notifier = RecordingNotifier()
    c = Controller(store=SessionStore(sessions), session="pick-place", backend=SimulatedBaxter(), notifier=notifier)
    c.start()
    judgement = c.training.judgement
    assert judgement is not None and started.wait(30), "the skill was not being judged"
    c.close()
    c.shutdown()
    stopped.set()
    assert judgement.result(timeout=30) is None
    assert folds == [1], "the judge went on to its next fold after the studio stopped"
    assert not c.training.verdicts() and not c.training.judging
    assert notifier.notes == [], notifier.notes
