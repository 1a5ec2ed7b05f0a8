"""The studio's scene, steps and stale-state fixes with a real viser server (no browser): what the server holds
for every tab (and sends again to a reloaded one) is checked against the controller's state."""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from studio.app import Studio, build_app
from studio.controller import REPLAY, Layer, Step
from studio.controller.teaching import DISCARD_CONFIRM_S, REACH_HOLD_S
from studio.core.rotations import matrix_from_quat_wxyz
from studio.panels.steps import HOME_CAMERA_LOOK_AT, HOME_CAMERA_POSITION
from tests.conftest import ROOT, RecordingNotifier, free_port, trained_copy, wait_for
from tests.viser_client import ViserClient


@pytest.fixture
def app(sessions: Path) -> Iterator[Studio]:
    shutil.copytree(ROOT / "sessions" / "pick-place", sessions / "pick-place")
    a = build_app(port=free_port(), session="pick-place", sessions_dir=sessions)
    a.controller.notifier = RecordingNotifier(then=a.notifier)
    yield a
    a.stop()


@pytest.fixture
def trained_app(trained_examples: Path, sessions: Path) -> Iterator[Studio]:
    """The studio on the "pick-place" example trained as the Train button trains (once per worker): for a test
    whose subject comes after training."""
    trained_copy(trained_examples, "pick-place", sessions)
    a = build_app(port=free_port(), session="pick-place", sessions_dir=sessions)
    a.controller.notifier = RecordingNotifier(then=a.notifier)
    yield a
    a.stop()


@pytest.fixture
def page(app: Studio) -> Iterator[ViserClient]:
    """A tab of the studio (viser's websocket protocol, no browser): the scene as the page receives it."""
    c = ViserClient.tab_of(app)
    assert c.wait_for(lambda _m: "/table/top" in c.scene() and c.scene().keys() >= {"/demos", "/objects"}, 30)
    yield c
    c.close()


def all_drawn(page: ViserClient, prefix: str) -> bool:
    got = page.layer(prefix)
    return bool(got) and all(got.values())


def none_drawn(page: ViserClient, prefix: str) -> bool:
    return not any(page.layer(prefix).values())


def objects(page: ViserClient) -> dict[str, dict]:
    """The objects the page draws, by their names in the world (node "/objects/<name>-<tag>")."""
    return {
        n.split("/")[2].rsplit("-", 1)[0]: v
        for n, v in page.scene().items()
        if n.count("/") == 2 and n.startswith("/objects/")
    }


def notes(app: Studio) -> list[tuple[str, str, str]]:
    notifier = app.controller.notifier
    assert isinstance(notifier, RecordingNotifier)
    return notifier.notes


def test_the_step_shows_its_section_and_its_layers(app: Studio, page: ViserClient) -> None:
    panels, view = app.panels, app.controller.view
    sections = panels.steps.sections
    assert [s for s, f in sections.items() if f.visible] == [Step.TEACH]
    assert 'data-step="Teach"' in panels.steps.title.content
    # the page may still be receiving the scene: wait until it has the gripper markers too
    assert page.wait_for(lambda _m: all_drawn(page, "/demos") and all_drawn(page, "/demo_grips"))
    assert all_drawn(page, "/objects") and len(page.layer("/objects")) == 2
    assert none_drawn(page, "/keypoints/left")
    view.set_step(Step.KEYPOINTS)
    assert [s for s, f in sections.items() if f.visible] == [Step.KEYPOINTS]
    assert page.wait_for(lambda _m: any(page.layer("/keypoints/left").values()))
    assert not panels.teach.handles["left"].visible  # the gripper handle is a Teach thing
    view.set_step(Step.TRAIN)
    assert page.wait_for(lambda _m: none_drawn(page, "/demos") and none_drawn(page, "/keypoints/left"))
    # A "Show" toggle brings a layer back until the next step change.
    view.set_shown(Layer.DEMOS, True)
    assert page.wait_for(lambda _m: all_drawn(page, "/demos"))
    assert panels.steps.toggles[Layer.DEMOS].value is True
    view.set_shown(Layer.OBJECTS, False)
    assert page.wait_for(lambda _m: none_drawn(page, "/objects"))
    view.set_step(Step.TEACH)
    assert page.wait_for(lambda _m: all_drawn(page, "/objects")) and panels.teach.handles["left"].visible


