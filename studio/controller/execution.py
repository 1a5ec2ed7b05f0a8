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
    ESTOP_WORDS,
    HELD,
    IDLE,
    NOT_CONFIRMED,
    RELEASED,
    TITLES,
    FeasibilityCache,
    Run,
    RunObjects,
    RunPaths,
    RunStatus,
    abandon,
    ended,
    hold_still,
    judgement,
    wait_confirmed,
)
from studio.core import sampling
from studio.core.errors import StudioError
from studio.core.execution import (
    ExecutionPlan,
    RunVerdict,
    TrackingReport,
    judge_run,
    plan_execution,
)
from studio.core.feasibility import Feasibility
from studio.core.touches import Touch
from studio.core.types import Arm, Recording, Skill
from studio.robot_backend.base import ExecutionProgress, RobotBackend, RobotHealth
from studio.words import contact_advice, touch_words
from studio.words.controls import Control
from studio.words.robot import feasibility_words
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
            objects where no demonstration put them, in words; contacts: what the skills would touch, in words.
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
        contacts: Callable[[], str] = str,
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
        self._feasible = FeasibilityCache()
        self._paths = RunPaths()
        self.plan: ExecutionPlan | None = None
        self.recording: Recording | None = None
        self.report: TrackingReport | None = None
        self.task: TaskResult | None = None
        self.verdict: RunVerdict | None = None
        self.robot = RobotActions(ctx, backend)
        #: Objects where no demonstration put them, in words (told when a run starts).
        self.warnings = warnings
        #: What the skills touch that they must not, in words ("" when nothing; decision 087).
        self.contacts = contacts
        #: The skills a run plays (the controller's: placed where the objects are now).
        self.skills: Callable[[], Mapping[Arm, Skill]] = skills or (lambda: ctx.session.skills)
        ctx.on_leave(self._check_leave)
        ctx.events.on(Topic.SKILL, self._forget_last_run)
        ctx.events.on(Topic.SESSION, self._forget_last_run)
        for topic in (Topic.TASK, Topic.DEMOS):  # the objects or the demonstrations changed
            ctx.events.on(topic, self._last_run_out_of_date)

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
        return self._feasible.get(sampling.executable(self.skills()), self.ctx.baxter)

    def unreachable_paths(self) -> dict[Arm, list[np.ndarray]]:
        """arm -> the stretches (each (n, 3) m) of its learned path the robot cannot follow, to draw in red."""
        pos = {a: s.trajectory.position for a, s in self.skills().items()}
        return {a: [pos[a][s.i_start : s.i_end + 2] for s in f.spans] for a, f in self.feasibility().items()}

    def why_not(self) -> str:
        """Why "Run on robot" cannot start now, in plain words ("" when it can)."""
        say = self.ctx.say
        if self._status.estop:
            return f"The emergency stop is on. When it is safe, {say(Control.RELEASE_ESTOP)}, then run again."
        health = self.backend.health()
        if not health.ready:
            return health.message
        if self._run is not None:
            return f"The robot is already running the skill: wait for it to finish, or {say(Control.STOP)}."
        if self.teaching.recording:
            return "Stop the recording before running the skill on the robot."
        if self.training_busy():
            return "Wait for the training to finish before running the skill on the robot."
        if not sampling.executable(self.skills()):
            return f"There is no learned skill to run yet: record demonstrations and {say(Control.TRAIN)} first."
        bad = [feasibility_words(f) for f in self.feasibility().values() if not f.ok]
        if bad:
            return " ".join(bad) + " The robot does not run a skill it cannot follow."
        touching = self.contacts()
        if touching:
            return f"{touching} The robot does not run a skill that would hit something."
        return ""

    def check_free(self, doing: str) -> None:
        """Refuse, in plain words, ``doing`` something that moves the robot while it runs or is emergency-stopped."""
        say = self.ctx.say
        if self._status.estop:
            raise StudioError(
                f"The emergency stop is on: {say(Control.RELEASE_ESTOP)} (when it is safe) before {doing}."
            )
        if self._run is not None:
            raise StudioError(
                f"The robot is running the learned skill: wait for it to finish, or {say(Control.STOP)}, before "
                f"{doing}."
            )
        health = self.backend.health()
        if not health.ready:
            raise StudioError(health.message)

    def _check_leave(self, doing: str) -> None:
        if self.backend.progress().active:
            raise StudioError(f"Wait for the robot's run to end (or {self.ctx.say(Control.STOP)}) before {doing}.")

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
            hold_still(self.backend, again=self.ctx.say(Control.RUN))
            st = self.backend.state()
            plan = plan_execution(jts, st.q, st.gripper, self.ctx.baxter, rate_hz=self.backend.rate_hz)
            self._check_approach(plan, st.q)
            run = Run.start(plan, self.backend, self.scene, self.ctx.baxter, on_touch=self._stop_at_contact)
            with self._lock:
                self._run = self._last = run
                self.plan, self.recording, self.report, self.task, self.verdict = plan, None, None, None, None
                self._status = RunStatus("running", 0.0, plan.duration, "The robot is running the skill.")
            run.thread = threading.Thread(target=self._follow, args=(run,), name="studio-run", daemon=True)
            run.thread.start()
            said = self.warnings()
        self.ctx.emit(Topic.EXECUTION)
        if said:
            self.ctx.notify("The objects are somewhere new", " ".join(said), kind="warning")

    def _check_approach(self, plan: ExecutionPlan, q_now: np.ndarray) -> None:
        """Refuse, in words, a run whose way to the skill's start would touch something (the skill itself is
        checked with the preview: :attr:`contacts`)."""
        n = round(plan.skill_start * plan.rate_hz)
        if n < 2:
            return
        step = max(1, int(plan.rate_hz / 100.0))
        found = self.scene.touches_at(plan.q[:n:step], plan.gripper[:n:step], q_now)
        if found:
            raise StudioError(
                f"On the way to the skill's start, {touch_words(found[0])}. Move the arm near the skill's start by "
                f"hand first (clear of the table and the objects), then {self.ctx.say(Control.RUN)} again."
            )

    def _stop_at_contact(self, touch: Touch) -> None:
        """The robot touches something during a run: the emergency stop, and why in words; an object it ran into
        is pushed or knocked over in the scene."""
        self.emergency_stop()
        t = self.backend.progress().t
        self.scene.hit(touch, self.backend.state().q)
        with self._lock:
            msg = stopped_words(touch, t, self.ctx.say(Control.RELEASE_ESTOP))
            self._status = dataclasses.replace(self._status, estop=True, message=msg)
        self.ctx.emit(Topic.EXECUTION)
        self.ctx.notify("The robot touched something", msg, kind="warning")

    def stop(self) -> None:
        """Controlled stop: the robot slows down along the skill's path to rest."""
        self.backend.stop_motion()
        with self._lock:
            if self._run is not None and self._status.phase == "running":
                self._status = dataclasses.replace(self._status, phase="stopping", message="The robot is stopping.")
        self.ctx.emit(Topic.EXECUTION)

    def emergency_stop(self) -> None:
        """Halt the robot within one control cycle (whatever it does) and refuse motion until released; "halted"
        is said only once the robot (or the simulator) confirmed it. Runs on its own path (the panel's), never
        behind other work."""
        result = self.backend.emergency_stop()  # first, before anything else
        with self._lock:
            msg = ESTOP_WORDS[result] if result != "halted" or self._run else HELD
            self._status = dataclasses.replace(self._status, estop=True, message=msg)
        if result == "sent":
            threading.Thread(target=self._confirm_estop, name="studio-estop", daemon=True).start()
        self.ctx.emit(Topic.EXECUTION)

    def _confirm_estop(self) -> None:
        confirmed = wait_confirmed(self.backend)
        with self._lock:
            if not self._status.estop:
                return
            msg = ESTOP_WORDS["halted"] if confirmed else NOT_CONFIRMED
            self._status = dataclasses.replace(self._status, message=msg)
        self.ctx.emit(Topic.EXECUTION)

    def release_emergency_stop(self) -> None:
        """Allow motion again (the robot stays where it halted); the robot is reset and enabled (its own emergency-stop
        button, when down, is told in words and keeps it stopped)."""
        why = ""
        try:
            self.backend.clear_emergency_stop()
        except StudioError as exc:
            why = str(exc)
            raise
        finally:
            self.teaching.forget_targets()
            self._released(why)

    def _released(self, why: str) -> None:
        with self._lock:
            st = self._status
            if why:
                msg = f"The emergency stop is released, but the robot cannot move yet. {why}"
            elif st.phase == "emergency-stopped":
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
            task_ok = None if judged.task is None else judged.task.ok
            done = p.state == "done"
            verdict = judge_run(run.plan, judged.recording, judged.report, p.fraction, task_ok, reached_end=done)
            with self._lock:
                self.recording, self.report, self.task = judged.recording, judged.report, judged.task
                self.verdict = verdict
                result, ok = judgement(p, verdict, judged.task), p.state == "done" and verdict.works
                if run.touch is not None:
                    result, ok = f"The robot {touch_words(run.touch, 'did')}, and was stopped. {result}", False
        except Exception as exc:
            log.exception("judging the run on the robot")
            result, ok = f"The run could not be compared with its plan ({exc}).", False
        finally:
            run.release()
            self.teaching.forget_targets()  # the next move by hand starts from where the robot is
        with self._lock:
            st = self._status
            duration = p.duration or run.plan.duration
            said = (
                stopped_words(run.touch, p.t, self.ctx.say(Control.RELEASE_ESTOP))
                if run.touch is not None and st.estop
                else ended(p, st.estop)
            )
            self._status = RunStatus(p.state, p.t, duration, said, result, ok, st.estop)
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
            self.plan = self.recording = self.report = self.task = self.verdict = None
            self._last, self._paths = None, RunPaths()
            self._status = RunStatus(estop=self._status.estop, message=IDLE)
        self.ctx.emit(Topic.EXECUTION)

    def _last_run_out_of_date(self) -> None:
        """The set-up or the demonstrations changed: the last run's result is kept, marked as of before."""
        with self._lock:
            st = self._status
            if self._run is not None or st.phase == "idle" or st.stale:
                return
            self._status = dataclasses.replace(st, stale=True)
        self.ctx.emit(Topic.EXECUTION)

    def close(self) -> None:
        """The studio stops: the robot stops (controlled), a run in progress is abandoned (recording deleted)."""
        run = self._run
        if run is None:
            return
        abandon(run, self.backend)


