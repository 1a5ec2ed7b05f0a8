"""From a learned skill to what the robot executes, and back: joint trajectory, execution plan, tracking report.

:func:`joint_trajectory`: whole-path IK (:mod:`studio.core.ik_path`) timed within the joint limits at the
taught pace (:mod:`studio.core.timing`); unreachable stretches keep the closest continuous pose and are
reported by :func:`skill_feasibility`. :func:`plan_execution`: one or both arms as one 14-joint plan with a
slow approach from where the arms are. :func:`compare_execution`: a recording of the run against the plan."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import Enum

import numpy as np
from scipy.interpolate import CubicSpline

from studio.core.errors import IkFailed, InvalidInput, NotEnoughData
from studio.core.feasibility import Feasibility, feasibility
from studio.core.ik_path import solve_path
from studio.core.ik_solver import ACCEPT_ORIENTATION_RAD, ACCEPT_POSITION_M, PathSolver, pose_reachable, rotation_angle
from studio.core.kinematics import Baxter, matrix_from_quat_wxyz
from studio.core.rotations import make_sign_continuous
from studio.core.timing import _trapezoid, _trapezoid_progress, retime
from studio.core.types import ALL_ARM_JOINTS, ARMS, Arm, Demo, JointTrajectory, Recording, check_arm, readonly

#: A start pose farther than this from anything the arm can reach refuses the whole skill (IkFailed).
START_POSITION_M = 0.01
START_ORIENTATION_RAD = 0.1
#: The approach to the skill's start moves at this fraction of the joint limits.
APPROACH_SPEED = 0.3
#: Arms closer than this (rad, every joint) to the skill's start need no approach.
AT_START_RAD = 1e-9
#: During the approach the grippers move to the skill's first openings at this speed (percent per second, half
#: of Baxter's electric gripper), so that the skill starts with them where it starts (a gripper still closing
#: from fully open when the skill begins would count as a grasp of nothing).
APPROACH_GRIPPER_SPEED = 100.0
#: Grippers closer than this (percent) to the skill's first openings need no approach.
AT_START_PERCENT = 1e-6


def _pose_at(trajectory: Demo, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (M, 3) and rotation matrices (M, 3, 3) of ``trajectory`` at times ``s``: cubic splines through
    its samples (positions and quaternion components, normalised), held at its ends. Decision 084."""
    t = trajectory.t
    n = t.shape[0]
    if n == 1:
        P = np.repeat(trajectory.position, s.shape[0], axis=0)
        return P, np.repeat(matrix_from_quat_wxyz(trajectory.orientation), s.shape[0], axis=0)
    s = np.clip(s, t[0], t[-1])
    P = CubicSpline(t, trajectory.position, axis=0)(s)
    q = CubicSpline(t, make_sign_continuous(trajectory.orientation), axis=0)(s)
    return P, matrix_from_quat_wxyz(q / np.linalg.norm(q, axis=1, keepdims=True))


