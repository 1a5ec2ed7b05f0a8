"""What stands around the robot, as its collision checks see it: boxes and upright cylinders, and their poses.

:class:`Obstacle` is one thing the robot must not go through (the table, a cup, a carried block), with its coal
geometry; :func:`obstacle_pose` places one. The checks: :mod:`studio.core.collision`. Decisions 087 and 096."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import coal
import numpy as np

from studio.core.errors import InvalidInput


@dataclass(frozen=True)
class Obstacle:
    """Something the robot must not go through: a box or an upright cylinder.

    Attributes:
        name: how it is called ("table", "cup 2").
        shape: "box" or "cylinder".
        size: box: its extents x, y, z; cylinder: diameter, diameter, height (m).
        pose: (4, 4) where its centre is (the default where it stands; a check may move it:
            :meth:`~studio.core.collision.CollisionModel.near`).
    """

    name: str
    shape: str
    size: tuple[float, float, float]
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        if self.shape not in ("box", "cylinder"):
            raise InvalidInput(f'An obstacle is a box or a cylinder, not "{self.shape}".')
        s = np.asarray(self.size, dtype=np.float64)
        T = np.asarray(self.pose, dtype=np.float64)
        if s.shape != (3,) or not np.all(np.isfinite(s)) or s.min() <= 0 or T.shape != (4, 4):
            raise InvalidInput(f"The {self.name} needs three positive sizes and a pose.")
        object.__setattr__(self, "pose", T)

    @property
    def half(self) -> np.ndarray:
        """Half extents (3,) of its bounding box in its own frame."""
        return 0.5 * np.asarray(self.size, dtype=np.float64)

    def geometry(self) -> coal.CollisionGeometry:
        if self.shape == "box":
            return coal.Box(*self.size)
        return coal.Cylinder(0.5 * self.size[0], self.size[2])


def obstacle_pose(position: Sequence[float] | np.ndarray, R: np.ndarray | None = None) -> np.ndarray:
    """(4, 4) pose of an obstacle's centre at ``position`` with rotation ``R`` (default upright)."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = position
    return T


__all__ = ["Obstacle", "obstacle_pose"]
