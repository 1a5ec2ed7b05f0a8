"""The task scene without a GUI: a table, the task's objects, and how they respond to Baxter's grippers.

A :class:`Scene` is what the teacher sets up (a table and cups, blocks and pads with sizes and poses; presets
"empty table", "stack-cup" and "pick-place"; objects added, moved and removed). A :class:`World` plays a
stream of robot poses (time, 14 joint angles, 2 gripper openings) against a scene, whatever produces it:
the live simulated robot, a demonstration replay, the skill preview or a robot execution. It is a
``RobotBackend.subscribe`` listener (:meth:`World.on_batch`) and also a plain function, :func:`simulate`.

The rules are simple and deterministic (no physics engine, no randomness):

* the gripper's point is the ``<arm>_gripper`` frame of :mod:`studio.core.kinematics` (between the
  fingertips); the gripper *closes* when its opening falls :data:`SWING` percent below its last maximum and
  *opens* when it rises :data:`SWING` percent above its last minimum (any widths, any tempo, sensor noise);
* closing with the gripper point within :data:`GRASP_XY_TOL` of a cup's or block's vertical axis and between
  its bottom and a little above its top grasps it: it moves rigidly with the gripper, together with anything
  resting on it. Closing anywhere else is a *miss* (recorded, for the task result's wording);
* opening releases what the gripper holds straight down, upright and keeping its heading, onto the highest
  surface under its centre: the table, the pad or block below it, or into the cup below it (cups nest,
  :data:`NEST_STEP` higher); off the table it falls to the floor. A pad lies flat and cannot be grasped.
  An object the teacher holds out in the air (the stack-cup task's handed-over cup) stays there until grasped.

Events (:class:`WorldEvent`) record every object's pose at the start and end of a demonstration and at each
grasp, release and miss; they are frozen and convert to and from JSON-ready dicts (:func:`events_to_dict`,
:func:`events_from_dict`, versioned) for the session. :func:`task_goal` reads the demonstrations' events and
:func:`task_result` judges a simulated run against them in plain words ("The cup ended 0.6 cm from where you
put it — the skill works").
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from studio.core.errors import InvalidInput, SessionFormatError
from studio.core.kinematics import Baxter, matrix_from_quat_wxyz, quat_wxyz_from_matrix
from studio.core.types import ARMS, check_arm

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
EVENT_KINDS: tuple[str, ...] = ("start", "grasp", "miss", "release", "end")
#: Workspace limits for object positions (m): beyond these a typed or dragged position is refused.
_WORKSPACE = ((-2.0, 2.0), (-2.0, 2.0), (FLOOR_Z, 2.0))


# -- small helpers ----------------------------------------------------------------------------------------------


def _finite(name: str, value: object, n: int) -> tuple[float, ...]:
    try:
        a = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InvalidInput(f"The {name} must be {n} numbers, got {value!r}.") from exc
    if a.shape != (n,):
        raise InvalidInput(f"The {name} must be {n} numbers, got {a.size}.")
    if not np.all(np.isfinite(a)):
        raise InvalidInput(f"The {name} contains missing or invalid values (NaN or infinity).")
    return tuple(float(x) for x in a)


def _finite3(name: str, value: object) -> tuple[float, float, float]:
    a = _finite(name, value, 3)
    return (a[0], a[1], a[2])


def _finite4(name: str, value: object) -> tuple[float, float, float, float]:
    a = _finite(name, value, 4)
    return (a[0], a[1], a[2], a[3])


def _yaw_quat(yaw: float) -> tuple[float, float, float, float]:
    return (math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0))


def _yaw_of(R: np.ndarray) -> float:
    """Heading (rad) of a rotation: the angle of its x axis (or y axis when x is near vertical) in the plane."""
    x = R[:, 0]
    if math.hypot(x[0], x[1]) > 0.2:
        return math.atan2(x[1], x[0])
    y = R[:, 1]
    return math.atan2(y[1], y[0]) - math.pi / 2.0


def _transform(position: Sequence[float] | np.ndarray, wxyz: Sequence[float] | np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = matrix_from_quat_wxyz(np.asarray(wxyz, dtype=np.float64))
    T[:3, 3] = position
    return T


def format_distance(d: float) -> str:
    """A distance in plain words: "0.6 cm" under 1 cm, "3 cm" above, "1.2 m" beyond a metre."""
    d = abs(float(d))
    if d >= 1.0:
        return f"{d:.1f} m"
    if d < 0.0095:
        return f"{d * 100:.1f} cm"
    return f"{d * 100:.0f} cm"


def describe_offset(v: Sequence[float] | np.ndarray, ref: str = "it") -> str:
    """Where something is relative to ``ref``, in the robot's directions: "3 cm above it", "4 cm to the
    robot's left of where you put it and 2 cm below it" (the one or two largest components of ``v``)."""
    a = np.asarray(v, dtype=np.float64)
    words = {
        (2, 1): "{d} above {ref}",
        (2, -1): "{d} below {ref}",
        (0, 1): "{d} beyond {ref}, away from the robot",
        (0, -1): "{d} short of {ref}, towards the robot",
        (1, 1): "{d} to the robot's left of {ref}",
        (1, -1): "{d} to the robot's right of {ref}",
    }
    order = sorted(range(3), key=lambda i: -abs(a[i]))
    parts: list[str] = []
    for i in order[:2]:
        if parts and abs(a[i]) < 0.01:
            break
        parts.append(words[(i, 1 if a[i] >= 0 else -1)].format(d=format_distance(a[i]), ref=ref))
    return " and ".join(parts)


# -- the scene ----------------------------------------------------------------------------------------------------


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
        c = _finite("table centre", d["center"], 2)
        s = _finite("table size", d["size"], 2)
        if min(s) <= 0:
            raise InvalidInput("The table must have a positive size.")
        return cls((c[0], c[1]), (s[0], s[1]), _finite("table height", [d["top_z"]], 1)[0])


