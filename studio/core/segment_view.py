"""A skill that follows the objects, seen the way it learns: each demonstration's stretches between grasps and
releases in the frame of the object they act on, placed where the objects are now (:func:`demos_in_frames`, for
the key-point view and its clusters), and how closely each learned segment follows the demonstrations in its
own frame (:func:`segment_fits`, for the verdict per segment). GUI-free facts; the words are in
:mod:`studio.words`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from studio.core import quality
from studio.core.errors import StudioError
from studio.core.frames import ROBOT, DemoObjects, ObjectAt, ObjectFrames, frames_at, to_local, to_world, turn
from studio.core.rotations import make_sign_continuous
from studio.core.segments import _in_frame, _split, path_roles, plan, segment_frames
from studio.core.types import Demo


def demos_in_frames(
    demos: Sequence[Demo], objects: Sequence[DemoObjects], now: Sequence[ObjectAt]
) -> list[Demo] | None:
    """Each demonstration with every stretch between its grasps and releases moved from where its object stood
    then to where the object is ``now`` (the frame the stretch is learned in). Same samples and times, so
    key-point indices hold. None when the demonstrations share no grasps and releases (:func:`plan`) or an
    object is missing."""
    borders, _ = plan(objects)
    if not borders or len(demos) != len(objects):
        return None
    roles = [ROBOT, *(b.role for b in borders), ROBOT]
    try:
        F = frames_at(borders, now)
        out = []
        for d, o in zip(demos, objects, strict=True):
            cuts = _split(d, o)
            pos = np.array(d.position, dtype=np.float64)
            ori = np.array(d.orientation, dtype=np.float64)
            for k in range(len(borders) + 1):
                seg_roles = (roles[k], roles[k + 1])
                fp, _ = segment_frames(o, k, seg_roles)
                f_now = F[k] if path_roles(seg_roles)[0] == seg_roles[0] else F[k + 1]
                sl = slice(cuts[k], cuts[k + 1] + 1)
                pos[sl] = to_world(f_now, to_local(fp, d.position[sl]))
                ori[sl] = turn(d.orientation[sl], float(f_now[3] - fp[3]))
            out.append(Demo(d.t, pos, make_sign_continuous(ori), d.gripper, q=d.q, name=d.name))
    except StudioError:
        return None
    return out


@dataclass(frozen=True)
class SegmentFit:
    """How closely one learned segment follows the demonstrations, in the frame it is learned in.

    Attributes:
        start, end: what begins and ends it: "start", "grasp", "release" or "end".
        object: the object the segment acts on (the end's border, or the start's for the last one).
        role: the frame it is learned in ("object:<name>", "start:<name>" or "robot").
        distance: root of the mean normalised DTW distance to the demonstrations' stretches, m.
        g_over_r: that mean ÷ the stretches' mean pairwise distance (G/R).
    """

    start: str
    end: str
    object: str
    role: str
    distance: float
    g_over_r: float


def segment_fits(frames: ObjectFrames, demos: Sequence[Demo], objects: Sequence[DemoObjects]) -> tuple[SegmentFit, ...]:
    """Each learned segment of ``frames`` against the demonstrations' stretches in its frame (() when the
    demonstrations no longer split the same way)."""
    borders, _ = plan(objects)
    if [(b.kind, b.object) for b in borders] != [(b.kind, b.object) for b in frames.borders]:
        return ()
    roles = [ROBOT, *(b.role for b in frames.borders), ROBOT]
    kinds = ["start", *(b.kind for b in frames.borders), "end"]
    try:
        cuts = [_split(d, o) for d, o in zip(demos, objects, strict=True)]
        out = []
        for k, seg in enumerate(frames.segments):
            seg_roles = (roles[k], roles[k + 1])
            parts = [
                _in_frame(d, c[k], c[k + 1], segment_frames(o, k, seg_roles)[0])
                for d, o, c in zip(demos, objects, cuts, strict=True)
            ]
            curves = [quality.curve(p) for p in parts]
            learned = quality.curve(Demo(seg.t, seg.position, seg.orientation, seg.gripper, name="segment"))
            g = float(np.mean([quality.ndtw(learned, c) for c in curves]))
            r = quality.spread(curves)[0] if len(curves) > 1 else math.nan
            near = frames.borders[k] if k < len(frames.borders) else frames.borders[-1]
            out.append(
                SegmentFit(
                    kinds[k],
                    kinds[k + 1],
                    near.object,
                    path_roles(seg_roles)[0],
                    math.sqrt(g),
                    g / r if r > 0 else math.nan,
                )
            )
    except StudioError:
        return ()
    return tuple(out)


__all__ = ["SegmentFit", "demos_in_frames", "segment_fits"]
