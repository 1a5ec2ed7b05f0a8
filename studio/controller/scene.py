"""The task scene: the session's objects (add, move, remove, a preset), the live world the simulated robot
acts on, the objects of each recorded take, the objects shown during a replay or the preview, and the task
result of the learned skill in plain words.

The live :class:`~studio.world.World` listens to the robot backend; a take keeps the world's events since
its start (:meth:`SceneActions.end_take`); replay and preview play a world of their own up to the moment
shown; a run on the robot restarts the objects (:meth:`SceneActions.begin_run`, :meth:`SceneActions.end_run`)."""

from __future__ import annotations

import hashlib
import logging
import math
import threading
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.controller.placed import goal_of
from studio.controller.playback import Playback, PlaybackKind
from studio.core.errors import StudioError
from studio.core.touches import Touch
from studio.core.types import ARMS, Arm, Recording
from studio.robot_backend.base import RobotBackend
from studio.words import contact_sentence, hit_words, recorded_touch_words
from studio.world import (
    KINDS,
    PRESETS,
    Goal,
    GraspNote,
    ObjectPose,
    Placement,
    Scene,
    TaskResult,
    World,
    WorldEvent,
    WorldRun,
    bounded,
    grasp_note,
    on_clock,
    preset,
    simulate,
    task_result,
)
from studio.world.contacts import first_contact, touches, touches_at
from studio.world.goal import alternatives
from studio.world.hits import Hit, simulate_hits, struck

log = logging.getLogger(__name__)

#: Where a new object goes on the table, tried in order until one is free: in front of the robot, within
#: reach of both grippers (x forward, y to the robot's left, metres).
_SPOTS = tuple((x, y) for x in (0.62, 0.72, 0.82, 0.55) for y in (0.0, 0.2, -0.2, 0.35, -0.35, 0.1, -0.1, 0.45, -0.45))


class Playing(Protocol):
    """The playback the scene shows objects for (:class:`~studio.controller.playback.Player`)."""

    @property
    def loaded(self) -> Playback | None: ...
    def preview_recording(self) -> Recording: ...


#: What a demonstration went through, in words, by all it depends on (its samples, the scene, the objects at its
#: start, the robot's model file): shared by the controllers of one process (the studio built again on a session).
_SAID: dict[tuple[object, ...], str] = {}
_SAID_LOCK = threading.Lock()
_SAID_MAX = 1024


