"""The learned skills where the objects are now: a skill that follows the objects is placed in the session's
scene (its path rebuilt from its segments, whole-path IK) once per skill and scene; the others are as learned.

Preview, the task result and "Run on robot" all play :meth:`PlacedSkills.get`. :meth:`PlacedSkills.warnings`
says, before a run, which objects stand where no demonstration put them.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

from studio.controller.context import Context
from studio.core.frames import DemoObjects
from studio.core.types import Arm, Skill
from studio.storage import Session
from studio.world.reach import one_place, outside, suggestion
from studio.world.relative import demo_objects, objects_now


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


class PlacedSkills:
    """The session's skills placed in its scene (cached per skill and scene; safe to call from any thread)."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self._lock = threading.Lock()
        self._cache: dict[str, tuple[Skill, object, Skill]] = {}

    def get(self) -> dict[Arm, Skill]:
        """arm -> the skill to play with the objects where they are now."""
        from studio.core.segments import place_skill

        session = self.ctx.session
        scene = session.objects.scene
        out: dict[Arm, Skill] = {}
        for arm, skill in dict(session.skills).items():
            if skill.frames is None:
                out[arm] = skill
                continue
            with self._lock:
                hit = self._cache.get(arm)
            if hit is not None and hit[0] is skill and hit[1] == scene:
                out[arm] = hit[2]
                continue
            placed = place_skill(skill, objects_now(scene), arm=arm, baxter=self.ctx.baxter)
            with self._lock:
                self._cache[arm] = (skill, scene, placed)
            out[arm] = placed
        return out

    def warnings(self) -> list[str]:
        """Plain sentences, one per object that stands where no demonstration put it."""
        session = self.ctx.session
        out: list[str] = []
        for skill in session.skills.values():
            if skill.frames is not None:
                out += [w for w in outside(skill.frames, session.objects.scene) if w not in out]
        return out

    def note(self) -> str:
        """A note when the demonstrations kept the objects in one place ("" otherwise)."""
        return next((n for s in self.ctx.session.skills.values() if s.frames and (n := one_place(s.frames))), "")

    def suggestion(self) -> str:
        """Where to put the objects for the next demonstration ("" before a skill that follows them is learned)."""
        session = self.ctx.session
        frames = next((s.frames for s in session.skills.values() if s.frames is not None), None)
        return suggestion(frames, session.objects.scene)
