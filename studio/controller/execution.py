"""Running the learned skill on the robot ("Run on robot"), stopping it, the emergency stop, and the last run.

:meth:`ExecutionActions.run` checks that the robot can follow every learned skill, plans it from where the
robot is (a slow approach, then the skill) and starts a :class:`~studio.controller.run.Run`; the last run
(plan, recording, tracking report, task result) is kept in memory, never as a demonstration
(docs/decisions/028). :meth:`~ExecutionActions.stop` slows down along the path; the emergency stop halts
within one control cycle and refuses motion until released."""

from __future__ import annotations

import dataclasses
import logging
import threading
from collections.abc import Callable, Mapping
from typing import Protocol

import numpy as np

from studio.controller.context import Context, Kind
from studio.controller.events import Topic
from studio.controller.run import (
    HELD,
    IDLE,
    RELEASED,
    TITLES,
    Run,
    RunObjects,
    RunPaths,
    RunStatus,
    ended,
    hold_still,
    judgement,
)
from studio.core import sampling
from studio.core.errors import StudioError
from studio.core.execution import ExecutionPlan, TrackingReport, plan_execution, skill_feasibility
from studio.core.ik_path import Feasibility
from studio.core.types import Arm, Recording, Skill
from studio.robot_backend.base import ExecutionProgress, RobotBackend
from studio.world import TaskResult

log = logging.getLogger(__name__)


class Hands(Protocol):
    """Teaching by hand, as a run on the robot sees it (:class:`~studio.controller.teaching.Teaching`)."""

    @property
    def recording(self) -> bool: ...
    def forget_targets(self) -> None: ...


