"""One run of a plan on the robot (what :class:`~studio.controller.execution.ExecutionActions` starts): its
recording, its trace, following its progress, judging it at the end; and the run's status in plain words.

:meth:`Run.start` puts the objects back, records into a temporary folder of the run's own (never the
session's demonstration folder, docs/decisions/028) and sends the plan; :meth:`Run.follow` reads the
progress; :meth:`Run.judge` compares the recording with the plan and measures the task result;
:meth:`Run.release` deletes the recorder's file."""

from __future__ import annotations

import dataclasses
import logging
import shutil
import tempfile
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from studio.core.errors import StudioError
from studio.core.execution import ExecutionPlan, RunVerdict, TrackingReport, compare_execution, skill_feasibility
from studio.core.feasibility import Feasibility
from studio.core.kinematics import Baxter
from studio.core.touches import Touch
from studio.core.types import Arm, Recording, Skill
from studio.recorder import Recorder
from studio.robot_backend.base import ExecutionProgress, JointStateBatch, RobotBackend, RobotHealth
from studio.words.robot import run_failure_words
from studio.world import TaskResult, format_distance

log = logging.getLogger(__name__)

#: How often (s) the run's thread reads the robot's progress.
POLL_S = 0.02
#: How often (s of the robot's clock) a run checks whether the robot touches something (decision 087).
GUARD_S = 0.01
#: Samples per second of the drawn paths (planned and executed).
PATH_RATE_HZ = 100.0
#: Longest wait (s) for the run's last joint states to arrive once the robot reports the end.
TAIL_WAIT_S = 1.0
#: Longest wait (s) for a robot moved by hand a moment ago to hold still before a run is planned.
HOLD_S = 0.3
IDLE = "Nothing has run on the robot yet."
HELD = "Emergency stop: the robot is held where it is. Release the emergency stop to move it again."
RELEASED = "the emergency stop is released: the robot can move again."
#: What the studio's emergency stop achieved (RobotBackend.emergency_stop), in words.
ESTOP_WORDS = {
    "halted": "Emergency stop: the robot halted. Release the emergency stop to move it again.",
    "sent": "Emergency stop sent: waiting for the robot to confirm that it halted.",
    "undelivered": "The emergency stop could not be delivered: the connection to the robot is lost. Use the "
    "robot's own emergency-stop button.",
}
NOT_CONFIRMED = (
    "The robot did not confirm the emergency stop within 2 s: use its own emergency-stop button if it still moves."
)
#: Notification titles at the end of a run.
TITLES = {
    "done": "The robot finished the skill",
    "stopped": "The robot stopped",
    "emergency-stopped": "Emergency stop",
    "failed": "The run on the robot failed",
}


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
        stale: the objects' set-up or the demonstrations changed since this run: its result is of before.
    """

    phase: str = "idle"
    t: float = 0.0
    duration: float = 0.0
    message: str = IDLE
    result: str = ""
    ok: bool | None = None
    estop: bool = False
    stale: bool = False

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
    approach: dict[Arm, np.ndarray] = dataclasses.field(default_factory=dict)
    executed: dict[Arm, np.ndarray] = dataclasses.field(default_factory=dict)


class Trace:
    """A backend listener during a run: keeps the joint states at about :data:`PATH_RATE_HZ` (to draw where the
    gripper went) and the newest sample's time, and calls ``begin`` with the samples from the skill's start
    (stream time ``skill_at``, set once the robot says when the plan started); ``mark`` is what it returned;
    ``guard`` sees every batch (whether the robot touches something)."""

    def __init__(
        self,
        begin: Callable[[np.ndarray, np.ndarray, np.ndarray], int] | None = None,
        guard: Callable[[JointStateBatch], None] | None = None,
    ) -> None:
        self._guard = guard
        self._lock = threading.Lock()
        self._q: list[np.ndarray] = []
        self._bucket = -np.inf
        self.count = 0
        self.last_t = -np.inf
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
            if len(t):
                self.last_t = float(t[-1])
        at = self.skill_at
        if self._begin is not None and at is not None and len(t) and t[-1] >= at - 1e-9:
            k = int(np.searchsorted(t, at - 1e-9))
            begin, self._begin = self._begin, None
            self.mark = begin(t[k:], np.asarray(batch.q)[k:], np.asarray(batch.gripper)[k:])
        if self._guard is not None and len(t):
            self._guard(batch)

    def joints(self) -> np.ndarray:
        with self._lock:
            return np.concatenate(self._q) if self._q else np.zeros((0, 14))


@dataclass(frozen=True)
class Judged:
    """A finished run: its recording (times from 0 at the first sample), tracking report and task result."""

    recording: Recording
    report: TrackingReport
    task: TaskResult | None


class RunObjects(Protocol):
    """The objects on the table during a run (:class:`~studio.controller.scene.SceneActions`)."""

    def begin_run(
        self, t: np.ndarray | None = None, q: np.ndarray | None = None, gripper: np.ndarray | None = None
    ) -> int: ...
    def end_run(self, mark: int, recording: Recording, t0: float) -> TaskResult | None: ...
    def touches_at(self, q: np.ndarray, gripper: np.ndarray, q_now: np.ndarray) -> list[Touch]: ...
    def hit(self, touch: Touch, q_now: np.ndarray) -> None: ...


class Run:
    """One plan executed by the robot (see the module docstring); :meth:`start` makes one."""

    def __init__(
        self,
        plan: ExecutionPlan,
        backend: RobotBackend,
        scene: RunObjects,
        baxter: Baxter,
        on_touch: Callable[[Touch], None] | None = None,
    ) -> None:
        self.plan = plan
        self.backend = backend
        self.scene = scene
        self.baxter = baxter
        self.folder = Path(tempfile.mkdtemp(prefix="teaching-studio-run-"))
        self.recorder = Recorder(backend, self.folder, plan.arms, name="run on the robot", baxter=baxter)
        self._on_touch = on_touch
        self._checked = -np.inf
        self.trace = Trace(scene.begin_run, self._guard if on_touch is not None else None)
        self.mark = 0
        self.cancel = threading.Event()
        self.thread: threading.Thread | None = None
        #: what the robot touched during the run (it was stopped then), or None
        self.touch: Touch | None = None
        self._unsubscribe: Callable[[], None] | None = None

    @classmethod
    def start(
        cls,
        plan: ExecutionPlan,
        backend: RobotBackend,
        scene: RunObjects,
        baxter: Baxter,
        on_touch: Callable[[Touch], None] | None = None,
    ) -> Run:
        """Objects to the set-up, the recorder on, the plan sent to the robot (all undone if the robot refuses);
        ``on_touch``: told (on a thread of its own) when the robot touches something, once it was stopped."""
        run = cls(plan, backend, scene, baxter, on_touch)
        try:
            run.mark = scene.begin_run()
            run.recorder.start()
            run._unsubscribe = backend.subscribe(run.trace)
            t_now = backend.state().t
            backend.execute(plan)
            started = backend.progress().started_at
            run.trace.skill_at = (started if started is not None else t_now) + plan.skill_start
        except BaseException:
            run.release()
            raise
        return run

    def follow(self, on_progress: Callable[[ExecutionProgress], None]) -> ExecutionProgress | None:
        """Read the robot's progress until it reports the end (returned) or the run is abandoned (None)."""
        while not self.cancel.wait(POLL_S):
            p = self.backend.progress()
            on_progress(p)
            if not p.active:
                return p
        return None

    def _guard(self, batch: JointStateBatch) -> None:
        """On the robot's stream: whether it touches something where it is now (every :data:`GUARD_S` of its
        clock); at the first contact it is stopped at once, as by the emergency stop, then ``on_touch`` is told."""
        t = float(batch.t[-1])
        if self.touch is not None or t - self._checked < GUARD_S:
            return
        self._checked = t
        q, g = np.asarray(batch.q[-1], dtype=np.float64), np.asarray(batch.gripper[-1], dtype=np.float64)
        found = self.scene.touches_at(q[None, :], g[None, :], q)
        if not found:
            return
        self.touch = found[0]
        try:
            self.backend.emergency_stop()  # first, from here, before anything else
        finally:
            if self._on_touch is not None:
                threading.Thread(target=self._on_touch, args=(found[0],), name="studio-contact", daemon=True).start()

    def judge(self, p: ExecutionProgress) -> Judged:
        """The robot reports the end ``p``: the recording's tail, the comparison with the plan, the task result."""
        end = (p.started_at or 0.0) + p.t
        for _ in range(int(TAIL_WAIT_S / POLL_S)):  # the recorder has every sample the trace has seen
            if self.trace.last_t >= end - 1e-6:
                break
            self.cancel.wait(POLL_S)
        recording = self.recorder.stop()
        t0 = self.recorder.first_time or 0.0
        start = p.started_at - t0 if p.started_at is not None else None
        report = compare_execution(self.plan, recording, self.baxter, start_time=start)
        mark = self.trace.mark if self.trace.mark is not None else self.mark  # the skill began, or only the approach
        return Judged(recording, report, self.scene.end_run(mark, recording, t0))

    def paths(self) -> RunPaths:
        """The planned approach and the executed path so far (see :class:`RunPaths`)."""
        plan, b = self.plan, self.baxter
        cols = {"left": slice(0, 7), "right": slice(7, 14)}
        step = max(1, round(plan.rate_hz / PATH_RATE_HZ))
        n_app = round(plan.skill_start * plan.rate_hz) + 1
        approach = {a: b.fk_batch(a, plan.q[:n_app:step, cols[a]])[0] for a in plan.arms} if n_app > step else {}
        q = self.trace.joints()
        executed = {a: b.fk_batch(a, q[:, cols[a]])[0] for a in plan.arms} if len(q) else {}
        return RunPaths((id(self), self.trace.count), approach, executed)

    def release(self) -> None:
        """The run is over (or abandoned): stop listening, delete its recorder file and folder."""
        unsubscribe, self._unsubscribe = self._unsubscribe, None
        if unsubscribe is not None:
            try:
                unsubscribe()
            except Exception:  # the backend may be gone at shutdown
                log.debug("unsubscribing the run's trace", exc_info=True)
        try:
            self.recorder.discard()
        finally:
            shutil.rmtree(self.folder, ignore_errors=True)


