"""A scene brought to life by a stream of robot poses (:class:`World`, live and thread-safe), or over a whole
recording at once (:func:`simulate`); the rules it applies are in :mod:`studio.world.rules`."""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from studio.core.errors import InvalidInput
from studio.core.rotations import matrix_from_quat_wxyz
from studio.core.types import ARMS, Arm, check_arm
from studio.world.events import ObjectPose, WorldEvent
from studio.world.geometry import transform
from studio.world.rules import Grip, Objects
from studio.world.scene import Scene

if TYPE_CHECKING:  # pinocchio is loaded only when a world is made (the session store reads scenes without it)
    from studio.core.kinematics import Baxter
    from studio.robot_backend.base import JointStateBatch


@dataclass(frozen=True, eq=False)
class WorldRun:
    """A pose stream played through a scene.

    Attributes:
        events: start, grasps, misses, releases and end, in time order.
        final: every object's pose at the end.
        path_t: (M,) times (s) of the gripper path samples (about every 10 ms).
        path: arm -> (M, 3) gripper points (m) at ``path_t`` (for the task result's wording).
    """

    events: tuple[WorldEvent, ...]
    final: tuple[ObjectPose, ...]
    path_t: np.ndarray
    path: dict[Arm, np.ndarray]


class World:
    """A scene brought to life by a stream of robot poses: grasps, carries and releases its objects.

    Feed it with :meth:`feed` (arrays) or subscribe :meth:`on_batch` to a ``RobotBackend``; read the objects
    with :meth:`poses` (``version`` changes whenever they move) and what happened with :attr:`events`.
    Thread-safe: a backend thread may feed it while the GUI reads it.
    """

    def __init__(
        self,
        scene: Scene | None = None,
        baxter: Baxter | None = None,
        *,
        start: Sequence[ObjectPose] | None = None,
        record_path: bool = False,
        path_rate_hz: float = 100.0,
    ) -> None:
        if baxter is None:
            from studio.core.kinematics import Baxter

            baxter = Baxter.load()
        self.baxter = baxter
        self._lock = threading.RLock()
        self._scene = scene if scene is not None else Scene()
        self._path_rate = float(path_rate_hz) if record_path else 0.0
        self.version = 0
        self.reset(self._scene, start)

    # -- set-up ---------------------------------------------------------------------------------------------
    @property
    def scene(self) -> Scene:
        return self._scene

    def reset(self, scene: Scene | None = None, start: Sequence[ObjectPose] | None = None) -> None:
        """Put every object back where the scene sets it up (or set up a new scene); forget the events.

        ``start``: begin instead from these poses (a demonstration's "start" event, to replay it as it was
        recorded): the objects are the ones listed there, an object held by a gripper is attached to it at
        the first sample fed.
        """
        with self._lock:
            if scene is not None:
                self._scene = scene
            self._objects = Objects(self._scene, start)
            self._grips: dict[Arm, Grip] | None = None
            self._events: list[WorldEvent] = []
            self._last: tuple[float, np.ndarray, np.ndarray] | None = None
            self._path_t: list[np.ndarray] = []
            self._path: dict[Arm, list[np.ndarray]] = {arm: [] for arm in ARMS}
            self._path_bucket = -math.inf
            self.version += 1

    # -- reading --------------------------------------------------------------------------------------------
    def poses(self) -> tuple[ObjectPose, ...]:
        """Every object's current pose, in the scene's order."""
        with self._lock:
            return self._objects.poses()

    @property
    def events(self) -> list[WorldEvent]:
        with self._lock:
            return list(self._events)

    @property
    def last_time(self) -> float | None:
        """Time (s, on the stream's clock) of the last sample fed, or None before the first."""
        with self._lock:
            return None if self._last is None else self._last[0]

    def mark(self) -> int:
        """A bookmark in the event list (e.g. when a recording starts); see :meth:`events_since`."""
        with self._lock:
            return len(self._events)

    def events_since(self, mark: int) -> list[WorldEvent]:
        with self._lock:
            return list(self._events[mark:])

    def held(self, arm: Arm) -> list[str]:
        """Names of the objects ``arm``'s gripper holds (the grasped one first)."""
        check_arm(arm)
        with self._lock:
            return [s.obj.name for s in self._objects.holding(arm)]

    def push(self, pose: ObjectPose, t: float, arm: Arm | None = None) -> WorldEvent:
        """The robot (``arm``) ran into an object at time ``t``: it stands at ``pose`` now (:mod:`.hits`); a "push"
        event records it (never kept in a session)."""
        with self._lock:
            self._objects.push(pose)
            ev = WorldEvent(float(t), "push", arm, pose.name, None, self._objects.poses())
            self._events.append(ev)
            self.version += 1
            return ev

    def snapshot(self, kind: str, t: float | None = None) -> WorldEvent:
        """Record a "start" or "end" event (every object's pose) at time ``t`` (default: the last sample's)."""
        if kind not in ("start", "end"):
            raise InvalidInput('A snapshot is a "start" or an "end".')
        with self._lock:
            if t is None:
                t = self._last[0] if self._last is not None else 0.0
            ev = WorldEvent(float(t), kind, None, None, None, self._objects.poses())
            self._events.append(ev)
            return ev

    # -- feeding --------------------------------------------------------------------------------------------
    def on_batch(self, batch: JointStateBatch) -> None:
        """``RobotBackend.subscribe`` listener: feed a :class:`JointStateBatch`."""
        self.feed(batch.t, batch.q, batch.gripper)

    def feed(self, t: np.ndarray, q: np.ndarray, gripper: np.ndarray) -> list[WorldEvent]:
        """Play samples (n,) times, (n, 14) joints (rad), (n, 2) gripper openings (percent); returns new events.

        Rows with missing values (NaN) are skipped, as the recorder skips them.
        """
        t, q, g = _clean(t, q, gripper)
        if len(t) == 0:
            return []
        with self._lock:
            grips = self._grips if self._grips is not None else self._first_sample(q[0], g[0])
            if self._path_rate > 0:
                self._record_path(t, q)
            new: list[WorldEvent] = []
            for i, arm in enumerate(ARMS):
                new += self._gripper_events(arm, grips[arm], t, q, g[:, i])
            new.sort(key=lambda e: e.t)
            self._events.extend(new)
            self._last = (float(t[-1]), q[-1].copy(), g[-1].copy())
            moved = False
            for arm in ARMS:
                if self._objects.holding(arm):
                    self._objects.carry(arm, self._gripper_T(arm, q[-1]))
                    moved = True
            if moved or new:
                self.version += 1
            return new

    def run(self) -> WorldRun:
        """What happened so far as a :class:`WorldRun` (for :func:`task_result`); the gripper path is there
        only when the world was made with ``record_path=True``."""
        with self._lock:
            if self._path_t:
                path_t = np.concatenate(self._path_t)
                path = {arm: np.concatenate(self._path[arm]) for arm in ARMS}
            else:
                path_t, path = np.zeros(0), {arm: np.zeros((0, 3)) for arm in ARMS}
            return WorldRun(tuple(self._events), self._objects.poses(), path_t, path)

    # -- internals ------------------------------------------------------------------------------------------
    def _first_sample(self, q0: np.ndarray, g0: np.ndarray) -> dict[Arm, Grip]:
        grips = {arm: Grip(float(g0[i])) for i, arm in enumerate(ARMS)}
        for arm in ARMS:  # objects held at the start (a replayed demonstration) follow this gripper
            if self._objects.attach(arm, self._gripper_T(arm, q0)):
                grips[arm].closed = True
        self._grips = grips
        return grips

    def _gripper_events(self, arm: Arm, det: Grip, t: np.ndarray, q: np.ndarray, col: np.ndarray) -> list[WorldEvent]:
        out: list[WorldEvent] = []
        last = 0
        for k, g in enumerate(col.tolist()):
            action = det.step(g)
            if action is None:
                continue
            self._sweep(arm, t[last:k], q[last:k])
            last = k
            T = self._gripper_T(arm, q[k])
            self._objects.carry(arm, T)
            objects = self._objects
            ev = objects.close(arm, float(t[k]), T) if action == "close" else objects.open(arm, float(t[k]), T)
            if ev is not None:
                out.append(ev)
        self._sweep(arm, t[last:], q[last:])
        return out

    def _sweep(self, arm: Arm, t: np.ndarray, q: np.ndarray) -> None:
        """A held cup's way down into another (:meth:`Objects.sweep`), checked about every 10 ms."""
        objs = self._objects
        if len(t) == 0 or not any(s.obj.kind == "cup" for s in objs.holding(arm)):
            return
        if not any(s.obj.kind == "cup" and s.held_by is None and not s.held_out for s in objs.states.values()):
            return  # no cup to go into
        idx = np.flatnonzero(np.diff(np.floor(t / 0.01), prepend=-math.inf) > 0)
        if len(idx) <= 8:  # the live stream's batches: one or two samples (fk_batch pays a set-up per call)
            objs.sweep(arm, [self._gripper_T(arm, q[k]) for k in idx])
            return
        p, wxyz = self.baxter.fk_batch(arm, q[idx, :7] if arm == "left" else q[idx, 7:])
        T = np.tile(np.eye(4), (len(idx), 1, 1))
        T[:, :3, :3] = matrix_from_quat_wxyz(wxyz)
        T[:, :3, 3] = p
        objs.sweep(arm, list(T))

    def _record_path(self, t: np.ndarray, q: np.ndarray) -> None:
        bucket = np.floor(t * self._path_rate)
        prev = np.concatenate([[self._path_bucket], bucket[:-1]])
        idx = np.flatnonzero(bucket > prev)
        if len(idx) == 0:
            return
        self._path_bucket = float(bucket[-1])
        self._path_t.append(t[idx].copy())
        for arm in ARMS:
            self._path[arm].append(self.baxter.fk_batch(arm, q[idx, :7] if arm == "left" else q[idx, 7:])[0])

    def _gripper_T(self, arm: Arm, q14: np.ndarray) -> np.ndarray:
        p, wxyz = self.baxter.fk(arm, q14[:7] if arm == "left" else q14[7:])
        return transform(p, wxyz)