def joint_trajectory(
    trajectory: Demo,
    arm: Arm,
    q_seed: np.ndarray,
    baxter: Baxter | None = None,
    *,
    pace: float = 1.0,
    rate_hz: float | None = None,
    avoid: Callable[[np.ndarray], np.ndarray] | None = None,
) -> JointTrajectory:
    """Joint angles that execute ``trajectory`` with ``arm``, timed within the joint limits.

    Args:
        trajectory: the generalized trajectory (Cartesian, the skill's time line).
        arm: "left" or "right".
        q_seed: (7,) joint angles near the trajectory's start (the reference demo's first sample, or the
            neutral pose when the demos carry no joint angles).
        pace: 1.0 = as taught (never faster); smaller = slower.
        rate_hz: output rate (default: the trajectory's own rate).
        avoid: the arm's postures that touch something (see :func:`~studio.core.ik_path.solve_path`).

    Returns:
        A :class:`JointTrajectory` starting and ending at rest, within the URDF position and velocity limits
        and :data:`~studio.core.kinematics.ACCELERATION_LIMITS` (checked by finite differences at its rate).
        ``t`` equals the skill's time line where the taught pace is within the limits; ``skill_time`` says
        which moment of the skill each sample executes.

    Raises:
        IkFailed: the start pose cannot be reached at all (more than 1 cm or 0.1 rad away).
    """
    check_arm(arm)
    b = baxter or Baxter.load()
    n = len(trajectory)
    t = trajectory.t
    if rate_hz is None:
        rate_hz = 1.0 / float(np.median(np.diff(t))) if n > 1 else 1000.0
    sol = solve_path(t, trajectory.position, trajectory.orientation, arm, q_seed, b, avoid=avoid)
    if sol.position_error[0] > START_POSITION_M or sol.orientation_error[0] > START_ORIENTATION_RAD:
        raise IkFailed(
            f"The {arm} arm cannot reach the learned skill's start pose "
            f"({sol.position_error[0] * 1000:.0f} mm away, gripper turned "
            f"{math.degrees(sol.orientation_error[0]):.0f}° from the taught direction). "
            "Teach the task closer to the robot, with the gripper in a direction the arm can hold."
        )
    if n == 1 or sol.s.shape[0] == 1:
        q = sol.q[:1]
        tm_t, tm_s, tm_q = np.zeros(1), t[:1].copy(), q
    else:
        timing = retime(
            sol.pieces(),
            b.velocity_limits(arm),
            b.acceleration_limits(arm),
            rate_hz=rate_hz,
            pace=pace,
            s_range=(float(t[0]), float(t[-1])),
        )
        tm_t, tm_s, tm_q = timing.t, timing.s, timing.q
    # The spline between knots at a joint limit can overshoot it by micro-radians; keep the samples inside.
    tm_q = np.clip(tm_q, b.lower_limits(arm), b.upper_limits(arm))
    P, R = _pose_at(trajectory, tm_s)
    rot, pos = b.rotations_batch(arm, tm_q)
    perr = np.linalg.norm(pos - P, axis=1)
    oerr = rotation_angle(rot, R)
    conv = (perr <= ACCEPT_POSITION_M) & (oerr <= ACCEPT_ORIENTATION_RAD)
    g = np.asarray(trajectory.gripper)[np.clip(np.searchsorted(t, tm_s + 1e-9, side="right") - 1, 0, n - 1)]
    return JointTrajectory(t[0] + tm_t, tm_q, perr, oerr, conv, arm, g, skill_time=tm_s)


def skill_feasibility(jt: JointTrajectory, trajectory: Demo | None = None, baxter: Baxter | None = None) -> Feasibility:
    """Where the robot cannot follow the skill, on the skill's time line, and why.

    Args:
        jt: the skill's joint trajectory (from :func:`joint_trajectory`).
        trajectory: the Cartesian skill; when given, the spans' ``i_start`` / ``i_end`` index its samples
            (to draw those stretches of the path in red), and each span is probed (a few multi-start IK
            solves) to tell a stretch out of reach from one where the arm only has to change posture.
            Otherwise they index ``jt``.

    Returns:
        A :class:`~studio.core.feasibility.Feasibility` (``ok``, ``spans``; its words:
        :func:`studio.words.feasibility_words`).
    """
    s = jt.skill_time if jt.skill_time is not None else jt.t - jt.t[0]
    if trajectory is None:
        return feasibility(s, jt.position_error, jt.orientation_error, jt.arm)
    # per skill sample: the worst error of the joint samples that execute it
    tt = trajectory.t
    k = np.clip(np.searchsorted(tt, s + 1e-9, side="right") - 1, 0, len(trajectory) - 1)
    pe = np.zeros(len(trajectory))
    oe = np.zeros(len(trajectory))
    np.maximum.at(pe, k, jt.position_error)
    np.maximum.at(oe, k, jt.orientation_error)
    b = baxter or Baxter.load()
    solver = PathSolver(b, jt.arm, tt, trajectory.position, matrix_from_quat_wxyz(trajectory.orientation))
    return feasibility(tt, pe, oe, jt.arm, reachable=lambda i: pose_reachable(solver, i))


