"""Numbers and shapes of the task scene: its constants, the table, and where a let-go object comes to rest.

Shared by the scene set-up (:mod:`.scene`), the events (:mod:`.events`) and the simulation
(:mod:`.simulation`). Positions are metres in Baxter's base frame (x forward, y to the robot's left, z up);
an object's position is the centre of its bottom face, its heading (yaw) a turn about the vertical.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from studio.core.errors import InvalidInput
from studio.core.rotations import matrix_from_quat_wxyz

# -- constants --------------------------------------------------------------------------------------------------


#: Height of the table top in the robot base frame (m): the pick-place block (5 cm) stands on it with the
#: teacher's grasp point (z = -0.03) 1 cm below its top.
TABLE_TOP_Z = -0.07
#: The floor (the ground grid of the scene), m.
FLOOR_Z = -0.93
#: The table: centre (x, y) and size (x, y), m — in front of Baxter, within reach of both grippers.
TABLE_CENTER = (0.75, 0.0)
TABLE_SIZE = (0.70, 1.50)

KINDS: tuple[str, ...] = ("cup", "block", "pad")
#: Default sizes (x, y, height) in metres: a cup is a cylinder (diameter, diameter, height).
DEFAULT_SIZE: dict[str, tuple[float, float, float]] = {
    "cup": (0.07, 0.07, 0.095),
    "block": (0.05, 0.05, 0.05),
    "pad": (0.12, 0.12, 0.004),
}
GRASPABLE = frozenset({"cup", "block"})
#: Height above a cup's bottom at which the teacher's gripper point holds it (3 cm below the rim).
CUP_GRASP_HEIGHT = 0.065

#: Percent of gripper travel that makes a close or an open (hysteresis: noise and small moves do nothing).
SWING = 10.0
#: Grasp tolerance: horizontal distance of the gripper point from the object's axis, m.
GRASP_XY_TOL = 0.025
#: ... and how far above the object's top / below its bottom the gripper point may be, m.
GRASP_ABOVE_TOL = 0.015
GRASP_BELOW_TOL = 0.01
#: A cup put into a cup sits this much higher than the one below (cups nest).
NEST_STEP = 0.02
#: A released object lands on a surface at most this far above its bottom (it was pushed into it).
SNAP_UP = 0.025
#: An object that ends within this distance of where the demonstrations left it is where you put it, m.
SUCCESS_TOL = 0.02

SCENE_VERSION = 1
EVENTS_VERSION = 1
PRESETS: tuple[str, ...] = ("empty table", "stack-cup", "pick-place")
#: Most objects a scene holds, and most events one demonstration keeps (bounds on what a session stores).
MAX_OBJECTS = 40
MAX_EVENTS = 500
EVENT_KINDS: tuple[str, ...] = ("start", "grasp", "miss", "release", "end")
#: Workspace limits for object positions (m): beyond these a typed or dragged position is refused.
WORKSPACE = ((-2.0, 2.0), (-2.0, 2.0), (FLOOR_Z, 2.0))


# -- small helpers ----------------------------------------------------------------------------------------------


def finite(name: str, value: object, n: int) -> tuple[float, ...]:
    try:
        a = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InvalidInput(f"The {name} must be {n} numbers, got {value!r}.") from exc
    if a.shape != (n,):
        raise InvalidInput(f"The {name} must be {n} numbers, got {a.size}.")
    if not np.all(np.isfinite(a)):
        raise InvalidInput(f"The {name} contains missing or invalid values (NaN or infinity).")
    return tuple(float(x) for x in a)


def finite3(name: str, value: object) -> tuple[float, float, float]:
    a = finite(name, value, 3)
    return (a[0], a[1], a[2])


def finite4(name: str, value: object) -> tuple[float, float, float, float]:
    a = finite(name, value, 4)
    return (a[0], a[1], a[2], a[3])


def yaw_quat(yaw: float) -> tuple[float, float, float, float]:
    return (math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0))


def yaw_of(R: np.ndarray) -> float:
    """Heading (rad) of a rotation: the angle of its x axis (or y axis when x is near vertical) in the plane."""
    x = R[:, 0]
    if math.hypot(x[0], x[1]) > 0.2:
        return math.atan2(x[1], x[0])
    y = R[:, 1]
    return math.atan2(y[1], y[0]) - math.pi / 2.0


def transform(position: Sequence[float] | np.ndarray, wxyz: Sequence[float] | np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = matrix_from_quat_wxyz(np.asarray(wxyz, dtype=np.float64))
    T[:3, 3] = position
    return T


# -- the table and resting places ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Table:
    """A table: centre (x, y) and size (x, y) in metres, top at height ``top_z``."""

    center: tuple[float, float] = TABLE_CENTER
    size: tuple[float, float] = TABLE_SIZE
    top_z: float = TABLE_TOP_Z

    def contains(self, x: float, y: float) -> bool:
        return abs(x - self.center[0]) <= self.size[0] / 2 and abs(y - self.center[1]) <= self.size[1] / 2

    def to_dict(self) -> dict[str, Any]:
        return {"center": list(self.center), "size": list(self.size), "top_z": self.top_z}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Table:
        c = finite("table centre", d["center"], 2)
        s = finite("table size", d["size"], 2)
        if min(s) <= 0:
            raise InvalidInput("The table must have a positive size.")
        return cls((c[0], c[1]), (s[0], s[1]), finite("table height", [d["top_z"]], 1)[0])


class Footprint(Protocol):
    """What rest positions need of an object (a set-up :class:`WorldObject` or a moment's ``ObjectPose``)."""

    @property
    def name(self) -> str: ...
    @property
    def kind(self) -> str: ...
    @property
    def size(self) -> tuple[float, float, float]: ...
    @property
    def position(self) -> tuple[float, float, float]: ...


def _footprint_contains(o: Footprint, x: float, y: float, yaw: float) -> bool:
    """Whether the point (x, y) lies within the object's footprint (its outline seen from above)."""
    px, py = o.position[0], o.position[1]
    dx, dy = x - px, y - py
    if o.kind == "cup":
        return math.hypot(dx, dy) <= o.size[0] / 2
    c, s = math.cos(yaw), math.sin(yaw)
    u, v = c * dx + s * dy, -s * dx + c * dy
    return abs(u) <= o.size[0] / 2 and abs(v) <= o.size[1] / 2


def _support_level(kind: str, below: Footprint) -> float:
    """Height at which an object of ``kind`` rests on ``below``: on its top, or nested into a cup."""
    if kind == "cup" and below.kind == "cup":
        return below.position[2] + NEST_STEP
    return below.position[2] + below.size[2]


def landing(
    kind: str,
    x: float,
    y: float,
    bottom: float,
    table: Table | None,
    others: Iterable[tuple[Footprint, float]],
) -> tuple[float, str]:
    """(height, what it rests on) for an object of ``kind`` let go with its bottom centre at (x, y, bottom).

    An object whose centre is beyond the table's edge falls: nothing standing on the table holds it up there."""
    off_table = table is not None and not table.contains(x, y)
    if table is not None and not off_table:
        level, on = table.top_z, "table"
    else:
        level, on = FLOOR_Z, "floor"
    for o, yaw in others:
        if not _footprint_contains(o, x, y, yaw):
            continue
        if off_table and table is not None and o.position[2] >= table.top_z - 1e-6:
            continue
        z = _support_level(kind, o)
        if z <= bottom + SNAP_UP and z > level:
            level, on = z, o.name
    return level, on