def drawn_where_the_world_has_them(app: Studio, page: ViserClient) -> bool:
    drawn = objects(page)
    poses = {p.name: p for p in app.controller.scene.live.poses()}
    return sorted(drawn) == sorted(poses) and all(
        drawn[n]["position"] is not None
        and np.allclose(drawn[n]["position"], p.position)
        and np.allclose(drawn[n]["wxyz"] or (1.0, 0.0, 0.0, 0.0), p.wxyz)
        for n, p in poses.items()
    )


def test_objects_are_drawn_where_the_world_has_them(app: Studio, page: ViserClient) -> None:
    ctl, panel = app.controller, app.panels.scene
    assert sorted(objects(page)) == ["block", "pad"]
    assert page.wait_for(lambda _m: drawn_where_the_world_has_them(app, page))
    table = ctl.scene.scene.table
    assert table is not None and sorted(page.layer("/table")) == [
        "/table/leg0",
        "/table/leg1",
        "/table/leg2",
        "/table/leg3",
        "/table/top",
    ]
    top = page.scene()["/table/top"]
    assert top["position"][2] + 0.5 * top["props"]["dimensions"][2] == pytest.approx(table.top_z)
    # Added, moved and removed objects follow at the next pump tick.
    name = ctl.scene.add("cup")
    assert page.wait_for(lambda _m: name in objects(page))
    ctl.scene.move(name, (0.62, -0.3, 0.1), yaw=0.4)
    panel.tick(0.0)
    assert page.wait_for(lambda _m: np.allclose(objects(page)[name]["position"] or (0, 0, 0), (0.62, -0.3, -0.07)))
    R = matrix_from_quat_wxyz(np.asarray(objects(page)[name]["wxyz"]))
    assert np.arctan2(R[1, 0], R[0, 0]) == pytest.approx(0.4)
    assert list(panel.pick.options) == ["(none)", "pad", "block", name]
    ctl.scene.remove(name)
    assert page.wait_for(lambda _m: name not in objects(page))
    assert list(panel.pick.options) == ["(none)", "pad", "block"]


def test_replaying_a_demo_moves_the_drawn_block(app: Studio, page: ViserClient) -> None:
    ctl = app.controller
    rec = ctl.session.recordings[0]
    events = ctl.session.objects.events(ctl.session.demo_files[0])
    release = next(e for e in events if e.kind == "release")
    landed = release.pose("block")
    assert landed is not None and landed.on == "pad"
    ctl.playback.seek(REPLAY, release.t + 0.5, rec, lambda: rec)
    assert page.wait_for(
        lambda _m: (p := objects(page)["block"]["position"]) is not None and np.allclose(p, landed.position, atol=1e-6)
    )


def test_task_result_in_the_preview_panel(app: Studio) -> None:
    ctl, panel = app.controller, app.panels.preview
    assert panel.task.content == ""  # not trained yet
    ctl.training.set_frames("robot")  # fixed places: moving the block leaves the skill behind
    ctl.training.train().result()
    assert wait_for(lambda: 'data-ok="true"' in panel.task.content)
    assert "The skill does the task." in panel.task.content
    assert "The block went onto the pad (" in panel.task.content and 'data-claim="works"' in panel.task.content
    ctl.scene.move("block", (0.55, -0.35, -0.07))  # somewhere the skill never goes
    assert wait_for(lambda: 'data-ok="false"' in panel.task.content)
    assert "The skill misses the task." in panel.task.content
    assert "The block was never picked up: the gripper closed" in panel.task.content