@dataclass(frozen=True)
class WorldObject:
    """A task object as set up in the scene.

    Attributes:
        name: unique label, used in messages ("cup", "block 2").
        kind: "cup", "block" or "pad".
        size: (x, y, height) metres; a cup's x and y are its diameter.
        position: centre of its bottom face, metres, robot base frame.
        yaw: heading about the vertical, radians.
        held_out: the teacher holds it out in the air (the handed-over cup): it stays there until grasped.
    """

    name: str
    kind: str
    size: tuple[float, float, float]
    position: tuple[float, float, float]
    yaw: float = 0.0
    held_out: bool = False

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InvalidInput(f'Unknown object "{self.kind}": choose a cup, a block or a pad.')
        if not isinstance(self.name, str) or not self.name.strip() or len(self.name) > 60:
            raise InvalidInput("An object needs a name of 1 to 60 characters.")
        size = _finite(f"size of the {self.name}", self.size, 3)
        if min(size) <= 0 or max(size) > 1.0:
            raise InvalidInput(f"The {self.name} must be between 0 and 1 m in each direction.")
        pos = _finite(f"position of the {self.name}", self.position, 3)
        for v, (lo, hi) in zip(pos, _WORKSPACE, strict=True):
            if not lo <= v <= hi:
                raise InvalidInput(f"The {self.name} would be out of the robot's workspace; put it closer.")
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "position", pos)
        object.__setattr__(self, "yaw", _finite(f"heading of the {self.name}", [self.yaw], 1)[0])

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "kind": self.kind,
            "size": list(self.size),
            "position": list(self.position),
            "yaw": self.yaw,
            "held_out": self.held_out,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> WorldObject:
        return cls(
            name=str(d["name"]),
            kind=str(d["kind"]),
            size=_finite3("object size", d["size"]),
            position=_finite3("object position", d["position"]),
            yaw=float(d.get("yaw", 0.0)),
            held_out=bool(d.get("held_out", False)),
        )


