"""The robot on screen is the robot: every link the browser draws sits where pinocchio's FK puts it.

The studio runs in-process (viser server on a free port, simulated Baxter, the real pose pump). Both arms and
grippers are commanded to random configurations; whatever the pump last drew is compared, link by link, with
forward kinematics of the configuration it drew, by composing the scene-graph poses the server holds for the
browser (what every tab receives). Checked while the arms move and after they arrive.
"""

from __future__ import annotations

import shutil
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from studio.app import build_app
from studio.core.kinematics import Baxter
from tests.conftest import free_port, wait_for
from tests.drawing import drawn_node_poses, fk_link_poses, pose_errors

ROOT = Path(__file__).resolve().parent.parent
POS_TOL = 1e-3  # m
ROT_TOL = 0.01  # rad


@pytest.fixture
def app(tmp_path: Path):
    d = tmp_path / "sessions"
    shutil.copytree(ROOT / "sessions", d)
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=d)
    yield a
    a.stop()


class _Spy:
    """Wraps the robot panel's show_pose (the pose pump's path) to remember what it drew, under a lock."""

    def __init__(self, panel) -> None:
        self.panel = panel
        self.original = panel.show_pose
        self.lock = threading.Lock()
        self.q: np.ndarray | None = None
        self.g: np.ndarray | None = None
        self.calls = 0
        panel.show_pose = self

    def __call__(self, q: np.ndarray, gripper: np.ndarray) -> None:
        with self.lock:
            self.original(q, gripper)
            self.q, self.g = np.array(q, dtype=float), np.array(gripper, dtype=float)
            self.calls += 1

    def snapshot(self, server) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        with self.lock:
            assert self.q is not None and self.g is not None
            return self.q.copy(), self.g.copy(), drawn_node_poses(server)


def _calls_above(spy: _Spy, n: int) -> Callable[[], bool]:
    return lambda: spy.calls > n


def _near(read: Callable[[], np.ndarray], target: np.ndarray) -> Callable[[], bool]:
    return lambda: bool(np.max(np.abs(read() - target)) < 1e-6)


def _check(baxter: Baxter, q: np.ndarray, g: np.ndarray, drawn: dict[str, np.ndarray], what: str) -> None:
    fk = fk_link_poses(baxter, q, g)
    missing = sorted(set(fk) - set(drawn))
    assert not missing, f"{what}: links not drawn at all: {missing}"
    errs = pose_errors(drawn, fk)
    bad = {k: (round(p * 1000, 2), round(r, 4)) for k, (p, r) in errs.items() if p > POS_TOL or r > ROT_TOL}
    assert not bad, f"{what}: drawn links away from FK (mm, rad): {bad}"


def test_every_drawn_link_is_where_fk_puts_it(app) -> None:
    baxter = app.controller.baxter
    spy = _Spy(app.panels.robot)
    app.controller.display.live.touch()  # make the pump draw once more, through the spy
    assert wait_for(lambda: spy.calls > 0)
    q, g, drawn = spy.snapshot(app.server)
    _check(baxter, q, g, drawn, "at start")
    # The link count: every URDF link (57 in Baxter's) is drawn.
    assert len(fk_link_poses(baxter, q, g)) >= 57

    rng = np.random.default_rng(20260)
    for k in range(4):
        target = np.concatenate([baxter.random_configuration(a, rng) for a in ("left", "right")])
        # Stay a little inside the limits so the simulated robot reaches the target exactly.
        lo = np.concatenate([baxter.lower_limits(a) for a in ("left", "right")])
        hi = np.concatenate([baxter.upper_limits(a) for a in ("left", "right")])
        target = np.clip(target, lo + 0.05, hi - 0.05)
        grip = rng.uniform(0.0, 100.0, 2)
        app.controller.teaching.command_arm("left", target[:7])
        app.controller.teaching.command_arm("right", target[7:])
        app.controller.teaching.set_gripper("left", float(grip[0]))
        app.controller.teaching.set_gripper("right", float(grip[1]))
        # While moving: what was drawn matches FK of what was drawn.
        n0 = spy.calls
        assert wait_for(_calls_above(spy, n0 + 3))
        q, g, drawn = spy.snapshot(app.server)
        _check(baxter, q, g, drawn, f"configuration {k}, moving")
        # Arrived: the drawn robot is the commanded configuration.
        assert wait_for(_near(app.controller.teaching.robot_q, target))
        assert wait_for(_near(app.controller.teaching.robot_gripper, grip))
        n1 = spy.calls
        app.controller.display.live.touch()
        assert wait_for(_calls_above(spy, n1))
        time.sleep(0.05)
        q, g, drawn = spy.snapshot(app.server)
        assert np.max(np.abs(q - target)) < 1e-6
        _check(baxter, q, g, drawn, f"configuration {k}, arrived")
        # The point between the fingertips (the skill's end-effector) in particular.
        for arm, cols in (("left", slice(0, 7)), ("right", slice(7, 14))):
            p, _ = baxter.fk(arm, target[cols])
            assert np.linalg.norm(drawn[f"{arm}_gripper"][:3, 3] - p) < POS_TOL


def test_the_drawing_matches_a_full_update_cfg(app) -> None:
    """The fast per-joint path and viser's own full update place every frame identically."""
    panel = app.panels.robot
    spy = _Spy(panel)
    rng = np.random.default_rng(7)
    baxter = Baxter.load()
    with spy.lock:
        q = np.concatenate([baxter.random_configuration(a, rng) for a in ("left", "right")])
        g = np.array([30.0, 80.0])
        spy.original(q, g)
        fast = drawn_node_poses(app.server)
        panel.urdf.update_cfg(panel._cfg.copy())
        full = drawn_node_poses(app.server)
        spy.original(q, g)  # back on the fast path, same pose
    for name, T in full.items():
        assert np.allclose(fast[name], T, atol=1e-6), name
