"""What the robot touches in the task scene along a motion, or at one pose, and what may touch (decision 087).

The table (down to the floor) and every object with its size are obstacles of a :class:`CollisionModel` (one per
scene, cached); along a motion the objects stand where the world's events left them, and a carried one moves
with its gripper. May touch: a gripper's fingers and what it holds, the object it closes around next or let go of
last (by hand: one it is around); a carried object and what it is being put down on (as ``landing`` puts it)."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, replace

import numpy as np

from studio.core.collision import CollisionModel, Near
from studio.core.kinematics import Baxter
from studio.core.obstacles import Obstacle
from studio.core.robot_geometry import FEW, Part
from studio.core.rotations import matrix_from_quat_wxyz
from studio.core.touches import Touch, stretches
from studio.core.types import ARMS, Arm
from studio.world.events import ObjectPose
from studio.world.geometry import FLOOR_Z, GRASP_BELOW_TOL, GRASP_XY_TOL, NEST_STEP, SNAP_UP, Table, yaw_quat
from studio.world.scene import Scene, WorldObject
from studio.world.simulation import WorldRun

#: Fingers may touch an object they are about to close around, or just let go of, while the gripper point is this
#: close to its axis (m) ...
AROUND_XY_M = 2 * GRASP_XY_TOL
#: ... and at most this far above its top (m).
AROUND_ABOVE_M = 0.02
TABLE = "table"


@functools.lru_cache(maxsize=16)
def _model(
    table: Table | None, objects: tuple[tuple[str, str, tuple[float, float, float]], ...], moving: frozenset[str]
) -> CollisionModel:
    obstacles = []
    if table is not None:
        h = table.top_z - FLOOR_Z
        T = np.eye(4)
        T[:3, 3] = (table.center[0], table.center[1], table.top_z - h / 2)
        obstacles.append(Obstacle(TABLE, "box", (table.size[0], table.size[1], h), T))
    for name, kind, size in objects:
        obstacles.append(Obstacle(name, "cylinder" if kind == "cup" else "box", size))
    return CollisionModel(obstacles, moving=sorted(moving))


def scene_model(
    scene: Scene,
    names: Sequence[tuple[str, str, tuple[float, float, float]]] | None = None,
    moving: Collection[str] = (),
) -> CollisionModel:
    """The collision model of a scene's table and objects (``names``: (name, kind, size) of the objects, default
    the scene's); ``moving``: the objects that may be carried."""
    objs = tuple(names) if names is not None else tuple((o.name, o.kind, o.size) for o in scene.objects)
    return _model(scene.table, objs, frozenset(moving))


def arm_clearance(scene: Scene, arm: Arm, other: np.ndarray | None) -> Callable[[np.ndarray], np.ndarray]:
    """For the path IK (:func:`studio.core.ik_path.solve_path`'s ``avoid``): joints (K, 7) of ``arm`` -> where its
    shoulder, upper arm, elbow or forearm touch the table, an object where it stands, the robot's body or the other
    arm held at ``other`` (7,; None: left out)."""
    model = scene_model(scene)
    poses = {o.name: centre_pose(_standing(o)) for o in scene.objects}
    return model.arm_touching(arm, other, poses)


def _standing(o: WorldObject) -> ObjectPose:
    return ObjectPose(o.name, o.kind, o.size, o.position, yaw_quat(o.yaw))


def centre_pose(p: ObjectPose) -> np.ndarray:
    """(4, 4) pose of an object's centre (half its height up its own axis from its bottom centre)."""
    T = np.eye(4)
    T[:3, :3] = matrix_from_quat_wxyz(np.asarray(p.wxyz))
    T[:3, 3] = p.position
    T[:3, 3] += T[:3, 2] * p.size[2] / 2
    return T


@dataclass(frozen=True, eq=False)
class Along:
    """The objects along a motion of N samples.

    Attributes:
        names, kinds, sizes: the objects (K).
        bottom: (K, N, 4, 4) their bottom centres' poses.
        holder: (N, K) which arm holds each (0 left, 1 right, -1 none).
        grip: (2, N, 3) the gripper points.
        next_grasp, last_release: (N, 2) per arm, the object its gripper closes around next, and the one it let
            go of last (-1: none, or a miss comes first).
    """

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    sizes: np.ndarray
    bottom: np.ndarray
    holder: np.ndarray
    grip: np.ndarray
    next_grasp: np.ndarray
    last_release: np.ndarray


