"""Frozen data types shared by every stage of the pipeline.

Arrays stored in these types are made read-only on construction so that no panel or stage can mutate a
demonstration by accident (the pattern pink uses for its configurations).
"""

from __future__ import annotations

import functools
import math
import numbers
from dataclasses import dataclass, fields
from enum import StrEnum
from typing import Literal, TypeGuard

import numpy as np

from studio.core.errors import InvalidInput
from studio.core.frames import ObjectFrames

#: One of Baxter's arms.
Arm = Literal["left", "right"]
ARMS: tuple[Arm, Arm] = ("left", "right")
JOINT_SUFFIXES: tuple[str, ...] = ("s0", "s1", "e0", "e1", "w0", "w1", "w2")
ARM_JOINTS: dict[Arm, tuple[str, ...]] = {arm: tuple(f"{arm}_{s}" for s in JOINT_SUFFIXES) for arm in ARMS}
#: The 14 arm joints in the order the backend streams them (and the Baxter SDK CSV lists them).
ALL_ARM_JOINTS: tuple[str, ...] = ARM_JOINTS["left"] + ARM_JOINTS["right"]


class Generalization(StrEnum):
    """How training makes one path of the learned states (see :mod:`studio.core.pipeline`); here so that storage
    can check a saved choice without importing the pipeline."""

    #: The demonstrations averaged along their alignment to the reference (the default).
    ALIGNED_MEAN = "aligned-mean"
    #: The paper's spline through the timed states (the reference).
    PAPER = "paper"

    @classmethod
    def of(cls, name: str) -> Generalization:
        """The mode called ``name``; an unknown one raises :class:`InvalidInput` in plain words."""
        try:
            return cls(name)
        except ValueError:
            raise InvalidInput(f'Unknown way to generalise "{name}".') from None


GENERALIZATIONS: tuple[Generalization, ...] = tuple(Generalization)
DEFAULT_GENERALIZATION = Generalization.ALIGNED_MEAN
#: Where a skill keeps its path (see :mod:`studio.core.segments`): "objects" (each stretch in the frame of the
#: object it acts on; the default) or "robot" (the paper's: one path in the robot's frame).
FRAMES: tuple[str, str] = ("objects", "robot")
DEFAULT_FRAMES = "objects"


def readonly(a: np.ndarray | list | tuple, dtype: type = np.float64) -> np.ndarray:
    """Return a C-contiguous read-only copy of ``a`` (a view is not enough: the caller keeps ``a``)."""
    out: np.ndarray = np.array(a, dtype=dtype, copy=True, order="C")
    out.setflags(write=False)
    return out


def is_arm(name: object) -> TypeGuard[Arm]:
    """Whether ``name`` is "left" or "right"."""
    return name in ARMS


def check_arm(arm: str) -> Arm:
    """Return ``arm`` if it is "left" or "right", else raise :class:`InvalidInput`."""
    if not is_arm(arm):
        raise InvalidInput(f'Unknown arm "{arm}": choose "left" or "right".')
    return arm


def _check_finite(name: str, a: np.ndarray) -> None:
    if not np.all(np.isfinite(a)):
        bad = int(np.count_nonzero(~np.isfinite(a)))
        raise InvalidInput(
            f"The {name} contains {bad} missing or invalid values (NaN or infinity); "
            "record the demonstration again or trim the damaged part."
        )


