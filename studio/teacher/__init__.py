"""A scripted, human-like teacher: demonstrations of the paper's two tasks without a human.

The simulated backend, the example sessions and the core's tests learn from these plans, built the way a
person moves a Baxter arm by hand: jittered Cartesian key-frames, minimum-jerk motion along slightly bowed
paths at varying speeds, pauses, and the gripper closing to the object's width. Joint targets come from
:meth:`Baxter.ik`, interpolated per segment within the URDF limits and checked by FK; sensor noise is added
only by :func:`recording_from_plan` (docs/decisions/026)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from scipy.interpolate import CubicSpline

from studio.core.errors import InvalidInput
from studio.core.kinematics import Baxter
from studio.core.rotations import matrix_from_quat_wxyz, quat_angle, quat_wxyz_from_matrix, rotvec_matrix, slerp
from studio.core.types import ARMS, Arm, Recording, check_arm, readonly
from studio.teacher.places import SITE_OBJECTS, USUAL, Place, Places
from studio.teacher.tasks import (
    PICK_PLACE_A,
    PICK_PLACE_B,
    PICK_PLACE_YAW_A,
    PICK_PLACE_YAW_B,
    STACK_CUP_HANDOVER,
    STACK_CUP_STACK,
    TASKS,
    _Key,
    _task_keys,
)

#: Gripper opening (percent) when holding each task's object and when open.
GRIP_WIDTH = {"stack-cup": 46.0, "pick-place": 31.0}
OPEN_WIDTH = {"stack-cup": 100.0, "pick-place": 88.0}

#: Joint encoder noise (rad, 1 σ) and quantisation step (Baxter's 14-bit encoders) added when recording.
JOINT_NOISE_RAD = 2.5e-4
JOINT_QUANTUM_RAD = 2.0 * math.pi / 2**14
GRIPPER_NOISE_PERCENT = 0.3


#: IK knots per second along a moving segment (the 1 kHz signal is a clamped cubic between them).
_IK_RATE_HZ = 40.0
#: Fraction of the URDF velocity limit a plan may use (a human does not drive the arm to its limit).
_VELOCITY_MARGIN = 0.8


class GripperEvent(NamedTuple):
    """One gripper action of a plan: when it starts, which arm, "close" or "open", and the gripper pose."""

    time: float
    arm: Arm
    action: str
    position: np.ndarray
    wxyz: np.ndarray


@dataclass(frozen=True, eq=False)
class TeacherPlan:
    """A scripted demonstration: smooth joint targets at ``rate_hz`` plus what the quality checks need.

    Attributes:
        t: (N,) seconds from 0 at ``rate_hz``.
        q: (N, 14) joint targets, radians, order ALL_ARM_JOINTS; within the URDF position and velocity limits.
        gripper: (N, 2) opening percent (left, right).
        arms: the arms that teach (the other arm rests at its neutral pose).
        task: one of :data:`TASKS`.
        seed: the random seed that made this demonstration.
        events: gripper actions in time order, poses from forward kinematics of ``q`` at that time.
        rate_hz: the sampling rate.
        noise: whether :func:`recording_from_plan` adds sensor noise by default.
    """

    t: np.ndarray
    q: np.ndarray
    gripper: np.ndarray
    arms: tuple[Arm, ...]
    task: str
    seed: int
    events: list[GripperEvent]
    rate_hz: float = 1000.0
    noise: bool = True

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def event_poses(self, action: str, arm: Arm | None = None) -> list[GripperEvent]:
        """The events of one kind ("close" or "open"), optionally for one arm, in time order."""
        return [e for e in self.events if e.action == action and (arm is None or e.arm == arm)]


# -- geometry helpers -----------------------------------------------------------------------------------------


def _down(yaw: float, tilt: np.ndarray | None = None) -> np.ndarray:
    """Quaternion w, x, y, z of the gripper pointing down, turned by ``yaw`` about the vertical."""
    c, s = math.cos(yaw), math.sin(yaw)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    Ry = np.diag([-1.0, 1.0, -1.0])  # rotation by π about y: the gripper's z axis points down
    R = Rz @ Ry
    if tilt is not None:  # a small hand wobble, rotation vector in the world frame
        R = rotvec_matrix(tilt) @ R
    return quat_wxyz_from_matrix(R)


def _min_jerk(u: np.ndarray) -> np.ndarray:
    """Minimum-jerk progress 10u³ − 15u⁴ + 6u⁵ for u in [0, 1]."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10 - 15 * u + 6 * u * u)


def _mirror(p: np.ndarray) -> np.ndarray:
    return p * np.array([1.0, -1.0, 1.0])