@dataclass(frozen=True)
class Scene:
    """The task scene a session starts from: a table (or none) and objects. Immutable: edits return a new one.

    Attributes:
        preset: the preset it started from ("empty table", "stack-cup", "pick-place", or "" for none).
        table: the table, or None (objects then rest on the floor).
        objects: the objects, names unique.
    """

    preset: str = "empty table"
    table: Table | None = field(default_factory=Table)
    objects: tuple[WorldObject, ...] = ()

    def __post_init__(self) -> None:
        names = [o.name for o in self.objects]
        if len(set(names)) != len(names):
            raise InvalidInput("Two objects in the scene have the same name.")

    def names(self) -> list[str]:
        return [o.name for o in self.objects]

    def object(self, name: str) -> WorldObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise InvalidInput(f'There is no "{name}" in the scene.')

    def add(
        self,
        kind: str,
        position: Sequence[float],
        yaw: float = 0.0,
        *,
        name: str | None = None,
        size: Sequence[float] | None = None,
        settle: bool = True,
        held_out: bool = False,
    ) -> Scene:
        """A new scene with one more object (a cup, block or pad); named "<kind>", "<kind> 2", ... by default.

        With ``settle`` it comes to rest on the surface below; ``held_out``: the teacher holds it out in the
        air (it stays where it is put until a gripper takes it)."""
        if kind not in KINDS:
            raise InvalidInput(f'Unknown object "{kind}": choose a cup, a block or a pad.')
        if name is None:
            taken = set(self.names())
            name = kind
            n = 2
            while name in taken:
                name = f"{kind} {n}"
                n += 1
        elif name in self.names():
            raise InvalidInput(f'There is already a "{name}" in the scene; choose another name.')
        size_t = _finite3("object size", size) if size is not None else DEFAULT_SIZE[kind]
        obj = WorldObject(name, kind, size_t, _finite3("object position", position), float(yaw), held_out)
        if settle and not held_out:
            obj = replace(obj, position=_rest_position(obj, self.table, self.objects))
        return replace(self, objects=(*self.objects, obj))

    def move(self, name: str, position: Sequence[float], yaw: float | None = None, *, settle: bool = True) -> Scene:
        """A new scene with ``name`` put at ``position`` (bottom centre) and heading ``yaw`` (kept when None).

        With ``settle`` it comes to rest on the surface below (as when let go); an object the teacher holds
        out in the air stays where it is put.
        """
        old = self.object(name)
        obj = replace(old, position=_finite3("object position", position), yaw=old.yaw if yaw is None else float(yaw))
        if settle and not obj.held_out:
            others = tuple(o for o in self.objects if o.name != name)
            obj = replace(obj, position=_rest_position(obj, self.table, others))
        return replace(self, objects=tuple(obj if o.name == name else o for o in self.objects))

    def remove(self, name: str) -> Scene:
        """A new scene without ``name``."""
        self.object(name)
        return replace(self, objects=tuple(o for o in self.objects if o.name != name))

    def to_dict(self) -> dict[str, Any]:
        return {
            "version": SCENE_VERSION,
            "preset": self.preset,
            "table": None if self.table is None else self.table.to_dict(),
            "objects": [o.to_dict() for o in self.objects],
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> Scene:
        """The scene from :meth:`to_dict`; None (an older session without a scene) gives an empty table."""
        if d is None:
            return cls()
        try:
            version = int(d.get("version", 0))
            if version > SCENE_VERSION:
                raise SessionFormatError(
                    f"The task scene was saved by a newer Teaching Studio (scene format {version}); update the studio."
                )
            table = None if d.get("table") is None else Table.from_dict(d["table"])
            objects = tuple(WorldObject.from_dict(o) for o in d.get("objects", []))
            return cls(str(d.get("preset", "")), table, objects)
        except SessionFormatError:
            raise
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise SessionFormatError(f"The task scene is damaged ({exc}).") from exc


def _footprint_contains(o: WorldObject | ObjectPose, x: float, y: float, yaw: float) -> bool:
    """Whether the point (x, y) lies within the object's footprint (its outline seen from above)."""
    px, py = o.position[0], o.position[1]
    dx, dy = x - px, y - py
    if o.kind == "cup":
        return math.hypot(dx, dy) <= o.size[0] / 2
    c, s = math.cos(yaw), math.sin(yaw)
    u, v = c * dx + s * dy, -s * dx + c * dy
    return abs(u) <= o.size[0] / 2 and abs(v) <= o.size[1] / 2


def _support_level(kind: str, below: WorldObject | ObjectPose) -> float:
    """Height at which an object of ``kind`` rests on ``below``: on its top, or nested into a cup."""
    if kind == "cup" and below.kind == "cup":
        return below.position[2] + NEST_STEP
    return below.position[2] + below.size[2]


def _landing(
    kind: str,
    x: float,
    y: float,
    bottom: float,
    table: Table | None,
    others: Iterable[tuple[WorldObject | ObjectPose, float]],
) -> tuple[float, str]:
    """(height, what it rests on) for an object of ``kind`` let go with its bottom centre at (x, y, bottom)."""
    if table is not None and table.contains(x, y):
        level, on = table.top_z, "table"
    else:
        level, on = FLOOR_Z, "floor"
    for o, yaw in others:
        if not _footprint_contains(o, x, y, yaw):
            continue
        z = _support_level(kind, o)
        if z <= bottom + SNAP_UP and z > level:
            level, on = z, o.name
    return level, on


def _rest_position(obj: WorldObject, table: Table | None, others: Sequence[WorldObject]) -> tuple[float, float, float]:
    if obj.held_out:
        return obj.position
    x, y, z = obj.position
    level, _ = _landing(obj.kind, x, y, max(z, -10.0), table, ((o, o.yaw) for o in others if not o.held_out))
    return (x, y, level)


# -- presets --------------------------------------------------------------------------------------------------


def preset(name: str, arms: Sequence[str] = ("left",)) -> Scene:
    """A scene preset, its objects where the scripted teacher's demonstrations act (one set per teaching arm;
    the right arm's set mirrors the left one across the robot's middle).

    * "empty table": the table only;
    * "stack-cup": the cup the teacher hands over, held out in the air, and the cup it is stacked on;
    * "pick-place": a block at A and the target pad at B (with both arms one pad in the middle: the two arms'
      B points are 4 cm apart).
    """
    from studio import teacher

    if name not in PRESETS:
        raise InvalidInput(f'Unknown scene "{name}": choose {", ".join(PRESETS)}.')
    arms = tuple(check_arm(a) for a in arms) or ("left",)
    scene = Scene(preset=name)
    for arm in ARMS:
        if arm not in arms:
            continue
        m = 1.0 if arm == "left" else -1.0
        tag = f" ({arm})" if len(arms) > 1 else ""
        if name == "stack-cup":
            hx, hy, hz = teacher.STACK_CUP_HANDOVER
            sx, sy, _ = teacher.STACK_CUP_STACK
            scene = scene.add("cup", (sx, m * sy, TABLE_TOP_Z), name=f"bottom cup{tag}")
            scene = scene.add("cup", (hx, m * hy, hz - CUP_GRASP_HEIGHT), name=f"cup{tag}", held_out=True)
        elif name == "pick-place":
            ax, ay, _ = teacher.PICK_PLACE_A
            bx, by, _ = teacher.PICK_PLACE_B
            if len(arms) == 1:
                scene = scene.add("pad", (bx, m * by, TABLE_TOP_Z), m * teacher.PICK_PLACE_YAW_B, name="pad")
            elif arm == "left":
                scene = scene.add("pad", (bx, 0.0, TABLE_TOP_Z), 0.0, name="pad", size=(0.12, 0.16, 0.004))
            scene = scene.add("block", (ax, m * ay, TABLE_TOP_Z), m * teacher.PICK_PLACE_YAW_A, name=f"block{tag}")
    return scene


# -- poses and events -----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ObjectPose:
    """Where an object is at one moment.

    Attributes:
        name, kind, size: as in :class:`WorldObject`.
        position: centre of its bottom face (m), wxyz: its orientation (upright unless held).
        held_by: "left" / "right" while a gripper holds it (directly or resting on what it holds), else None.
        on: what it rests on ("table", "floor", another object's name, "hand" when held out by the teacher),
            None while held.
    """

    name: str
    kind: str
    size: tuple[float, float, float]
    position: tuple[float, float, float]
    wxyz: tuple[float, float, float, float]
    held_by: str | None = None
    on: str | None = None

    @property
    def yaw(self) -> float:
        return _yaw_of(matrix_from_quat_wxyz(np.asarray(self.wxyz)))

    @property
    def center(self) -> np.ndarray:
        """The object's centre (m): half its height up its own vertical axis."""
        R = matrix_from_quat_wxyz(np.asarray(self.wxyz))
        return np.asarray(self.position) + R[:, 2] * self.size[2] / 2

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "kind": self.kind,
            "size": list(self.size),
            "position": list(self.position),
            "wxyz": list(self.wxyz),
            "held_by": self.held_by,
            "on": self.on,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ObjectPose:
        kind = str(d["kind"])
        if kind not in KINDS:
            raise InvalidInput(f'Unknown object kind "{kind}".')
        held = d.get("held_by")
        if held is not None:
            check_arm(str(held))
        return cls(
            name=str(d["name"]),
            kind=kind,
            size=_finite3("object size", d["size"]),
            position=_finite3("object position", d["position"]),
            wxyz=_finite4("object orientation", d["wxyz"]),
            held_by=None if held is None else str(held),
            on=None if d.get("on") is None else str(d["on"]),
        )


@dataclass(frozen=True)
class WorldEvent:
    """Something that happened to the objects, with every object's pose just after it.

    Attributes:
        t: time (s) on the stream's clock.
        kind: "start" / "end" (of a demonstration or run), "grasp", "release", or "miss" (the gripper closed
            on nothing).
        arm: the gripper's arm (None for start/end).
        object: the grasped or released object (None for start/end/miss).
        gripper: the gripper point (m) at that moment (None for start/end).
        poses: every object's pose after the event (a released object already resting where it landed).
    """

    t: float
    kind: str
    arm: str | None
    object: str | None
    gripper: tuple[float, float, float] | None
    poses: tuple[ObjectPose, ...]

    def pose(self, name: str) -> ObjectPose | None:
        for p in self.poses:
            if p.name == name:
                return p
        return None

    def to_dict(self) -> dict[str, Any]:
        return {
            "t": self.t,
            "kind": self.kind,
            "arm": self.arm,
            "object": self.object,
            "gripper": None if self.gripper is None else list(self.gripper),
            "poses": [p.to_dict() for p in self.poses],
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> WorldEvent:
        kind = str(d["kind"])
        if kind not in EVENT_KINDS:
            raise InvalidInput(f'Unknown object event "{kind}".')
        arm = d.get("arm")
        if arm is not None:
            check_arm(str(arm))
        g = d.get("gripper")
        return cls(
            t=_finite("event time", [d["t"]], 1)[0],
            kind=kind,
            arm=None if arm is None else str(arm),
            object=None if d.get("object") is None else str(d["object"]),
            gripper=None if g is None else _finite3("gripper position", g),
            poses=tuple(ObjectPose.from_dict(p) for p in d.get("poses", [])),
        )


def events_to_dict(events: Sequence[WorldEvent]) -> dict[str, Any]:
    """JSON-ready form of a demonstration's object events: ``{"version": 1, "events": [...]}``."""
    return {"version": EVENTS_VERSION, "events": [e.to_dict() for e in events]}


def events_from_dict(d: Mapping[str, Any] | None) -> list[WorldEvent]:
    """Events from :func:`events_to_dict`; None (a demonstration recorded before objects existed) gives []."""
    if d is None:
        return []
    try:
        version = int(d.get("version", 0))
        if version > EVENTS_VERSION:
            raise SessionFormatError(
                f"The object events were saved by a newer Teaching Studio (format {version}); update the studio."
            )
        return [WorldEvent.from_dict(e) for e in d.get("events", [])]
    except SessionFormatError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise SessionFormatError(f"The object events of a demonstration are damaged ({exc}).") from exc


# -- the world ------------------------------------------------------------------------------------------------


class _Grip:
    """One gripper's close/open detector with hysteresis (:data:`SWING`)."""

    __slots__ = ("closed", "extreme")

    def __init__(self, opening: float) -> None:
        self.closed = False
        self.extreme = float(opening)

    def step(self, g: float) -> str | None:
        if self.closed:
            if g < self.extreme:
                self.extreme = g
            elif g > self.extreme + SWING:
                self.closed, self.extreme = False, g
                return "open"
        else:
            if g > self.extreme:
                self.extreme = g
            elif g < self.extreme - SWING:
                self.closed, self.extreme = True, g
                return "close"
        return None


class _State:
    """An object's current state: world transform of its bottom centre, holder, support."""

    __slots__ = ("T", "held_by", "held_out", "obj", "on", "rel", "was_on")

    def __init__(self, obj: WorldObject) -> None:
        self.obj = obj
        self.T = _transform(obj.position, _yaw_quat(obj.yaw))
        self.held_by: str | None = None
        self.held_out = obj.held_out
        self.on: str | None = "hand" if obj.held_out else None
        self.rel: np.ndarray | None = None  # transform in the gripper frame while held
        self.was_on: str | None = None  # what it rested on when it was picked up (carried along on it)

    def pose(self) -> ObjectPose:
        o = self.obj
        wxyz = quat_wxyz_from_matrix(self.T[:3, :3])
        return ObjectPose(
            o.name,
            o.kind,
            o.size,
            (float(self.T[0, 3]), float(self.T[1, 3]), float(self.T[2, 3])),
            (float(wxyz[0]), float(wxyz[1]), float(wxyz[2]), float(wxyz[3])),
            self.held_by,
            self.on,
        )


class World:
    """A scene brought to life by a stream of robot poses: grasps, carries and releases its objects.

    Feed it with :meth:`feed` (arrays) or subscribe :meth:`on_batch` to a ``RobotBackend``; read the objects
    with :meth:`poses` (``version`` changes whenever they move) and what happened with :attr:`events`.
    Thread-safe: a backend thread may feed it while the GUI reads it.
    """

    def __init__(
        self,
        scene: Scene | None = None,
        baxter: Baxter | None = None,
        *,
        start: Sequence[ObjectPose] | None = None,
        record_path: bool = False,
        path_rate_hz: float = 100.0,
    ) -> None:
        self.baxter = baxter if baxter is not None else Baxter.load()
        self._lock = threading.RLock()
        self._scene = scene if scene is not None else Scene()
        self._path_rate = float(path_rate_hz) if record_path else 0.0
        self.version = 0
        self.reset(self._scene, start)

    # -- set-up ---------------------------------------------------------------------------------------------
    @property
    def scene(self) -> Scene:
        return self._scene

    def reset(self, scene: Scene | None = None, start: Sequence[ObjectPose] | None = None) -> None:
        """Put every object back where the scene sets it up (or set up a new scene); forget the events.

        ``start``: begin instead from these poses (a demonstration's "start" event, to replay it as it was
        recorded): the objects are the ones listed there, an object held by a gripper is attached to it at
        the first sample fed.
        """
        with self._lock:
            if scene is not None:
                self._scene = scene
            if start is None:
                objects = list(self._scene.objects)
            else:
                objects = [
                    WorldObject(p.name, p.kind, p.size, p.position, p.yaw, held_out=p.on == "hand") for p in start
                ]
            self._objects: dict[str, _State] = {o.name: _State(o) for o in objects}
            if start is None:
                for o in objects:  # resting objects know what they rest on
                    st = self._objects[o.name]
                    if not o.held_out:
                        others = [
                            (x.obj, x.obj.yaw) for n, x in self._objects.items() if n != o.name and not x.held_out
                        ]
                        level, on = _landing(
                            o.kind, o.position[0], o.position[1], o.position[2], self._scene.table, others
                        )
                        st.on = on if abs(level - o.position[2]) < 1e-6 else None
            else:
                for p in start:
                    st = self._objects[p.name]
                    st.T = _transform(p.position, p.wxyz)
                    st.held_by, st.on = p.held_by, p.on  # a held one is attached at the first sample
            self._grips: dict[str, _Grip] | None = None
            self._events: list[WorldEvent] = []
            self._last: tuple[float, np.ndarray, np.ndarray] | None = None
            self._path_t: list[np.ndarray] = []
            self._path: dict[str, list[np.ndarray]] = {arm: [] for arm in ARMS}
            self._path_bucket = -math.inf
            self.version += 1

    # -- reading --------------------------------------------------------------------------------------------
    def poses(self) -> tuple[ObjectPose, ...]:
        """Every object's current pose, in the scene's order."""
        with self._lock:
            return tuple(s.pose() for s in self._objects.values())

    @property
    def events(self) -> list[WorldEvent]:
        with self._lock:
            return list(self._events)

    def mark(self) -> int:
        """A bookmark in the event list (e.g. when a recording starts); see :meth:`events_since`."""
        with self._lock:
            return len(self._events)

    def events_since(self, mark: int) -> list[WorldEvent]:
        with self._lock:
            return list(self._events[mark:])

    def held(self, arm: str) -> list[str]:
        """Names of the objects ``arm``'s gripper holds (the grasped one first)."""
        check_arm(arm)
        with self._lock:
            return [n for n, s in self._objects.items() if s.held_by == arm]

    def snapshot(self, kind: str, t: float | None = None) -> WorldEvent:
        """Record a "start" or "end" event (every object's pose) at time ``t`` (default: the last sample's)."""
        if kind not in ("start", "end"):
            raise InvalidInput('A snapshot is a "start" or an "end".')
        with self._lock:
            if t is None:
                t = self._last[0] if self._last is not None else 0.0
            ev = WorldEvent(float(t), kind, None, None, None, self.poses())
            self._events.append(ev)
            return ev

    # -- feeding --------------------------------------------------------------------------------------------
    def on_batch(self, batch: Any) -> None:
        """``RobotBackend.subscribe`` listener: feed a :class:`JointStateBatch`."""
        self.feed(batch.t, batch.q, batch.gripper)

    def feed(self, t: np.ndarray, q: np.ndarray, gripper: np.ndarray) -> list[WorldEvent]:  # noqa: C901
        """Play samples (n,) times, (n, 14) joints (rad), (n, 2) gripper openings (percent); returns new events.

        Rows with missing values (NaN) are skipped, as the recorder skips them.
        """
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        q = np.asarray(q, dtype=np.float64).reshape(-1, 14)
        g = np.asarray(gripper, dtype=np.float64).reshape(-1, 2)
        if not (len(t) == len(q) == len(g)):
            raise InvalidInput("Times, joint angles and gripper openings must have the same number of samples.")
        ok = np.isfinite(t) & np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(g), axis=1)
        if not ok.all():
            t, q, g = t[ok], q[ok], g[ok]
        if len(t) == 0:
            return []
        with self._lock:
            if self._grips is None:
                self._grips = {arm: _Grip(float(g[0, i])) for i, arm in enumerate(ARMS)}
                for arm in ARMS:  # objects held at the start (a replayed demonstration) follow this gripper
                    held = [st for st in self._objects.values() if st.held_by == arm and st.rel is None]
                    if held:
                        self._grips[arm].closed = True
                        inv = np.linalg.inv(self._gripper_T(arm, q[0]))
                        for st in held:
                            st.rel = inv @ st.T
            if self._path_rate > 0:
                self._record_path(t, q)
            new: list[WorldEvent] = []
            for i, arm in enumerate(ARMS):
                det = self._grips[arm]
                col = g[:, i]
                for k in range(len(col)):  # ~0.4 µs a sample: no need to be clever
                    action = det.step(float(col[k]))
                    if action is None:
                        continue
                    T = self._gripper_T(arm, q[k])
                    self._carry(T, arm)
                    ev = self._close(arm, float(t[k]), T) if action == "close" else self._open(arm, float(t[k]), T)
                    if ev is not None:
                        new.append(ev)
            new.sort(key=lambda e: e.t)
            self._events.extend(new)
            self._last = (float(t[-1]), q[-1].copy(), g[-1].copy())
            moved = False
            for arm in ARMS:
                if any(s.held_by == arm for s in self._objects.values()):
                    self._carry(self._gripper_T(arm, q[-1]), arm)
                    moved = True
            if moved or new:
                self.version += 1
            return new

    def run(self) -> WorldRun:
        """What happened so far as a :class:`WorldRun` (for :func:`task_result`); the gripper path is there
        only when the world was made with ``record_path=True``."""
        with self._lock:
            if self._path_t:
                path_t = np.concatenate(self._path_t)
                path = {arm: np.concatenate(self._path[arm]) for arm in ARMS}
            else:
                path_t, path = np.zeros(0), {arm: np.zeros((0, 3)) for arm in ARMS}
            return WorldRun(tuple(self._events), self.poses(), path_t, path)

    # -- internals ------------------------------------------------------------------------------------------
    def _record_path(self, t: np.ndarray, q: np.ndarray) -> None:
        bucket = np.floor(t * self._path_rate)
        prev = np.concatenate([[self._path_bucket], bucket[:-1]])
        idx = np.flatnonzero(bucket > prev)
        if len(idx) == 0:
            return
        self._path_bucket = float(bucket[-1])
        self._path_t.append(t[idx].copy())
        for arm in ARMS:
            self._path[arm].append(self.baxter.fk_batch(arm, q[idx, :7] if arm == "left" else q[idx, 7:])[0])

    def _gripper_T(self, arm: str, q14: np.ndarray) -> np.ndarray:
        p, wxyz = self.baxter.fk(arm, q14[:7] if arm == "left" else q14[7:])
        return _transform(p, wxyz)

    def _carry(self, T_grip: np.ndarray, arm: str) -> None:
        for s in self._objects.values():
            if s.held_by == arm and s.rel is not None:
                s.T = T_grip @ s.rel

    def _close(self, arm: str, t: float, T_grip: np.ndarray) -> WorldEvent:
        p = T_grip[:3, 3]
        best: _State | None = None
        for s in self._objects.values():
            o = s.obj
            if o.kind not in GRASPABLE or s.held_by is not None:
                continue
            base = s.T[:3, 3]
            if math.hypot(p[0] - base[0], p[1] - base[1]) > GRASP_XY_TOL:
                continue
            if not (base[2] - GRASP_BELOW_TOL <= p[2] <= base[2] + o.size[2] + GRASP_ABOVE_TOL):
                continue
            if best is None or base[2] > best.T[2, 3]:  # from a stack, the top one
                best = s
        gp = (float(p[0]), float(p[1]), float(p[2]))
        if best is None:
            return WorldEvent(t, "miss", arm, None, gp, self.poses())
        inv = np.linalg.inv(T_grip)
        for s in [best, *self._resting_on(best.obj.name)]:
            s.held_by, s.held_out, s.was_on, s.on = arm, False, s.on, None
            s.rel = inv @ s.T
        return WorldEvent(t, "grasp", arm, best.obj.name, gp, self.poses())

    def _resting_on(self, name: str) -> list[_State]:
        """The objects resting on ``name``, directly or through others."""
        out: list[_State] = []
        frontier = [name]
        while frontier:
            n = frontier.pop()
            for s in self._objects.values():
                if s.on == n and s.held_by is None and s not in out:
                    out.append(s)
                    frontier.append(s.obj.name)
        return out

    def _open(self, arm: str, t: float, T_grip: np.ndarray) -> WorldEvent | None:
        held = [s for s in self._objects.values() if s.held_by == arm]
        if not held:
            return None  # an open gripper holding nothing changes nothing
        # The grasped object is the lowest of what the gripper carries (the others rest on it).
        main = min(held, key=lambda s: s.T[2, 3])
        others = [
            (p, p.yaw) for p in (s.pose() for s in self._objects.values() if s.held_by is None and not s.held_out)
        ]
        base = main.T[:3, 3]
        yaw = _yaw_of(main.T[:3, :3])
        level, on = _landing(main.obj.kind, base[0], base[1], base[2], self._scene.table, others)
        upright = _transform((base[0], base[1], level), _yaw_quat(yaw))
        inv_old = np.linalg.inv(main.T)
        for s in held:
            if s is main:
                s.T, s.on = upright, on
            else:  # keeps its place on what it was carried on, upright
                T = upright @ (inv_old @ s.T)
                s.T = _transform(T[:3, 3], _yaw_quat(_yaw_of(T[:3, :3])))
                s.on = s.was_on
            s.held_by, s.rel = None, None
        p = T_grip[:3, 3]
        gp = (float(p[0]), float(p[1]), float(p[2]))
        return WorldEvent(t, "release", arm, main.obj.name, gp, self.poses())


# -- a whole run ----------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class WorldRun:
    """A pose stream played through a scene.

    Attributes:
        events: start, grasps, misses, releases and end, in time order.
        final: every object's pose at the end.
        path_t: (M,) times (s) of the gripper path samples (about every 10 ms).
        path: arm -> (M, 3) gripper points (m) at ``path_t`` (for the task result's wording).
    """

    events: tuple[WorldEvent, ...]
    final: tuple[ObjectPose, ...]
    path_t: np.ndarray
    path: dict[str, np.ndarray]


def simulate(
    t: np.ndarray,
    q: np.ndarray,
    gripper: np.ndarray,
    scene: Scene,
    *,
    baxter: Baxter | None = None,
    start: Sequence[ObjectPose] | None = None,
    path_rate_hz: float = 100.0,
) -> WorldRun:
    """Play a whole pose stream through ``scene``: (N,) times s, (N, 14) joints rad, (N, 2) openings percent.

    Deterministic: the same stream and scene give the same events. Works for any stream (a demonstration,
    the skill preview, a robot execution's joint states). ``start``: begin from these object poses instead
    of the scene's set-up (see :meth:`World.reset`).
    """
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    q = np.asarray(q, dtype=np.float64)
    gripper = np.asarray(gripper, dtype=np.float64)
    if len(t) == 0:
        raise InvalidInput("There is nothing to play: the motion has no samples.")
    if q.shape != (len(t), 14) or gripper.shape != (len(t), 2):
        raise InvalidInput(
            "The motion must have 14 joint angles and 2 gripper openings per sample "
            f"(got {q.shape} and {gripper.shape} for {len(t)} samples)."
        )
    ok = np.isfinite(t) & np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(gripper), axis=1)
    if not ok.any():
        raise InvalidInput("The motion contains only missing or invalid values (NaN).")
    world = World(scene, baxter, start=start, record_path=True, path_rate_hz=path_rate_hz)
    world.snapshot("start", float(t[ok][0]))
    world.feed(t, q, gripper)
    world.snapshot("end", float(t[ok][-1]))
    return world.run()