def test_the_cannot_reach_text_goes_once_the_arm_is_back(app: Studio) -> None:
    ctl, robot = app.controller, app.panels.robot
    pos, wxyz = ctl.baxter.fk("left", ctl.teaching.arm_q("left"))
    ctl.teaching.move_gripper("left", pos + np.array([3.0, 0.0, 0.0]), wxyz)
    assert wait_for(lambda: "cannot reach" in robot.status.content)
    assert app.panels.teach.miss_markers["left"].visible
    # The handle is back on the gripper a moment after the drag: the words and the marker go, for every tab
    # (a reloaded tab gets this status).
    ctl.teaching.reach["left"] = type(ctl.teaching.reach["left"])(False, (3.0, 0.0, 0.0), at=-1e9)  # long ago
    assert wait_for(lambda: "cannot reach" not in robot.status.content, timeout=REACH_HOLD_S + 30)
    assert not app.panels.teach.miss_markers["left"].visible
    # Moving the arm with a joint slider also ends it at once.
    ctl.teaching.move_gripper("left", pos + np.array([3.0, 0.0, 0.0]), wxyz)
    assert wait_for(lambda: "cannot reach" in robot.status.content)
    # (from where the arm is going: the arm itself may still be on its way, and the elbow bent from there by the
    # difference would sweep the gripper into the table, which the studio now stops short of: decision 087)
    ctl.teaching.move_joint(3, float(ctl.teaching.target_q("left")[3]) + 0.05)
    assert ctl.teaching.reach_message() == ""
    assert wait_for(lambda: "cannot reach" not in robot.status.content)


def test_switching_session_resets_trim_and_replay(app: Studio) -> None:
    ctl, demos, sessions = app.controller, app.panels.demos, app.panels.sessions
    ctl.playback.play_demo(2)
    sessions.replay_pick.value = ctl.demos.names()[2]  # type: ignore[misc]
    sessions.replay_time.max = 25.42
    sessions.replay_time.value = 12.3  # type: ignore[misc]
    demos.demo_trim.value = (3.0, 9.0)  # type: ignore[misc]
    ctl.sessions.open("stack-cup")
    first = ctl.session.recordings[0]
    assert sessions.replay_pick.value == first.name
    assert sessions.replay_time.value == 0.0
    assert sessions.replay_time.max == pytest.approx(round(first.duration, 2))
    picked = ctl.session.recordings[ctl.demos.names().index(demos.demo_pick.value)]
    assert demos.demo_trim.value == (0.0, pytest.approx(round(picked.duration + 0.005, 2)))
    assert demos.demo_trim.max == pytest.approx(round(picked.duration + 0.005, 2))


def test_duplicate_says_what_was_done(app: Studio) -> None:
    ctl = app.controller
    ctl.sessions.open("stack-cup")
    ctl.sessions.duplicate("my cup copy")
    said = [(t, b) for _, t, b in notes(app)]
    assert ("Copied", 'Session "stack-cup" was copied as "my cup copy"; the copy is open now.') in said
    assert not any("is saved" in b for _, b in said)
    assert ctl.session.name == "my cup copy"


def test_export_says_train_first(app: Studio) -> None:
    panel, ctl = app.panels.sessions, app.controller
    assert panel.export.disabled and panel.export_why.visible and "Train first" in panel.export_why.content
    ctl.training.train().result()
    assert wait_for(lambda: not panel.export.disabled and not panel.export_why.visible)


class Tab:
    """Stands for a browser tab (viser's ClientHandle has a ``client_id``)."""

    def __init__(self, client_id: int) -> None:
        self.client_id = client_id

    def add_notification(self, title: str, body: str, **kwargs: object) -> None:
        pass


def test_discarding_another_tabs_recording_asks_first(app: Studio) -> None:
    teaching = app.controller.teaching
    a, b = Tab(1), Tab(2)
    teaching.start_recording(by=a)
    assert teaching.discard_recording(by=b, now=100.0) is False and teaching.recording
    kind, _, body = notes(app)[-1]
    assert kind == "warning" and "another browser tab" in body and "Press Discard again" in body
    assert teaching.discard_recording(by=b, now=100.0 + DISCARD_CONFIRM_S + 1) is False  # too late: asks again
    assert teaching.discard_recording(by=b, now=100.0 + DISCARD_CONFIRM_S + 2) is True and not teaching.recording
    teaching.start_recording(by=a)
    assert teaching.discard_recording(by=a) is True  # the tab that records discards at once


