"""How far a skill that follows the objects stretches, in plain words: which objects stand where no demonstration
put them (:func:`outside`), whether the demonstrations showed them in one place only (:func:`one_place`), and
where to put them for the next demonstration (:func:`suggestion`)."""

from __future__ import annotations

import math

import numpy as np

from studio.core.frames import REGION_MARGIN_M, REGION_MARGIN_RAD, ObjectFrames, Region
from studio.world.result import format_distance
from studio.world.scene import Scene

#: How far (m) the Teach step suggests moving an object for the next demonstration.
SUGGEST_STEP_M = 0.10
#: Where the arms reach best on the table (x forward, |y| to the side), m: suggestions move objects towards it.
_COMFORT = (0.70, 0.20)


def _direction(v: np.ndarray) -> str:
    """The larger component of a table offset (x forward, y to the robot's left) in words."""
    if abs(v[0]) >= abs(v[1]):
        return "this far from the robot" if v[0] > 0 else "this close to the robot"
    return "this far to the robot's left" if v[1] > 0 else "this far to the robot's right"


def outside(frames: ObjectFrames, scene: Scene) -> list[str]:
    """One sentence per object of the scene that stands where no demonstration put it (empty: all inside)."""
    out = []
    objs = {o.name: o for o in scene.objects}
    for r in frames.regions:
        o = objs.get(r.name)
        if o is None:
            out.append(f"The skill needs the {r.name}, but there is no {r.name} on the table: put it back.")
            continue
        d, near = r.distance(o.position[0], o.position[1])
        turned = r.yaw_beyond(o.yaw)
        if d > REGION_MARGIN_M:
            where = _direction(np.array(o.position[:2]) - near)
            out.append(
                f"You never showed me the {r.name} {where} ({format_distance(d)} beyond the places you used) — "
                "show one more demonstration there, or move it back."
            )
        elif turned > REGION_MARGIN_RAD:
            out.append(
                f"You never showed me the {r.name} turned this far ({math.degrees(turned):.0f}° more than in your "
                "demonstrations) — show one more demonstration with it turned like this, or turn it back."
            )
    return out


def one_place(frames: ObjectFrames) -> str:
    """A note when the demonstrations had the objects in one place only ("" otherwise)."""
    if not frames.regions or not frames.one_place():
        return ""
    names = " and the ".join(r.name for r in frames.regions)
    return (
        f"You showed me the {names} in one place only: the skill works there, but it has not seen other places. "
        "Move them somewhere else and show one more demonstration so that it learns to follow them."
    )


def _spread(r: Region) -> float:
    p = r.places[:, :2]
    return float(np.max(np.linalg.norm(p - p.mean(axis=0), axis=1))) if len(p) else 0.0


def suggestion(frames: ObjectFrames | None, scene: Scene) -> str:
    """Where to put the objects for the next demonstration so that the skill covers more ("" when nothing to say)."""
    if frames is None or not frames.regions:
        return ""
    r = min(frames.regions, key=lambda x: round(_spread(x), 2))  # a tie (one place): the carried object, first
    p = r.places[:, :2]
    centre = p.mean(axis=0)
    m = 1.0 if centre[1] >= 0 else -1.0
    comfort = np.array([_COMFORT[0], m * _COMFORT[1]])
    if len(p) >= 2 and _spread(r) >= 0.02:
        c = np.cov((p - centre).T)
        _, v = np.linalg.eigh(c)
        axis = v[:, 0]  # the direction the demonstrations covered least
    else:
        axis = comfort - centre
        if np.linalg.norm(axis) < 0.05:
            axis = np.array([0.0, -m])
    axis = axis / max(float(np.linalg.norm(axis)), 1e-9)
    if np.dot(comfort - centre, axis) < 0:
        axis = -axis
    if abs(axis[0]) >= abs(axis[1]):
        where = "farther from the robot than" if axis[0] > 0 else "closer to the robot than"
    else:
        where = "to the robot's left of" if axis[1] > 0 else "to the robot's right of"
    return (
        f"Move the {r.name} somewhere else for your next demonstration — about "
        f"{format_distance(SUGGEST_STEP_M)} {where} where it stood so far — so the skill learns to follow it."
    )
