"""Where the scripted teacher's task objects stand: :class:`Places` moves and turns them from the usual spots,
and the teacher's key-frames at an object with it."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Place:
    """Where one of a task's objects stands, relative to the teacher's usual spot: moved ``dx``, ``dy`` metres
    on the table (left arm's coordinates: the right arm mirrors them) and turned ``dyaw`` radians about its
    own vertical axis. The teacher's key-frames at that object move and turn with it (a cup is round: the
    gripper keeps its direction)."""

    dx: float = 0.0
    dy: float = 0.0
    dyaw: float = 0.0


@dataclass(frozen=True)
class Places:
    """Where the task's two objects stand: ``pick`` the one the teacher grasps (the handed-over cup, the block
    at A), ``put`` the one it is put on (the bottom cup, the pad at B). The default is the usual spots."""

    pick: Place = Place()
    put: Place = Place()

    def move(
        self, site: str, centres: Sequence[Sequence[float]], p: np.ndarray, yaw: float, *, turn: bool
    ) -> tuple[np.ndarray, float]:
        """A key-frame (position ``p``, gripper heading ``yaw``) at ``site`` ("pick" or "put", whose usual spots
        are ``centres``) moved and turned with its object; the heading turns too when ``turn``."""
        pl = self.pick if site == "pick" else self.put
        if pl == Place():
            return p, yaw
        centre = np.asarray(centres[0 if site == "pick" else 1], dtype=np.float64)
        c, s = math.cos(pl.dyaw), math.sin(pl.dyaw)
        d = p - centre
        moved = centre + np.array([c * d[0] - s * d[1] + pl.dx, s * d[0] + c * d[1] + pl.dy, d[2]])
        return moved, yaw + pl.dyaw if turn else yaw


#: The name of the object at each site of a task (as :func:`studio.world.preset` names them for one arm).
SITE_OBJECTS = {"stack-cup": {"pick": "cup", "put": "bottom cup"}, "pick-place": {"pick": "block", "put": "pad"}}


#: The usual spots (where the presets put the objects).
USUAL = Places()
