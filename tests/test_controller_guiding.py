"""Guiding the gripper without a browser (issue 18): steps in the room's axes (1 cm, big 5 cm), a typed
position, "Go above" an object (carrying one: what it carries stays clear), Home, the object chosen and the
handle's mode with their event, and the arm never left trapped by the handle."""

from __future__ import annotations

import numpy as np
import pytest

from studio.controller import Controller, Topic
from studio.controller.guiding import ABOVE_M, BIG_STEP_M, STEP_M
from studio.core.errors import StudioError
from studio.core.rotations import matrix_from_quat_wxyz
from tests.conftest import wait_for


def test_a_step_moves_the_gripper_along_one_room_axis(ctl: Controller) -> None:
    g = ctl.guide
    w0 = g.pose("left")[1]
    for axis, i in (("x", 0), ("y", 1), ("z", 2)):
        before = g.pose("left")[0]
        res = g.step(axis, 1)
        after = g.pose("left")[0]
        assert res.converged
        expected = before.copy()
        expected[i] += STEP_M
        assert np.allclose(after, expected, atol=2e-3), (axis, after - before)
    assert np.allclose(g.pose("left")[1], w0, atol=1e-2)  # the orientation is kept
    assert g.key_arm == "left"


def test_a_big_step_is_five_steps_and_a_step_never_grows(ctl: Controller) -> None:
    g = ctl.guide
    z = [float(g.pose("left")[0][2])]
    for _ in range(8):  # presses close together (a held key's clicks): the server's step stays one step
        g.step("z", 1)
        z.append(float(g.pose("left")[0][2]))
    assert np.allclose(np.diff(z), STEP_M, atol=2e-3)
    before = float(g.pose("left")[0][0])
    g.step("x", 1, big=True)  # Shift (or a key held a second, the page's script): a big step
    assert float(g.pose("left")[0][0]) - before == pytest.approx(BIG_STEP_M, abs=2e-3)


def test_typed_position_and_go_above_a_cup_pointing_down(ctl: Controller) -> None:
    g = ctl.guide
    g.move_axis("left", "y", 0.3)
    assert g.pose("left")[0][1] == pytest.approx(0.3, abs=1e-3)
    res = g.above("cup")
    cup = next(o for o in ctl.scene.live.poses() if o.name == "cup")
    p, w = g.pose("left")
    assert res.converged
    assert np.allclose(p, [cup.position[0], cup.position[1], cup.position[2] + cup.size[2] + ABOVE_M], atol=1e-3)
    assert matrix_from_quat_wxyz(w)[:, 2] == pytest.approx([0.0, 0.0, -1.0], abs=1e-3)  # pointing down
    with pytest.raises(StudioError, match="Choose an object"):
        g.above("no such thing")


def test_carrying_a_cup_above_the_bottom_cup_keeps_it_clear(ctl: Controller) -> None:
    g, t = ctl.guide, ctl.teaching
    g.above("cup")
    for _ in range(4):
        g.step("z", -1)
    assert wait_for(lambda: np.allclose(t.robot_q()[:7], t.target_q("left"), atol=1e-3))
    t.set_gripper("left", 0.0)
    assert wait_for(lambda: any(o.held_by == "left" for o in ctl.scene.live.poses()))
    held = next(o for o in ctl.scene.live.poses() if o.held_by == "left")
    hang = float(g.pose("left")[0][2]) - held.position[2]
    res = g.above("bottom cup")
    bottom = next(o for o in ctl.scene.live.poses() if o.name == "bottom cup")
    assert res.converged
    assert g.pose("left")[0][2] == pytest.approx(bottom.position[2] + bottom.size[2] + ABOVE_M + hang, abs=2e-3)
    with pytest.raises(StudioError, match="in the gripper"):
        g.above("cup")


def test_home_and_the_trap_of_issue_18(ctl: Controller) -> None:
    """Out of reach away from the robot and back: the release place is reached; Home brings the start back."""
    g, t, b = ctl.guide, ctl.teaching, ctl.baxter
    start = t.target_q("left")
    p0, _ = g.pose("left")
    for dx in np.linspace(0.0, 1.2, 25):
        g.move("left", p0 + np.array([dx, 0.0, 0.0]))
    assert t.unreachable("left") and "cannot reach" in t.reach_message()
    for dx in np.linspace(1.2, 0.2, 25):
        res = g.move("left", p0 + np.array([dx, -0.1, -0.05]))
    assert res.converged and not t.unreachable("left")
    q = t.target_q("left")
    lo, hi = b.lower_limits("left"), b.upper_limits("left")
    assert np.all(np.minimum(q - lo, hi - q)[[0, 1, 2, 4, 5, 6]] > np.radians(1.0))
    g.home()
    assert np.allclose(t.target_q("left"), start, atol=1e-9) and not t.unreachable("left")


def test_the_chosen_object_and_the_handle_mode_are_told(ctl: Controller) -> None:
    seen: list[tuple[str | None, bool]] = []
    ctl.events.on(Topic.GUIDE, lambda: seen.append((ctl.guide.chosen, ctl.guide.turning)))
    ctl.guide.choose("cup")
    ctl.guide.choose("cup")  # no change, no event
    ctl.guide.set_turning(True)
    ctl.guide.choose(None)
    assert seen == [("cup", False), ("cup", True), (None, True)]
