"""The studio's controller: its state and every action, over the core, the robot backend and the storage.

It knows nothing of viser (:class:`studio.app.Studio` adds the server, scene and panels), so it runs and is
tested without a browser. One module per concern (``events``, ``context``, ``teaching``, ``demos``,
``learning``, ``livepath``, ``suggest``, ``training``, ``playback``, ``sessions``, ``scene``, ``execution``,
``run``, ``view``, ``pose``). No part takes another: each gets the :class:`Context` and narrow protocols or
callables (ARCHITECTURE.md, "The controller")."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import ParamSpec, TypeVar

from studio.controller.context import Context, Kind, LogNotifier, Notifier
from studio.controller.demos import PALETTE, Demos, DemoSummary
from studio.controller.events import Events, Topic
from studio.controller.execution import ExecutionActions
from studio.controller.guiding import Guiding
from studio.controller.learning import KeypointItem, KeypointTuning, KeypointView
from studio.controller.livepath import LivePath, LivePaths
from studio.controller.placed import PlacedSkills
from studio.controller.playback import PREVIEW, REPLAY, Playback, PlaybackKind, Player
from studio.controller.pose import Display, PoseSource
from studio.controller.run import RunPaths, RunStatus
from studio.controller.scene import SceneActions
from studio.controller.sessions import RECOVERED, SessionActions, open_or_create
from studio.controller.suggest import Suggesting, SuggestState
from studio.controller.teaching import Reach, Teaching
from studio.controller.training import SkillVerdict, Training, UsedDemo
from studio.controller.undo import Undo
from studio.controller.unsaved import UnsavedTakes
from studio.controller.view import Layer, Step, View
from studio.core.kinematics import Baxter
from studio.robot_backend.base import RobotBackend
from studio.storage import Session, SessionStore
from studio.words.controls import STUDIO_CONTROLS, Controls
from studio.world import FLOOR_Z, Goal, GraspNote, ObjectPose, Placement, Scene, TaskResult, WorldEvent, WorldObject
from studio.world import PRESETS as SCENE_PRESETS

log = logging.getLogger(__name__)
P = ParamSpec("P")
R = TypeVar("R")


class Controller:
    """The studio without its GUI: a thin composition of the parts, each an attribute a panel uses.

    Attributes:
        teaching, guide, demos, keypoints, live, suggest, training, playback, sessions, scene, execution, view: the
            parts (see the module docstring).
        display: the pose the scene draws; events: the topics to subscribe to; baxter: the kinematic model.

    Start it with :meth:`start` (robot streaming, key-point thread) and stop it with :meth:`shutdown`.
    ``headless``: for commands without a GUI (``studio learn``): a failed job raises from its future.
    ``controls``: how its audience reaches the controls its sentences point to (the studio's buttons by default).
    """

    def __init__(
        self,
        *,
        store: SessionStore,
        session: str | Session,
        backend: RobotBackend,
        baxter: Baxter | None = None,
        notifier: Notifier | None = None,
        headless: bool = False,
        controls: Controls = STUDIO_CONTROLS,
    ) -> None:
        baxter = baxter if baxter is not None else Baxter.load()
        opened = session if isinstance(session, Session) else open_or_create(store, session)
        self.ctx = ctx = Context(store, opened, baxter, notifier or LogNotifier(), headless=headless, controls=controls)
        # Each part gets the context and narrow callables or protocols for what it asks of the others (late
        # bound: a part is asked only once all exist); it subscribes to the events it follows itself.
        self.view = View(ctx.events)
        self.undo = Undo(ctx)  # a discarded take or a deleted demonstration, for a while
        self.unsaved = UnsavedTakes(ctx)  # takes a full disk did not take yet, saved when it has space
        self.demos = Demos(ctx, keep=self.undo.keep)
        self.placed = PlacedSkills(ctx)  # the skills where the objects are now: what preview and runs play
        self.playback = Player(
            ctx,
            guard=lambda: self.execution.check_not_running(),
            skills=self.placed.get,
            step=lambda: self.view.step.value,
        )
        self.scene = SceneActions(ctx, backend, player=self.playback)
        self.teaching = Teaching(
            ctx,
            backend,
            takes=self.scene,
            motion_guard=lambda d: self.execution.check_free(d),
            keep=lambda recording, events: self.undo.keep(recording, events),
            unsaved=self.unsaved.keep,
            contacts=self.scene.first_contact,
        )
        self.guide = Guiding(ctx, self.teaching, objects=lambda: self.scene.live.poses())
        self.keypoints = KeypointTuning(ctx, self.demos)
        self.live = LivePaths(
            ctx,
            self.demos,
            self.keypoints,
            wanted=lambda: self.view.shown(Layer.KEYPOINTS),
            route=lambda arm: self.training.chosen_route(arm),
        )
        self.suggest = Suggesting(ctx, self.demos, self.keypoints)
        self.training = Training(ctx, self.demos, self.keypoints)
        self.execution = ExecutionActions(
            ctx,
            backend,
            objects=self.scene,
            hands=self.teaching,
            training_busy=lambda: self.training.busy,
            unload_playback=self.playback.unload,
            skills=self.placed.get,
            warnings=self.placed.warnings,
            contacts=self.scene.contact_reason,
        )
        self.sessions = SessionActions(ctx, persist=self.keypoints.persist)

    @property
    def display(self) -> Display:
        """The pose the scene draws."""
        return self.ctx.display

    # -- shared things -------------------------------------------------------------------------------------
    @property
    def session(self) -> Session:
        """The open session (switch it with ``sessions.open`` / ``new`` / ``duplicate``)."""
        return self.ctx.session

    @property
    def store(self) -> SessionStore:
        return self.ctx.store

    @property
    def baxter(self) -> Baxter:
        return self.ctx.baxter

    @property
    def backend(self) -> RobotBackend:
        return self.teaching.backend

    @property
    def events(self) -> Events:
        return self.ctx.events

    @property
    def notifier(self) -> Notifier:
        return self.ctx.notifier

    @notifier.setter
    def notifier(self, notifier: Notifier) -> None:
        self.ctx.notifier = notifier

    def notify(self, title: str, body: str, *, kind: Kind = "error", client: object | None = None) -> None:
        self.ctx.notify(title, body, kind=kind, client=client)

    def report(self, exc: BaseException, *, title: str = "That did not work", client: object | None = None) -> None:
        self.ctx.report(exc, title=title, client=client)

    def guarded(self, title: str = "That did not work") -> Callable[[Callable[P, R]], Callable[P, R | None]]:
        """Decorator for GUI callbacks: any failure becomes a notification; the studio keeps running."""
        return self.ctx.guarded(title)

    # -- lifecycle -----------------------------------------------------------------------------------------
    def start(self) -> None:
        """Follow the robot (start streaming) and start the key-point thread."""
        self.teaching.start_robot()
        self.keypoints.start()
        if self.ctx.session.skills:
            self.training.judge()

    def close(self) -> None:
        """Keep a running take and unsaved thresholds (failures are logged), and stop the key-point thread."""
        self.teaching.save_running_recording()
        self.unsaved.close()  # what waits for disk space: a last try, else a spill folder (the next open adds it)
        try:
            self.keypoints.persist()
        except Exception:
            log.exception("saving the key-point settings at shutdown")
        self.keypoints.close()

    def shutdown(self) -> None:
        """Stop following the robot, stop it, unload playback and drop queued work."""
        self.execution.close()
        self.playback.unload()
        self.teaching.stop_robot()
        self.scene.close()
        self.ctx.shutdown()


__all__ = [
    "FLOOR_Z",
    "PALETTE",
    "PREVIEW",
    "RECOVERED",
    "REPLAY",
    "SCENE_PRESETS",
    "Context",
    "Controller",
    "DemoSummary",
    "Demos",
    "Display",
    "Events",
    "ExecutionActions",
    "Goal",
    "GraspNote",
    "Guiding",
    "KeypointItem",
    "KeypointTuning",
    "KeypointView",
    "Layer",
    "LivePath",
    "LivePaths",
    "LogNotifier",
    "Notifier",
    "ObjectPose",
    "Placement",
    "Playback",
    "PlaybackKind",
    "Player",
    "PoseSource",
    "Reach",
    "RunPaths",
    "RunStatus",
    "Scene",
    "SceneActions",
    "SessionActions",
    "SkillVerdict",
    "Step",
    "SuggestState",
    "Suggesting",
    "TaskResult",
    "Teaching",
    "Topic",
    "Training",
    "Undo",
    "UnsavedTakes",
    "UsedDemo",
    "View",
    "WorldEvent",
    "WorldObject",
]
