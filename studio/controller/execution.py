"""Running the learned skill on the robot ("Run on robot"), stopping it, the emergency stop, and judging the run.

:meth:`ExecutionActions.run` takes every learned skill of the session (both arms when both are taught), checks
that the robot can follow it (:func:`~studio.core.execution.skill_feasibility`, on the joint trajectories
training already computed, which Preview plays too), plans it from where the robot is now
(:func:`~studio.core.execution.plan_execution`: a slow approach to the skill's start, then the skill) and sends
it to the robot backend. While the robot runs:

* the drawn robot is the live one (a preview or replay is unloaded and refused until the run ends), and the
  objects on the table start from the session's set-up and respond to the robot's real joint states (the
  live world of :class:`~studio.controller.scene.SceneActions`);
* its joint states are recorded by the same :class:`~studio.recorder.Recorder` as a demonstration, written to
  disk as they arrive — into a temporary folder of the run's own, never the session's demonstration folder
  (whose leftovers crash recovery turns into demonstrations). At the end the recording is read back and the
  file deleted: the run is kept in memory as the studio's **last run** (plan, recording, tracking report,
  task result) until the next run, a new skill or another session. It is a check of the skill, not teaching
  material, so it is never added to the session's demonstrations;
* a thread follows the backend's progress. At the end the run is compared with its plan
  (:func:`~studio.core.execution.compare_execution`) and the task result is measured on what the objects did
  during the run (:meth:`SceneActions.end_run`), in one sentence: "The robot followed the plan within
  0.4 mm; the block ended 0.5 cm from where you put it — the skill works."

:meth:`stop` is the controlled stop (the robot slows down along the path); :meth:`emergency_stop` halts it
within one control cycle, at any time, and refuses every motion (runs, moves by hand, recordings) until
:meth:`release_emergency_stop`. :attr:`Topic.EXECUTION` is emitted when a run starts, changes phase and is
judged, and when the emergency stop is engaged or released; :attr:`status` also carries the progress.
"""

from __future__ import annotations

import dataclasses
import logging
import shutil
import tempfile
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from studio.controller.context import Context, Kind
from studio.controller.events import Topic
from studio.controller.playback import Player
from studio.controller.pose import Display
from studio.controller.scene import SceneActions
from studio.controller.teaching import Teaching
from studio.controller.training import Training
from studio.core import sampling
from studio.core.errors import StudioError
from studio.core.execution import ExecutionPlan, TrackingReport, compare_execution, plan_execution, skill_feasibility
from studio.core.ik_path import Feasibility
from studio.core.types import Recording, Skill
from studio.recorder import Recorder
from studio.robot_backend.base import ExecutionProgress, JointStateBatch, RobotBackend
from studio.world import TaskResult, format_distance

log = logging.getLogger(__name__)

#: How often (s) the run's thread reads the robot's progress.
POLL_S = 0.02
#: Samples per second of the drawn paths (planned and executed).
PATH_RATE_HZ = 100.0
#: Longest wait (s) for the recorder to receive the run's last joint states once the robot reports the end.
TAIL_WAIT_S = 1.0
IDLE = "Nothing has run on the robot yet."
HELD = "Emergency stop: the robot is held where it is. Release the emergency stop to move it again."
RELEASED = "the emergency stop is released: the robot can move again."


@dataclass(frozen=True)
class RunStatus:
    """The robot's run in plain words.

    Attributes:
        phase: "idle" (nothing ran since the skill was learned or the session opened), "running", "stopping",
            "done", "stopped", "emergency-stopped" or "failed" (see
            :data:`~studio.robot_backend.base.EXECUTION_STATES`).
        t, duration: plan time reached and the plan's duration (s).
        message: what the robot is doing or did, for every tab.
        result: after the run, how closely it followed the plan and what happened to the objects ("" before).
        ok: the run ended and did the task (None until judged).
        estop: the emergency stop is engaged.
    """

    phase: str = "idle"
    t: float = 0.0
    duration: float = 0.0
    message: str = IDLE
    result: str = ""
    ok: bool | None = None
    estop: bool = False

    @property
    def active(self) -> bool:
        """The robot is moving under a plan (running, or slowing down to stop)."""
        return self.phase in ("running", "stopping")

    @property
    def fraction(self) -> float:
        return min(max(self.t / self.duration, 0.0), 1.0) if self.duration > 0 else 0.0


