"""What a gripper closing just did, as facts for the teacher's feedback: which object it holds, or the object it
missed, how far the gripper point was from it and how much closer it must go, and which way in the room (the
grasp tolerances of :mod:`studio.world.rules`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from studio.world.events import ObjectPose, WorldEvent
from studio.world.geometry import GRASP_ABOVE_TOL, GRASP_BELOW_TOL, GRASP_XY_TOL, GRASPABLE


@dataclass(frozen=True)
class GraspNote:
    """One close of a gripper.

    Attributes:
        held: the object it now holds (None: a miss).
        near: the graspable object nearest the gripper point (None: there is none free).
        distance: horizontal distance (m) from the gripper point to ``near``'s axis.
        closer: how much closer (m) it must go sideways to hold ``near`` (0: close enough sideways).
        height: how far (m) the gripper point is above (+) or below (−) the band where it holds ``near``
            (0: within it).
        toward: the sideways move (m, room x away from the robot and y to its left) of length ``closer`` that
            brings the gripper point to ``near``.
    """

    held: str | None
    near: str | None = None
    distance: float = 0.0
    closer: float = 0.0
    height: float = 0.0
    toward: tuple[float, float] = (0.0, 0.0)


def grasp_note(event: WorldEvent) -> GraspNote | None:
    """The facts of a "grasp" or "miss" event (None for any other kind)."""
    if event.kind == "grasp":
        return GraspNote(held=event.object)
    if event.kind != "miss" or event.gripper is None:
        return None
    p = event.gripper
    best: tuple[float, ObjectPose] | None = None
    for o in event.poses:
        if o.kind not in GRASPABLE or o.held_by is not None:
            continue
        gap = _gap(p, o)
        if best is None or gap < best[0]:
            best = (gap, o)
    if best is None:
        return GraspNote(held=None)
    o = best[1]
    d = math.hypot(p[0] - o.position[0], p[1] - o.position[1])
    low, high = o.position[2] - GRASP_BELOW_TOL, o.position[2] + o.size[2] + GRASP_ABOVE_TOL
    height = p[2] - high if p[2] > high else (p[2] - low if p[2] < low else 0.0)
    closer = max(0.0, d - GRASP_XY_TOL)
    k = closer / d if d > 0.0 else 0.0
    toward = (k * (o.position[0] - p[0]), k * (o.position[1] - p[1]))
    return GraspNote(held=None, near=o.name, distance=d, closer=closer, height=height, toward=toward)


def _gap(p: tuple[float, float, float], o: ObjectPose) -> float:
    """How far (m) the point ``p`` is from where closing there would hold ``o``."""
    side = max(0.0, math.hypot(p[0] - o.position[0], p[1] - o.position[1]) - GRASP_XY_TOL)
    low, high = o.position[2] - GRASP_BELOW_TOL, o.position[2] + o.size[2] + GRASP_ABOVE_TOL
    up = max(0.0, p[2] - high, low - p[2])
    return math.hypot(side, up)
