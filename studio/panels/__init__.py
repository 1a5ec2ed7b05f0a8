"""The studio's panels, one module each; :func:`build_panels` lays them out in the side bar.

A panel receives the controller (its state and actions) and the viser server (its GUI and scene), never
another panel: what one panel changes, the others learn from the controller's events
(:class:`studio.controller.Topic`). A panel builds its handles, binds each callback to one controller action
(wrapped in ``controller.guarded``), redraws on events, and holds no math.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import viser

from studio.controller import Controller
from studio.panels.demos import DemosPanel
from studio.panels.keypoints import KeypointsPanel
from studio.panels.preview import PreviewPanel
from studio.panels.robot import RobotPanel
from studio.panels.sessions import SessionsPanel
from studio.panels.teach import TeachPanel
from studio.panels.train import TrainPanel


@dataclass
class Panels:
    robot: RobotPanel
    teach: TeachPanel
    demos: DemosPanel
    keypoints: KeypointsPanel
    train: TrainPanel
    preview: PreviewPanel
    sessions: SessionsPanel

    def tick(self, now: float) -> None:
        """Periodic refresh from the pose pump thread (timers, handles following the robot, playback)."""
        self.robot.tick(now)
        self.teach.tick(now)
        self.preview.tick(now)
        self.sessions.tick(now)

    def close(self) -> None:
        self.keypoints.close()


def build_panels(ctl: Controller, server: viser.ViserServer, urdf_path: Path) -> Panels:
    """The robot panel above a tab per step: Teach, Key-points, Train, Preview, Sessions."""
    gui = server.gui
    gui.add_markdown(
        "Teach Baxter a skill by showing it a few times: guide the arm, record three demonstrations, "
        "then train and preview.",
        order=-1,
    )
    robot = RobotPanel(ctl, server, urdf_path)
    tabs = gui.add_tab_group(order=1)
    with tabs.add_tab("Teach", viser.Icon.HAND_FINGER):
        teach = TeachPanel(ctl, server)
        demos = DemosPanel(ctl, server)
    with tabs.add_tab("Key-points", viser.Icon.POINT):
        keypoints = KeypointsPanel(ctl, server)
    with tabs.add_tab("Train", viser.Icon.BRAIN):
        train = TrainPanel(ctl, server)
    with tabs.add_tab("Preview", viser.Icon.PLAYER_PLAY):
        preview = PreviewPanel(ctl, server)
    with tabs.add_tab("Sessions", viser.Icon.FOLDER):
        sessions = SessionsPanel(ctl, server)
    return Panels(robot, teach, demos, keypoints, train, preview, sessions)