@dataclass(frozen=True, eq=False)
class Demo:
    """One arm's demonstration as the paper's 8-D pose series.

    Attributes:
        t: (N,) sample times in seconds, strictly increasing.
        position: (N, 3) gripper position in metres (robot base frame).
        orientation: (N, 4) unit quaternion w, x, y, z of the gripper frame, sign-continuous.
        gripper: (N,) opening in percent, 0 = closed .. 100 = open.
        q: optional (N, 7) joint angles in radians that produced the pose (used to seed IK).
        name: a label for messages and panels.
    """

    t: np.ndarray
    position: np.ndarray
    orientation: np.ndarray
    gripper: np.ndarray
    q: np.ndarray | None = None
    name: str = "demonstration"

    def __post_init__(self) -> None:
        t = readonly(self.t)
        pos = readonly(self.position)
        ori = readonly(self.orientation)
        grip = readonly(self.gripper)
        n = t.shape[0] if t.ndim == 1 else -1
        if t.ndim != 1:
            raise InvalidInput(f"{self.name}: the time stamps must be a list of numbers (got shape {t.shape}).")
        if pos.shape != (n, 3) or ori.shape != (n, 4) or grip.shape != (n,):
            raise InvalidInput(
                f"{self.name}: time, position, orientation and gripper must have the same number of samples "
                f"(got {n}, {pos.shape[0] if pos.ndim else 0}, {ori.shape[0] if ori.ndim else 0}, "
                f"{grip.shape[0] if grip.ndim else 0})."
            )
        for nm, a in (("time stamps", t), ("positions", pos), ("orientations", ori), ("gripper values", grip)):
            _check_finite(f"{self.name} {nm}", a)
        if n >= 2 and np.any(np.diff(t) <= 0):
            raise InvalidInput(f"{self.name}: the time stamps must increase from sample to sample.")
        norms = np.linalg.norm(ori, axis=1)
        if n and np.any(np.abs(norms - 1.0) > 1e-3):
            raise InvalidInput(f"{self.name}: the orientations must be unit quaternions (w, x, y, z).")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "position", pos)
        object.__setattr__(self, "orientation", ori)
        object.__setattr__(self, "gripper", grip)
        if self.q is not None:
            q = readonly(self.q)
            if q.shape != (n, 7):
                raise InvalidInput(f"{self.name}: joint angles must have shape ({n}, 7), got {q.shape}.")
            _check_finite(f"{self.name} joint angles", q)
            object.__setattr__(self, "q", q)

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def duration(self) -> float:
        """Length of the demonstration in seconds."""
        return float(self.t[-1] - self.t[0]) if len(self) else 0.0

    @functools.cached_property
    def extent(self) -> float:
        """The largest side of the positions' bounding box, m (0 when empty); computed once (the arrays are
        read-only), since every slider step of the studio asks for it."""
        return float(np.max(np.ptp(self.position, axis=0))) if len(self) else 0.0

    @property
    def features(self) -> np.ndarray:
        """(N, 8) array x, y, z, qw, qx, qy, qz, gripper: the paper's 8-D observation vector."""
        return np.column_stack([self.position, self.orientation, self.gripper])


@dataclass(frozen=True)
class Recording:
    """A raw demonstration as the robot streamed it: both arms' joints and grippers at 1 kHz.

    Attributes:
        t: (N,) seconds since the start of the recording.
        q: (N, 14) joint angles in radians, order :data:`ALL_ARM_JOINTS` (left s0..w2, right s0..w2).
        gripper: (N, 2) opening percent 0..100, columns left, right.
        arms: the arms the teacher taught in this demonstration ("left", "right" or both).
        name: the demonstration's name shown in the demo list.
    """

    t: np.ndarray
    q: np.ndarray
    gripper: np.ndarray
    arms: tuple[Arm, ...] = ("left",)
    name: str = "demo"

    def __post_init__(self) -> None:
        t, q, g = readonly(self.t), readonly(self.q), readonly(self.gripper)
        n = t.shape[0] if t.ndim == 1 else -1
        if t.ndim != 1 or q.shape != (n, 14) or g.shape != (n, 2):
            raise InvalidInput(
                f"{self.name}: expected times (N,), joints (N, 14) and grippers (N, 2); "
                f"got {t.shape}, {q.shape}, {g.shape}."
            )
        for nm, a in (("time stamps", t), ("joint angles", q), ("gripper values", g)):
            _check_finite(f"{self.name} {nm}", a)
        if n >= 2 and np.any(np.diff(t) <= 0):
            raise InvalidInput(f"{self.name}: the time stamps must increase from sample to sample.")
        arms = tuple(self.arms)
        if not arms or any(a not in ARMS for a in arms):
            raise InvalidInput(f'{self.name}: taught arms must be "left", "right" or both, got {arms}.')
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "gripper", g)
        object.__setattr__(self, "arms", arms)

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self) else 0.0

    def arm_q(self, arm: Arm) -> np.ndarray:
        """(N, 7) joint angles of one arm."""
        return self.q[:, :7] if check_arm(arm) == "left" else self.q[:, 7:]

    def arm_gripper(self, arm: Arm) -> np.ndarray:
        """(N,) gripper opening of one arm, percent."""
        return self.gripper[:, 0] if check_arm(arm) == "left" else self.gripper[:, 1]


