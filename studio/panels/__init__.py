"""The studio's panels, one module each; :func:`build_panels` lays them out in the side bar."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import viser

if TYPE_CHECKING:
    from studio.app import Studio


@dataclass
class Panels:
    robot: Any
    teach: Any
    keypoints: Any
    train: Any
    preview: Any
    sessions: Any

    def all(self) -> list[Any]:
        return [self.robot, self.teach, self.keypoints, self.train, self.preview, self.sessions]

    def tick(self, now: float) -> None:
        """Periodic refresh from the pose pump thread (timers, handles following the robot, playback)."""
        for p in self.all():
            fn = getattr(p, "tick", None)
            if fn is not None:
                fn(now)

    def close(self) -> None:
        for p in self.all():
            fn = getattr(p, "close", None)
            if fn is not None:
                fn()


def build_panels(app: Studio) -> Panels:
    from studio.panels.keypoints import KeypointsPanel
    from studio.panels.preview import PreviewPanel
    from studio.panels.robot import RobotPanel
    from studio.panels.sessions import SessionsPanel
    from studio.panels.teach import TeachPanel
    from studio.panels.train import TrainPanel

    gui = app.server.gui
    gui.add_markdown(
        "Teach Baxter a skill by showing it a few times: guide the arm, record three demonstrations, "
        "then train and preview.",
        order=-1,
    )
    robot = RobotPanel(app, gui)
    tabs = gui.add_tab_group(order=1)
    panels: dict[str, Any] = {"robot": robot}
    # Panels are created before they are filled so that cross-panel status calls find them.
    app.panels = Panels(robot=robot, teach=None, keypoints=None, train=None, preview=None, sessions=None)
    for key, label, icon, cls in (
        ("teach", "Teach", viser.Icon.HAND_FINGER, TeachPanel),
        ("keypoints", "Key-points", viser.Icon.POINT, KeypointsPanel),
        ("train", "Train", viser.Icon.BRAIN, TrainPanel),
        ("preview", "Preview", viser.Icon.PLAYER_PLAY, PreviewPanel),
        ("sessions", "Sessions", viser.Icon.FOLDER, SessionsPanel),
    ):
        with tabs.add_tab(label, icon):
            panels[key] = cls(app, gui)
            setattr(app.panels, key, panels[key])
    return app.panels
