"""The Move panel and the gripper handle with a server (issue 18): the handle's arrows in the room's axes with no
plane squares, rings behind "Turn with the handle", one handle at a time, "Go above the" lists the objects, the
position boxes follow the gripper, the View buttons and a camera kept above the floor."""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from studio.app import Studio
from studio.controller import FLOOR_Z
from studio.controller.guiding import BIG_STEP_M, STEP_M
from studio.panels._camera import CAMERA_ABOVE_FLOOR_M, VIEWS, lifted, set_view
from studio.panels.move import KEYS
from studio.panels.steps import VIEW_BUTTONS
from tests.conftest import wait_for
from tests.viser_client import ViserClient


def test_the_handle_moves_in_room_axes_and_turns_behind_a_toggle(app: Studio) -> None:
    h = app.panels.teach.handles["left"]
    assert tuple(h.wxyz) == (1.0, 0.0, 0.0, 0.0) and h.disable_sliders
    assert h.disable_rotations and not h.disable_axes
    app.controller.guide.set_turning(True)
    assert not h.disable_rotations and h.disable_axes and h.disable_sliders
    assert h.scale < 0.2 and app.panels.move.turn.value is True
    app.controller.guide.set_turning(False)
    assert h.disable_rotations and not h.disable_axes
    assert app.panels.scene.handle.disable_sliders  # the objects' handle has no plane squares either


def test_one_handle_at_a_time(app: Studio) -> None:
    ctl, teach = app.controller, app.panels.teach
    assert teach.handles["left"].visible
    ctl.guide.choose("cup")
    assert not teach.handles["left"].visible
    ctl.guide.choose(None)
    assert teach.handles["left"].visible


def test_go_above_lists_the_objects_and_the_boxes_follow_the_gripper(app: Studio) -> None:
    ctl, move = app.controller, app.panels.move
    assert tuple(move.above.options) == tuple(ctl.scene.scene.names()) == ("bottom cup", "cup")
    ctl.guide.above("cup")
    p = ctl.guide.pose("left")[0] * 100.0
    assert wait_for(lambda: all(abs(float(move.boxes[a].value) - p[i]) < 0.06 for i, a in enumerate("xyz")))
    assert 'class="gripper-goal"' in move.where.content
    ctl.scene.use_preset("empty table")
    assert not move.above.visible
    # every key shows on a button of the panel: the key script clicks that button
    labels = {o for grp in move.rows.values() for o in grp.options} | set(move.grip.options) | {move.home.label}
    assert set(KEYS.values()) <= labels
    assert all(f"Shift+{code}" in KEYS for code in ("KeyW", "KeyS", "KeyA", "KeyD", "KeyQ", "KeyE"))  # 5 cm


def test_view_buttons_and_the_camera_above_the_floor() -> None:
    assert VIEW_BUTTONS == ("Front", "Top", "Side", "Reset")

    class Camera:
        pass

    class Client:
        camera = Camera()

        def atomic(self) -> contextlib.nullcontext[None]:
            return contextlib.nullcontext()

    c = Client()
    for name in ("Front", "Top", "Side"):
        set_view(c, name)  # type: ignore[arg-type]
        assert (c.camera.position, c.camera.look_at) == VIEWS[name]  # type: ignore[attr-defined]
        assert c.camera.position[2] > FLOOR_Z  # type: ignore[attr-defined]
    assert lifted((2.0, 0.0, 0.5), (0.7, 0.0, 0.0)) is None
    up = lifted((2.0, 0.0, -1.5), (0.7, 0.0, -1.2))
    assert up is not None
    assert up[0] == pytest.approx((2.0, 0.0, FLOOR_Z + CAMERA_ABOVE_FLOOR_M)) and up[1][2] == pytest.approx(FLOOR_Z)
    assert np.isfinite(up[0]).all()


@pytest.fixture
def tab(app: Studio) -> Iterator[ViserClient]:
    c = ViserClient.tab_of(app)
    c.wait_gui("Gripper z (cm)")
    yield c
    c.close()