def _grip_frames(q: np.ndarray, baxter: Baxter) -> np.ndarray:
    """(2, N, 4, 4) the gripper frames of both arms (a few poses: one by one, fewer steps than in batch)."""
    out = np.zeros((2, q.shape[0], 4, 4))
    for i, arm in enumerate(ARMS):
        Q = q[:, 7 * i : 7 * i + 7]
        if Q.shape[0] <= FEW:
            for k in range(Q.shape[0]):
                out[i, k] = baxter.gripper_transform(arm, Q[k])
            continue
        R, p = baxter.rotations_batch(arm, Q)
        out[i, :, :3, :3], out[i, :, :3, 3], out[i, :, 3, 3] = R, p, 1.0
    return out


def along(t: np.ndarray, q: np.ndarray, run: WorldRun, baxter: Baxter) -> Along:
    """Where the objects are at each sample of a motion (``t`` (N,) on the run's clock, ``q`` (N, 14)), from the
    world's events of that motion (``run``): still between events, a held one carried by its gripper."""
    t = np.asarray(t, dtype=np.float64)
    n = t.shape[0]
    events = sorted(run.events, key=lambda e: e.t)
    first = next((e for e in events if e.kind == "start"), None)
    poses0 = first.poses if first is not None else run.final
    names = tuple(p.name for p in poses0)
    K = len(names)
    G = _grip_frames(q, baxter)
    bottom = np.zeros((K, n, 4, 4))
    holder = np.full((n, K), -1, dtype=np.int8)
    now = {p.name: (_bottom(p), p.held_by) for p in poses0}
    cuts = [(int(np.searchsorted(t, e.t - 1e-9)), e) for e in events if e.kind in ("grasp", "release", "push")]
    bounds = [0, *[c for c, _ in cuts], n]
    for j in range(len(bounds) - 1):
        a, b = bounds[j], bounds[j + 1]
        if j > 0:
            now.update({p.name: (_bottom(p), p.held_by) for p in cuts[j - 1][1].poses if p.name in now})
        for k, name in enumerate(names):
            T, by = now[name]
            if by in ARMS and a < n:
                h = ARMS.index(by)
                bottom[k, a:b] = G[h, a:b] @ (np.linalg.inv(G[h, a]) @ T)
                holder[a:b, k] = h
            else:
                bottom[k, a:b] = T
    nxt = np.full((n, 2), -1, dtype=np.int64)
    last = np.full((n, 2), -1, dtype=np.int64)
    for i, arm in enumerate(ARMS):
        closes = [
            (c, e)
            for c, e in ((int(np.searchsorted(t, e.t - 1e-9)), e) for e in events)
            if e.arm == arm and e.kind in ("grasp", "miss", "release")
        ]
        prev = 0
        for c, e in closes:
            if e.kind in ("grasp", "miss"):
                nxt[prev : c + 1, i] = names.index(e.object) if e.kind == "grasp" and e.object in names else -1
                prev = c + 1
            if e.kind == "release" and e.object in names:
                last[c:, i] = names.index(e.object)
            elif e.kind == "grasp":
                last[c:, i] = -1
    kinds = tuple(p.kind for p in poses0)
    sizes = np.array([p.size for p in poses0], dtype=np.float64).reshape(K, 3)
    return Along(names, kinds, sizes, bottom, holder, G[:, :, :3, 3], nxt, last)


def _bottom(p: ObjectPose) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = matrix_from_quat_wxyz(np.asarray(p.wxyz))
    T[:3, 3] = p.position
    return T