class ExecutionActions:
    """Run on robot, Stop, Emergency stop and its release; the last run's status, paths and judgement.

    Attributes:
        plan, recording, report, task: the last run's plan, its recorded joint states (times from 0), how
            closely it followed the plan, and its task result (None when the demonstrations moved no object),
            kept in memory until the next run, a new skill or another session.

    Args:
        objects: the objects on the table during a run; hands: whether a take is recorded, and forgetting the
            hand-moved targets once the robot moved by itself; training_busy, unload_playback: what a run
            checks and does first; skills: what a run plays (default: the session's, as learned); warnings:
            objects where no demonstration put them, in words.
    """

    def __init__(
        self,
        ctx: Context,
        backend: RobotBackend,
        *,
        objects: RunObjects,
        hands: Hands,
        training_busy: Callable[[], bool],
        unload_playback: Callable[[], None],
        skills: Callable[[], Mapping[Arm, Skill]] | None = None,
        warnings: Callable[[], list[str]] = list,
    ) -> None:
        self.ctx = ctx
        self.backend = backend
        self.display = ctx.display
        self.scene = objects
        self.teaching = hands
        self.training_busy = training_busy
        self.unload_playback = unload_playback
        self._lock = threading.RLock()
        self._status = RunStatus()
        self._run: Run | None = None
        self._last: Run | None = None
        self._feasible: dict[Arm, tuple[Skill, Feasibility]] = {}
        self._paths = RunPaths()
        self.plan: ExecutionPlan | None = None
        self.recording: Recording | None = None
        self.report: TrackingReport | None = None
        self.task: TaskResult | None = None
        #: Objects where no demonstration put them, in words (told when a run starts).
        self.warnings = warnings
        #: The skills a run plays (the controller's: placed where the objects are now).
        self.skills: Callable[[], Mapping[Arm, Skill]] = skills or (lambda: ctx.session.skills)
        ctx.on_leave(self._check_leave)
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

    def feasibility(self) -> dict[Arm, Feasibility]:
        """arm -> whether the robot can follow its learned skill, in plain words (computed once per skill)."""
        out = {}
        for arm, skill in sampling.executable(self.skills()).items():
            with self._lock:
                hit = self._feasible.get(arm)
            if hit is None or hit[0] is not skill:
                assert skill.joint_trajectory is not None
                hit = (skill, skill_feasibility(skill.joint_trajectory, skill.trajectory, self.ctx.baxter))
                with self._lock:
                    self._feasible[arm] = hit
            out[arm] = hit[1]
        return out

    def unreachable_paths(self) -> dict[Arm, list[np.ndarray]]:
        """arm -> the stretches (each (n, 3) m) of its learned path the robot cannot follow, to draw in red."""
        skills = self.skills()
        out: dict[Arm, list[np.ndarray]] = {}
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
        if self.training_busy():
            return "Wait for the training to finish before running the skill on the robot."
        if not sampling.executable(self.skills()):
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

    def _check_leave(self, doing: str) -> None:
        if self.backend.progress().active:
            raise StudioError(f"Wait for the robot's run to end (or press Stop) before {doing}.")

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
            skills = sampling.executable(self.skills())
            jts = {arm: s.joint_trajectory for arm, s in skills.items() if s.joint_trajectory is not None}
            self.unload_playback()
            self.display.show_live()  # the drawn robot is the real one during the run
            hold_still(self.backend)
            st = self.backend.state()
            plan = plan_execution(jts, st.q, st.gripper, self.ctx.baxter, rate_hz=self.backend.rate_hz)
            run = Run.start(plan, self.backend, self.scene, self.ctx.baxter)
            with self._lock:
                self._run = self._last = run
                self.plan, self.recording, self.report, self.task = plan, None, None, None
                self._status = RunStatus("running", 0.0, plan.duration, "The robot is running the skill.")
            run.thread = threading.Thread(target=self._follow, args=(run,), name="studio-run", daemon=True)
            run.thread.start()
            said = self.warnings()
        self.ctx.emit(Topic.EXECUTION)
        if said:
            self.ctx.notify("The objects are somewhere new", " ".join(said), kind="warning")

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
            msg = "Emergency stop: the robot halted. Release the emergency stop to move it again."
            self._status = dataclasses.replace(self._status, estop=True, message=msg if self._run else HELD)
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
        """The last run's planned way to the skill's start and where the gripper really went (growing while the
        robot runs); ``key`` changes whenever they do."""
        with self._lock:
            run, cached = self._last, self._paths
        if run is None:
            return RunPaths()
        if cached.key == (id(run), run.trace.count):
            return cached
        out = run.paths()
        with self._lock:
            self._paths = out
        return out

    # -- the run's thread ----------------------------------------------------------------------------------
    def _follow(self, run: Run) -> None:
        p = run.follow(self._on_progress)
        if p is None:  # abandoned (the studio stops)
            return
        try:
            judged = run.judge(p)
            with self._lock:
                self.recording, self.report, self.task = judged.recording, judged.report, judged.task
                result, ok = (
                    judgement(p, judged.report, judged.task),
                    p.state == "done" and (judged.task is None or judged.task.ok),
                )
        except Exception as exc:
            log.exception("judging the run on the robot")
            result, ok = f"The run could not be compared with its plan ({exc}).", False
        finally:
            run.release()
            self.teaching.forget_targets()  # the next move by hand starts from where the robot is
        with self._lock:
            st = self._status
            duration = p.duration or run.plan.duration
            self._status = RunStatus(p.state, p.t, duration, ended(p, st.estop), result, ok, st.estop)
            if self._run is run:
                self._run = None
        self.ctx.emit(Topic.EXECUTION)
        kind: Kind = "success" if ok else "warning"
        self.ctx.notify(TITLES.get(p.state, "The robot's run ended"), result or self._status.message, kind=kind)

    def _on_progress(self, p: ExecutionProgress) -> None:
        """The robot's progress during the run: a new phase (stopping) is told, the time only kept."""
        with self._lock:
            st = self._status
            if p.state == "stopping" and st.phase != "stopping":
                self._status = dataclasses.replace(st, phase="stopping", t=p.t, message="The robot is stopping.")
            elif p.active:
                self._status = dataclasses.replace(st, t=p.t)
                return
            else:
                return
        self.ctx.emit(Topic.EXECUTION)

    def _forget_last_run(self) -> None:
        """A new skill or another session: the last run was of something else (a run in progress goes on)."""
        with self._lock:
            if self._run is not None or (self.plan is None and self._status.phase == "idle"):
                return
            self.plan = self.recording = self.report = self.task = None
            self._last, self._paths = None, RunPaths()
            self._status = RunStatus(estop=self._status.estop, message=IDLE)
        self.ctx.emit(Topic.EXECUTION)

    def close(self) -> None:
        """The studio stops: the robot stops (controlled) and a run in progress is abandoned (its recording is
        deleted)."""
        run = self._run
        if run is None:
            return
        try:
            self.backend.stop_motion()
        except Exception:  # the connection to the robot may already be gone
            log.exception("stopping the robot's run at shutdown")
        run.cancel.set()
        if run.thread is not None and run.thread is not threading.current_thread():
            run.thread.join(timeout=2.0)
        run.release()


__all__ = ["ExecutionActions"]
