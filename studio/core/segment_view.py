"""A skill that follows the objects, seen the way it learns: each demonstration's stretches between grasps and
releases in the frame of the object they act on, placed where the objects are now (:func:`demos_in_frames`, for
the key-point view and its clusters), and how closely each learned segment follows the demonstrations in its
own frame (:func:`segment_fits`, for the verdict per segment). GUI-free facts; the words are in
:mod:`studio.words`."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from studio.core import quality
from studio.core.errors import StudioError
from studio.core.frames import ROBOT, DemoObjects, ObjectAt, ObjectFrames, frames_at, to_local, to_world
from studio.core.rotations import make_sign_continuous
from studio.core.segments import contact_cuts, frame_at_contact, in_frame, minjerk, path_roles, plan, segment_frames
from studio.core.types import Demo


def demos_in_frames(
    demos: Sequence[Demo],
    objects: Sequence[DemoObjects],
    now: Sequence[ObjectAt],
    frames: ObjectFrames | None = None,
    rules: Mapping[int, str] | None = None,
) -> list[Demo] | None:
    """Each demonstration moved the way the skill moves its path when the objects are ``now``: every stretch
    between grasps and releases goes from its start's frame (where it begins) to its end's frame (where it
    ends), blended as the learned segments of ``frames`` blend them (without ``frames``: a minimum-jerk blend).
    Same samples and times, so key-point indices hold. None when the demonstrations share no grasps and
    releases (:func:`plan`) or an object is missing."""
    borders, _ = plan(objects)
    if not borders or len(demos) != len(objects):
        return None
    roles = [ROBOT, *(b.role for b in borders), ROBOT]
    try:
        F = frames_at(borders, now)
        out = []
        for d, o in zip(demos, objects, strict=True):
            cuts = contact_cuts(d, o)
            pos = np.array(d.position, dtype=np.float64)
            ori = np.array(d.orientation, dtype=np.float64)
            for k in range(len(borders) + 1):
                sl = slice(cuts[k], cuts[k + 1] + 1)
                t = np.asarray(d.t[sl]) - d.t[cuts[k]]
                u = t / max(float(t[-1]), 1e-9)
                w_end = _end_weight(u, k, roles, frames)[:, None]
                f_start = np.zeros(4) if roles[k] == ROBOT else frame_at_contact(o, k - 1, roles[k])
                f_end = np.zeros(4) if roles[k + 1] == ROBOT else frame_at_contact(o, k, roles[k + 1])
                if f_start is None or f_end is None:
                    return None
                p = d.position[sl]
                a = to_world(F[k], to_local(f_start, p))
                b = to_world(F[k + 1], to_local(f_end, p))
                pos[sl] = (1.0 - w_end) * a + w_end * b
                yaw = (1.0 - w_end[:, 0]) * _wrap(F[k][3] - f_start[3]) + w_end[:, 0] * _wrap(F[k + 1][3] - f_end[3])
                ori[sl] = _turn_each(d.orientation[sl], yaw)
            out.append(Demo(d.t, pos, make_sign_continuous(ori), d.gripper, q=d.q, name=d.name))
    except StudioError:
        return None
    return out


def taught_placement(objects: Sequence[DemoObjects]) -> tuple[ObjectAt, ...]:
    """The objects as one demonstration had them at its start: the one nearest the middle of all the
    demonstrations' places (where a skill is judged against the demonstrations, whatever the scene is now)."""
    if not objects:
        return ()
    names = list(dict.fromkeys(o.name for d in objects for o in d.start))
    middle = {n: np.median([o.position for d in objects if (o := d.start_pose(n)) is not None], axis=0) for n in names}

    def off(d: DemoObjects) -> float:
        return sum(float(np.linalg.norm(np.asarray(o.position) - middle[o.name])) for o in d.start)

    return min(objects, key=off).start


def _end_weight(u: np.ndarray, k: int, roles: Sequence[str], frames: ObjectFrames | None) -> np.ndarray:
    """How much the end's frame decides at each normalised instant ``u`` of stretch ``k``."""
    if roles[k] == roles[k + 1]:
        return np.ones_like(u)
    if frames is not None and k < len(frames.segments):
        seg = frames.segments[k]
        w_path = np.interp(u * seg.duration, seg.t, seg.weight)
        return w_path if path_roles((roles[k], roles[k + 1]))[0] == roles[k + 1] else 1.0 - w_path
    return np.asarray(minjerk(u), dtype=np.float64)


def _wrap(a: float) -> float:
    return float(np.angle(np.exp(1j * a)))


def _turn_each(q: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Quaternions (N, 4) each turned by its own ``yaw`` about the vertical."""
    c, s = np.cos(yaw / 2.0), np.sin(yaw / 2.0)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([c * w - s * z, c * x - s * y, c * y + s * x, c * z + s * w], axis=-1)


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
        cuts = [contact_cuts(d, o) for d, o in zip(demos, objects, strict=True)]
        out = []
        for k, seg in enumerate(frames.segments):
            seg_roles = (roles[k], roles[k + 1])
            parts = [
                in_frame(d, c[k], c[k + 1], segment_frames(o, k, seg_roles)[0])
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


__all__ = ["SegmentFit", "demos_in_frames", "segment_fits", "taught_placement"]