# -- what the demonstrations did, and whether a run does the same ----------------------------------------------


@dataclass(frozen=True)
class ObjectGoal:
    """What the demonstrations did with one object.

    Attributes:
        name, kind: the object.
        arm: the arm that grasped it.
        start: where it was at the start (bottom centre, m).
        releases: where it came to rest after each release, in order (mean over the demonstrations).
        landed_on: what it landed on after each release ("table", "pad", ...; the first demonstration's).
        final: where it ended (mean).
        spread: largest distance of one demonstration's end position from ``final`` (m).
        demos: how many demonstrations agree on this (the others grasped it a different number of times).
    """

    name: str
    kind: str
    arm: str
    start: tuple[float, float, float]
    releases: tuple[tuple[float, float, float], ...]
    final: tuple[float, float, float]
    spread: float
    demos: int
    landed_on: tuple[str | None, ...] = ()


@dataclass(frozen=True)
class TaskGoal:
    """The objects the demonstrations moved (:class:`ObjectGoal`), from ``demos`` demonstrations with events."""

    objects: tuple[ObjectGoal, ...]
    demos: int
    notes: tuple[str, ...] = ()


def _vec(p: Sequence[float]) -> tuple[float, float, float]:
    return (float(p[0]), float(p[1]), float(p[2]))