# -- the plan a robot executes ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ExecutionPlan:
    """Both arms' joint and gripper commands over time, what :meth:`RobotBackend.execute` follows.

    Attributes:
        t: (M,) seconds from the start of the execution, at ``rate_hz``.
        q: (M, 14) joint targets in :data:`~studio.core.types.ALL_ARM_JOINTS` order, radians.
        gripper: (M, 2) gripper targets, percent open (left, right).
        arms: the arms that execute a skill (the others hold still).
        skill_start: time (s) at which the skill itself begins (after the approach to its first pose).
        skill_time: (M,) the skill's own time executed at each sample (NaN during the approach).
        rate_hz: samples per second.
    """

    t: np.ndarray
    q: np.ndarray
    gripper: np.ndarray
    arms: tuple[Arm, ...]
    skill_start: float
    skill_time: np.ndarray
    rate_hz: float

    def __post_init__(self) -> None:
        t = readonly(self.t)
        m = t.shape[0]
        if m == 0 or self.q.shape != (m, 14) or self.gripper.shape != (m, 2) or self.skill_time.shape != (m,):
            raise InvalidInput("An execution plan needs M times, M × 14 joint targets and M × 2 gripper targets.")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(self.q)) and np.all(np.isfinite(self.gripper))):
            raise InvalidInput("The execution plan contains missing or invalid values (NaN or infinity).")
        if m > 1 and np.any(np.diff(t) <= 0):
            raise InvalidInput("The execution plan's times must increase from sample to sample.")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "q", readonly(self.q))
        object.__setattr__(self, "gripper", readonly(self.gripper))
        object.__setattr__(self, "skill_time", readonly(self.skill_time))

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Joint targets (14,) and gripper targets (2,) at time ``t`` (held before the start and after the end)."""
        i = int(np.clip(round((t - float(self.t[0])) * self.rate_hz), 0, len(self) - 1))
        return self.q[i], self.gripper[i]


#: The longest plan (s) sent to a robot at once.
MAX_PLAN_S = 600.0
#: The robot's joints may read this far (rad) outside their limits (encoder noise at a limit).
LIMIT_TOLERANCE = 0.02


def _check_in_limits(q_now: np.ndarray, b: Baxter) -> None:
    """Refuse, in plain words, to plan from a pose outside the joint limits (a faulty or hostile report)."""
    lo = np.concatenate([b.lower_limits(a) for a in ARMS]) - LIMIT_TOLERANCE
    hi = np.concatenate([b.upper_limits(a) for a in ARMS]) + LIMIT_TOLERANCE
    bad = np.flatnonzero((q_now < lo) | (q_now > hi))
    if bad.size:
        j = int(bad[0])
        raise InvalidInput(
            f"The robot reports its {ALL_ARM_JOINTS[j]} joint at {q_now[j]:.3g} rad, outside the range it can move "
            f"in ({math.degrees(lo[j]):.0f}° to {math.degrees(hi[j]):.0f}°): the studio does not plan a run from "
            "there. Check the robot's joint readings."
        )


def plan_execution(
    joint_trajectories: Mapping[Arm, JointTrajectory],
    q_now: np.ndarray,
    gripper_now: np.ndarray,
    baxter: Baxter | None = None,
    *,
    rate_hz: float = 1000.0,
    approach_speed: float = APPROACH_SPEED,
) -> ExecutionPlan:
    """One plan for the robot: approach the skills' start poses, then play them (both arms at once).

    Args:
        joint_trajectories: {arm: JointTrajectory} of the arms that execute a skill.
        q_now: (14,) the robot's joint angles now; gripper_now: (2,) its gripper openings now.
        rate_hz: plan rate (the backend's control rate).
        approach_speed: fraction of the joint velocity and acceleration limits used for the approach.

    Returns:
        An :class:`ExecutionPlan` that starts at ``q_now`` at rest and ends at rest; the approach also brings
        the grippers to the skill's first openings (at :data:`APPROACH_GRIPPER_SPEED`).
    """
    if not joint_trajectories:
        raise NotEnoughData("There is no learned joint trajectory to run yet; learn the skill first.")
    b = baxter or Baxter.load()
    q_now = np.asarray(q_now, dtype=np.float64)
    g_now = np.asarray(gripper_now, dtype=np.float64)
    if q_now.shape != (14,) or g_now.shape != (2,) or not (np.all(np.isfinite(q_now)) and np.all(np.isfinite(g_now))):
        raise InvalidInput("The robot's current joints (14) and grippers (2) are needed to plan the execution.")
    cols = {"left": slice(0, 7), "right": slice(7, 14)}
    arms = tuple(a for a in ARMS if a in joint_trajectories)
    for a in joint_trajectories:
        check_arm(a)
    _check_in_limits(q_now, b)
    # approach: every arm that runs a skill moves (rest to rest, straight in joint space) to its first sample
    q_first = q_now.copy()
    g_first = g_now.copy()
    for a in arms:
        q_first[cols[a]] = joint_trajectories[a].q[0]
        g_jt = joint_trajectories[a].gripper
        if g_jt is not None:
            g_first[0 if a == "left" else 1] = float(np.clip(g_jt[0], 0.0, 100.0))
    dq = q_first - q_now
    dg = g_first - g_now
    vlim = np.concatenate([b.velocity_limits(a) for a in ARMS]) * approach_speed
    alim = np.concatenate([b.acceleration_limits(a) for a in ARMS]) * approach_speed
    T, v, acc = _trapezoid(dq, vlim, alim) if np.max(np.abs(dq)) > AT_START_RAD else (0.0, 0.0, 1.0)
    Tg = float(np.max(np.abs(dg))) / APPROACH_GRIPPER_SPEED if np.max(np.abs(dg)) > AT_START_PERCENT else 0.0
    dur = max(float(jt.t[-1] - jt.t[0]) for jt in joint_trajectories.values())
    if not max(T, Tg) + dur <= MAX_PLAN_S:
        raise InvalidInput(
            f"The run would take {(max(T, Tg) + dur) / 60:.0f} minutes, longer than the {MAX_PLAN_S / 60:.0f} "
            "minutes the studio sends to the robot at once. Teach a shorter skill."
        )
    na = math.ceil(max(T, Tg) * rate_hz) if max(T, Tg) > 0 else 0
    ta = np.arange(na) / rate_hz
    L = float(np.max(np.abs(dq)))
    lam = _trapezoid_progress(np.minimum(ta, T), T, v, acc, L) / max(L, 1e-300) if na and T > 0 else np.zeros(na)
    q_app = q_now + np.outer(lam, dq)
    g_app = g_now + np.outer(np.clip(ta / Tg, 0.0, 1.0) if Tg > 0 else np.ones(na), dg)
    # the skills, on one time line at the plan rate (sample-and-hold of each arm's own samples)
    ns = math.floor(dur * rate_hz + 1e-9) + 1
    ts = np.arange(ns) / rate_hz
    q_sk = np.tile(q_first, (ns, 1))
    g_sk = np.tile(g_now, (ns, 1))
    s_sk = np.full(ns, np.nan)
    for a in arms:
        jt = joint_trajectories[a]
        tt = jt.t - jt.t[0]
        q_sk[:, cols[a]] = np.column_stack([np.interp(ts, tt, jt.q[:, j]) for j in range(7)])
        if jt.gripper is not None:
            k = np.clip(np.searchsorted(tt, ts + 1e-9, side="right") - 1, 0, len(jt) - 1)
            g_sk[:, 0 if a == "left" else 1] = jt.gripper[k]
        st = jt.skill_time if jt.skill_time is not None else tt
        s_here = np.interp(ts, tt, st)
        s_sk = np.where(np.isnan(s_sk), s_here, np.maximum(s_sk, s_here))
    t_all = np.concatenate([ta, na / rate_hz + ts])
    return ExecutionPlan(
        t=t_all,
        q=np.vstack([q_app, q_sk]),
        gripper=np.vstack([g_app, g_sk]),
        arms=arms,
        skill_start=na / rate_hz,
        skill_time=np.concatenate([np.full(na, np.nan), s_sk]),
        rate_hz=float(rate_hz),
    )


# -- execution against the plan --------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class TrackingReport:
    """How closely an execution followed its plan, over the plan's time line.

    Two errors: ``position_error`` compares with where the plan was *at the same time* (it includes any lag,
    and grows after a stop, when the plan goes on and the robot does not); ``path_error`` compares with the
    nearest planned posture (by joints), i.e. how far the gripper left the planned *path*.

    Attributes:
        t: (K,) plan time (s) of each compared sample (recording time − ``offset``).
        plan_time: (K,) the plan time whose posture each sample is closest to (progress along the plan).
        joint_error: (K,) largest joint angle difference (rad) among the executing arms' joints, same time.
        position_error: {arm: (K,)} distance (m) between executed and planned gripper positions, same time.
        path_error: {arm: (K,)} distance (m) from the executed gripper position to the planned one at
            ``plan_time``.
        planned_position, executed_position: {arm: (K, 3)} gripper positions (m) at the same time, for drawing.
        gripper_error: (K,) largest gripper opening difference (percent), same time.
        offset: seconds added to the plan's times to line them up with the recording's.
        completed: fraction of the plan executed (furthest ``plan_time`` reached / duration, 0..1).
    """

    t: np.ndarray
    plan_time: np.ndarray
    joint_error: np.ndarray
    position_error: dict[Arm, np.ndarray]
    path_error: dict[Arm, np.ndarray]
    planned_position: dict[Arm, np.ndarray]
    executed_position: dict[Arm, np.ndarray]
    gripper_error: np.ndarray
    offset: float
    completed: float

    @property
    def max_position_error(self) -> float:
        return max((float(e.max()) for e in self.position_error.values() if e.size), default=0.0)

    @property
    def max_path_error(self) -> float:
        return max((float(e.max()) for e in self.path_error.values() if e.size), default=0.0)

    @property
    def rms_path_error(self) -> float:
        vals = [e for e in self.path_error.values() if e.size]
        return float(np.sqrt(np.mean(np.concatenate(vals) ** 2))) if vals else 0.0


def _estimate_offset(plan: ExecutionPlan, rec_t: np.ndarray, rec_q: np.ndarray, cols: np.ndarray) -> float:
    """Time shift (s) that best lines up the recorded joints with the planned ones (coarse, then finer)."""
    pt, pq = plan.t, plan.q[:, cols]
    if pq.shape[0] < 2:
        return float(rec_t[0] - pt[0])
    sub = max(1, rec_t.shape[0] // 3000)
    rt, rq = rec_t[::sub], rec_q[::sub]

    def cost(off: float) -> float:
        tq = rt - off
        inside = (tq >= pt[0]) & (tq <= pt[-1])
        if inside.sum() < 2:
            return math.inf
        ref = np.column_stack([np.interp(tq[inside], pt, pq[:, j]) for j in range(pq.shape[1])])
        # mostly overlapping shifts only: a shift that keeps a sliver of both matches too easily
        return float(np.mean(np.abs(ref - rq[inside]))) + (0.0 if inside.mean() >= 0.5 else 1.0)

    lo, hi = float(rt[0] - pt[-1]), float(rt[-1] - pt[0])
    step = max((hi - lo) / 400.0, 1e-3)
    best = float(min(np.arange(lo, hi + step, step), key=cost))
    for _ in range(3):
        best = float(min(np.linspace(best - step, best + step, 21), key=cost))
        step /= 10.0
    return best


def compare_execution(
    plan: ExecutionPlan,
    recording: Recording,
    baxter: Baxter | None = None,
    *,
    start_time: float | None = None,
) -> TrackingReport:
    """Tracking error of an executed plan, from a recording of the robot's joint states during it.

    Args:
        plan: what was executed.
        recording: the robot's joint states while it executed (e.g. the recorder's file of the run).
        start_time: the recording's time (s) at which the plan started (its ``t = 0``); when None it is
            found by lining the recorded joints up with the planned ones.

    Returns:
        A :class:`TrackingReport` over the plan samples the recording covers.
    """
    b = baxter or Baxter.load()
    if len(recording) < 2:
        raise NotEnoughData("The execution recording has fewer than two samples; nothing to compare.")
    cols = (
        np.concatenate([np.arange(7) if a == "left" else np.arange(7, 14) for a in plan.arms])
        if plan.arms
        else (np.arange(14))
    )
    rt, rq = recording.t, recording.q
    off = float(start_time) if start_time is not None else _estimate_offset(plan, rt, rq[:, cols], cols)
    tp = rt - off
    inside = (tp >= plan.t[0] - 1e-9) & (tp <= plan.t[-1] + 1e-9)
    tp, rq_in, rg_in = tp[inside], rq[inside], recording.gripper[inside]
    if tp.shape[0] == 0:
        raise InvalidInput("The recording does not overlap the plan's time; was it recorded during the run?")
    pq = np.column_stack([np.interp(tp, plan.t, plan.q[:, j]) for j in range(14)])
    pg = np.column_stack([np.interp(tp, plan.t, plan.gripper[:, j]) for j in range(2)])
    jerr = np.max(np.abs(pq[:, cols] - rq_in[:, cols]), axis=1)
    # progress along the plan: the nearest planned posture (joints of the executing arms), searched in a tree
    from scipy.spatial import cKDTree

    _, near = cKDTree(plan.q[:, cols]).query(rq_in[:, cols])
    perr, path_err, ppos, epos = {}, {}, {}, {}
    for a in plan.arms:
        c = slice(0, 7) if a == "left" else slice(7, 14)
        _, p_plan = b.rotations_batch(a, pq[:, c])
        _, p_exec = b.rotations_batch(a, rq_in[:, c])
        _, p_near = b.rotations_batch(a, plan.q[near, c])
        perr[a], ppos[a], epos[a] = np.linalg.norm(p_exec - p_plan, axis=1), p_plan, p_exec
        path_err[a] = np.linalg.norm(p_exec - p_near, axis=1)
    gi = [0 if a == "left" else 1 for a in plan.arms] or [0, 1]
    gerr = np.max(np.abs(pg[:, gi] - rg_in[:, gi]), axis=1)
    plan_time = plan.t[near]
    completed = float(plan_time.max() - plan.t[0]) / plan.duration if plan.duration > 0 else 1.0
    return TrackingReport(
        t=tp,
        plan_time=plan_time,
        joint_error=jerr,
        position_error=perr,
        path_error=path_err,
        planned_position=ppos,
        executed_position=epos,
        gripper_error=gerr,
        offset=off,
        completed=float(np.clip(completed, 0.0, 1.0)),
    )


# -- what the robot did: the run's verdict ------------------------------------------------------------------

#: "The skill works" needs all of these: this much of the plan done, the gripper this close to where the plan
#: was at the same moment, and at the end this close to the plan's last pose, every gripper action done.
COMPLETE_MIN = 0.99
TRACK_MAX_M = 0.02
FINAL_MAX_M = 0.005
#: A gripper action is a change of the planned opening by at least this (percent); it is done when the
#: recorded gripper moved at least half-way within :data:`GRIP_WAIT_S` after it.
GRIP_CHANGE = 10.0
GRIP_WAIT_S = 2.0


class RunFailure(Enum):
    """One way a run fell short of "the skill works" (its numbers are the :class:`RunVerdict`'s)."""

    UNFINISHED = "unfinished"  #: less than :data:`COMPLETE_MIN` of the plan done
    OFF_TRACK = "off-track"  #: the gripper strayed more than :data:`TRACK_MAX_M`
    OFF_END = "off-end"  #: it ended more than :data:`FINAL_MAX_M` from the plan's last pose
    GRIPS = "grips"  #: a gripper action was not done
    TASK = "task"  #: the objects did not end where the demonstrations put them


@dataclass(frozen=True)
class RunVerdict:
    """A run judged on what the robot did.

    Attributes:
        completed: fraction of the plan done (0..1, the progress the robot reached).
        tracking_error: largest distance (m) between the gripper and where the plan was at the same moment (a
            run that ended early: from the planned path, since the plan went on where the robot did not).
        same_time: ``tracking_error`` is the same-moment one (the run reached its end).
        final_error: distance (m) between the gripper's last recorded position and the plan's last one.
        grips_done, grips_planned: gripper actions (closing or opening) done and planned.
        task_ok: the objects ended where the demonstrations put them (None: no object to check).
    """

    completed: float
    tracking_error: float
    final_error: float
    grips_done: int
    grips_planned: int
    task_ok: bool | None
    same_time: bool = True

    @property
    def works(self) -> bool:
        return not self.failures()

    def failures(self) -> list[RunFailure]:
        """What failed, in order ([] when the skill works); by how much is in the verdict's fields (words:
        :func:`studio.words.run_failure_words`)."""
        out = []
        if self.completed < COMPLETE_MIN:
            out.append(RunFailure.UNFINISHED)
        if self.tracking_error > TRACK_MAX_M:
            out.append(RunFailure.OFF_TRACK)
        if self.final_error > FINAL_MAX_M:
            out.append(RunFailure.OFF_END)
        if self.grips_done < self.grips_planned:
            out.append(RunFailure.GRIPS)
        if self.task_ok is False:
            out.append(RunFailure.TASK)
        return out


def _grips(plan: ExecutionPlan, recording: Recording, offset: float) -> tuple[int, int]:
    """Gripper actions of the executing arms: (done, planned)."""
    done = planned = 0
    for a in plan.arms:
        i = 0 if a == "left" else 1
        g = plan.gripper[:, i]
        change = np.flatnonzero(np.abs(np.diff(g)) > 0)
        k = 0
        while k < len(change):  # one action: a run of changes, from rest to rest
            j0 = j1 = change[k]
            while k + 1 < len(change) and change[k + 1] - j1 <= 2:
                k += 1
                j1 = change[k]
            k += 1
            before, after = float(g[j0]), float(g[j1 + 1])
            if abs(after - before) < GRIP_CHANGE:
                continue
            planned += 1
            t0 = float(plan.t[j0]) + offset
            win = (recording.t >= t0) & (recording.t <= float(plan.t[j1 + 1]) + offset + GRIP_WAIT_S)
            moved = (recording.gripper[win, i] - before) / (after - before) if win.any() else np.zeros(1)
            done += int(np.max(moved) >= 0.5)
    return done, planned


def judge_run(
    plan: ExecutionPlan,
    recording: Recording,
    report: TrackingReport,
    completed: float,
    task_ok: bool | None,
    baxter: Baxter | None = None,
    *,
    reached_end: bool = True,
) -> RunVerdict:
    """The :class:`RunVerdict` of a run: ``completed`` is the progress the robot reported (0..1);
    ``reached_end``: the run was not cut short (stopped, failed), so it is judged at the same moment."""
    b = baxter or Baxter.load()
    final = 0.0
    for a in plan.arms:
        c = slice(0, 7) if a == "left" else slice(7, 14)
        _, p_plan = b.rotations_batch(a, plan.q[-1:, c])
        _, p_end = b.rotations_batch(a, recording.q[-1:, c])
        final = max(final, float(np.linalg.norm(p_plan[0] - p_end[0])))
    done, planned = _grips(plan, recording, report.offset)
    track = report.max_position_error if reached_end else report.max_path_error
    return RunVerdict(float(completed), track, final, done, planned, task_ok, reached_end)


__all__ = [
    "ALL_ARM_JOINTS",
    "COMPLETE_MIN",
    "FINAL_MAX_M",
    "TRACK_MAX_M",
    "ExecutionPlan",
    "RunFailure",
    "RunVerdict",
    "TrackingReport",
    "compare_execution",
    "joint_trajectory",
    "judge_run",
    "plan_execution",
    "skill_feasibility",
]
