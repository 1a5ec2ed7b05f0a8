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

from studio.controller import Controller, Step
from studio.panels.demos import DemosPanel
from studio.panels.keypoints import KeypointsPanel
from studio.panels.move import MovePanel
from studio.panels.preview import PreviewPanel
from studio.panels.robot import RobotPanel
from studio.panels.run import RunPanel
from studio.panels.scene import ScenePanel
from studio.panels.sessions import SessionsPanel
from studio.panels.steps import StepPanel
from studio.panels.task import TaskPanel
from studio.panels.teach import TeachPanel
from studio.panels.train import TrainPanel


@dataclass
class Panels:
    robot: RobotPanel
    run: RunPanel
    teach: TeachPanel
    move: MovePanel
    demos: DemosPanel
    keypoints: KeypointsPanel
    train: TrainPanel
    preview: PreviewPanel
    sessions: SessionsPanel
    scene: ScenePanel
    steps: StepPanel
    task: TaskPanel

    def tick(self, now: float) -> None:
        """Periodic refresh from the pose pump thread (timers, handles following the robot, playback)."""
        self.robot.tick(now)
        self.run.tick(now)
        self.scene.tick(now)
        self.task.tick(now)
        self.teach.tick(now)
        self.move.tick(now)
        self.preview.tick(now)
        self.sessions.tick(now)

    def close(self) -> None:
        self.keypoints.close()


def build_panels(ctl: Controller, server: viser.ViserServer, urdf_path: Path) -> Panels:
    """The robot panel, the robot's run (status, Stop, Emergency stop), the step buttons, then one section per
    step: Teach, Key-points, Train, Preview, Sessions (only the current step's is shown; see
    :mod:`studio.panels.steps`)."""
    gui = server.gui
    gui.add_markdown(
        "Teach Baxter a skill by showing it a few times: guide the arm, record three demonstrations, "
        "then train and preview.",
        order=-1,
    )
    robot = RobotPanel(ctl, server, urdf_path)
    run = RunPanel(ctl, server)  # on every step: the robot's run, Stop and the Emergency stop
    sections = {step: gui.add_folder(None, order=10 + i, visible=step == ctl.view.step) for i, step in enumerate(Step)}
    with sections[Step.TEACH]:
        task = TaskPanel(ctl, server)  # the task and the grasp feedback, above the teaching controls
        teach = TeachPanel(ctl, server)
        move = MovePanel(ctl, server)  # keys, position boxes, Go above, Home pose
        scene = ScenePanel(ctl, server)
        demos = DemosPanel(ctl, server)
    with sections[Step.KEYPOINTS]:
        keypoints = KeypointsPanel(ctl, server)
    with sections[Step.TRAIN]:
        train = TrainPanel(ctl, server)
    with sections[Step.PREVIEW]:
        preview = PreviewPanel(ctl, server)
    with sections[Step.SESSIONS]:
        sessions = SessionsPanel(ctl, server)
    steps = StepPanel(ctl, server, sections)
    return Panels(robot, run, teach, move, demos, keypoints, train, preview, sessions, scene, steps, task)