def test_reset_view_puts_the_camera_back(app: Studio) -> None:
    from studio.panels.steps import reset_camera

    class Camera:
        pass

    class Client:
        camera = Camera()

        def atomic(self) -> contextlib.nullcontext[None]:
            return contextlib.nullcontext()

    c = Client()
    reset_camera(c)  # type: ignore[arg-type]
    cam = c.camera
    assert cam.position == HOME_CAMERA_POSITION and cam.look_at == HOME_CAMERA_LOOK_AT  # type: ignore[attr-defined]
    assert cam.up_direction == (0.0, 0.0, 1.0)  # type: ignore[attr-defined]


def test_an_object_is_moved_with_its_handle(app: Studio, page: ViserClient) -> None:
    ctl = app.controller
    handle = lambda: page.scene()["/objects_handle"]  # noqa: E731
    assert not handle()["visible"]  # no object chosen: no handle
    page.set_value("Object", "block")
    block = ctl.scene.scene.object("block")
    assert abs(block.yaw) > 0.1  # the example's block stands turned …
    top = np.add(block.position, (0, 0, block.size[2]))
    # … and its handle is in the room's axes all the same: x and y arrows, no ring, no z arrow
    assert page.wait_for(lambda _m: handle()["visible"] and np.allclose(handle()["position"] or (0, 0, 0), top))
    assert np.allclose(handle()["wxyz"] or (1, 0, 0, 0), (1, 0, 0, 0))
    props = handle()["props"]
    assert props["active_axes"] == [True, True, False] or tuple(props["active_axes"]) == (True, True, False)
    assert not props["disable_axes"] and props["disable_rotations"] and props["disable_sliders"]
    # Dragged: the object follows the handle in x and y at its height (a tab may send any z, and a turn, which
    # the arrows cannot make: ignored); let go: saved.
    page.drag("/objects_handle", (0.6, -0.25, 0.2), (0.9659, 0.0, 0.0, 0.2588), end=False)
    z = block.position[2]
    assert page.wait_for(lambda _m: np.allclose(objects(page)["block"]["position"], (0.6, -0.25, z)))
    page.drag("/objects_handle", (0.6, -0.25, 0.2))
    assert wait_for(lambda: ctl.scene.scene.object("block").position == pytest.approx((0.6, -0.25, -0.07)))
    assert ctl.scene.scene.object("block").yaw == pytest.approx(block.yaw)  # a move never turns it
    # back on the block's top, in the room's axes
    assert page.wait_for(lambda _m: np.allclose(handle()["position"], (0.6, -0.25, -0.02)))
    ctl.view.set_step(Step.PREVIEW)
    assert page.wait_for(lambda _m: not handle()["visible"])  # a Teach thing


def test_an_object_turns_only_behind_the_toggle(app: Studio, page: ViserClient) -> None:
    ctl = app.controller
    handle = lambda: page.scene()["/objects_handle"]  # noqa: E731
    page.set_value("Object", "block")
    block = ctl.scene.scene.object("block")
    page.set_value("Turn with the handle", True)
    assert wait_for(lambda: ctl.guide.turning)
    assert page.wait_for(lambda _m: handle()["props"]["disable_axes"] and not handle()["props"]["disable_rotations"])
    assert page.wait_for(lambda _m: np.allclose(handle()["position"][:2], block.position[:2]))  # on the block
    turn = 0.4  # rad about z: the handle shows the ring only, and its turn is added to the block's heading
    wxyz = (float(np.cos(turn / 2)), 0.0, 0.0, float(np.sin(turn / 2)))
    x, y, z = (float(v) for v in handle()["position"])
    page.drag("/objects_handle", (x, y, z), wxyz)
    assert wait_for(lambda: ctl.scene.scene.object("block").yaw == pytest.approx(block.yaw + turn, abs=1e-6))
    assert ctl.scene.scene.object("block").position[:2] == pytest.approx(block.position[:2])
    # back in the room's axes (once the tab has the handle's orientation)
    assert page.wait_for(lambda _m: handle().get("wxyz") is not None and np.allclose(handle()["wxyz"], (1, 0, 0, 0)))
    # the Move panel's toggle is the same one: the gripper's handle turns too
    assert app.panels.move.turn.value is True
    page.set_value("Turn with the handle", False)
    assert wait_for(lambda: not ctl.guide.turning and app.panels.move.turn.value is False)