@dataclass(frozen=True)
class RunPaths:
    """What the scene draws of the last run, per arm (each (n, 3) m, about 100 points a second): ``approach``,
    the planned way from where the robot was to the skill's start (the rest of the plan is the learned path);
    ``executed``, where the gripper really went. ``key`` changes whenever they do."""

    key: tuple[int, ...] = ()
    approach: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    executed: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)


class _Trace:
    """A backend listener during a run: keeps the joint states at about :data:`PATH_RATE_HZ` (to draw where the
    gripper went), and calls ``begin`` with the samples from the skill's start (stream time ``skill_at``, set
    once the robot says when the plan started) when the approach is over; ``mark`` is what it returned."""

    def __init__(self, begin: Callable[[np.ndarray, np.ndarray, np.ndarray], int] | None = None) -> None:
        self._lock = threading.Lock()
        self._q: list[np.ndarray] = []
        self._bucket = -np.inf
        self.count = 0
        self._begin = begin
        self.skill_at: float | None = None
        self.mark: int | None = None

    def __call__(self, batch: JointStateBatch) -> None:
        t = np.asarray(batch.t)
        bucket = np.floor(t * PATH_RATE_HZ)
        with self._lock:
            keep = bucket > np.concatenate([[self._bucket], bucket[:-1]])
            if keep.any():
                self._q.append(np.array(batch.q[keep], dtype=np.float64))
                self._bucket = float(bucket[-1])
                self.count += int(keep.sum())
        at = self.skill_at
        if self._begin is not None and at is not None and len(t) and t[-1] >= at - 1e-9:
            k = int(np.searchsorted(t, at - 1e-9))
            begin, self._begin = self._begin, None
            self.mark = begin(t[k:], np.asarray(batch.q)[k:], np.asarray(batch.gripper)[k:])

    def joints(self) -> np.ndarray:
        with self._lock:
            return np.concatenate(self._q) if self._q else np.zeros((0, 14))


@dataclass
class _Run:
    """One run: its plan, recorder (in its own temporary folder), trace and the objects' bookmark."""

    plan: ExecutionPlan
    recorder: Recorder
    folder: Path
    trace: _Trace
    mark: int
    unsubscribe: Callable[[], None]
    cancel: threading.Event = dataclasses.field(default_factory=threading.Event)
    thread: threading.Thread | None = None