@functools.lru_cache(maxsize=32)
def _pair_facts(model: CollisionModel, names: tuple[str, ...]) -> tuple[np.ndarray, ...]:
    """Per pair of ``model``: the first body's arm (-1: none), whether it is a finger or the hand, the objects (by
    index into ``names``, -1: none) of its first and second body, and whether the second is the table."""
    index = {name: k for k, name in enumerate(names)}
    P = model.pairs.shape[0]
    arm, fingers = np.full(P, -1), np.zeros(P, dtype=bool)
    obj_a, obj_b, table = np.full(P, -1), np.full(P, -1), np.zeros(P, dtype=bool)
    for k, (a, b) in enumerate(model.pairs.tolist()):
        pa, pb = model.parts[a], model.parts[b]
        if pa.robot and pa.arm is not None:
            arm[k] = ARMS.index(pa.arm)
            fingers[k] = pa.part in ("fingers", "hand")
        if not pa.robot:
            obj_a[k] = index.get(pa.part, -1)
        if not pb.robot:
            obj_b[k] = index.get(pb.part, -1)
            table[k] = pb.part == TABLE
    return arm, fingers, obj_a, obj_b, table


class _Rules:
    """Which candidate pairs of a :class:`CollisionModel` may touch, sample by sample (see the module docstring)."""

    def __init__(self, model: CollisionModel, objs: Along, table: Table | None, *, live: bool) -> None:
        self.m, self.o, self.table, self.live = model, objs, table, live
        self.arm, self.fingers, self.obj_a, self.obj_b, self.b_table = _pair_facts(model, objs.names)

    def __call__(self, s: np.ndarray, k: np.ndarray) -> np.ndarray:
        o = self.o
        allow = np.zeros(s.shape[0], dtype=bool)
        arm, ob, oa = self.arm[k], self.obj_b[k], self.obj_a[k]
        # a finger or the hand and an object: held by that gripper, or about to be closed around / just let go of
        fk = np.flatnonzero(self.fingers[k] & (ob >= 0))
        if fk.size:
            ss, aa, kk = s[fk], arm[fk], ob[fk]
            ok = o.holder[ss, kk] == aa
            rest = np.flatnonzero(~ok)
            if rest.size:
                r_s, r_a, r_k = ss[rest], aa[rest], kk[rest]
                # along a motion: the object it closes around next or let go of last (its approach and departure);
                # moved by hand, where the future is unknown: an object the gripper is around
                ok[rest] = self._around(r_s, r_a, r_k) if self.live else self._grasped(r_s, r_a, r_k)
            allow[fk] = ok
        # a carried object: with what it rests on while carried, or what it is being put down on; never checked
        # while it stands still (objects at rest do not move each other)
        ck = np.flatnonzero(oa >= 0)
        if ck.size:
            ss, ka = s[ck], oa[ck]
            still = o.holder[ss, ka] < 0
            both = (ob[ck] >= 0) & (o.holder[ss, np.maximum(ob[ck], 0)] == o.holder[ss, ka])
            allow[ck] = still | both | self._put_down(ss, ka, ob[ck], self.b_table[k[ck]])
        return allow

    def _grasped(self, s: np.ndarray, arm: np.ndarray, k: np.ndarray) -> np.ndarray:
        """Object k is the one the gripper closes around next, or the one it let go of last."""
        return (self.o.next_grasp[s, arm] == k) | (self.o.last_release[s, arm] == k)

    def real(self, near: Near) -> np.ndarray:
        """Which rows of ``near`` are contacts: the robot's parts with each other and with the table within the
        margin; an object (standing, or carried) only where it overlaps (decision 087)."""
        k = near.pair
        soft = (self.obj_b[k] >= 0) | (self.obj_a[k] >= 0)
        return ~soft | (near.distance < 0.0)

    def _around(self, s: np.ndarray, arm: np.ndarray, k: np.ndarray) -> np.ndarray:
        """The gripper point is near object k's axis, between its bottom and a little above its top."""
        o = self.o
        T = o.bottom[k, s]  # (m, 4, 4)
        g = o.grip[arm, s]  # (m, 3)
        d = g - T[:, :3, 3]
        up = T[:, :3, 2]
        along = (d * up).sum(axis=1)
        side = np.linalg.norm(d - along[:, None] * up, axis=1)
        h = o.sizes[k, 2]
        return (side <= AROUND_XY_M) & (along >= -GRASP_BELOW_TOL) & (along <= h + AROUND_ABOVE_M)

    def _put_down(self, s: np.ndarray, ka: np.ndarray, kb: np.ndarray, table: np.ndarray) -> np.ndarray:
        """A carried object k_a over what it is being put down on (the table, or object k_b), its bottom at most
        :data:`SNAP_UP` below where it would come to rest."""
        o = self.o
        base = o.bottom[ka, s, :3, 3]
        out = np.zeros(s.shape[0], dtype=bool)
        if self.table is not None:
            tb = self.table
            over = (np.abs(base[:, 0] - tb.center[0]) <= tb.size[0] / 2) & (
                np.abs(base[:, 1] - tb.center[1]) <= tb.size[1] / 2
            )
            out |= table & over & (base[:, 2] >= tb.top_z - SNAP_UP)
        for m in np.flatnonzero(kb >= 0).tolist():
            b = int(kb[m])
            Tb = o.bottom[b, s[m]]
            d = Tb[:3, :3].T @ (base[m] - Tb[:3, 3])
            w = o.sizes[b]
            if o.kinds[b] == "cup":
                inside = math.hypot(d[0], d[1]) <= w[0] / 2
                level = NEST_STEP if o.kinds[int(ka[m])] == "cup" else w[2]
            else:
                inside = abs(d[0]) <= w[0] / 2 and abs(d[1]) <= w[1] / 2
                level = w[2]
            out[m] = inside and d[2] >= level - SNAP_UP
        return out