def test_a_tab_moves_and_turns_the_gripper_with_the_handle_and_the_buttons(app: Studio, tab: ViserClient) -> None:
    ctl = app.controller
    g = ctl.guide
    p0, w0 = g.pose("left")
    # move mode: arrows in room axes; what the page sends as orientation does not turn the gripper
    t = p0 + np.array([0.05, -0.03, 0.02])
    target = (float(t[0]), float(t[1]), float(t[2]))
    tab.drag("/teach/left_handle", target, wxyz=(0.9659, 0.0, 0.0, 0.2588))
    assert wait_for(lambda: np.allclose(g.pose("left")[0], target, atol=2e-3))
    assert np.allclose(np.abs(g.pose("left")[1] @ w0), 1.0, atol=1e-4)
    # turn mode: the handle's turn from the room's axes turns the gripper about the room's z
    ctl.guide.set_turning(True)
    turn = Rotation.from_euler("z", 30, degrees=True)
    x, y, z, w = (float(v) for v in turn.as_quat())
    tab.drag("/teach/left_handle", target, wxyz=(w, x, y, z))
    expected = turn * Rotation.from_quat(np.roll(w0, -1))
    assert wait_for(lambda: (Rotation.from_quat(np.roll(g.pose("left")[1], -1)) * expected.inv()).magnitude() < 1e-2)
    assert wait_for(lambda: tuple(app.panels.teach.handles["left"].wxyz) == (1.0, 0.0, 0.0, 0.0))
    # the keypad's buttons (what the keys press): one step down, then open and home
    z0 = float(g.pose("left")[0][2])
    tab.set_value("Down / up (z)", "Q down")
    assert wait_for(lambda: abs(float(g.pose("left")[0][2]) - (z0 - STEP_M)) < 2e-3)
    tab.set_value("Big steps (Shift)", "⇧E")  # what Shift+E (or E held a second) presses: 5 cm up
    assert wait_for(lambda: abs(float(g.pose("left")[0][2]) - (z0 - STEP_M + BIG_STEP_M)) < 2e-3)
    tab.set_value("H home pose", True)
    assert wait_for(lambda: np.allclose(ctl.teaching.target_q("left"), ctl.teaching.home_q("left")))


def test_a_drag_waiting_behind_a_press_runs_its_steps_in_order_with_its_poses(app: Studio, tab: ViserClient) -> None:
    """A busy studio: the release of one drag and the whole next one wait behind a press. Each step then runs in
    the order and with the pose the tab sent: the first drag (move mode) never turns the gripper, the second (turn
    mode) turns it by its own 30 degrees, and the handle is back in room axes."""
    g = app.controller.guide
    presses = app.access.presses
    assert presses is not None
    gate, held = threading.Event(), threading.Event()
    hold = app.server.gui.add_button("Hold (test)")

    @hold.on_click
    def _(_event: object) -> None:
        held.set()
        gate.wait(60)

    p0, w0 = g.pose("left")
    t = p0 + np.array([0.04, 0.0, 0.0])
    target = (float(t[0]), float(t[1]), float(t[2]))
    tab.drag("/teach/left_handle", target, wxyz=(0.9659, 0.0, 0.0, 0.2588), end=False)  # move mode: no turn
    assert wait_for(lambda: np.allclose(g.pose("left")[0], target, atol=2e-3))
    tab.set_value("Hold (test)", True)
    assert held.wait(30)
    tab.send({"type": "TransformControlsDragEndMessage", "name": "/teach/left_handle", "owner": ""})
    g.set_turning(True)
    turn = Rotation.from_euler("z", 30, degrees=True)
    x, y, z, w = (float(v) for v in turn.as_quat())
    tab.drag("/teach/left_handle", target, wxyz=(w, x, y, z))
    # the release, the grab, the move and the release wait, each its own step
    assert wait_for(lambda: sum(len(tb.waiting) for tb in list(presses._tabs.values())) == 4)
    gate.set()
    expected = turn * Rotation.from_quat(np.roll(w0, -1))
    assert wait_for(lambda: (Rotation.from_quat(np.roll(g.pose("left")[1], -1)) * expected.inv()).magnitude() < 1e-2)
    assert wait_for(lambda: tuple(app.panels.teach.handles["left"].wxyz) == (1.0, 0.0, 0.0, 0.0))
    assert np.allclose(g.pose("left")[0], target, atol=2e-3)
