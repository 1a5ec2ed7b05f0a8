"""The task scene as the teacher sets it up: a table (or none) and cups, blocks and pads with sizes and poses.

A :class:`Scene` is immutable: adding, moving and removing an object returns a new one, the object settled
onto the surface below it (unless the teacher holds it out in the air). It converts to and from a versioned,
JSON-ready dict for the session; None (a session saved before scenes existed) gives an empty table.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from studio.core.errors import InvalidInput, SessionFormatError
from studio.world.geometry import (
    DEFAULT_SIZE,
    KINDS,
    MAX_OBJECTS,
    SCENE_VERSION,
    WORKSPACE,
    Table,
    finite,
    finite3,
    landing,
)
from studio.world.goal import MAX_PLACEMENTS, START, TABLE, Placement, declared, placements_from


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
        size = finite(f"size of the {self.name}", self.size, 3)
        if min(size) <= 0 or max(size) > 1.0:
            raise InvalidInput(f"The {self.name} must be between 0 and 1 m in each direction.")
        pos = finite(f"position of the {self.name}", self.position, 3)
        for v, (lo, hi) in zip(pos, WORKSPACE, strict=True):
            if not lo <= v <= hi:
                raise InvalidInput(f"The {self.name} would be out of the robot's workspace; put it closer.")
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "position", pos)
        object.__setattr__(self, "yaw", finite(f"heading of the {self.name}", [self.yaw], 1)[0])

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
            size=finite3("object size", d["size"]),
            position=finite3("object position", d["position"]),
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
        goal: the task's goal as the set-up states it or the teacher confirmed it (() : read it from the
            demonstrations; :mod:`studio.world.goal`).
    """

    preset: str = "empty table"
    table: Table | None = field(default_factory=Table)
    objects: tuple[WorldObject, ...] = ()
    goal: tuple[Placement, ...] = ()

    def __post_init__(self) -> None:
        if len(self.objects) > MAX_OBJECTS:
            raise InvalidInput(f"A scene holds at most {MAX_OBJECTS} objects; remove one first.")
        names = [o.name for o in self.objects]
        if len(set(names)) != len(names):
            raise InvalidInput("Two objects in the scene have the same name.")
        if len(self.goal) > MAX_PLACEMENTS:
            raise InvalidInput(f"A task's goal holds at most {MAX_PLACEMENTS} placements.")

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
        size_t = finite3("object size", size) if size is not None else DEFAULT_SIZE[kind]
        obj = WorldObject(name, kind, size_t, finite3("object position", position), float(yaw), held_out)
        if settle and not held_out:
            obj = replace(obj, position=rest_position(obj, self.table, self.objects))
        return replace(self, objects=(*self.objects, obj))

    def move(self, name: str, position: Sequence[float], yaw: float | None = None, *, settle: bool = True) -> Scene:
        """A new scene with ``name`` put at ``position`` (bottom centre) and heading ``yaw`` (kept when None).

        With ``settle`` it comes to rest on the surface below (as when let go), and what rested on it where it
        stood comes down onto what is below it now; an object the teacher holds out in the air stays where it
        is put.
        """
        old = self.object(name)
        obj = replace(old, position=finite3("object position", position), yaw=old.yaw if yaw is None else float(yaw))
        if settle and not obj.held_out:
            others = tuple(o for o in self.objects if o.name != name)
            obj = replace(obj, position=rest_position(obj, self.table, others))
        moved = replace(self, objects=tuple(obj if o.name == name else o for o in self.objects))
        return moved.settled() if settle else moved

    def settled(self) -> Scene:
        """The scene with every object not held out resting on what is below it, lowest first (one left in the
        air by a move, or standing with its centre beyond the table's edge, comes down)."""
        objs = {o.name: o for o in self.objects}
        for o in sorted(self.objects, key=lambda x: x.position[2]):
            if o.held_out:
                continue
            others = tuple(x for n, x in objs.items() if n != o.name and x.position[2] < o.position[2] + 1e-9)
            objs[o.name] = replace(o, position=rest_position(o, self.table, others))
        return replace(self, objects=tuple(objs[o.name] for o in self.objects))

    def remove(self, name: str) -> Scene:
        """A new scene without ``name`` (and without the goal's placements that name it)."""
        self.object(name)
        goal = tuple(p for p in self.goal if name not in (p.object, p.onto))
        return replace(self, objects=tuple(o for o in self.objects if o.name != name), goal=goal).settled()

    def with_goal(self, goal: Sequence[Placement]) -> Scene:
        """A new scene whose task's goal is ``goal`` (every object it names must be in the scene)."""
        names = set(self.names())
        for p in goal:
            if p.object not in names or (p.onto not in (START, TABLE) and p.onto not in names):
                raise InvalidInput(f"The goal names an object that is not on the table ({p.object} onto {p.onto}).")
        return replace(self, goal=tuple(goal))

    def to_dict(self) -> dict[str, Any]:
        return {
            "version": SCENE_VERSION,
            "preset": self.preset,
            "table": None if self.table is None else self.table.to_dict(),
            "objects": [o.to_dict() for o in self.objects],
            "goal": [p.to_dict() for p in self.goal],
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> Scene:
        """The scene from :meth:`to_dict`; None (an older session without a scene) gives an empty table. A scene
        saved before goals were kept has its set-up's goal (:func:`studio.world.goal.declared`)."""
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
            preset = str(d.get("preset", ""))
            names = {o.name for o in objects}
            if "goal" in d:  # a placement naming an object no longer there is left out
                goal = tuple(
                    p
                    for p in placements_from(d["goal"])
                    if p.object in names and (p.onto in (START, TABLE) or p.onto in names)
                )
            else:
                goal = declared(preset, [o.name for o in objects])
            return cls(preset, table, objects, goal)
        except SessionFormatError:
            raise
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise SessionFormatError(f"The task scene is damaged ({exc}).") from exc


def rest_position(obj: WorldObject, table: Table | None, others: Sequence[WorldObject]) -> tuple[float, float, float]:
    if obj.held_out:
        return obj.position
    x, y, z = obj.position
    level, _ = landing(obj.kind, x, y, max(z, -10.0), table, ((o, o.yaw) for o in others if not o.held_out))
    return (x, y, level)
