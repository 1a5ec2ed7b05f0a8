"""Objects the robot runs into: pushed along the arm's way, or knocked over (a taller-than-wide object hit deep).

:func:`simulate_hits` plays a motion through a scene as :func:`~studio.world.simulation.simulate` does, finds the
first stretch where the robot (or what it carries) overlaps an object standing on its own
(:func:`~studio.world.contacts.touches`), moves that object there (a "push" event) and plays the motion again from
the start, until nothing more is hit. Rules, not physics (decision 027); the rule: decision 087."""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass, replace

import numpy as np

from studio.core.kinematics import Baxter
from studio.core.robot_geometry import Part
from studio.core.rotations import matrix_from_quat_wxyz, quat_wxyz_from_matrix
from studio.core.touches import Touch
from studio.core.types import ARMS
from studio.world.contacts import along, touches
from studio.world.events import ObjectPose, WorldEvent
from studio.world.scene import Scene
from studio.world.simulation import World, WorldRun

#: An upright object taller than it is wide is knocked over when hit deeper than this share of its width.
TOPPLE_SHARE = 0.25
#: A pushed object ends this much (m) beyond the deepest overlap.
PUSH_CLEAR_M = 0.01
#: Most objects hit in one motion (each one plays the motion again).
MAX_HITS = 4


@dataclass(frozen=True)
class Hit:
    """An object the robot ran into: when (s), which, by what (a robot part or a carried object), how far it was
    pushed (m), and whether it was knocked over."""

    t: float
    name: str
    by: Part
    distance: float
    toppled: bool


def simulate_hits(
    t: np.ndarray,
    q: np.ndarray,
    gripper: np.ndarray,
    scene: Scene,
    baxter: Baxter,
    *,
    start: Sequence[ObjectPose] | None = None,
    new: Collection[str] = (),
) -> tuple[WorldRun, tuple[Hit, ...], list[Touch]]:
    """Play a motion through ``scene`` with the objects it runs into pushed or knocked over.

    Returns:
        the run (its events include a "push" per hit), the hits in time order, and what the robot (or what it
        carries) touches that it must not along it, the objects where they stand (:func:`studio.world.contacts.
        touches`; ``new``: the objects no demonstration had).
    """
    t = np.asarray(t, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    g = np.asarray(gripper, dtype=np.float64)
    pushes: list[tuple[int, ObjectPose, Hit]] = []
    run = _play(t, q, g, scene, baxter, start, pushes)
    found = first = touches(t, q, g, scene, run, baxter, new=new)
    for _ in range(MAX_HITS):
        after = pushes[-1][0] if pushes else -1
        nxt = _first_hit(t, q, run, found, baxter, after)
        if nxt is None:
            break
        pushes.append(nxt)
        run = _play(t, q, g, scene, baxter, start, pushes)
        found = touches(t, q, g, scene, run, baxter, new=new)
    return run, tuple(h for _, _, h in pushes), first


def _play(
    t: np.ndarray,
    q: np.ndarray,
    g: np.ndarray,
    scene: Scene,
    baxter: Baxter,
    start: Sequence[ObjectPose] | None,
    pushes: Sequence[tuple[int, ObjectPose, Hit]],
) -> WorldRun:
    world = World(scene, baxter, start=start, record_path=True)
    world.snapshot("start", float(t[0]))
    k0 = 0
    for k, pose, hit in pushes:
        if k > k0:
            world.feed(t[k0:k], q[k0:k], g[k0:k])
        world.push(pose, float(t[k]), hit.by.arm)
        k0 = k
    world.feed(t[k0:], q[k0:], g[k0:])
    world.snapshot("end", float(t[-1]))
    return world.run()


def _first_hit(
    t: np.ndarray, q: np.ndarray, run: WorldRun, found: Sequence[Touch], baxter: Baxter, after: int
) -> tuple[int, ObjectPose, Hit] | None:
    """The earliest overlap, after sample ``after``, with an object that stands on its own: where it ends."""
    objs = along(t, q, run, baxter)
    for x in sorted(found, key=lambda x: x.i_start):
        b = x.b
        if b.robot or b.part not in objs.names or x.i_start <= after or x.depth <= 0.0:
            continue
        k = objs.names.index(b.part)
        if objs.holder[x.i_start, k] >= 0:
            continue  # in a gripper: it goes where that gripper goes
        pose = _pose_at(run, b.part, t[x.i_start])
        if pose is None:
            continue
        moved, hit = struck(pose, x, _direction(objs.grip, x, np.asarray(pose.center)), float(x.at))
        return x.i_start, moved, hit
    return None


def struck(pose: ObjectPose, x: Touch, way: np.ndarray, t: float) -> tuple[ObjectPose, Hit]:
    """Object ``pose`` run into as ``x`` says, by something moving along ``way`` (2,) at time ``t``: where it ends
    (slid beyond the overlap, or knocked over when taller than wide and hit deep), and the hit."""
    width = min(pose.size[0], pose.size[1])
    toppled = pose.size[2] > width and x.depth > TOPPLE_SHARE * width
    moved = x.depth + PUSH_CLEAR_M
    return _pushed(pose, way, moved, toppled), Hit(t, pose.name, x.a, moved, toppled)


def _pose_at(run: WorldRun, name: str, t: float) -> ObjectPose | None:
    """Where object ``name`` stands at time ``t`` (the last event before it)."""
    last = None
    for e in sorted(run.events, key=lambda e: e.t):
        if e.t > t + 1e-9:
            break
        p = e.pose(name)
        last = p if p is not None else last
    return last


def _direction(grip: np.ndarray, x: Touch, centre: np.ndarray) -> np.ndarray:
    """The horizontal way (2,) the toucher moves when it meets the object (or from it towards the object)."""
    arm = x.a.arm
    if arm is not None:
        i = ARMS.index(arm)
        n = grip.shape[1]
        d = grip[i, min(x.i_start + 3, n - 1), :2] - grip[i, max(x.i_start - 3, 0), :2]
        if float(np.linalg.norm(d)) > 1e-4:
            return d / np.linalg.norm(d)
        d = centre[:2] - grip[i, x.i_start, :2]
        if float(np.linalg.norm(d)) > 1e-6:
            return d / np.linalg.norm(d)
    return np.array([1.0, 0.0])


def _pushed(pose: ObjectPose, way: np.ndarray, distance: float, toppled: bool) -> ObjectPose:
    """The object slid ``distance`` along ``way`` (2,), or knocked over in that direction (lying on its side)."""
    p = np.asarray(pose.position, dtype=np.float64)
    p[:2] += way * distance
    R = matrix_from_quat_wxyz(np.asarray(pose.wxyz))
    if toppled:  # its axis now lies along the way it fell, its bottom face where its side was
        axis = np.array([-way[1], way[0], 0.0])
        c, s = math.cos(math.pi / 2), math.sin(math.pi / 2)
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        R = (np.eye(3) + s * K + (1 - c) * K @ K) @ R
        p[2] += min(pose.size[0], pose.size[1]) / 2
        p[:2] -= way * pose.size[2] / 2
    w = quat_wxyz_from_matrix(R)
    return replace(pose, position=(float(p[0]), float(p[1]), float(p[2])), wxyz=tuple(float(v) for v in w))  # type: ignore[arg-type]


def hit_events(events: Sequence[WorldEvent]) -> tuple[WorldEvent, ...]:
    """The "push" events among ``events`` (never kept in a session: a take's events leave them out)."""
    return tuple(e for e in events if e.kind == "push")


__all__ = ["MAX_HITS", "TOPPLE_SHARE", "Hit", "hit_events", "simulate_hits", "struck"]