class ExecutionActions:
    """Run on robot, Stop, Emergency stop and its release; the last run's status, paths and judgement."""

    def __init__(
        self,
        ctx: Context,
        backend: RobotBackend,
        display: Display,
        player: Player,
        teaching: Teaching,
        training: Training,
        scene: SceneActions,
    ) -> None:
        self.ctx = ctx
        self.backend = backend
        self.display = display
        self.player = player
        self.teaching = teaching
        self.training = training
        self.scene = scene
        self._lock = threading.RLock()
        self._status = RunStatus()
        self._run: _Run | None = None
        self._feasible: dict[str, tuple[Skill, Feasibility]] = {}
        self._last_trace = _Trace()
        self._paths = RunPaths()
        self.plan: ExecutionPlan | None = None
        self.recording: Recording | None = None
        self.report: TrackingReport | None = None
        self.task: TaskResult | None = None
        ctx.events.on(Topic.SKILL, self._forget_last_run)
        ctx.events.on(Topic.SESSION, self._forget_last_run)

    # -- state -------------------------------------------------------------------------------------------
    @property
    def status(self) -> RunStatus:
        """The current (or last) run, with its progress read from the robot now."""
        with self._lock:
            st, run = self._status, self._run
        if run is not None and st.active:
            p = self.backend.progress()
            if p.active:
                return dataclasses.replace(st, t=p.t)
        return st

    @property
    def running(self) -> bool:
        return self._run is not None

    def feasibility(self) -> dict[str, Feasibility]:
        """arm -> whether the robot can follow its learned skill, in plain words (computed once per skill)."""
        out = {}
        for arm, skill in sampling.executable(self.ctx.session.skills).items():
            with self._lock:
                hit = self._feasible.get(arm)
            if hit is None or hit[0] is not skill:
                assert skill.joint_trajectory is not None
                hit = (skill, skill_feasibility(skill.joint_trajectory, skill.trajectory, self.ctx.baxter))
                with self._lock:
                    self._feasible[arm] = hit
            out[arm] = hit[1]
        return out

    def unreachable_paths(self) -> dict[str, list[np.ndarray]]:
        """arm -> the stretches (each (n, 3) m) of its learned path the robot cannot follow, to draw in red."""
        skills = self.ctx.session.skills
        out: dict[str, list[np.ndarray]] = {}
        for arm, f in self.feasibility().items():
            pos = np.asarray(skills[arm].trajectory.position)
            out[arm] = [pos[s.i_start : s.i_end + 2] for s in f.spans]
        return out

    def why_not(self) -> str:
        """Why "Run on robot" cannot start now, in plain words ("" when it can)."""
        if self._status.estop:
            return "The emergency stop is on. When it is safe, press Release emergency stop, then run again."
        if self._run is not None:
            return "The robot is already running the skill: wait for it to finish, or press Stop."
        if self.teaching.recording:
            return "Stop the recording before running the skill on the robot."
        if self.training.busy:
            return "Wait for the training to finish before running the skill on the robot."
        if not sampling.executable(self.ctx.session.skills):
            return "There is no learned skill to run yet: record demonstrations and press Train first."
        bad = [f.message for f in self.feasibility().values() if not f.ok]
        if bad:
            return " ".join(bad) + " The robot does not run a skill it cannot follow."
        return ""

    def check_free(self, doing: str) -> None:
        """Refuse, in plain words, ``doing`` something that moves the robot while it runs or is emergency-stopped."""
        if self._status.estop:
            raise StudioError(
                f"The emergency stop is on: press Release emergency stop (when it is safe) before {doing}."
            )
        if self._run is not None:
            raise StudioError(
                f"The robot is running the learned skill: wait for it to finish, or press Stop, before {doing}."
            )

    def check_not_running(self) -> None:
        """Refuse a preview or replay while the robot runs: the scene shows the real robot then."""
        if self._run is not None:
            raise StudioError("The robot is running the skill: the scene shows the real robot until the run ends.")

    # -- actions -----------------------------------------------------------------------------------------
    def run(self) -> None:
        """Run every learned skill on the robot from where it is now (see the module docstring)."""
        with self.ctx.lock:
            reason = self.why_not()
            if reason:
                raise StudioError(reason)
            skills = sampling.executable(self.ctx.session.skills)
            jts = {arm: s.joint_trajectory for arm, s in skills.items() if s.joint_trajectory is not None}
            self.player.unload()
            self.display.show_live()  # the drawn robot is the real one during the run
            st = self.backend.state()
            plan = plan_execution(jts, st.q, st.gripper, self.ctx.baxter, rate_hz=self.backend.rate_hz)
            folder = Path(tempfile.mkdtemp(prefix="teaching-studio-run-"))
            recorder = Recorder(self.backend, folder, plan.arms, name="run on the robot", baxter=self.ctx.baxter)
            trace = _Trace(self.scene.begin_run)
            try:
                mark = self.scene.begin_run()
                recorder.start()
                unsubscribe = self.backend.subscribe(trace)
                try:
                    self.backend.execute(plan)
                except BaseException:
                    unsubscribe()
                    raise
                started = self.backend.progress().started_at
                trace.skill_at = (started if started is not None else st.t) + plan.skill_start
            except BaseException:
                recorder.discard()
                shutil.rmtree(folder, ignore_errors=True)
                raise
            run = _Run(plan, recorder, folder, trace, mark, unsubscribe)
            with self._lock:
                self._run = run
                self.plan, self.recording, self.report, self.task = plan, None, None, None
                self._status = RunStatus("running", 0.0, plan.duration, "The robot is running the skill.")
            run.thread = threading.Thread(target=self._follow, args=(run,), name="studio-run", daemon=True)
            run.thread.start()
        self.ctx.emit(Topic.EXECUTION)

    def stop(self) -> None:
        """Controlled stop: the robot slows down along the skill's path to rest."""
        self.backend.stop_motion()
        with self._lock:
            if self._run is not None and self._status.phase == "running":
                self._status = dataclasses.replace(self._status, phase="stopping", message="The robot is stopping.")
        self.ctx.emit(Topic.EXECUTION)

    def emergency_stop(self) -> None:
        """Halt the robot within one control cycle (whatever it does) and refuse motion until released."""
        self.backend.emergency_stop()  # first, before anything else
        with self._lock:
            msg = (
                "Emergency stop: the robot halted. Release the emergency stop to move it again."
                if self._run is not None
                else HELD
            )
            self._status = dataclasses.replace(self._status, estop=True, message=msg)
        self.ctx.emit(Topic.EXECUTION)

    def release_emergency_stop(self) -> None:
        """Allow motion again (the robot stays where it halted)."""
        self.backend.clear_emergency_stop()
        self.teaching.forget_targets()
        with self._lock:
            st = self._status
            if st.phase == "emergency-stopped":
                msg = f"The run ended with an emergency stop at {st.t:.1f} s of {st.duration:.1f} s; {RELEASED}"
            elif st.active or self._run is not None:
                msg = st.message
            else:
                msg = RELEASED[:1].upper() + RELEASED[1:]
            self._status = dataclasses.replace(st, estop=False, message=msg)
        self.ctx.emit(Topic.EXECUTION)

    # -- what the scene draws ----------------------------------------------------------------------------
    def paths(self) -> RunPaths:
        """The last run's planned way to the skill's start and where the gripper really went (live while the
        robot runs); ``key`` changes whenever they do."""
        with self._lock:
            plan, run, cached = self.plan, self._run, self._paths
        trace = run.trace if run is not None else self._last_trace
        key = (id(plan), id(trace), trace.count)
        if plan is None or key == cached.key:
            return cached if plan is not None else RunPaths()
        b, cols = self.ctx.baxter, {"left": slice(0, 7), "right": slice(7, 14)}
        step = max(1, round(plan.rate_hz / PATH_RATE_HZ))
        n_app = round(plan.skill_start * plan.rate_hz) + 1
        approach = {a: b.fk_batch(a, plan.q[:n_app:step, cols[a]])[0] for a in plan.arms} if n_app > step else {}
        q = trace.joints()
        executed = {a: b.fk_batch(a, q[:, cols[a]])[0] for a in plan.arms} if len(q) else {}
        out = RunPaths(key, approach, executed)
        with self._lock:
            self._paths = out
        return out

    # -- the run's thread ----------------------------------------------------------------------------------
    def _follow(self, run: _Run) -> None:
        p = self.backend.progress()
        while not run.cancel.wait(POLL_S):
            p = self.backend.progress()
            changed = False
            with self._lock:
                st = self._status
                if p.state != st.phase and p.state in ("running", "stopping"):
                    msg = "The robot is stopping." if p.state == "stopping" else st.message
                    self._status = dataclasses.replace(st, phase=p.state, t=p.t, message=msg)
                    changed = True
                elif p.active:
                    self._status = dataclasses.replace(st, t=p.t)
            if changed:
                self.ctx.emit(Topic.EXECUTION)
            if not p.active:
                break
        if run.cancel.is_set():
            return
        try:
            self._finish(run, p)
        except Exception as exc:
            log.exception("judging the run on the robot")
            with self._lock:
                self._status = dataclasses.replace(
                    self._status,
                    phase="failed" if p.state not in ("done", "stopped", "emergency-stopped") else p.state,
                    t=p.t,
                    message=_ended(p, self._status.estop),
                    result=f"The run could not be compared with its plan ({exc}).",
                    ok=False,
                )
        finally:
            self._release(run)
        self.ctx.emit(Topic.EXECUTION)
        st = self.status
        kind: Kind = "success" if st.ok else "warning"
        self.ctx.notify(_TITLES.get(st.phase, "The robot's run ended"), st.result or st.message, kind=kind)

    def _finish(self, run: _Run, p: ExecutionProgress) -> None:
        """The robot reports the end: the recording's tail, compare with the plan, the task result."""
        rec = run.recorder
        end = (p.started_at or 0.0) + p.t
        for _ in range(int(TAIL_WAIT_S / POLL_S)):
            first = rec.first_time
            if first is not None and first + rec.elapsed >= end - 1e-6:
                break
            run.cancel.wait(POLL_S)
        recording = rec.stop()
        t0 = rec.first_time or 0.0
        start = p.started_at - t0 if p.started_at is not None else None
        report = compare_execution(run.plan, recording, self.ctx.baxter, start_time=start)
        mark = run.trace.mark if run.trace.mark is not None else run.mark  # the skill began, or only the approach
        task = self.scene.end_run(mark, recording, t0)
        self.teaching.forget_targets()
        with self._lock:
            self.recording, self.report, self.task = recording, report, task
            self._status = dataclasses.replace(
                self._status,
                phase=p.state,
                t=p.t,
                duration=p.duration or run.plan.duration,
                message=_ended(p, self._status.estop),
                result=_judgement(p, report, task),
                ok=p.state == "done" and (task is None or task.ok),
            )

    def _release(self, run: _Run) -> None:
        """The run is over (or abandoned): stop listening, delete its recorder file and folder."""
        try:
            run.unsubscribe()
        except Exception:
            log.debug("unsubscribing the run's trace", exc_info=True)
        try:
            run.recorder.discard()
        finally:
            shutil.rmtree(run.folder, ignore_errors=True)
        with self._lock:
            if self._run is run:
                self._run = None
                self._last_trace = run.trace

    def _forget_last_run(self) -> None:
        """A new skill or another session: the last run was of something else (a run in progress goes on)."""
        with self._lock:
            if self._run is not None or (self.plan is None and self._status.phase == "idle"):
                return
            self.plan = self.recording = self.report = self.task = None
            self._last_trace = _Trace()
            self._status = RunStatus(estop=self._status.estop, message=IDLE)
        self.ctx.emit(Topic.EXECUTION)

    def close(self) -> None:
        """The studio stops: abandon a run in progress (its recording is deleted)."""
        run = self._run
        if run is None:
            return
        run.cancel.set()
        if run.thread is not None and run.thread is not threading.current_thread():
            run.thread.join(timeout=2.0)
        self._release(run)