class FeasibilityCache:
    """Whether the robot can follow each arm's learned skill, computed once per skill."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._hits: dict[Arm, tuple[Skill, Feasibility]] = {}

    def get(self, skills: Mapping[Arm, Skill], baxter: Baxter) -> dict[Arm, Feasibility]:
        out = {}
        for arm, skill in skills.items():
            with self._lock:
                hit = self._hits.get(arm)
            if hit is None or hit[0] is not skill:
                assert skill.joint_trajectory is not None
                hit = (skill, skill_feasibility(skill.joint_trajectory, skill.trajectory, baxter))
                with self._lock:
                    self._hits[arm] = hit
            out[arm] = hit[1]
        return out


def wait_confirmed(backend: RobotBackend, wait_s: float = 2.0) -> bool:
    """Whether the robot says it is stopped within ``wait_s`` seconds (after the studio's emergency stop)."""
    deadline = time.monotonic() + wait_s
    while not backend.health().estopped:
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


def abandon(run: Run, backend: RobotBackend) -> None:
    """The studio stops during ``run``: the robot stops (controlled), the run's thread ends, its file goes."""
    try:
        backend.stop_motion()
    except Exception:  # the connection to the robot may already be gone
        log.exception("stopping the robot's run at shutdown")
    run.cancel.set()
    if run.thread is not None and run.thread is not threading.current_thread():
        run.thread.join(timeout=2.0)
    run.release()


def hold_still(backend: RobotBackend, again: str) -> None:
    """A robot still going where it was moved by hand holds where it is, at rest for a few control cycles, so a
    plan starts from rest there; refused in plain words (``again``: how to start the run again) when it does not
    settle within :data:`HOLD_S`."""
    if not backend.state().moving:
        return
    backend.stop_motion()
    t_hold = backend.state().t
    deadline = time.monotonic() + HOLD_S
    while time.monotonic() < deadline:
        st = backend.state()
        if not st.moving and st.t >= t_hold + 3.0 / backend.rate_hz:
            return
        time.sleep(0.005)
    raise StudioError(
        f"The robot is still moving to where you moved it by hand: wait until it stands still, then {again} again."
    )


# -- the run in words ----------------------------------------------------------------------------------------
def ended(p: ExecutionProgress, estop: bool) -> str:
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


def judgement(p: ExecutionProgress, verdict: RunVerdict, task: TaskResult | None) -> str:
    """The run in one or two sentences, judged on what the robot did (:class:`RunVerdict`): "the skill works"
    only when the whole run was done, closely, with every gripper action, and the task result holds."""
    if verdict.works and p.state == "done":
        head = (
            f"The robot followed the plan within {tracking_words(verdict.tracking_error)} at every moment and ended "
            f"{tracking_words(verdict.final_error)} from its last pose"
        )
        if task is None:
            return head + " — the skill works."
        return f"{head}; {task.text[:1].lower()}{task.text[1:].rstrip('.')} — the skill works."
    failed = run_failure_words(verdict) or [f"the run ended before its end ({p.state})"]
    text = "The skill did not work: " + "; ".join(failed) + "."
    if task is not None and not task.ok:
        text += f" {task.text}"
    return text


__all__ = [
    "Judged",
    "RobotHealth",
    "Run",
    "RunPaths",
    "RunStatus",
    "Trace",
    "ended",
    "hold_still",
    "judgement",
    "tracking_words",
]