# -- building a plan ---------------------------------------------------------------------------------------------


@dataclass
class _Segment:
    t0: float
    duration: float
    p0: np.ndarray
    p1: np.ndarray
    q0: np.ndarray  # orientation wxyz
    q1: np.ndarray
    bow: np.ndarray  # lateral offset at mid-way, m

    def cartesian(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s = _min_jerk((t - self.t0) / self.duration)
        pos = self.p0 + np.outer(s, self.p1 - self.p0) + np.outer(np.sin(math.pi * s), self.bow)
        return pos, slerp(self.q0, self.q1, s)


def _plan_arm(
    task: str,
    arm: Arm,
    rng: np.random.Generator,
    baxter: Baxter,
    places: Places = USUAL,
    detour: float = 0.0,
    once: bool = False,
    dip: float = 0.0,
    tempo: float = 1.0,
    hesitate: float = 0.0,
) -> tuple[list[tuple[str, float, object]], np.ndarray]:
    """Timeline of one arm: list of ("move", t0, _Segment) / ("hold", t0, duration) and the start q."""
    q_home = baxter.neutral(arm)
    home, home_ori = baxter.fk(arm, q_home)
    keys = _task_keys(task, rng, _mirror(home) if arm == "right" else home, places, detour, once, dip)
    if arm == "right":
        keys = [_Key(_mirror(k.position), -k.yaw, k.hold, k.speed, k.grip, k.kind, bow=-k.bow, dip=k.dip) for k in keys]
        keys[0].position = home + (keys[0].position - _mirror(home))
        keys[-1].position = home + (keys[-1].position - _mirror(home))
    pace = rng.uniform(0.82, 1.3) * (1.25 if task == "pick-place" else 1.0) * tempo  # overall speed
    if hesitate > 0:  # still before the first motion, while thinking above each object, and after the last
        for k in (keys[0], keys[1], keys[4], keys[-1]):
            k.hold += hesitate
    oris = [_down(k.yaw, rng.normal(0, 0.03, 3)) for k in keys]
    oris[0] = home_ori
    oris[-1] = quat_wxyz_from_matrix(rotvec_matrix(rng.normal(0, 0.01, 3)) @ matrix_from_quat_wxyz(home_ori))
    # Start exactly at the home configuration's pose so IK starts from a solved seed.
    keys[0].position = home
    items: list[tuple[str, float, object]] = []
    t = 0.0
    for i, k in enumerate(keys):
        if i > 0:
            prev = keys[i - 1]
            d = float(np.linalg.norm(k.position - prev.position))
            rot = float(quat_angle(oris[i - 1], oris[i]))
            v = k.speed * pace * rng.uniform(0.85, 1.15)
            dur = max(0.7, d / v, rot / 0.6)
            direction = (k.position - prev.position) / max(d, 1e-9)
            side = np.cross(direction, [0.0, 0.0, 1.0])
            if np.linalg.norm(side) < 1e-6:
                side = np.array([1.0, 0.0, 0.0])
            side /= np.linalg.norm(side)
            bow = side * (k.bow + rng.normal(0, 0.012) * min(1.0, d / 0.2)) - np.array([0.0, 0.0, k.dip])
            seg = _Segment(t, dur, prev.position, k.position, oris[i - 1], oris[i], bow)
            items.append(("move", t, seg))
            t += dur
        items.append(("hold", t, k))
        t += k.hold
    return items, q_home


def _ik_segment(baxter: Baxter, arm: Arm, seg: _Segment, q_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """IK knots (times (K,), joints (K, 7)) along a segment, each solve seeded by the previous one."""
    n = max(3, math.ceil(seg.duration * _IK_RATE_HZ) + 1)
    tk = seg.t0 + np.linspace(0.0, seg.duration, n)
    pos, ori = seg.cartesian(tk)
    qs = np.empty((n, 7))
    q = q_start
    for j in range(n):
        res = baxter.ik(arm, pos[j], ori[j], q, max_iterations=200, position_tolerance=2e-5, orientation_tolerance=2e-4)
        if not res.converged:  # far from the usual spots a solve can need more steps
            res = baxter.ik(
                arm, pos[j], ori[j], res.q, max_iterations=2000, position_tolerance=2e-5, orientation_tolerance=2e-4
            )
        if not res.converged:  # pragma: no cover - the scripted key-frames are chosen reachable
            raise RuntimeError(
                f"Teacher plan unreachable for the {arm} arm at t={tk[j]:.2f} s "
                f"(error {res.position_error * 1000:.1f} mm, {res.orientation_error:.3f} rad)"
            )
        q = res.q
        qs[j] = q
    return tk, qs


def _arm_joints(
    items: list[tuple[str, float, object]], q_home: np.ndarray, arm: Arm, baxter: Baxter, t: np.ndarray
) -> tuple[np.ndarray, list[tuple[float, float, str]], float]:
    """(N, 7) joint targets at times ``t``, the gripper actions (t_start, hold length, action), end time."""
    vmax = baxter.velocity_limits(arm) * _VELOCITY_MARGIN
    q_out = np.empty((t.shape[0], 7))
    q_cur = q_home.copy()
    grips: list[tuple[float, float, str]] = []
    shift = 0.0  # extra time added so far by slowing segments down to respect the velocity limits
    for kind, t0, obj in items:
        t0 = t0 + shift
        if kind == "hold":
            k = obj
            assert isinstance(k, _Key)
            sel = (t >= t0) & (t < t0 + k.hold)
            q_out[sel] = q_cur
            if k.grip:
                grips.append((t0, k.hold, k.grip))
            continue
        seg = obj
        assert isinstance(seg, _Segment)
        seg = _Segment(t0, seg.duration, seg.p0, seg.p1, seg.q0, seg.q1, seg.bow)
        while True:
            tk, qk = _ik_segment(baxter, arm, seg, q_cur)
            spline = CubicSpline(tk, qk, bc_type="clamped")
            tt = np.linspace(tk[0], tk[-1], 400)
            ratio = float(np.max(np.abs(spline(tt, 1)) / vmax))
            if ratio <= 1.0:
                break
            extra = seg.duration * (ratio * 1.05 - 1.0)
            shift += extra
            seg = _Segment(seg.t0, seg.duration + extra, seg.p0, seg.p1, seg.q0, seg.q1, seg.bow)
        sel = (t >= seg.t0) & (t < seg.t0 + seg.duration)
        q_out[sel] = spline(t[sel])
        q_cur = qk[-1]
    end = items[-1][1] + shift + _item_len(items[-1])
    q_out[t >= end] = q_cur
    return q_out, grips, end


@lru_cache(maxsize=64)
def teach(
    task: str,
    seed: int,
    arm: Arm = "left",
    rate_hz: float = 1000.0,
    noise: bool = True,
    places: Places = USUAL,
    detour: float = 0.0,
    once: bool = False,
    dip: float = 0.0,
    tempo: float = 1.0,
    hesitate: float = 0.0,
) -> TeacherPlan:
    """A human-like scripted demonstration of ``task`` (20–30 s, varied speed, pauses, jitter).

    Args:
        task: "stack-cup" (take a cup handed over in the air, put it on a stack) or "pick-place" (pick a
            block at A, place it at B, pick it again and bring it back to A).
        seed: random seed; different seeds give different speeds, pauses and a few cm of spatial variation.
        arm: "left", "right" (the task mirrored) or "both" (each arm its own variation, at once).
        rate_hz: output rate (Baxter streams at 1 kHz in the paper's setting).
        noise: default for :func:`recording_from_plan`; the plan itself is always noise-free.
        places: where the task's objects stand (default: the usual spots, where the presets put them); the
            same ``places`` go to :func:`studio.world.preset` for the matching scene.
        detour: the first carry bows this far sideways at mid-way (m, ±20 % per demonstration; + is to the left
            of the carry's direction, mirrored for the right arm): a way around an obstacle.
        once: pick-place puts the block on the pad and goes home, as a newcomer shows it (no way back).
        dip: the first carry sags this far down at mid-way (m, ±10 % per demonstration): a careless carry.
        tempo: × the usual speed of every motion (0.1: slow careful drags).
        hesitate: seconds the arm stays still before its first motion, above the first object, above where it
            goes and after its last motion (a newcomer thinking).

    Returns:
        A :class:`TeacherPlan` (cached: the same arguments return the same read-only plan).
    """
    if task not in TASKS:
        raise InvalidInput(f'Unknown task "{task}": choose one of {", ".join(TASKS)}.')
    arms = ("left", "right") if arm == "both" else (check_arm(arm),)
    if not (tempo > 0 and math.isfinite(tempo) and hesitate >= 0 and math.isfinite(hesitate)):
        raise InvalidInput("The teacher's tempo must be positive and its hesitation not negative.")
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise InvalidInput(f"The sampling rate must be a positive number of samples per second (got {rate_hz}).")
    baxter = Baxter.load()
    rng = np.random.default_rng([seed, TASKS.index(task)])
    timelines = {a: _plan_arm(task, a, rng, baxter, places, detour, once, dip, tempo, hesitate) for a in arms}
    # Generous horizon; slowed segments only lengthen a plan by a little.
    horizon = max(sum(_item_len(it) for it in items) for items, _ in timelines.values())
    t = np.arange(math.ceil(horizon * 1.5 * rate_hz) + 1) / rate_hz
    q = np.empty((t.shape[0], 14))
    grip = np.empty((t.shape[0], 2))
    ends = []
    grip_actions: dict[Arm, list[tuple[float, float, str]]] = {}
    for i_arm, a in enumerate(ARMS):
        cols = slice(0, 7) if a == "left" else slice(7, 14)
        if a not in timelines:
            q[:, cols] = baxter.neutral(a)
            grip[:, i_arm] = 100.0
            continue
        items, q_home = timelines[a]
        qa, grips, end_a = _arm_joints(items, q_home, a, baxter, t)
        ends.append(end_a)
        q[:, cols] = qa
        grip[:, i_arm] = _gripper_signal(t, grips, task, rng)
        grip_actions[a] = grips
    end = max(ends)
    n = int(np.searchsorted(t, end))
    t, q, grip = t[:n], q[:n], grip[:n]
    lo = np.concatenate([baxter.lower_limits("left"), baxter.lower_limits("right")])
    hi = np.concatenate([baxter.upper_limits("left"), baxter.upper_limits("right")])
    q = np.clip(q, lo, hi)
    events: list[GripperEvent] = []
    for a, grips in grip_actions.items():
        Q = q[:, :7] if a == "left" else q[:, 7:]
        for t0, hold, action in grips:
            ts = t0 + 0.3 * hold
            i = min(round(ts * rate_hz), n - 1)
            p, o = baxter.fk(a, Q[i])
            events.append(GripperEvent(float(t[i]), a, action, readonly(p), readonly(o)))
    events.sort(key=lambda e: e.time)
    return TeacherPlan(readonly(t), readonly(q), readonly(grip), arms, task, int(seed), events, float(rate_hz), noise)


def _item_len(item: tuple[str, float, object]) -> float:
    kind, _, obj = item
    return obj.duration if kind == "move" else obj.hold  # type: ignore[attr-defined]


def _gripper_signal(
    t: np.ndarray, grips: list[tuple[float, float, str]], task: str, rng: np.random.Generator
) -> np.ndarray:
    """Opening (percent) over time: open at the start, a 0.5 s ramp at 30 % into each action's pause."""
    g = np.full(t.shape[0], OPEN_WIDTH[task])
    level = OPEN_WIDTH[task]
    for t0, hold, action in grips:
        ts = t0 + 0.3 * hold
        ramp = rng.uniform(0.4, 0.6)
        target = GRIP_WIDTH[task] if action == "close" else OPEN_WIDTH[task]
        sel = t >= ts
        g[sel] = level + (target - level) * _min_jerk((t[sel] - ts) / ramp)
        level = target
    return g


def recording_from_plan(plan: TeacherPlan, noise: bool | None = None, name: str | None = None) -> Recording:
    """The :class:`Recording` a 1 kHz joint-state stream would have produced while following ``plan`` exactly:
    its time stamps, arms and joints, with encoder noise (``JOINT_NOISE_RAD`` white, then quantised to
    ``JOINT_QUANTUM_RAD``) and gripper noise when ``noise`` (default ``plan.noise``); ``name`` defaults to
    "<task> #<seed>"."""
    noise = plan.noise if noise is None else noise
    q, g = np.array(plan.q), np.array(plan.gripper)
    if noise:
        rng = np.random.default_rng([plan.seed, 7919])
        q = q + rng.normal(0.0, JOINT_NOISE_RAD, q.shape)
        q = np.round(q / JOINT_QUANTUM_RAD) * JOINT_QUANTUM_RAD
        g = np.clip(g + rng.normal(0.0, GRIPPER_NOISE_PERCENT, g.shape), 0.0, 100.0)
    return Recording(plan.t, q, g, plan.arms, name or f"{plan.task} #{plan.seed}")


__all__ = ["GRIP_WIDTH", "OPEN_WIDTH", "SITE_OBJECTS", "TASKS", "GripperEvent", "Place", "Places", "TeacherPlan"]
__all__ += ["PICK_PLACE_A", "PICK_PLACE_B", "PICK_PLACE_YAW_A", "PICK_PLACE_YAW_B", "STACK_CUP_HANDOVER"]
__all__ += ["STACK_CUP_STACK", "recording_from_plan", "teach"]