def test_an_object_is_put_where_its_boxes_say(app: Studio, page: ViserClient) -> None:
    ctl = app.controller
    page.set_value("Object", "block")
    block = ctl.scene.scene.object("block")
    boxes = app.panels.scene.boxes
    assert wait_for(
        lambda: not boxes["x"].disabled and boxes["x"].value == pytest.approx(100 * block.position[0], abs=0.05)
    )
    page.set_value("Object y (cm)", -20.0)
    assert wait_for(lambda: ctl.scene.scene.object("block").position[1] == pytest.approx(-0.2))
    assert ctl.scene.scene.object("block").position[0] == pytest.approx(block.position[0])
    page.set_value("Object x (cm)", 70.0)
    assert wait_for(lambda: ctl.scene.scene.object("block").position[:2] == pytest.approx((0.7, -0.2)))
    assert page.wait_for(lambda _m: np.allclose(page.scene()["/objects_handle"]["position"][:2], (0.7, -0.2)))
    page.set_value("Object", "(none)")
    assert wait_for(lambda: boxes["x"].disabled and boxes["y"].disabled)  # a fixed slot: disabled, not gone
    assert boxes["x"].visible and "Choose an object" in app.panels.scene.where.content


def test_put_back_to_the_tasks_layout(app: Studio, page: ViserClient) -> None:
    from studio.world import preset

    ctl = app.controller
    layout = preset("pick-place", ctl.ctx.arms)
    ctl.scene.move("block", (0.6, -0.3, -0.07))
    ctl.scene.add("cup")
    # "Put all back" returns them to where they were last put: the teacher's set-up
    page.set_value("Object action", "Put all back")
    assert wait_for(lambda: any(p.name == "cup" for p in ctl.scene.live.poses()))
    assert ctl.scene.scene.object("block").position[:2] == pytest.approx((0.6, -0.3))
    # the task's layout: every object where the task starts, the added cup gone
    page.set_value("Put back to the task's layout", True)
    assert wait_for(lambda: ctl.scene.scene.names() == layout.names())
    for o in layout.objects:
        assert ctl.scene.scene.object(o.name).position == pytest.approx(o.position)
    assert page.wait_for(lambda _m: np.allclose(objects(page)["block"]["position"], layout.object("block").position))
    ctl.scene.use_preset("empty table")
    page.set_value("Put back to the task's layout", True)
    assert wait_for(lambda: any("no task layout" in body for _, _, body in notes(app)))


def test_the_preview_stays_in_the_preview_step(app: Studio, page: ViserClient) -> None:
    """Teach shows the live robot and the objects as placed; Preview shows where its playback was."""
    ctl = app.controller
    ctl.training.train().result()
    ctl.view.set_step(Step.PREVIEW)
    end = ctl.playback.preview_duration()
    ctl.playback.seek_preview(end)  # the preview's pose and objects at its end: the block on the pad
    assert wait_for(lambda: not ctl.display.is_live)
    moved = {p.name: p.position for p in ctl.scene.shown()[1]}
    assert moved["block"] != pytest.approx(ctl.scene.scene.object("block").position)
    ctl.view.set_step(Step.TEACH)
    assert wait_for(lambda: ctl.display.is_live and ctl.playback.label() == "Showing the robot live.")
    placed = ctl.scene.scene.object("block").position
    assert {p.name: p.position for p in ctl.scene.shown()[1]}["block"] == pytest.approx(placed)
    assert page.wait_for(lambda _m: np.allclose(objects(page)["block"]["position"], placed))  # what the tab draws
    ctl.view.set_step(Step.PREVIEW)  # back: the preview where it was, paused
    assert wait_for(lambda: not ctl.display.is_live)
    assert ctl.playback.label() == "Showing the learned skill (preview), paused."
    assert {p.name: p.position for p in ctl.scene.shown()[1]}["block"] == pytest.approx(moved["block"])