def task_goal(demos: Sequence[Sequence[WorldEvent]]) -> TaskGoal:
    """The task as the demonstrations show it: for each object they grasped, where each release left it and
    where it ended. ``demos`` are the demonstrations' event lists (as the session stores them); a demonstration
    without events (recorded before objects existed) is left out."""
    demos = [list(d) for d in demos if d]
    names: list[str] = []
    for d in demos:
        for e in d:
            if e.kind == "grasp" and e.object is not None and e.object not in names:
                names.append(e.object)
    goals: list[ObjectGoal] = []
    notes: list[str] = []
    for name in names:
        per_demo = []
        for d in demos:
            grasps = [e for e in d if e.kind == "grasp" and e.object == name]
            releases = [e for e in d if e.kind == "release" and e.object == name]
            first_pose = next((e.pose(name) for e in d if e.kind == "start" and e.pose(name) is not None), None)
            last_pose = next((e.pose(name) for e in reversed(d) if e.pose(name) is not None), None)
            rests = [e.pose(name) for e in releases]
            per_demo.append((grasps, rests, first_pose, last_pose))
        counts = [len(g) for g, _, _, _ in per_demo]
        k = max(set(counts), key=lambda c: (counts.count(c), c))
        if k == 0:
            continue
        agree = [p for p in per_demo if len(p[0]) == k]
        if len(agree) < len(per_demo):
            notes.append(
                f"{len(agree)} of {len(per_demo)} demonstrations pick up the {name} {_times(k)}; "
                "the others are left out of the check."
            )
        arms = [p[0][0].arm for p in agree if p[0][0].arm]
        arm = max(set(arms), key=arms.count) if arms else "left"
        n_rel = min(len(p[1]) for p in agree)
        rel = tuple(
            _vec(np.mean([p[1][i].position for p in agree], axis=0))  # type: ignore[union-attr]
            for i in range(n_rel)
        )
        ends = np.array([p[3].position for p in agree if p[3] is not None])
        final = _vec(ends.mean(axis=0)) if len(ends) else (rel[-1] if rel else (0.0, 0.0, 0.0))
        spread = float(np.max(np.linalg.norm(ends - np.asarray(final), axis=1))) if len(ends) else 0.0
        starts = [p[2] for p in agree if p[2] is not None]
        start_at = _vec(starts[0].position) if starts else final
        first = agree[0][0][0]
        kind = next((pp.kind for pp in first.poses if pp.name == name), "block")
        landed = tuple(r.on if r is not None else None for r in agree[0][1][:n_rel])
        goals.append(ObjectGoal(name, kind, arm, start_at, rel, final, spread, len(agree), landed))
    return TaskGoal(tuple(goals), len(demos), tuple(notes))


