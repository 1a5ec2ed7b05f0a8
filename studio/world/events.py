"""What happened to the objects: every object's pose at a moment (:class:`ObjectPose`), and the events of a
stream (:class:`WorldEvent`: start, grasp, miss, release, end), frozen and versioned for the session."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from studio.core.errors import InvalidInput, SessionFormatError
from studio.core.rotations import matrix_from_quat_wxyz
from studio.core.types import Arm, check_arm
from studio.world.geometry import EVENT_KINDS, EVENTS_VERSION, KINDS, MAX_EVENTS, finite, finite3, finite4, yaw_of


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
        return yaw_of(matrix_from_quat_wxyz(np.asarray(self.wxyz)))

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
            size=finite3("object size", d["size"]),
            position=finite3("object position", d["position"]),
            wxyz=finite4("object orientation", d["wxyz"]),
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
    arm: Arm | None
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
            t=finite("event time", [d["t"]], 1)[0],
            kind=kind,
            arm=None if arm is None else check_arm(str(arm)),
            object=None if d.get("object") is None else str(d["object"]),
            gripper=None if g is None else finite3("gripper position", g),
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
        events = d.get("events", [])
        if len(events) > MAX_EVENTS:
            raise SessionFormatError(f"A demonstration lists an absurd number of object events ({len(events)}).")
        return [WorldEvent.from_dict(e) for e in events]
    except SessionFormatError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise SessionFormatError(f"The object events of a demonstration are damaged ({exc}).") from exc


def retime(events: Sequence[WorldEvent], t0: float, t1: float) -> tuple[WorldEvent, ...]:
    """The events of a demonstration trimmed to ``t0 ≤ t ≤ t1``, times restarting at 0 (as the trim does).

    The objects at the new start are as the last event before ``t0`` left them (an object then held is where
    it was grasped: replaying the trimmed demonstration attaches it to the gripper at its first sample).
    """
    if not events:
        return ()
    before = [e for e in events if e.t < t0]
    kept = [replace(e, t=e.t - t0) for e in events if t0 <= e.t <= t1 and e.kind not in ("start", "end")]
    start = before[-1] if before else next((e for e in events if e.kind == "start"), events[0])
    ends = [e for e in events if e.t <= t1]
    end = ends[-1] if ends else start
    first = WorldEvent(0.0, "start", None, None, None, start.poses)
    last = WorldEvent(max(t1 - t0, 0.0), "end", None, None, None, end.poses)
    return (first, *kept, last)


def bounded(events: Sequence[WorldEvent], limit: int = MAX_EVENTS) -> tuple[WorldEvent, ...]:
    """At most ``limit`` events for the session: the first and last, every grasp and release, then as many
    misses (closes on nothing) as still fit, in time order."""
    if len(events) <= limit:
        return tuple(events)
    keep = {0, len(events) - 1} | {i for i, e in enumerate(events) if e.kind != "miss"}
    keep_sorted = [*sorted(keep)[: limit - 1], len(events) - 1] if len(keep) > limit else sorted(keep)
    spare = limit - len(keep_sorted)
    misses = [i for i, e in enumerate(events) if e.kind == "miss" and i not in keep][: max(spare, 0)]
    return tuple(events[i] for i in sorted(set(keep_sorted) | set(misses)))


def on_clock(events: Sequence[WorldEvent], t0: float, duration: float) -> tuple[WorldEvent, ...]:
    """Events of a live stream on a recording's clock: ``t0`` (the stream's time of the recording's first
    sample) becomes 0; times are kept within ``0..duration``, the "end" at ``duration``."""
    return tuple(replace(e, t=duration if e.kind == "end" else min(max(e.t - t0, 0.0), duration)) for e in events)
