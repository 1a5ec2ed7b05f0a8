"""The scene as a skill that follows the objects sees it: each demonstration's objects and contacts
(:func:`demo_objects`), the objects where they are now (:func:`objects_now`), and the task goal relative to
the objects (:func:`relative_goal`): where each release put the object, in the frame the skill learned."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from studio.core.frames import Contact, DemoObjects, ObjectAt, ObjectFrames, border_frames, to_world
from studio.core.types import Arm
from studio.world.events import ObjectPose, WorldEvent
from studio.world.result import ObjectGoal, TaskGoal
from studio.world.scene import Scene


def object_at(p: ObjectPose) -> ObjectAt:
    return ObjectAt(p.name, p.kind, p.position, p.yaw, p.on)


def demo_objects(events: Sequence[WorldEvent], arm: Arm) -> DemoObjects | None:
    """A demonstration's objects at its start and ``arm``'s grasps and releases (None without events)."""
    start = next((e for e in events if e.kind == "start"), None)
    if start is None:
        return None
    contacts = tuple(
        Contact(e.t, e.kind, e.object, tuple(object_at(p) for p in e.poses))
        for e in events
        if e.kind in ("grasp", "release") and e.arm == arm and e.object is not None
    )
    return DemoObjects(tuple(object_at(p) for p in start.poses), contacts)


def objects_now(scene: Scene) -> list[ObjectAt]:
    """The scene's objects as set up (where a skill starts from)."""
    return [ObjectAt(o.name, o.kind, o.position, o.yaw, "hand" if o.held_out else None) for o in scene.objects]


def relative_goal(goal: TaskGoal, frames: ObjectFrames, scene: Scene) -> TaskGoal:
    """``goal`` with each release of an object the skill puts down moved to where the skill's frames say it
    lands with the objects where they are now (the goal of the other objects is kept)."""
    F = border_frames(frames, objects_now(scene))
    targets: dict[str, list[tuple[float, float, float]]] = {}
    names: dict[str, list[str | None]] = {}
    for k, b in enumerate(frames.borders):
        if b.kind != "release":
            continue
        p = to_world(F[k + 1], np.asarray(b.landed[:3]))
        targets.setdefault(b.object, []).append((float(p[0]), float(p[1]), float(p[2])))
        role_name = b.role.partition(":")[2]
        names.setdefault(b.object, []).append(role_name if b.role.startswith("object:") else None)
    out = []
    for g in goal.objects:
        rel = targets.get(g.name)
        if not rel or len(rel) != len(g.releases):
            out.append(g)
            continue
        out.append(
            ObjectGoal(
                g.name,
                g.kind,
                g.arm,
                g.start,
                tuple(rel),
                rel[-1],
                g.spread,
                g.demos,
                g.landed_on,
                tuple(names[g.name]),
            )
        )
    return TaskGoal(tuple(out), goal.demos, goal.notes)