def _times(k: int) -> str:
    return {1: "once", 2: "twice"}.get(k, f"{k} times")


def _ordinal(k: int) -> str:
    return ["first", "second", "third", "fourth", "fifth"][k] if k < 5 else f"{k + 1}th"


@dataclass(frozen=True)
class ObjectResult:
    """How one object fared: ``verdict`` is "works", "never picked up", "still held", "dropped early",
    "wrong place" or "moved"; ``text`` says it in plain words; ``distance`` is how far it ended (or landed)
    from where the demonstrations put it (m), when it got that far."""

    name: str
    ok: bool
    verdict: str
    text: str
    distance: float | None


@dataclass(frozen=True)
class TaskResult:
    """The task result in plain words: ``text`` for the teacher, ``ok`` when every object ended where the
    demonstrations put it, and one :class:`ObjectResult` per object."""

    ok: bool
    text: str
    objects: tuple[ObjectResult, ...]


def task_result(run: WorldRun, goal: TaskGoal) -> TaskResult:
    """Judge a run (e.g. the skill preview played through the scene) against what the demonstrations did.

    The first thing that went wrong with each object is reported: never picked up (and where the gripper closed
    instead), still held at the end, dropped early (the gripper opened on the way and then went on to where
    the demonstrations let go), released in the wrong place, or ended away from where the demonstrations
    left it; otherwise how close it ended: "The cup ended 0.6 cm from where you put it — the skill works."
    """
    if not goal.objects:
        text = (
            "There is nothing to check: your demonstrations did not pick up any object. "
            "Put objects in the scene and record demonstrations that move them."
        )
        return TaskResult(False, text, ())
    results = [_object_result(run, g) for g in goal.objects]
    bad = [r for r in results if not r.ok]
    text = " ".join(r.text for r in (bad or results))
    return TaskResult(not bad, text, tuple(results))