def _clean(t: np.ndarray, q: np.ndarray, gripper: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The samples as float arrays without the rows holding missing values."""
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    q = np.asarray(q, dtype=np.float64).reshape(-1, 14)
    g = np.asarray(gripper, dtype=np.float64).reshape(-1, 2)
    if not (len(t) == len(q) == len(g)):
        raise InvalidInput("Times, joint angles and gripper openings must have the same number of samples.")
    ok = np.isfinite(t) & np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(g), axis=1)
    if not ok.all():
        t, q, g = t[ok], q[ok], g[ok]
    return t, q, g


def simulate(
    t: np.ndarray,
    q: np.ndarray,
    gripper: np.ndarray,
    scene: Scene,
    *,
    baxter: Baxter | None = None,
    start: Sequence[ObjectPose] | None = None,
    path_rate_hz: float = 100.0,
) -> WorldRun:
    """Play a whole pose stream through ``scene``: (N,) times s, (N, 14) joints rad, (N, 2) openings percent.

    Deterministic: the same stream and scene give the same events. Works for any stream (a demonstration,
    the skill preview, a robot execution's joint states). ``start``: begin from these object poses instead
    of the scene's set-up (see :meth:`World.reset`).
    """
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    q = np.asarray(q, dtype=np.float64)
    gripper = np.asarray(gripper, dtype=np.float64)
    if len(t) == 0:
        raise InvalidInput("There is nothing to play: the motion has no samples.")
    if q.shape != (len(t), 14) or gripper.shape != (len(t), 2):
        raise InvalidInput(
            "The motion must have 14 joint angles and 2 gripper openings per sample "
            f"(got {q.shape} and {gripper.shape} for {len(t)} samples)."
        )
    ok = np.isfinite(t) & np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(gripper), axis=1)
    if not ok.any():
        raise InvalidInput("The motion contains only missing or invalid values (NaN).")
    world = World(scene, baxter, start=start, record_path=True, path_rate_hz=path_rate_hz)
    world.snapshot("start", float(t[ok][0]))
    world.feed(t, q, gripper)
    world.snapshot("end", float(t[ok][-1]))
    return world.run()


def trimmed_events(
    events: Sequence[WorldEvent],
    t: np.ndarray,
    q: np.ndarray,
    gripper: np.ndarray,
    scene: Scene,
    t0: float,
    t1: float,
    *,
    baxter: Baxter | None = None,
) -> tuple[WorldEvent, ...]:
    """The object events of a demonstration (``events``, samples ``t``, ``q``, ``gripper``) trimmed to
    ``t0 ≤ t ≤ t1``, times restarting at 0: played again from its recorded start, so the new start is exactly
    the objects at ``t0`` (one then held is attached to the gripper). No events stay no events."""
    start = next((e.poses for e in events if e.kind == "start"), None)
    if start is None:
        return ()
    t = np.asarray(t, dtype=np.float64)
    before = t < t0 - 1e-9
    if before.any():
        start = simulate(t[before], q[before], gripper[before], scene, baxter=baxter, start=start).final
    keep = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    if not keep.any():
        return ()
    tk = t[keep]
    return simulate(tk - tk[0], q[keep], gripper[keep], scene, baxter=baxter, start=start).events