def test_playing_ends_when_the_playback_ends(trained_app: Studio) -> None:
    ctl = trained_app.controller
    assert ctl.session.skills
    ctl.view.set_step(Step.PREVIEW)
    ctl.playback.play_preview(speed=4.0)
    assert ctl.playback.label() == "Showing the learned skill (preview), playing."
    assert wait_for(lambda: ctl.playback.label() == "Showing the learned skill (preview), at its end.", timeout=60)
    ctl.view.set_step(Step.TEACH)  # playing in Preview, then Teach: paused there, the live robot here
    ctl.view.set_step(Step.PREVIEW)
    ctl.playback.play_preview(speed=0.25)
    ctl.view.set_step(Step.TEACH)
    assert wait_for(lambda: ctl.display.is_live and ctl.playback.loaded is not None)
    assert not ctl.playback.loaded.playing  # type: ignore[union-attr]


@pytest.mark.parametrize(
    ("verdict", "text"),
    [
        ("works", "The cup ended in the bottom cup, 0.6 cm from its centre."),
        ("never picked up", "The block was never picked up: the gripper closed 3 cm above it."),
        ("never picked up", "The block was not picked up the second time: the gripper did not close again."),
        ("still held", "The cup was still in the gripper at the end: the gripper never opened."),
        (
            "dropped early",
            "The cup was dropped early: it landed beside the bottom cup, 9 cm from its centre, because the gripper "
            "opened before it got there — the skill did not do the task.",
        ),
        (
            "wrong place",
            "The block was released in the wrong place the first time: it landed beside the pad, 8 cm from its "
            "centre — the skill did not do the task.",
        ),
        (
            "moved",
            "The block ended beside the pad, 9 cm from its centre: it was picked up again afterwards — the skill did "
            "not do the task.",
        ),
        (None, "There is nothing to check: your demonstrations did not pick up any object."),
    ],
)
def test_the_preview_panel_shows_each_task_result_wording(verdict: str | None, text: str) -> None:
    ok = verdict == "works"
    shown = preview_task_html(verdict, text)
    assert html_text(shown).endswith(text) and f'data-ok="{str(ok).lower()}"' in shown
    head = "The skill does the task." if ok else ("Task result." if verdict is None else "The skill misses the task.")
    assert html_text(shown).startswith(head)


def preview_task_html(verdict: str | None, text: str, warnings: list[str] | None = None, follows: bool = True) -> str:
    """The Preview panel's task result for a result of ``verdict``, with the reach words and whether the robot can
    follow the whole path."""
    from types import SimpleNamespace

    from studio.controller import TaskResult
    from studio.panels.preview import PreviewPanel
    from studio.world import ObjectResult

    ok = verdict == "works"
    objects = () if verdict is None else (ObjectResult("x", ok, verdict, text, 0.01),)
    result = TaskResult(ok, text, objects)
    ctl = SimpleNamespace(
        scene=SimpleNamespace(task_result=lambda: result),
        placed=SimpleNamespace(warnings=lambda: list(warnings or [])),
        execution=SimpleNamespace(feasibility=lambda: {"left": SimpleNamespace(ok=follows)}),
    )
    return PreviewPanel._task_html(SimpleNamespace(ctl=ctl))  # type: ignore[arg-type]