def _object_result(run: WorldRun, g: ObjectGoal) -> ObjectResult:
    name = g.name
    events = run.events
    grasps = [e for e in events if e.kind == "grasp" and e.object == name]
    releases = [e for e in events if e.kind == "release" and e.object == name]
    t_prev = -math.inf
    label = name[:1].upper() + name[1:]
    n = len(g.releases)
    for k in range(n):
        when = f" the {_ordinal(k)} time" if n > 1 else ""
        if k >= len(grasps):
            return ObjectResult(name, False, "never picked up", _not_picked(run, g, k, t_prev, label), None)
        if k >= len(releases) or releases[k].t < grasps[k].t:
            text = f"The {name} was still in the gripper at the end: the gripper never opened{when}."
            return ObjectResult(name, False, "still held", text, None)
        rel = releases[k]
        pose = rel.pose(name)
        assert pose is not None
        target = np.asarray(g.releases[k])
        d = float(np.linalg.norm(np.asarray(pose.position) - target))
        if d > SUCCESS_TOL:
            arm = rel.arm or g.arm
            let_go = np.asarray(rel.gripper if rel.gripper is not None else pose.position)
            t_next = min(
                (e.t for e in events if e.t > rel.t and e.arm == arm and e.kind in ("grasp", "miss")), default=math.inf
            )
            sel = (run.path_t > rel.t) & (run.path_t <= t_next)
            p = run.path[arm][sel]
            reach = np.hypot(p[:, 0] - target[0], p[:, 1] - target[1]) if len(p) else np.array([math.inf])
            short = math.hypot(let_go[0] - target[0], let_go[1] - target[1]) > 2 * GRASP_XY_TOL
            if short and float(reach.min()) <= 2 * GRASP_XY_TOL:
                text = (
                    f"The {name} was dropped early{when}: it landed {format_distance(d)} from where you put it, "
                    "because the gripper opened before it got there."
                )
                return ObjectResult(name, False, "dropped early", text, d)
            off = describe_offset(np.asarray(pose.position) - target, "where you put it")
            text = f"The {name} was released in the wrong place{when}: {off}"
            expected = g.landed_on[k] if k < len(g.landed_on) else None
            if expected is not None and pose.on != expected:
                text += f" (it landed on the {pose.on}, not on the {expected})"
            text += "."
            return ObjectResult(name, False, "wrong place", text, d)
        t_prev = rel.t
    end = run.final
    fp = next((p for p in end if p.name == name), None)
    if fp is None:  # pragma: no cover - the run's scene lacks the object
        return ObjectResult(name, False, "never picked up", f"The {name} is not in the scene.", None)
    if fp.held_by is not None:
        text = f"The {name} was still in the gripper at the end: the gripper never let go of it."
        return ObjectResult(name, False, "still held", text, None)
    d = float(np.linalg.norm(np.asarray(fp.position) - np.asarray(g.final)))
    if d > SUCCESS_TOL:
        off = describe_offset(np.asarray(fp.position) - np.asarray(g.final), "where you put it")
        again = ": it was picked up again afterwards" if len(grasps) > n else ""
        return ObjectResult(name, False, "moved", f"The {name} ended {off}{again}.", d)
    return ObjectResult(
        name, True, "works", f"The {name} ended {format_distance(d)} from where you put it — the skill works.", d
    )


