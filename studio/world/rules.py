"""The grasp, carry and release rules, object by object (what a :class:`~studio.world.simulation.World` applies).

Deterministic, no physics: the gripper *closes* when its opening falls :data:`SWING` percent below its last
maximum and *opens* when it rises as much above its last minimum; closing with the gripper point near a cup's
or block's axis and height grasps it (with what rests on it), elsewhere *misses*; opening lets it down,
upright, onto the highest surface under its centre (:func:`~studio.world.geometry.landing`). A cup goes into
another only through its opening (:meth:`Objects.sweep`)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from studio.core.rotations import matrix_from_quat_wxyz, quat_wxyz_from_matrix
from studio.core.types import Arm
from studio.world.events import ObjectPose, WorldEvent
from studio.world.geometry import (
    GRASP_ABOVE_TOL,
    GRASP_BELOW_TOL,
    GRASP_XY_TOL,
    GRASPABLE,
    SWING,
    landing,
    transform,
    yaw_of,
    yaw_quat,
)
from studio.world.scene import Scene, WorldObject


class Grip:
    """One gripper's close/open detector with hysteresis (:data:`SWING`)."""

    __slots__ = ("closed", "extreme")

    def __init__(self, opening: float) -> None:
        self.closed = False
        self.extreme = float(opening)

    def step(self, g: float) -> str | None:
        """Feed one opening (percent); returns "close" or "open" when the gripper just did so, else None."""
        if self.closed:
            if g < self.extreme:
                self.extreme = g
            elif g > self.extreme + SWING:
                self.closed, self.extreme = False, g
                return "open"
        else:
            if g > self.extreme:
                self.extreme = g
            elif g < self.extreme - SWING:
                self.closed, self.extreme = True, g
                return "close"
        return None


def gripper_actions(gripper: np.ndarray) -> list[tuple[int, str]]:
    """(sample index, "close" or "open") of every close and open of one gripper's openings (N,) percent, with
    the same hysteresis as the world (for drawing where a demonstration's gripper closed and opened)."""
    g = np.asarray(gripper, dtype=np.float64).reshape(-1)
    ok = np.flatnonzero(np.isfinite(g))
    if len(ok) == 0:
        return []
    det = Grip(float(g[ok[0]]))
    out = []
    for k in ok.tolist():
        action = det.step(float(g[k]))
        if action is not None:
            out.append((k, action))
    return out


class _State:
    """An object's current state: world transform of its bottom centre, holder, support."""

    __slots__ = ("T", "held_by", "held_out", "inside", "obj", "on", "rel", "walls", "was_on")

    def __init__(self, obj: WorldObject) -> None:
        self.obj = obj
        self.T = transform(obj.position, yaw_quat(obj.yaw))
        self.held_by: str | None = None
        self.held_out = obj.held_out
        self.on: str | None = "hand" if obj.held_out else None
        self.rel: np.ndarray | None = None  # transform in the gripper frame while held
        self.was_on: str | None = None  # what it rested on when it was picked up (carried along on it)
        self.inside: set[str] = set()  # cups this held cup went into through their opening
        self.walls: set[str] = set()  # cups whose wall this held cup went through

    def pose(self) -> ObjectPose:
        o = self.obj
        wxyz = quat_wxyz_from_matrix(self.T[:3, :3])
        return ObjectPose(
            o.name,
            o.kind,
            o.size,
            (float(self.T[0, 3]), float(self.T[1, 3]), float(self.T[2, 3])),
            (float(wxyz[0]), float(wxyz[1]), float(wxyz[2]), float(wxyz[3])),
            self.held_by,
            self.on,
        )