class SceneActions:
    """The session's task scene and the worlds that bring it to life (see the module docstring).

    Args:
        backend: the robot whose joint states drive the live world.
        player: the loaded playback (a replay's or the preview's objects) and the preview's recording (the task
            result).
    """

    def __init__(self, ctx: Context, backend: RobotBackend, player: Playing) -> None:
        self.ctx = ctx
        self.display = ctx.display
        self.player = player
        self._lock = threading.RLock()
        self.live = World(ctx.session.objects.scene, ctx.baxter)
        self._unsubscribe = backend.subscribe(self.live.on_batch)
        self._take: tuple[int, float] | None = None  # (event mark, stream time at the start of the take)
        self._played: tuple[Playback, World, int] | None = None  # (playback, its world, samples fed)
        self._shown: tuple[tuple[int, ...], tuple[ObjectPose, ...]] | None = None  # shown()'s last answer
        self._result: TaskResult | None = None
        self._result_key: object = None
        self._touches: tuple[Touch, ...] = ()  # what the learned skill touches, as the preview plays it
        self._run_hits: list[Hit] = []  # objects the robot ran into during the current run
        self._demo_said: dict[int, tuple[Recording, str]] = {}  # what each demonstration went through, in words
        self._touch_rec: Recording | None = None
        ctx.events.on(Topic.SESSION, self._on_session)
        for topic in (Topic.SKILL, Topic.DEMOS, Topic.SESSION):
            ctx.events.on(topic, self._result_may_change)

    # -- the scene set-up ------------------------------------------------------------------------------
    @property
    def scene(self) -> Scene:
        """The open session's scene, as the teacher set it up."""
        return self.ctx.session.objects.scene

    def add(self, kind: str) -> str:
        """Put a new cup, block or pad on the table at a free spot in reach; returns its name."""
        if kind not in KINDS:
            raise StudioError(f'Choose a cup, a block or a pad (not "{kind}").')
        scene = self.scene
        x, y = _free_spot(scene)
        z = scene.table.top_z if scene.table is not None else -0.93
        new = scene.add(kind, (x, y, z))
        self._set(new)
        return new.objects[-1].name

    def move(self, name: str, position: Sequence[float], yaw: float | None = None) -> None:
        """Put object ``name`` at ``position`` (its bottom centre, m; it settles on what is below) and heading
        ``yaw`` (rad; kept when None)."""
        self._set(self.scene.move(name, position, yaw))

    def remove(self, name: str) -> None:
        self._set(self.scene.remove(name))

    def use_preset(self, name: str) -> None:
        """Replace the scene by a preset ("empty table", "stack-cup", "pick-place") for the taught arms."""
        if name not in PRESETS:
            raise StudioError(f'Unknown scene "{name}": choose {", ".join(PRESETS)}.')
        self._set(preset(name, self.ctx.arms))

    def put_back_layout(self) -> None:
        """Every object back to the task's layout (the preset the set-up started from, for the taught arms): the
        teacher's moves, additions and removals are undone."""
        name = self.scene.preset
        if name not in PRESETS or name == PRESETS[0]:
            raise StudioError('This table has no task layout to go back to: choose one in "Task set-up".')
        self.use_preset(name)

    def put_back(self) -> None:
        """Put every object back where the scene sets it up (what a gripper holds is let go)."""
        if self.taking:
            raise StudioError("Stop the recording before putting the objects back.")
        self.live.reset(self.scene)
        self.ctx.emit(Topic.SCENE)

    def _set(self, scene: Scene) -> None:
        with self.ctx.lock:
            if self.taking:
                raise StudioError("Stop the recording before changing the objects on the table.")
            self.ctx.session.set_scene(scene)
            self.live.reset(scene)
        self.ctx.emit(Topic.SCENE)
        self._result_may_change()

    def _on_session(self) -> None:
        """Another session is open: its scene comes to life."""
        with self.ctx.lock:
            self._take = None
            self.live.reset(self.scene)

    # -- recording takes -------------------------------------------------------------------------------
    @property
    def taking(self) -> bool:
        """A take is being recorded (between :meth:`begin_take` and its end): the scene cannot change."""
        return self._take is not None

    def begin_take(self) -> None:
        """A recording starts: objects go back to the set-up (unless a gripper holds one), then a start event."""
        t0 = self.live.last_time  # the recording's first sample is the next one the robot sends
        if not any(p.held_by for p in self.live.poses()):
            self.live.reset(self.scene)
        mark = self.live.mark()
        start = self.live.snapshot("start", t0)
        self._take = (mark, start.t)

    def end_take(self, recording: Recording) -> tuple[WorldEvent, ...]:
        """The take stopped: its object events on the recording's clock (0 at its first sample)."""
        take, self._take = self._take, None
        if take is None:
            return ()
        self.live.snapshot("end")
        mark, t0 = take
        kept = [e for e in self.live.events_since(mark) if e.kind != "push"]  # a session keeps no "push"
        return bounded(on_clock(kept, t0, float(recording.duration)))

    def cancel_take(self) -> None:
        self._take = None

    def demo_start(self, i: int) -> tuple[ObjectPose, ...] | None:
        """The objects at the start of demonstration ``i`` (None when it was recorded without them)."""
        session = self.ctx.session
        events = session.objects.events(session.demo_files[i]) if i < len(session.demo_files) else ()
        return next((e.poses for e in events if e.kind == "start"), None)

    def last_grip(self) -> tuple[WorldEvent, GraspNote] | None:
        """The live world's latest grasp or miss and what it did (None before any since the objects were last
        put back, and once the gripper that grasped let go: it holds nothing then); the same event object until
        the next one."""
        events = self.live.events
        i = next((i for i in range(len(events) - 1, -1, -1) if events[i].kind in ("grasp", "miss")), -1)
        ev = events[i] if i >= 0 else None
        if ev is not None and ev.kind == "grasp" and any(e.kind == "release" and e.arm == ev.arm for e in events[i:]):
            return None
        note = grasp_note(ev) if ev is not None else None
        return None if ev is None or note is None else (ev, note)

    # -- what the scene shows --------------------------------------------------------------------------
    def shown(self) -> tuple[tuple[int, ...], tuple[ObjectPose, ...]]:
        """(key, object poses) to draw now: the live world's, or the replay's or preview's at the moment shown.
        The key changes whenever the poses may have (draw again only then)."""
        pb = self.player.loaded
        key: tuple[int, ...]
        with self._lock:
            if pb is None or self.display.is_live:
                world, key = self.live, (id(self.live), self.live.version, len(self.scene.objects))
            else:
                world = self._played_world(pb)
                key = (id(world), world.version)
            if self._shown is None or self._shown[0] != key:  # the panels ask at every pose-pump tick
                self._shown = (key, world.poses())
            return self._shown

    def _played_world(self, pb: Playback) -> World:
        rec = pb.recording
        if self._played is None or self._played[0] is not pb:
            start = None
            if pb.kind == PlaybackKind.REPLAY:
                i = next((k for k, r in enumerate(self.ctx.session.recordings) if r is pb.key), None)
                start = self.demo_start(i) if i is not None else None
            self._played = (pb, World(self.scene, self.ctx.baxter, start=start), 0)
        _, world, fed = self._played
        upto = int(np.searchsorted(rec.t, pb.position + 1e-9, side="right"))
        if upto < fed:  # went back: start over from the first sample
            world.reset()
            fed = 0
        if upto > fed:
            world.feed(rec.t[fed:upto], rec.q[fed:upto], rec.gripper[fed:upto])
        self._played = (pb, world, upto)
        return world

    # -- the task result -------------------------------------------------------------------------------
    def task_result(self) -> TaskResult | None:
        """What the learned skill does with the objects, in plain words (None before a skill is learned)."""
        self._up_to_date()
        return self._result

    def _up_to_date(self) -> None:
        """The task result and the skill's contacts are of the skills and the scene now (a session opened with a
        learned skill has had no event yet)."""
        if self.ctx.session.skills and self._result_key is None:
            self._result_may_change()

    def _result_may_change(self) -> None:
        try:
            with self._lock:
                self._update_result()
        except Exception:
            log.exception("task result")
            self._result = None
            self.ctx.emit(Topic.TASK)

    def _update_result(self) -> None:
        session = self.ctx.session
        found: tuple[Touch, ...] = ()
        rec: Recording | None = None
        if not session.skills:
            result = None
            key: object = None
        else:
            events = [session.objects.events(f) for f in session.demo_files]
            key = (id(session), tuple(id(s) for s in session.skills.values()), self.scene, tuple(map(id, events)))
            key = (*key, tuple(session.hidden_demos))
            if key == self._result_key:
                return
            rec = self.player.preview_recording()
            run, hits, touched = simulate_hits(
                rec.t, rec.q, rec.gripper, self.scene, self.ctx.baxter, new=self._new(events)
            )
            found = tuple(touched)
            result = with_contacts(task_result(run, self.goal()), found, hits)
        self._result, self._result_key = result, key
        self._touches, self._touch_rec = found, rec
        self.ctx.emit(Topic.TASK)

    # -- the task's goal -------------------------------------------------------------------------------
    def goal(self) -> Goal:
        """The task's goal the skill is judged by (:func:`studio.world.session_goal`): the set-up's, or the one
        the teacher confirmed, matched to the shown demonstrations; else read from them."""
        return goal_of(self.ctx.session)

    def goal_choices(self) -> list[tuple[Placement, ...]]:
        """Other goals the teacher may choose instead (another target for the last release of each object)."""
        scene = self.scene
        return alternatives(self.goal(), scene.names(), {o.name: o.kind for o in scene.objects})

    def set_goal(self, placements: Sequence[Placement]) -> None:
        """The teacher's goal for the task (kept with the scene; the skill follows it once trained again)."""
        self._set(self.scene.with_goal(placements))

    def confirm_goal(self) -> None:
        """The teacher agrees with the goal as read from the demonstrations: keep it."""
        goal = self.goal()
        if not goal.placements:
            raise StudioError("There is no goal to confirm yet: record a demonstration that moves an object.")
        self.set_goal(goal.placements)

    def _new(self, events: list[tuple[WorldEvent, ...]]) -> set[str]:
        """The objects of the scene that no shown demonstration had at its start."""
        had = {p.name for evs in events for e in evs if e.kind == "start" for p in e.poses}
        return {o.name for o in self.scene.objects if o.name not in had} if had else set()

    # -- what the robot touches --------------------------------------------------------------------------
    def skill_touches(self) -> tuple[Touch, ...]:
        """What the learned skill (as the preview plays it, the objects where they are now) touches that it must
        not: the table, an object, the other arm, the robot's body (decision 087); () when nothing."""
        self._up_to_date()
        return self._touches

    def contact_reason(self) -> str:
        """Why the skill must not run because it touches something, in words ("" when it touches nothing)."""
        return contact_sentence(self.skill_touches())

    def contact_paths(self) -> dict[Arm, list[np.ndarray]]:
        """arm -> the stretches (each (n, 3) m) of its gripper's path, as the preview plays it, where it touches
        something (to draw in red)."""
        self._up_to_date()
        rec = self._touch_rec
        out: dict[Arm, list[np.ndarray]] = {}
        if rec is None:
            return {}
        for x in self._touches:
            for arm in x.arms:
                cols = slice(0, 7) if arm == "left" else slice(7, 14)
                lo, hi = max(x.i_start - 1, 0), min(x.i_end + 2, len(rec))
                out.setdefault(arm, []).append(self.ctx.baxter.fk_batch(arm, rec.q[lo:hi, cols])[0])
        return out

    def demo_contact(self, i: int) -> str:
        """What demonstration ``i`` went through (imported, or recorded on a real robot by hand), in words with the
        stretch ("" when nothing; computed once per demonstration)."""
        session = self.ctx.session
        if not 0 <= i < len(session.recordings):
            return ""
        rec = session.recordings[i]
        with self._lock:
            hit = self._demo_said.get(id(rec))
        if hit is not None and hit[0] is rec:
            return hit[1]
        events = session.objects.events(session.demo_files[i]) if i < len(session.demo_files) else ()
        step = max(1, round(len(rec) / max(rec.duration * 100.0, 1.0)))  # about 100 a second
        t, q, g = rec.t[::step], rec.q[::step], rec.gripper[::step]
        start = next((e.poses for e in events if e.kind == "start"), None)
        scene, baxter = self.scene, self.ctx.baxter
        samples = hashlib.blake2b(digest_size=16)
        for a in (t, q, g):
            samples.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        key = (samples.digest(), t.shape, q.shape, g.shape, scene, start, str(baxter.urdf_path))
        with _SAID_LOCK:
            said = _SAID.get(key)
        if said is None:
            run = simulate(t, q, g, scene, baxter=baxter, start=start)
            said = recorded_touch_words(touches(t, q, g, scene, run, baxter))
            with _SAID_LOCK:
                if len(_SAID) >= _SAID_MAX:
                    _SAID.clear()
                _SAID[key] = said
        with self._lock:
            self._demo_said[id(rec)] = (rec, said)
        return said

    def touches_at(self, q: np.ndarray, gripper: np.ndarray, q_now: np.ndarray) -> list[Touch]:
        """What the robot would touch at poses ``q`` (N, 14) with grippers (N, 2), the objects where they are now
        (one held moves with its gripper from where the arms are now, ``q_now``)."""
        return touches_at(q, gripper, self.live.poses(), self.scene, self.ctx.baxter, q_now=q_now)

    def first_contact(self, q: np.ndarray, gripper: np.ndarray, q_now: np.ndarray) -> tuple[int, Touch] | None:
        """Along poses ``q`` (N, 14) from where the arms are: the first that touches something (or deeper than at
        ``q[0]``) and what; None when the way is free (:func:`studio.world.contacts.first_contact`)."""
        return first_contact(q, gripper, self.live.poses(), self.scene, self.ctx.baxter, q_now=q_now)

    # -- a run on the robot (studio.controller.execution) ------------------------------------------------
    def begin_run(
        self, t: np.ndarray | None = None, q: np.ndarray | None = None, gripper: np.ndarray | None = None
    ) -> int:
        """A run on the robot starts: every object goes back to the set-up, and the live world (which the robot's
        joint states drive) records what happens from here; returns the bookmark for :meth:`end_run`.

        Called when the run starts (the objects are drawn at the set-up during the approach), and again from
        the robot's stream when the skill itself starts, with the samples ``t``, ``q``, ``gripper`` from that
        moment on: the grippers' close/open detection then starts from the skill's first openings, as in the
        preview, whatever the grippers did on the way there.
        """
        t0 = float(t[0]) if t is not None and len(t) else self.live.last_time
        self.live.reset(self.scene)
        self._run_hits = []
        mark = self.live.mark()
        self.live.snapshot("start", t0)
        if t is not None and q is not None and gripper is not None and len(t):
            self.live.feed(t, q, gripper)
        return mark

    def end_run(self, mark: int, recording: Recording, t0: float) -> TaskResult | None:
        """The task result of the run since ``mark``: what the live world did with the objects as the robot's
        real joint states grasped and released them, against what the shown demonstrations did (None when they
        moved no object). ``recording``: the run's joint states (times from 0 at stream time ``t0``), for the
        gripper path the wording uses."""
        self.live.snapshot("end")
        events = tuple(self.live.events_since(mark))
        goal = self.goal()
        if not goal.placements:
            return None if not self._run_hits else TaskResult(False, hit_words(self._run_hits), ())
        step = max(1, round(len(recording) / max(recording.duration * 100.0, 1.0)))  # ~100 Hz, as simulate()
        q = recording.q[::step]
        path = {arm: self.ctx.baxter.fk_batch(arm, q[:, :7] if arm == "left" else q[:, 7:])[0] for arm in ARMS}
        run = WorldRun(events, self.live.poses(), recording.t[::step] + t0, path)
        return with_contacts(task_result(run, goal), (), self._run_hits)

    def hit(self, touch: Touch, q_now: np.ndarray) -> None:
        """During a run the robot ran into ``touch.b`` (an object standing on its own): it is pushed along the arm's
        way, or knocked over, in the live world; the run's task result says so."""
        pose = next((p for p in self.live.poses() if p.name == touch.b.part and p.held_by is None), None)
        if pose is None or touch.b.robot or touch.depth <= 0.0:
            return
        arm = touch.a.arm or "left"
        grip = self.ctx.baxter.fk(arm, q_now[:7] if arm == "left" else q_now[7:])[0]
        way = np.asarray(pose.center[:2]) - grip[:2]
        way = way / max(float(np.linalg.norm(way)), 1e-9)
        t = self.live.last_time or 0.0
        moved, hit = struck(pose, touch, way, t)
        self.live.push(moved, t, touch.a.arm)
        self._run_hits.append(hit)
        self.ctx.emit(Topic.SCENE)

    def close(self) -> None:
        self._unsubscribe()


def with_contacts(result: TaskResult | None, found: Sequence[Touch], hits: Sequence[Hit] = ()) -> TaskResult | None:
    """The task result of a skill that touches what it must not: never "works"; what it touches said first, then
    the objects it pushed or knocked over."""
    if result is None or not (found or hits):
        return result
    said = result.text.replace(" — the skill works", "")
    words = " ".join(w for w in (contact_sentence(found), hit_words(hits), said) if w)
    return TaskResult(False, words, result.objects)


def _free_spot(scene: Scene) -> tuple[float, float]:
    """The first of :data:`_SPOTS` on the table at least 12 cm from every object (else the first spot)."""
    taken = [o.position for o in scene.objects]
    for x, y in _SPOTS:
        if scene.table is not None and not scene.table.contains(x, y):
            continue
        if all(math.hypot(x - p[0], y - p[1]) >= 0.12 for p in taken):
            return x, y
    return _SPOTS[0]