_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class KeypointParams:
    """The paper's fourteen key-point thresholds (§ Key-point Extraction, Eqs. for P and O).

    Speeds are per second and durations in seconds so the defaults hold at any sampling rate (the paper
    counts samples at 1 kHz). Position thresholds ε1–ε7, orientation thresholds ε8–ε14 (orientation
    distances are rotation angles in radians, so q and −q are the same orientation).

    Attributes:
        eps1: corner test, rad in [π, 2π]: a sample is a corner if the angle at it between the directions
            to its neighbours is below 2π − ε1 (straight line = π). Higher keeps only sharper corners.
        eps2: pause test, speed below which the arm counts as still, m/s.
        eps3: pause test, the stillness must come this long after the last key-point, s.
        eps4: pause test, and this far from the last key-point, m.
        eps5: distance test, radius of the ball around the last key-point whose exit is a key-point, m.
        eps6: distance test, minimum time since the last key-point, s.
        eps7: distance test, all samples since the last key-point stayed within this radius, m.
        eps8..eps14: the same seven thresholds for orientation (rad, rad/s, s, rad, rad, s, rad).
    """

    eps1: float = _TWO_PI - 2.2
    eps2: float = 0.01
    eps3: float = 0.5
    eps4: float = 0.02
    eps5: float = 0.14
    eps6: float = 0.5
    eps7: float = 0.14
    eps8: float = _TWO_PI - 2.2
    eps9: float = 0.02
    eps10: float = 0.5
    eps11: float = 0.1
    eps12: float = 0.6
    eps13: float = 0.5
    eps14: float = 0.6

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(float(v)):
                raise InvalidInput(f"Threshold {f.name} must be a number, got {v!r}.")
            v = float(v)  # numpy scalars from a slider or a file become plain floats (JSON, hashing)
            object.__setattr__(self, f.name, v)
            if f.name in ("eps1", "eps8"):
                if not (math.pi <= v <= _TWO_PI):
                    raise InvalidInput(f"Corner sharpness ({f.name}) must lie between π and 2π (got {v:.3f}).")
            elif v < 0:
                raise InvalidInput(f"Threshold {f.name} cannot be negative (got {v}).")

    def as_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: dict[str, float]) -> KeypointParams:
        names = {f.name for f in fields(cls)}
        unknown = set(d) - names
        if unknown:
            raise InvalidInput(f"Unknown key-point thresholds: {', '.join(sorted(unknown))}.")
        return cls(**{k: float(v) for k, v in d.items()})


@dataclass(frozen=True, eq=False)
class JointTrajectory:
    """The learned skill in joint space, ready to execute or export.

    Attributes:
        t: (M,) seconds.
        q: (M, 7) joint angles of ``arm``, radians, within the URDF position and velocity limits.
        position_error: (M,) distance between the forward kinematics of ``q`` and the Cartesian skill, m.
        orientation_error: (M,) rotation angle between them, rad.
        converged: (M,) True where the errors are below 1 mm and 0.01 rad.
        arm: "left" or "right".
        gripper: (M,) opening percent to command alongside.
        skill_time: (M,) the time on the Cartesian skill's own time line that each sample executes (the
            timing may run slower than taught where the robot's limits require it); None for old files.
    """

    t: np.ndarray
    q: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    converged: np.ndarray
    arm: Arm
    gripper: np.ndarray | None = None
    skill_time: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = readonly(self.t)
        m = t.shape[0]
        object.__setattr__(self, "t", t)
        for name, shape in (("q", (m, 7)), ("position_error", (m,)), ("orientation_error", (m,))):
            a = readonly(getattr(self, name))
            if a.shape != shape:
                raise InvalidInput(f"Joint trajectory {name} must have shape {shape}, got {a.shape}.")
            object.__setattr__(self, name, a)
        c = readonly(self.converged, dtype=bool)
        if c.shape != (m,):
            raise InvalidInput(f"Joint trajectory converged flags must have shape ({m},), got {c.shape}.")
        object.__setattr__(self, "converged", c)
        if self.gripper is not None:
            g = readonly(self.gripper)
            if g.shape != (m,):
                raise InvalidInput(f"Joint trajectory gripper must have shape ({m},), got {g.shape}.")
            _check_finite("joint trajectory gripper values", g)
            object.__setattr__(self, "gripper", g)
        if self.skill_time is not None:
            st = readonly(self.skill_time)
            if st.shape != (m,):
                raise InvalidInput(f"Joint trajectory skill times must have shape ({m},), got {st.shape}.")
            _check_finite("joint trajectory skill times", st)
            object.__setattr__(self, "skill_time", st)
        # A joint trajectory goes to a robot: no NaN joint and no time running backwards, even from a file.
        _check_finite("joint trajectory time stamps", t)
        _check_finite("joint trajectory joint angles", self.q)
        if m >= 2 and np.any(np.diff(t) <= 0):
            raise InvalidInput("The joint trajectory's time stamps must increase from sample to sample.")
        check_arm(self.arm)

    def __len__(self) -> int:
        return int(self.t.shape[0])