class Objects:
    """The objects' states and the grasp, carry and release rules (the :class:`World` holds the lock)."""

    def __init__(self, scene: Scene, start: Sequence[ObjectPose] | None) -> None:
        self.table = scene.table
        if start is None:
            objects = list(scene.settled().objects)  # one left in the air, or beyond the table's edge, falls
        else:
            objects = [WorldObject(p.name, p.kind, p.size, p.position, p.yaw, held_out=p.on == "hand") for p in start]
        self.states: dict[str, _State] = {o.name: _State(o) for o in objects}
        if start is None:
            for o in objects:  # resting objects know what they rest on
                if o.held_out:
                    continue
                others = [(x.obj, x.obj.yaw) for n, x in self.states.items() if n != o.name and not x.held_out]
                level, on = landing(o.kind, o.position[0], o.position[1], o.position[2], self.table, others)
                self.states[o.name].on = on if abs(level - o.position[2]) < 1e-6 else None
        else:
            for p in start:
                st = self.states[p.name]
                st.T = transform(p.position, p.wxyz)
                st.held_by, st.on = p.held_by, p.on  # a held one is attached at the first sample

    def poses(self) -> tuple[ObjectPose, ...]:
        return tuple(s.pose() for s in self.states.values())

    def holding(self, arm: Arm) -> list[_State]:
        return [s for s in self.states.values() if s.held_by == arm]

    def attach(self, arm: Arm, T_grip: np.ndarray) -> bool:
        """Objects held by ``arm`` at the start (a replayed demonstration) follow its gripper from now on."""
        held = [s for s in self.holding(arm) if s.rel is None]
        inv = np.linalg.inv(T_grip)
        for s in held:
            s.rel = inv @ s.T
        return bool(held)

    def carry(self, arm: Arm, T_grip: np.ndarray) -> None:
        for s in self.holding(arm):
            if s.rel is not None:
                s.T = T_grip @ s.rel

    def close(self, arm: Arm, t: float, T_grip: np.ndarray) -> WorldEvent:
        """The gripper closed: grasp the graspable object around its point (from a stack, the top one)."""
        p = T_grip[:3, 3]
        best: _State | None = None
        for s in self.states.values():
            o = s.obj
            if o.kind not in GRASPABLE or s.held_by is not None:
                continue
            base = s.T[:3, 3]
            if math.hypot(p[0] - base[0], p[1] - base[1]) > GRASP_XY_TOL:
                continue
            if not (base[2] - GRASP_BELOW_TOL <= p[2] <= base[2] + o.size[2] + GRASP_ABOVE_TOL):
                continue
            if best is None or base[2] > best.T[2, 3]:
                best = s
        gp = (float(p[0]), float(p[1]), float(p[2]))
        if best is None:
            return WorldEvent(t, "miss", arm, None, gp, self.poses())
        inv = np.linalg.inv(T_grip)
        for s in [best, *self._resting_on(best.obj.name)]:
            s.held_by, s.held_out, s.was_on, s.on = arm, False, s.on, None
            s.rel = inv @ s.T
            s.inside, s.walls = ({s.was_on} if s.was_on else set()), set()
        return WorldEvent(t, "grasp", arm, best.obj.name, gp, self.poses())

    def _resting_on(self, name: str) -> list[_State]:
        """The objects resting on ``name``, directly or through others."""
        out: list[_State] = []
        frontier = [name]
        while frontier:
            n = frontier.pop()
            for s in self.states.values():
                if s.on == n and s.held_by is None and s not in out:
                    out.append(s)
                    frontier.append(s.obj.name)
        return out

    def push(self, pose: ObjectPose) -> None:
        """The robot ran into an object standing on its own: it is now at ``pose`` (slid, or knocked over), on
        whatever is under it (off the table it falls to the floor)."""
        s = self.states[pose.name]
        upright = abs(matrix_from_quat_wxyz(np.asarray(pose.wxyz))[2, 2]) > 0.9
        x, y, z = pose.position
        others = [(p, p.yaw) for p in (o.pose() for o in self.states.values() if o is not s and not o.held_out)]
        level, on = landing(s.obj.kind, x, y, z, self.table, others)
        if upright:
            z = level
        s.T = transform((x, y, z), pose.wxyz)
        s.on, s.held_out = on, False

    def open(self, arm: Arm, t: float, T_grip: np.ndarray) -> WorldEvent | None:
        """The gripper opened: what it holds drops straight down, upright, onto the highest surface below."""
        held = self.holding(arm)
        if not held:
            return None  # an open gripper holding nothing changes nothing
        # The grasped object is the lowest of what the gripper carries (the others rest on it).
        main = min(held, key=lambda s: s.T[2, 3])
        free = [s for s in self.states.values() if s.held_by is None and not s.held_out]
        others = [(p, p.yaw) for p in (s.pose() for s in free)]
        base = main.T[:3, 3].copy()
        yaw = yaw_of(main.T[:3, :3])
        if main.obj.kind == "cup":
            self._check_walls(main, free, [main.T])  # let go above a cup: the opening as it falls in
            base[:2] = self._beside_walls(main, free, base)
        level, on = landing(main.obj.kind, base[0], base[1], base[2], self.table, others)
        upright = transform((base[0], base[1], level), yaw_quat(yaw))
        inv_old = np.linalg.inv(main.T)
        for s in held:
            if s is main:
                s.T, s.on = upright, on
            else:  # keeps its place on what it was carried on, upright
                T = upright @ (inv_old @ s.T)
                s.T = transform(T[:3, 3], yaw_quat(yaw_of(T[:3, :3])))
                s.on = s.was_on
            s.held_by, s.rel = None, None
            s.inside, s.walls = set(), set()
        p = T_grip[:3, 3]
        return WorldEvent(t, "release", arm, main.obj.name, (float(p[0]), float(p[1]), float(p[2])), self.poses())

    # -- cups have walls -------------------------------------------------------------------------------------
    def sweep(self, arm: Arm, T_grips: Sequence[np.ndarray]) -> None:
        """The gripper of ``arm`` passed through the poses ``T_grips`` (in order): a cup it holds whose bottom goes
        down past another cup's rim goes in through the opening (its bottom's centre within the rim) or, coming
        in from the side, meets the wall (a slanted insertion through the wall); lifted above the rim, it is
        out again (decision 086)."""
        cups = [s for s in self.holding(arm) if s.obj.kind == "cup" and s.rel is not None]
        if not cups:
            return
        free = [s for s in self.states.values() if s.held_by is None and not s.held_out and s.obj.kind == "cup"]
        if not free:
            return
        for s in cups:
            rel = s.rel
            assert rel is not None
            self._check_walls(s, free, [T @ rel for T in T_grips])

    @staticmethod
    def _check_walls(cup: _State, free: Sequence[_State], poses: Sequence[np.ndarray]) -> None:
        r = cup.obj.size[0] / 2
        for T in poses:
            b = T[:3, 3]
            for o in free:
                if o.obj.kind != "cup" or o is cup:
                    continue
                ob = o.T[:3, 3]
                rim = ob[2] + o.obj.size[2]
                name = o.obj.name
                if b[2] >= rim or b[2] < ob[2] - GRASP_BELOW_TOL:
                    cup.inside.discard(name)
                    cup.walls.discard(name)
                    continue
                d = math.hypot(b[0] - ob[0], b[1] - ob[1])
                if name in cup.inside or name in cup.walls or d >= r + o.obj.size[0] / 2:
                    continue
                (cup.inside if d <= o.obj.size[0] / 2 else cup.walls).add(name)

    @staticmethod
    def _beside_walls(cup: _State, free: Sequence[_State], base: np.ndarray) -> np.ndarray:
        """Where a let-go cup comes down across the table: beside each cup whose wall it met, else where it is."""
        xy = np.array(base[:2], dtype=np.float64)
        r = cup.obj.size[0] / 2
        for o in free:
            if o is cup or o.obj.kind != "cup" or o.obj.name in cup.inside:
                continue
            ob = o.T[:3, 3]
            v = xy - ob[:2]
            d = float(np.hypot(*v))
            reach = r + o.obj.size[0] / 2
            if o.obj.name not in cup.walls or d >= reach:
                continue
            u = v / d if d > 1e-9 else np.array([1.0, 0.0])
            xy = ob[:2] + u * (reach + 0.002)
        return xy
