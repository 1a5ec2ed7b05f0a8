"""A session's task scene and what happened to its objects in each demonstration (session format 2).

The scene is what the teacher set up (:class:`studio.world.Scene`; an empty table for a session from before
scenes). Each demonstration's object events (:class:`studio.world.WorldEvent`: every object's pose at its
start and end and at each grasp, release and miss) are kept by the demonstration's file, so that they follow
it through renames, trims (a new file, times restarting at 0) and deletions.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from studio.world import Scene, WorldEvent, bounded, retime


@dataclass
class SessionObjects:
    """The task scene and the object events of each demonstration file (``demos/d0001.npz`` -> events)."""

    scene: Scene = field(default_factory=Scene)
    by_file: dict[str, tuple[WorldEvent, ...]] = field(default_factory=dict)

    def __copy__(self) -> SessionObjects:
        """A copy that a later change of this one leaves alone (the session's undo of a failed change)."""
        return SessionObjects(self.scene, dict(self.by_file))

    def events(self, file: str) -> tuple[WorldEvent, ...]:
        """The object events of the demonstration in ``file`` (empty: recorded before objects existed)."""
        return self.by_file.get(file, ())

    def added(self, file: str, events: Iterable[WorldEvent]) -> None:
        self.by_file[file] = bounded(tuple(events))

    def removed(self, file: str) -> None:
        self.by_file.pop(file, None)

    def trimmed(self, old: str, new: str, t0: float, t1: float, events: Iterable[WorldEvent] | None) -> None:
        """The demonstration in ``old`` was trimmed to ``t0..t1`` into ``new``: its events are ``events``, or
        by default those within the kept time (:func:`studio.world.retime`)."""
        kept = self.by_file.pop(old, ())
        self.added(new, retime(kept, t0, t1) if events is None else events)
