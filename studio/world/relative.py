"""The scene as a skill that follows the objects sees it: each demonstration's objects and contacts
(:func:`demo_objects`), the objects where they are now (:func:`objects_now`), and the frame each release
follows by the task's goal (:func:`release_rules`, decision 085)."""

from __future__ import annotations

from collections.abc import Sequence

from studio.core.frames import ROBOT, Contact, DemoObjects, ObjectAt
from studio.core.types import Arm
from studio.world.events import ObjectPose, WorldEvent
from studio.world.goal import START, TABLE, Goal, Placement
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


def rule_of(p: Placement) -> str:
    """The frame a release onto ``p``'s target follows by its meaning: the object it is put onto, where the
    object started, or the robot's (a spot on the table)."""
    if p.onto == TABLE:
        return ROBOT
    if p.onto == START:
        return f"start:{p.object}"
    return f"object:{p.onto}"


def release_rules(goal: Goal, objects: DemoObjects) -> dict[int, str]:
    """Contact index -> the frame each release of a demonstration's arm follows by the goal (the n-th release of
    an object, its n-th placement); releases the goal does not mention have none."""
    out: dict[int, str] = {}
    count: dict[str, int] = {}
    for k, c in enumerate(objects.contacts):
        if c.kind != "release":
            continue
        n = count.get(c.object, 0)
        count[c.object] = n + 1
        mine = goal.of(c.object)
        if n < len(mine):
            out[k] = rule_of(mine[n])
    return out