def stopped_words(touch: Touch, t: float, release: str) -> str:
    """A run stopped at a contact, in words: "The robot was stopped at 7.3 s: the left fingers touched the table.
    When it is safe, <release>, then lift the gripper first." (``release``: how to release the emergency stop)."""
    return (
        f"The robot was stopped at {t:.1f} s: {touch_words(touch, 'did')}. When it is safe, {release}, then "
        f"{contact_advice(touch)}."
    )


class RobotActions:
    """The robot itself: its health (the status light), Enable robot, Calibrate grippers, and a simulated
    robot's faults (its e-stop button, disabled, a lost connection) for the teacher to try."""

    def __init__(self, ctx: Context, backend: RobotBackend) -> None:
        self.ctx = ctx
        self.backend = backend
        self._warned = 0

    def health(self) -> RobotHealth:
        return self.backend.health()

    def poll(self) -> RobotHealth:
        """The robot's health now; a new faulty message from it (a bad stamp, …) is told to the teacher once."""
        h = self.backend.health()
        if h.warnings > self._warned:
            self._warned = h.warnings
            self.ctx.notify("The robot sent a faulty message", h.warning, kind="warning")
        return h

    def grippers(self) -> dict[str, str]:
        """arm -> why its gripper cannot open and close on command ("" when it can)."""
        return self.backend.grippers()

    def enable(self) -> None:
        """Reset (when stopped) and enable the robot; plain errors when it cannot."""
        self.backend.enable()
        self.ctx.emit(Topic.EXECUTION)

    def calibrate_grippers(self) -> None:
        """Calibrate the grippers that need it (the teacher agreed: each opens and closes once)."""
        self.backend.calibrate_grippers()
        self.ctx.emit(Topic.EXECUTION)

    @property
    def faults(self) -> tuple[str, ...]:
        """The simulated robot's faults the teacher may cause (none for a real robot)."""
        return tuple(self.backend.fault_switches())

    def cause(self, fault: str) -> None:
        switch = self.backend.fault_switches().get(fault)
        if switch is None:
            raise StudioError(f'This robot has no "{fault}" to try.')
        switch()
        self.ctx.emit(Topic.EXECUTION)


__all__ = ["ExecutionActions", "RobotActions"]