def touches(
    t: np.ndarray,
    q: np.ndarray,
    gripper: np.ndarray,
    scene: Scene,
    run: WorldRun,
    baxter: Baxter,
    *,
    new: Collection[str] = (),
) -> list[Touch]:
    """Everything the robot (or what it carries) touches that it must not, along a motion played through ``scene``
    (``run``: its world events): stretches per pair of parts, earliest first. ``new``: objects no demonstration
    had (said so in words)."""
    t = np.asarray(t, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    objs = along(t, q, run, baxter)
    carried = {objs.names[k] for k in range(len(objs.names)) if (objs.holder[:, k] >= 0).any()}
    model = scene_model(scene, list(zip(objs.names, objs.kinds, map(tuple, objs.sizes.tolist()), strict=True)), carried)
    poses = {name: _centres(objs.bottom[k], objs.sizes[k, 2]) for k, name in enumerate(objs.names)}
    rules = _Rules(model, objs, scene.table, live=False)
    near = model.near(q, np.asarray(gripper, dtype=np.float64), poses, skip=rules)
    out = stretches(near.rows(rules.real(near)), model.parts, t)
    return [_with_facts(x, objs, new) for x in out]


def touches_at(
    q: np.ndarray,
    gripper: np.ndarray,
    objects: Sequence[ObjectPose],
    scene: Scene,
    baxter: Baxter,
    *,
    q_now: np.ndarray | None = None,
) -> list[Touch]:
    """What the robot touches at poses ``q`` (N, 14) with grippers (N, 2), the objects where they are now (one held
    by a gripper moves with it: ``q_now`` (14,) is where the arms are now, default ``q[0]``). The fingers may touch
    an object they are around. One stretch per pair of parts over all N poses."""
    near, parts, objs = _live_near(q, gripper, objects, scene, baxter, q_now)
    t = np.arange(objs.holder.shape[0], dtype=np.float64)
    return [_with_facts(x, objs, ()) for x in stretches(near, parts, t, gap_s=math.inf)]


def _live_near(
    q: np.ndarray,
    gripper: np.ndarray,
    objects: Sequence[ObjectPose],
    scene: Scene,
    baxter: Baxter,
    q_now: np.ndarray | None,
) -> tuple[Near, tuple[Part, ...], Along]:
    """The contacts at poses ``q`` with the objects where they are now (see :func:`touches_at`)."""
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    g = np.atleast_2d(np.asarray(gripper, dtype=np.float64))
    if g.shape[0] == 1 and q.shape[0] > 1:
        g = np.repeat(g, q.shape[0], axis=0)
    n = q.shape[0]
    names = tuple(p.name for p in objects)
    G = _grip_frames(q, baxter)
    bottom = np.zeros((len(names), n, 4, 4))
    holder = np.full((n, len(names)), -1, dtype=np.int8)
    now = _grip_frames(np.atleast_2d(q[0] if q_now is None else np.asarray(q_now, dtype=np.float64)), baxter)
    for k, p in enumerate(objects):
        T = _bottom(p)
        if p.held_by in ARMS:
            h = ARMS.index(p.held_by)
            bottom[k] = G[h] @ (np.linalg.inv(now[h, 0]) @ T)
            holder[:, k] = h
        else:
            bottom[k] = T
    sizes = np.array([p.size for p in objects], dtype=np.float64).reshape(len(names), 3)
    none = np.full((n, 2), -1)
    objs = Along(names, tuple(p.kind for p in objects), sizes, bottom, holder, G[:, :, :3, 3], none, none)
    model = scene_model(scene, [(p.name, p.kind, p.size) for p in objects], {p.name for p in objects if p.held_by})
    poses = {name: _centres(bottom[k], sizes[k, 2]) for k, name in enumerate(names)}
    rules = _Rules(model, objs, scene.table, live=True)
    near = model.near(q, g, poses, skip=rules)
    return near.rows(rules.real(near)), model.parts, objs


def first_contact(
    q: np.ndarray,
    gripper: np.ndarray,
    objects: Sequence[ObjectPose],
    scene: Scene,
    baxter: Baxter,
    *,
    q_now: np.ndarray | None = None,
) -> tuple[int, Touch] | None:
    """Along poses ``q`` (N, 14) from where the arms are (``q[0]``): the first sample where something touches that
    did not at ``q[0]``, or touches deeper than there (by 1 mm), and that contact; None when the way is free."""
    near, parts, objs = _live_near(q, gripper, objects, scene, baxter, q_now)
    start: dict[tuple[int, int], float] = {}
    for a, b, s, d in zip(near.a.tolist(), near.b.tolist(), near.sample.tolist(), near.distance.tolist(), strict=True):
        if s == 0:
            start[(a, b)] = min(start.get((a, b), np.inf), d)
    worse = [
        m
        for m, (a, b, s, d) in enumerate(
            zip(near.a.tolist(), near.b.tolist(), near.sample.tolist(), near.distance.tolist(), strict=True)
        )
        if s > 0 and d < start.get((a, b), np.inf) - 0.001
    ]
    if not worse:
        return None
    first = min(worse, key=lambda m: (int(near.sample[m]), float(near.distance[m])))
    s = int(near.sample[first])
    rows = near.rows(np.isin(np.arange(len(near)), worse) & (near.sample == s))
    t = np.arange(objs.holder.shape[0], dtype=np.float64)
    return s, _with_facts(stretches(rows, parts, t)[0], objs, ())


def _centres(bottom: np.ndarray, height: float) -> np.ndarray:
    """(N, 4, 4) centre poses from bottom-centre poses."""
    out = bottom.copy()
    out[:, :3, 3] += out[:, :3, 2] * height / 2
    return out


def _with_facts(x: Touch, objs: Along, new: Collection[str]) -> Touch:
    """The stretch with what its arm carries then and whether the other is a new object."""
    a = x.a
    if not a.robot and a.part in objs.names:  # a carried object: the arm that carries it
        h = int(objs.holder[x.i_start, objs.names.index(a.part)])
        a = replace(a, arm=ARMS[h] if h >= 0 else None)
    carry = None
    if a.arm is not None:
        ks = np.flatnonzero(objs.holder[x.i_start] == ARMS.index(a.arm))
        carry = objs.names[int(ks[0])] if ks.size else None
    return replace(x, a=a, carry=carry, new=(not x.b.robot and x.b.part in new))


__all__ = [
    "TABLE",
    "Along",
    "along",
    "arm_clearance",
    "centre_pose",
    "first_contact",
    "scene_model",
    "touches",
    "touches_at",
]
