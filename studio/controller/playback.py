"""Playing a recording on the drawn robot: the learned skill (preview) or a recorded demonstration (replay).

One :class:`Player` does both; the only difference is where the recording comes from (the skills' joint
trajectories, sampled as the CSV export samples them, or a demonstration of the session). At most one
playback is loaded; the scene follows it while it is shown (:class:`~studio.controller.pose.Display`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from enum import StrEnum

import numpy as np

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.controller.pose import PoseSource
from studio.core import sampling
from studio.core.errors import NotEnoughData, StudioError
from studio.core.types import Arm, Recording, Skill
from studio.robot_backend.base import JointStateBatch
from studio.robot_backend.replay import ReplayBackend
from studio.words.controls import Control


class PlaybackKind(StrEnum):
    """What a playback plays: the learned skill, or a recorded demonstration."""

    PREVIEW = "preview"
    REPLAY = "replay"


PREVIEW = PlaybackKind.PREVIEW
REPLAY = PlaybackKind.REPLAY
#: The step each playback is shown in (elsewhere the scene shows the live robot and the objects as placed).
SHOWN_IN = {PREVIEW: "Preview", REPLAY: "Sessions"}
#: Samples per second of the preview recording.
PREVIEW_RATE_HZ = 100.0


class Playback:
    """A recording streamed by a :class:`ReplayBackend` into a :class:`PoseSource` the scene can show."""

    def __init__(self, kind: PlaybackKind, recording: Recording, key: object, speed: float = 1.0) -> None:
        self.kind = kind
        self.recording = recording
        self.key = key
        self.backend = ReplayBackend(recording, speed=speed)
        self.source = PoseSource()
        st = self.backend.state()
        self.source.set(st.t, st.q, st.gripper)
        self._unsub = self.backend.subscribe(self._on_batch)
        self._lock = threading.Lock()
        self._closed = False

    def _on_batch(self, batch: JointStateBatch) -> None:
        if len(batch):
            self.source.set(float(batch.t[-1]), batch.q[-1], batch.gripper[-1])

    @property
    def position(self) -> float:
        return self.backend.position

    @property
    def playing(self) -> bool:
        """Playing now (not paused, not at its end)."""
        return self.backend.running and not self.backend.finished

    @property
    def finished(self) -> bool:
        return self.backend.finished

    def play(self) -> None:
        """Play from where it is; nothing once closed (another tab may have unloaded it meanwhile)."""
        with self._lock:
            if not self._closed:
                self.backend.start()

    def pause(self) -> None:
        self.backend.stop()

    def set_speed(self, speed: float) -> None:
        self.backend.speed = float(speed)

    def seek(self, t: float) -> None:
        self.backend.seek(t)
        i = int(np.clip(np.searchsorted(self.recording.t, t), 0, len(self.recording) - 1))
        self.source.set(float(self.recording.t[i]), self.recording.q[i], self.recording.gripper[i])

    def close(self) -> None:
        with self._lock:
            self._closed = True
            self._unsub()
            self.backend.stop()


class Player:
    """Loads, plays, pauses, seeks and unloads the one playback; every action names the kind it is for.

    A new skill unloads the preview of the old one (:attr:`Topic.SKILL`); another session unloads any
    playback and shows the live robot (:attr:`Topic.SESSION`). A playback stays in its step (:data:`SHOWN_IN`):
    on another step it pauses and the scene shows the live robot; back in its step, the scene shows it again.

    Args:
        guard: refuses (raises, in plain words) to show a playback while the robot runs a skill: the scene
            shows the real robot then.
        skills: the skills the preview plays (default: the session's, as learned).
        step: the step the teacher is at (its name; :class:`~studio.controller.view.View`), read on
            :attr:`Topic.VIEW`.
    """

    def __init__(
        self,
        ctx: Context,
        guard: Callable[[], None] = lambda: None,
        skills: Callable[[], Mapping[Arm, Skill]] | None = None,
        step: Callable[[], str] | None = None,
    ) -> None:
        self.ctx = ctx
        self.display = ctx.display
        self.guard = guard
        self.step = step
        self._loaded: Playback | None = None
        #: The skills the preview plays (the controller's: placed where the objects are now).
        self.skills: Callable[[], Mapping[Arm, Skill]] = skills or (lambda: ctx.session.skills)
        # a new skill, or the objects set up elsewhere: a preview loaded before shows what is no longer so
        for topic in (Topic.SKILL, Topic.SCENE):
            ctx.events.on(topic, self.unload_preview)
        ctx.events.on(Topic.SESSION, self._on_session)
        ctx.events.on(Topic.VIEW, self._on_view)

    # -- state -----------------------------------------------------------------------------------------------
    @property
    def kind(self) -> PlaybackKind | None:
        """The loaded playback ("preview" or "replay", playing or paused), or None when the scene is live."""
        pb = self._loaded
        return pb.kind if pb is not None else None

    @property
    def loaded(self) -> Playback | None:
        return self._loaded

    def _get(self, kind: PlaybackKind) -> Playback | None:
        pb = self._loaded
        return pb if pb is not None and pb.kind == kind else None

    def position(self, kind: PlaybackKind) -> float | None:
        """Seconds into the ``kind`` playback while it plays or has just played to its end (None when paused or
        not loaded)."""
        pb = self._get(kind)
        return pb.position if pb is not None and pb.backend.running else None

    def label(self) -> str:
        """What the drawn robot shows, in plain words."""
        pb = self._loaded
        if self.display.is_live or pb is None:
            return "Showing the robot live."
        what = "the learned skill (preview)" if pb.kind == PREVIEW else f'demonstration "{pb.recording.name}"'
        state = "playing" if pb.playing else ("at its end" if pb.finished else "paused")
        return f"Showing {what}, {state}."

    # -- actions ---------------------------------------------------------------------------------------------
    def play(self, kind: PlaybackKind, key: object, make: Callable[[], Recording], speed: float = 1.0) -> Playback:
        """Play (resume when the ``kind`` playback of ``key`` is loaded, from the start once it finished)."""
        self.guard()
        pb = self._get(kind)
        if pb is not None and pb.key is key:
            if pb.finished:
                pb.seek(0.0)
            pb.set_speed(speed)
            self.display.show(pb.source)
            pb.play()
            return pb
        pb = self._load(kind, key, make(), speed)
        pb.play()
        return pb

    def pause(self, kind: PlaybackKind) -> None:
        pb = self._get(kind)
        if pb is not None:
            pb.pause()

    def set_speed(self, kind: PlaybackKind, speed: float) -> None:
        pb = self._get(kind)
        if pb is not None:
            pb.set_speed(speed)

    def seek(
        self, kind: PlaybackKind, t: float, key: object = None, make: Callable[[], Recording] | None = None
    ) -> None:
        """Show the moment ``t`` s; loads the playback paused when ``make`` is given and it is not loaded."""
        self.guard()
        pb = self._get(kind)
        if pb is None:
            if make is None:
                raise StudioError(
                    f"{self.ctx.say(Control.PLAY, first=True)} first to choose a demonstration to replay."
                )
            pb = self._load(kind, key, make(), 1.0)
        pb.seek(t)
        self.display.show(pb.source)

    def stop(self, kind: PlaybackKind) -> None:
        """Unload the ``kind`` playback (if loaded) and show the live robot."""
        if self._get(kind) is not None:
            self.unload()
        self.display.show_live()

    def unload_preview(self) -> None:
        """A new skill was learned or the objects moved: unload the preview of before (the scene goes live if it
        showed it)."""
        if self._get(PREVIEW) is not None:
            self.unload()
            self.display.show_live()

    def _on_view(self) -> None:
        """The teacher changed steps: the playback pauses and the live robot shows outside its step; back in its
        step it shows again (paused where it was), unless the robot is running a skill."""
        pb, step = self._loaded, self.step
        if pb is None or step is None:
            return
        if step() == SHOWN_IN[pb.kind]:
            try:
                self.guard()
            except StudioError:
                return
            self.display.show(pb.source)
            pb.source.touch()
        else:
            pb.pause()
            self.display.show_live()
        self.ctx.emit(Topic.PLAYBACK)

    def _on_session(self) -> None:
        self.unload()
        self.display.show_live()

    def unload(self) -> None:
        """Unload whatever is loaded (the scene keeps the current source until told otherwise)."""
        pb, self._loaded = self._loaded, None
        if pb is not None:
            pb.close()
            self.ctx.emit(Topic.PLAYBACK)

    def _load(self, kind: PlaybackKind, key: object, recording: Recording, speed: float) -> Playback:
        self.unload()
        pb = Playback(kind, recording, key, speed)
        self._loaded = pb
        self.display.show(pb.source)
        self.ctx.emit(Topic.PLAYBACK)
        return pb

    # -- the two sources ---------------------------------------------------------------------------------------
    def preview_duration(self) -> float:
        """The preview's length: the skills it plays (:meth:`PlacedSkills.duration`'s figure)."""
        return sampling.duration(self.skills())

    def preview_recording(self) -> Recording:
        """The learned joint trajectories of all arms as one Recording (arms without a skill hold still)."""
        skills = sampling.executable(self.skills())
        if not skills:
            raise NotEnoughData(f"There is no learned skill to preview yet: {self.ctx.say(Control.TRAIN)} first.")
        t_end = sampling.duration(skills)
        t = np.linspace(0.0, max(t_end, 0.01), max(2, int(t_end * PREVIEW_RATE_HZ) + 1))
        _, _, q_live, g_live = self.display.live.get()  # the arms without a skill hold the live robot's pose
        q, g = sampling.sample_joints(skills, t, q_live.copy(), g_live.copy())
        return Recording(t=t, q=q, gripper=g, arms=tuple(skills), name="learned skill")

    def play_preview(self, speed: float = 1.0) -> None:
        self.play(PREVIEW, PREVIEW, self.preview_recording, speed)

    def seek_preview(self, t: float) -> None:
        self.seek(PREVIEW, t, PREVIEW, self.preview_recording)

    def play_demo(self, i: int, speed: float = 1.0) -> float:
        """Replay recorded demonstration ``i`` on the (drawn) robot; returns its duration."""
        rec = self.ctx.session.recordings[i]
        self.play(REPLAY, rec, lambda: rec, speed)
        return float(rec.duration)
