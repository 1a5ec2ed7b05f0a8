"""The learned skills where the objects are now: a skill that follows the objects is placed in the session's
scene (its path rebuilt from its segments, whole-path IK) once per skill and scene; the others are as learned.

Preview, the task result and "Run on robot" all play :meth:`PlacedSkills.get`. :meth:`PlacedSkills.warnings`
says, before a run, which objects stand where no demonstration put them.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import replace

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.core.errors import StudioError
from studio.core.frames import DemoObjects
from studio.core.types import Arm, Skill
from studio.storage import Session
from studio.words import moved_words
from studio.world import Scene
from studio.world.events import ObjectPose
from studio.world.goal import Goal, session_goal
from studio.world.moved import moved_objects
from studio.world.reach import one_place, outside, suggestion
from studio.world.relative import demo_objects, objects_now, release_rules


def demo_objects_of(session: Session, arm: Arm, indices: Sequence[int]) -> list[DemoObjects] | str:
    """The objects and ``arm``'s contacts of the session's demonstrations ``indices``, or why a skill cannot
    follow them (in plain words)."""
    from studio.core.segments import plan

    out = []
    for i in indices:
        events = session.objects.events(session.demo_files[i]) if i < len(session.demo_files) else ()
        objs = demo_objects(events, arm)
        if objs is None:
            return "Some demonstrations were recorded without objects, so the skill follows fixed places."
        out.append(objs)
    _, why = plan(out)
    return why or out


def goal_of(session: Session, indices: Sequence[int] | None = None) -> Goal:
    """The task's goal (:func:`studio.world.session_goal`): the scene's own, or the teacher's, matched to the
    releases of the demonstrations ``indices`` (default: the shown ones); else read from them."""
    if indices is None:
        indices = [i for i, r in enumerate(session.recordings) if r.name not in session.hidden_demos]
    events = [session.objects.events(session.demo_files[i]) for i in indices if i < len(session.demo_files)]
    scene = session.objects.scene
    return session_goal(scene.preset, scene.goal, scene.names(), events)


def rules_of(session: Session, objects: Sequence[DemoObjects], indices: Sequence[int]) -> dict[int, str]:
    """The frame each release of the demonstrations ``indices`` (their ``objects``) follows by the task's goal."""
    return release_rules(goal_of(session, indices), objects[0]) if objects else {}


class PlacedSkills:
    """The session's skills placed in its scene (cached per skill and scene; safe to call from any thread)."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self._lock = threading.Lock()
        self._cache: dict[str, tuple[Skill, object, Skill]] = {}
        #: × the taught pace the skills play at (:meth:`set_speed`).
        self.speed = 1.0

    def get(self) -> dict[Arm, Skill]:
        """arm -> the skill to play with the objects where they are now, at the chosen :attr:`speed`."""
        from studio.core.segments import place_skill

        session = self.ctx.session
        scene = session.objects.scene
        speed = self.speed
        out: dict[Arm, Skill] = {}
        skills = dict(session.skills)
        for arm, skill in skills.items():
            with self._lock:
                hit = self._cache.get(arm)
            if hit is not None and hit[0] is skill and hit[1] == (scene, speed):
                out[arm] = hit[2]
                continue
            placed = skill
            if skill.frames is not None:
                placed = place_skill(skill, objects_now(scene), arm=arm, baxter=self.ctx.baxter)
            placed = self._kept_clear(placed, arm, scene, other_free=len(skills) == 1)
            placed = self._at_speed(placed, arm, speed)
            with self._lock:
                self._cache[arm] = (skill, (scene, speed), placed)
            out[arm] = placed
        return out

    def duration(self) -> float:
        """The skill's length (s): how long what Preview, the task result and Run on robot play lasts; the one
        figure Train and Preview show (the joint limits may make it longer than the learned path's own time)."""
        from studio.core.sampling import duration

        return duration(self.get())

    def _kept_clear(self, skill: Skill, arm: Arm, scene: Scene, *, other_free: bool) -> Skill:
        """The skill with its arm's posture moved (the self-motion) where its shoulder, elbow or forearm would touch
        the table, an object, the robot's body or the other arm at rest (decision 087); as it is when clear."""
        from studio.core.execution import joint_trajectory
        from studio.world.contacts import arm_clearance

        jt = skill.joint_trajectory
        if jt is None or len(jt.t) < 2:
            return skill
        other = None
        if other_free:
            live = self.ctx.display.live.get()[2]
            other = live[7:] if arm == "left" else live[:7]
        touching = arm_clearance(scene, arm, other)
        if not touching(jt.q[:: max(1, len(jt.q) // 300)]).any():
            return skill
        clear = joint_trajectory(skill.trajectory, arm, jt.q[0], self.ctx.baxter, avoid=touching)
        return replace(skill, joint_trajectory=clear)

    def _at_speed(self, skill: Skill, arm: Arm, speed: float) -> Skill:
        from studio.core.pace import at_speed

        jt = skill.joint_trajectory
        if speed == 1.0 or jt is None:
            return skill
        b = self.ctx.baxter
        return replace(skill, joint_trajectory=at_speed(jt, speed, b.velocity_limits(arm), b.acceleration_limits(arm)))

    def set_speed(self, speed: float) -> None:
        """Play the skills at ``speed`` × the taught pace (as fast as the robot's joint limits allow), in the
        preview, the task result and on the robot."""
        from studio.core.pace import MAX_SPEED, MIN_SPEED

        speed = float(speed)
        if not MIN_SPEED <= speed <= MAX_SPEED:
            raise StudioError(f"Choose a speed between {MIN_SPEED:g}× and {MAX_SPEED:g}×.")
        with self._lock:
            if speed == self.speed:
                return
            self.speed = speed
        self.ctx.emit(Topic.SKILL)  # what Preview, the task result and Run on robot play changed

    def warnings(self) -> list[str]:
        """Plain sentences, one per object that stands where no demonstration put it (a skill that follows the
        objects), or elsewhere than when the demonstrations started (a skill that repeats the taught motion)."""
        session = self.ctx.session
        out: list[str] = []
        for skill in session.skills.values():
            if skill.frames is not None:
                out += [w for w in outside(skill.frames, session.objects.scene) if w not in out]
        if any(s.frames is None for s in session.skills.values()):
            out += [moved_words(n, d) for n, d in moved_objects(self._starts(), session.objects.scene)]
        return out

    def _starts(self) -> list[tuple[ObjectPose, ...]]:
        """The objects at the start of each shown demonstration that recorded them."""
        session = self.ctx.session
        out = []
        for rec, file in zip(session.recordings, session.demo_files, strict=False):
            if rec.name in session.hidden_demos:
                continue
            start = next((e.poses for e in session.objects.events(file) if e.kind == "start"), None)
            if start is not None:
                out.append(start)
        return out

    def note(self) -> str:
        """A note when the demonstrations kept the objects in one place ("" otherwise)."""
        return next((n for s in self.ctx.session.skills.values() if s.frames and (n := one_place(s.frames))), "")

    def suggestion(self) -> str:
        """Where to put the objects for the next demonstration ("" before a skill that follows them is learned)."""
        session = self.ctx.session
        frames = next((s.frames for s in session.skills.values() if s.frames is not None), None)
        return suggestion(frames, session.objects.scene)