def _pack_list(d: dict[str, np.ndarray], name: str, arrays: list[np.ndarray], dtype: type) -> None:
    d[f"{name}_data"] = (
        np.concatenate([np.asarray(a, dtype=dtype).reshape(-1) for a in arrays])
        if arrays
        else (np.zeros(0, dtype=dtype))
    )
    d[f"{name}_offsets"] = np.cumsum([0] + [len(a) for a in arrays]).astype(np.int64)


def _unpack_list(d: dict[str, np.ndarray], name: str, dtype: type) -> list[np.ndarray]:
    data: np.ndarray = np.asarray(d[f"{name}_data"], dtype=dtype)
    off: np.ndarray = np.asarray(d[f"{name}_offsets"], dtype=np.int64)
    if off.ndim != 1 or off.size == 0 or off[0] != 0 or off[-1] != data.size or np.any(np.diff(off) < 0):
        raise InvalidInput(f"The saved skill's {name.replace('_', ' ')} list is damaged.")
    return [readonly(data[off[i] : off[i + 1]], dtype=dtype) for i in range(len(off) - 1)]


@dataclass(frozen=True)
class SkillRoute:
    """One way the demonstrations went, as a skill remembers it.

    Attributes:
        demos: the names of the demonstrations that went this way.
        at: (3,) m, their mean where the ways are farthest apart.
    """

    demos: tuple[str, ...]
    at: tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class Skill:
    """A learned skill: the generalized trajectory plus everything the panels draw.

    Attributes:
        trajectory: the generalized trajectory (a :class:`Demo` at the demos' rate, no joint angles).
        keypoints: one sorted index array per input demo.
        labels: the cluster (codebook symbol) of each key-point, one array per demo.
        centroids: (k, 8) x, y, z, qw, qx, qy, qz, gripper, ordered by mean normalised time.
        centroid_times: (k,) each cluster's time on the reference time line (mean DTW-aligned time of its
            members), seconds.
        states: the reference demo's Viterbi state sequence (one state per key-point).
        paths: every demo's Viterbi state sequence.
        reference: index of the demo with the highest forward-algorithm likelihood.
        zero_points: states absent from ``states`` (dropped from the trajectory).
        startprob, transmat, emissionprob: the trained HMM λ = {π, A, B}.
        loglik: (D,) log-likelihood of each demo under the trained model.
        path_times, path_points, path_states: the timed 8-D points the spline went through, and their states.
        joint_trajectory: IK of the trajectory for ``arm`` (None when no arm was given).
        arm: the arm the skill was learned for, or None.
        params: the key-point thresholds used.
        spline_through: "state-means" or "centroids" (the points paper mode's spline goes through).
        demo_names: names of the input demos.
        generalization: how the trajectory was made: "paper" (the spline through the timed states) or
            "aligned-mean" (the demos averaged along their DTW alignment to the reference); skills saved before the
            mode existed were paper mode.
        frames: for a skill that follows the objects (:mod:`studio.core.segments`), its segments in their
            objects' frames and the places the demonstrations covered; then ``trajectory``, ``joint_trajectory``,
            ``centroids`` and ``path_points`` are placed where the objects were when it was placed last. None: the
            path is in the robot's frame (the paper's way).
        routes: the ways the demonstrations went when they went more than one way (else empty); the skill is
            learned from the demonstrations of ``routes[route]`` only (``demo_names``).
        route: which of ``routes`` was learned; route_where: (3,) m, all demos' mean where the ways part most.
    """

    trajectory: Demo
    keypoints: list[np.ndarray]
    labels: list[np.ndarray]
    centroids: np.ndarray
    centroid_times: np.ndarray
    states: np.ndarray
    paths: list[np.ndarray]
    reference: int
    zero_points: np.ndarray
    startprob: np.ndarray
    transmat: np.ndarray
    emissionprob: np.ndarray
    loglik: np.ndarray
    path_times: np.ndarray
    path_points: np.ndarray
    path_states: np.ndarray
    joint_trajectory: JointTrajectory | None = None
    arm: Arm | None = None
    params: KeypointParams = KeypointParams()
    spline_through: str = "state-means"
    demo_names: tuple[str, ...] = ()
    generalization: Generalization = Generalization.PAPER
    frames: ObjectFrames | None = None
    routes: tuple[SkillRoute, ...] = ()
    route: int = 0
    route_where: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in (
            "centroids",
            "centroid_times",
            "startprob",
            "transmat",
            "emissionprob",
            "loglik",
            "path_times",
            "path_points",
        ):
            object.__setattr__(self, name, readonly(getattr(self, name)))
        for name in ("states", "zero_points", "path_states"):
            object.__setattr__(self, name, readonly(getattr(self, name), dtype=np.int64))
        for name in ("keypoints", "labels", "paths"):
            object.__setattr__(self, name, [readonly(a, dtype=np.int64) for a in getattr(self, name)])
        object.__setattr__(self, "demo_names", tuple(self.demo_names))

    @property
    def n_clusters(self) -> int:
        return int(self.centroids.shape[0])

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Everything as plain numeric/string arrays (``np.savez`` without pickle); see :meth:`from_arrays`."""
        tr = self.trajectory
        d: dict[str, np.ndarray] = {
            "format": np.array("teaching-studio-skill/1"),
            "trajectory_t": tr.t,
            "trajectory_position": tr.position,
            "trajectory_orientation": tr.orientation,
            "trajectory_gripper": tr.gripper,
            "trajectory_name": np.array(tr.name),
            "centroids": self.centroids,
            "centroid_times": self.centroid_times,
            "states": self.states,
            "reference": np.array(self.reference, dtype=np.int64),
            "zero_points": self.zero_points,
            "startprob": self.startprob,
            "transmat": self.transmat,
            "emissionprob": self.emissionprob,
            "loglik": self.loglik,
            "path_times": self.path_times,
            "path_points": self.path_points,
            "path_states": self.path_states,
            "arm": np.array(self.arm or ""),
            "params": np.array([getattr(self.params, f.name) for f in fields(KeypointParams)]),
            "spline_through": np.array(self.spline_through),
            "demo_names": np.array(list(self.demo_names), dtype=str),
            "generalization": np.array(self.generalization),
            "route": np.array(self.route, dtype=np.int64),
            "route_names": np.array([n for r in self.routes for n in r.demos], dtype=str),
            "route_sizes": np.array([len(r.demos) for r in self.routes], dtype=np.int64),
            "route_at": np.array([r.at for r in self.routes], dtype=np.float64).reshape(-1, 3),
            "route_where": np.array(self.route_where, dtype=np.float64),
        }
        if self.frames is not None:
            d.update(self.frames.to_arrays())
        _pack_list(d, "keypoints", self.keypoints, np.int64)
        _pack_list(d, "labels", self.labels, np.int64)
        _pack_list(d, "paths", self.paths, np.int64)
        jt = self.joint_trajectory
        if jt is not None:
            d["joint_t"] = jt.t
            d["joint_q"] = jt.q
            d["joint_position_error"] = jt.position_error
            d["joint_orientation_error"] = jt.orientation_error
            d["joint_converged"] = jt.converged
            d["joint_arm"] = np.array(jt.arm)
            if jt.gripper is not None:
                d["joint_gripper"] = jt.gripper
            if jt.skill_time is not None:
                d["joint_skill_time"] = jt.skill_time
        return d

    @classmethod
    def from_arrays(cls, d: dict[str, np.ndarray]) -> Skill:
        """Rebuild a skill saved with :meth:`to_arrays` (raises :class:`InvalidInput` if keys are missing)."""
        try:
            if str(d["format"]) != "teaching-studio-skill/1":
                raise InvalidInput(f"Unknown skill format {str(d['format'])!r}.")
            traj = Demo(
                d["trajectory_t"],
                d["trajectory_position"],
                d["trajectory_orientation"],
                d["trajectory_gripper"],
                name=str(d["trajectory_name"]),
            )
            jt = None
            if "joint_t" in d:
                jt = JointTrajectory(
                    d["joint_t"],
                    d["joint_q"],
                    d["joint_position_error"],
                    d["joint_orientation_error"],
                    d["joint_converged"],
                    check_arm(str(d["joint_arm"])),
                    d["joint_gripper"] if "joint_gripper" in d else None,
                    d["joint_skill_time"] if "joint_skill_time" in d else None,
                )
            names = [f.name for f in fields(KeypointParams)]
            params = KeypointParams(**{n: float(v) for n, v in zip(names, np.asarray(d["params"]), strict=True)})
            name = str(d["arm"])
            arm = name if is_arm(name) else None
            return cls(
                trajectory=traj,
                keypoints=_unpack_list(d, "keypoints", np.int64),
                labels=_unpack_list(d, "labels", np.int64),
                centroids=d["centroids"],
                centroid_times=d["centroid_times"],
                states=d["states"],
                paths=_unpack_list(d, "paths", np.int64),
                reference=int(d["reference"]),
                zero_points=d["zero_points"],
                startprob=d["startprob"],
                transmat=d["transmat"],
                emissionprob=d["emissionprob"],
                loglik=d["loglik"],
                path_times=d["path_times"],
                path_points=d["path_points"],
                path_states=d["path_states"],
                joint_trajectory=jt,
                arm=arm,
                params=params,
                spline_through=str(d["spline_through"]),
                demo_names=tuple(str(x) for x in np.asarray(d["demo_names"]).reshape(-1)),
                generalization=Generalization.of(str(d.get("generalization", Generalization.PAPER))),
                frames=ObjectFrames.from_arrays(d),
                **_routes_from_arrays(d),
            )
        except KeyError as exc:
            raise InvalidInput(f"The saved skill is incomplete: {exc.args[0]} is missing.") from exc


def _routes_from_arrays(d: dict[str, np.ndarray]) -> dict:
    """The routes of a saved skill (none in files from before routes were found)."""
    if "route_sizes" not in d:
        return {}
    names = [str(x) for x in np.asarray(d["route_names"]).reshape(-1)]
    sizes = np.asarray(d["route_sizes"], dtype=np.int64).reshape(-1)
    at = np.asarray(d["route_at"], dtype=np.float64).reshape(-1, 3)
    where = np.asarray(d["route_where"], dtype=np.float64).reshape(-1)
    if int(sizes.sum()) != len(names) or at.shape[0] != sizes.shape[0] or where.shape != (3,) or np.any(sizes < 1):
        raise InvalidInput("The saved skill's routes are damaged.")
    off = np.concatenate([[0], np.cumsum(sizes)])
    routes = tuple(
        SkillRoute(tuple(names[off[i] : off[i + 1]]), (float(a[0]), float(a[1]), float(a[2]))) for i, a in enumerate(at)
    )
    route = int(d["route"])
    if routes and not 0 <= route < len(routes):
        raise InvalidInput("The saved skill's routes are damaged.")
    return {"routes": routes, "route": route, "route_where": (float(where[0]), float(where[1]), float(where[2]))}


__all__ = [
    "ALL_ARM_JOINTS",
    "ARMS",
    "ARM_JOINTS",
    "Demo",
    "JointTrajectory",
    "KeypointParams",
    "Recording",
    "Skill",
    "SkillRoute",
    "check_arm",
    "readonly",
]