def test_the_preview_never_claims_works_above_words_that_say_otherwise() -> None:
    """One story: a result that holds is "does the task" only where the objects stand where the demonstrations had
    them and the robot can follow the whole path; otherwise the claim says why not (and agrees with the words)."""
    text = "The block ended on the pad, 0.4 cm from its centre."
    assert 'data-claim="works"' in preview_task_html("works", text)
    never = preview_task_html("works", text, warnings=["You never showed me the block this far to the robot's left"])
    assert 'data-claim="guess"' in never and "The skill does the task" not in never
    assert html_text(never).startswith("In the preview the skill does the task here, but you never showed me")
    cannot = preview_task_html("works", text, follows=False)
    assert 'data-claim="cannot-run"' in cannot and "cannot follow all of its path" in cannot
    missed = preview_task_html("wrong place", "The block ended beside the pad, 9 cm from its centre.", follows=False)
    assert 'data-claim="misses"' in missed


def html_text(fragment: str) -> str:
    import html
    import re

    return html.unescape(re.sub(r"<[^>]+>", "", fragment)).strip()


def test_the_teach_step_says_the_goal_and_the_teacher_confirms_or_corrects_it(app: Studio, page: ViserClient) -> None:
    ctl, panel = app.controller, app.panels.task
    # The set-up's goal, matched to the example's demonstrations (they bring the block back).
    assert 'data-source="set-up"' in panel.goal.content
    assert "The goal of this set-up:</b> Put the block on the pad, then back where it started." in panel.goal.content
    assert not panel.goal_ok.visible and panel.goal_pick.visible
    # The teacher's own table: no goal stated, so it is read from the demonstrations and asked about.
    ctl.scene.set_goal(())
    assert wait_for(lambda: 'data-source="demonstrations"' in panel.goal.content)
    assert "Put the block on the pad, then back where it started. Is that right?" in panel.goal.content
    assert panel.goal_ok.visible
    page.set_value("Yes, that is the goal", True)
    assert wait_for(lambda: 'data-source="you"' in panel.goal.content)
    assert [p.onto for p in ctl.scene.scene.goal] == ["pad", "where it started"] and not panel.goal_ok.visible
    # Corrected: the block stays on the table where the demonstrations put it at the end, a fixed spot.
    choice = "Put the block on the pad, then on the table where you put it."
    assert choice in panel.goal_pick.options
    page.set_value("Or the goal is", choice)
    assert wait_for(lambda: [p.onto for p in ctl.scene.scene.goal] == ["pad", "a spot on the table"])
    assert wait_for(lambda: choice in panel.goal.content and 'data-source="you"' in panel.goal.content)
    assert ctl.session.objects.scene.goal == ctl.scene.scene.goal  # kept with the session's scene


def test_the_path_drawn_in_preview_is_the_path_play_plays(trained_app: Studio) -> None:
    """The cyan path is where the gripper goes when the joints Play plays are followed, with the objects where
    they are now: moved with the block, it reaches the block where it now stands."""
    ctl, panel = trained_app.controller, trained_app.panels.preview
    assert ctl.session.skills
    assert wait_for(lambda: "path_left" in panel._nodes)
    block = ctl.scene.scene.object("block")

    def reach_to(at: tuple[float, float, float]) -> float:
        pts = np.asarray(panel._nodes["path_left"].points).reshape(-1, 3)  # type: ignore[attr-defined]
        return float(np.min(np.linalg.norm(pts[:, :2] - np.asarray(at[:2]), axis=1)))

    assert reach_to(block.position) < 0.01
    ctl.scene.move("block", (block.position[0] - 0.06, block.position[1] - 0.08, block.position[2]))
    moved = ctl.scene.scene.object("block").position
    assert wait_for(lambda: reach_to(moved) < 0.01), reach_to(moved)
    rec = ctl.playback.preview_recording()
    played = ctl.baxter.fk_batch("left", np.asarray(rec.q)[:, :7])[0]
    drawn = np.asarray(panel._nodes["path_left"].points).reshape(-1, 3)  # type: ignore[attr-defined]
    far = max(float(np.min(np.linalg.norm(played - p, axis=1))) for p in drawn[::25])
    assert far < 0.005, far  # every drawn point lies on the played path