def _not_picked(run: WorldRun, g: ObjectGoal, k: int, t_prev: float, label: str) -> str:
    """Why object ``g`` was not picked up (for the k-th time): where the gripper closed instead, in words."""
    head = f"The {g.name} was never picked up" if k == 0 else f"The {g.name} was not picked up the {_ordinal(k)} time"
    after = [e for e in run.events if e.t > t_prev and e.arm == g.arm]
    other = next((e for e in after if e.kind == "grasp" and e.object != g.name), None)
    misses = [e for e in after if e.kind == "miss" and e.gripper is not None and e.pose(g.name) is not None]
    if not misses:
        if other is not None:
            return f"{head}: the gripper picked up the {other.object} instead."
        return f"{head}: the gripper never closed." if k == 0 else f"{head}: the gripper did not close again."

    def offset(e: WorldEvent) -> np.ndarray:
        pose = e.pose(g.name)
        assert pose is not None and e.gripper is not None
        gp, base = np.asarray(e.gripper), np.asarray(pose.position)
        v = np.zeros(3)
        h = np.array([gp[0] - base[0], gp[1] - base[1]])
        if np.hypot(*h) > GRASP_XY_TOL:
            v[:2] = h
        top = base[2] + pose.size[2]
        if gp[2] > top:
            v[2] = gp[2] - top
        elif gp[2] < base[2]:
            v[2] = gp[2] - base[2]
        return v

    best = min(misses, key=lambda e: float(np.linalg.norm(offset(e))))
    v = offset(best)
    where = describe_offset(v, "it") if np.linalg.norm(v) >= 0.001 else "right next to it"
    return f"{head}: the gripper closed {where}."