_TITLES = {
    "done": "The robot finished the skill",
    "stopped": "The robot stopped",
    "emergency-stopped": "Emergency stop",
    "failed": "The run on the robot failed",
}


def _ended(p: ExecutionProgress, estop: bool) -> str:
    """How the run ended, in plain words (``estop``: the emergency stop is still engaged)."""
    when = f"{p.t:.1f} s of {p.duration:.1f} s"
    if p.state == "done":
        return f"The robot finished the skill ({p.duration:.1f} s)."
    if p.state == "stopped":
        return f"The robot stopped at {when}, as you asked."
    if p.state == "emergency-stopped":
        if not estop:  # released while the run was being judged
            return f"The run ended with an emergency stop at {when}; {RELEASED}"
        return f"Emergency stop: the robot halted at {when}. Release the emergency stop to move it again."
    return p.message or "The run on the robot ended."


def tracking_words(d: float) -> str:
    """A tracking error in words: "0.1 mm" at least, tenths of a millimetre below 1 cm, then centimetres."""
    if d < 0.01:
        return f"{max(d, 0.0001) * 1000:.1f} mm"
    return format_distance(d)


def _judgement(p: ExecutionProgress, report: TrackingReport, task: TaskResult | None) -> str:
    """The run in one or two sentences: how closely it followed the plan, then what happened to the objects."""
    within = f"within {tracking_words(report.max_path_error)}"
    if p.state == "done":
        head = f"The robot followed the plan {within}"
        if task is None:
            return head + "."
        return f"{head}; {task.text[:1].lower()}{task.text[1:]}"
    pct = round(report.completed * 100)
    head = f"Up to there ({pct}% of the run) the robot followed the plan {within}."
    return head + (f" {task.text}" if task is not None else "")


__all__ = ["ExecutionActions", "RunPaths", "RunStatus", "tracking_words"]
