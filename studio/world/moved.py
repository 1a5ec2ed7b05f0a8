"""Which objects stand elsewhere than when the demonstrations started (:func:`moved_objects`): what a skill
that repeats the taught motion (fixed places) does not follow."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from studio.world.events import ObjectPose
from studio.world.geometry import SUCCESS_TOL
from studio.world.scene import Scene


def moved_objects(starts: Sequence[Sequence[ObjectPose]], scene: Scene) -> list[tuple[str, float]]:
    """(name, distance m) of each object of ``scene`` more than :data:`SUCCESS_TOL` from where it stood at the
    start of the demonstrations (the median of ``starts``, one tuple of poses per demonstration), in the scene's
    order. Objects no demonstration started with are left out."""
    out = []
    for o in scene.objects:
        at = [p.position for poses in starts for p in poses if p.name == o.name]
        if not at:
            continue
        taught = np.median(np.asarray(at, dtype=float), axis=0)
        d = math.dist(o.position, taught)
        if d > SUCCESS_TOL:
            out.append((o.name, d))
    return out
