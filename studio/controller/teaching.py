"""Teaching: which arm(s) are taught, moving the live robot (gripper handle by IK, joints, grippers), whether
the handle is within reach, and recording demonstrations into the open session."""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.core.arms import arm_columns, arm_of_joint, gripper_column, normalize_arms
from studio.core.errors import InvalidInput, StorageError, StudioError
from studio.core.kinematics import IkResult
from studio.core.posture_ik import reach_pose
from studio.core.types import ARMS, Arm, Recording, readonly
from studio.recorder import Recorder
from studio.robot_backend.base import JointStateBatch, RobotBackend
from studio.storage import ReadOnly, Session
from studio.words import blocked_words
from studio.words.controls import Control
from studio.world import WorldEvent

if TYPE_CHECKING:
    from studio.core.touches import Touch

log = logging.getLogger(__name__)
#: Seconds an out-of-reach handle target stays told (marker and words) once the drag ended: the handle is
#: back on the gripper by then, so the message would be stale.
REACH_HOLD_S = 4.0
#: Seconds within which a second Discard from another tab than the one recording confirms the first.
DISCARD_CONFIRM_S = 5.0


#: Along a move by hand, the gripper moves at most this far (m) between two poses checked for contact.
CHECK_STEP_M = 0.005
#: ... and at most this many poses are checked.
CHECK_POSES = 80


@dataclass(frozen=True)
class Reach:
    """Whether an arm reached where its handle was dragged (``target``: the handle's position, m); ``blocked``:
    it stopped short because it would touch something, in words ("" otherwise)."""

    ok: bool
    target: tuple[float, float, float]
    #: When it was decided (``time.monotonic()``); not part of equality.
    at: float = field(default=0.0, compare=False)
    blocked: str = ""


#: Along poses (N, 14) from where the arms are, with the grippers (N or 1, 2) and the arms now (14,): the first
#: pose that touches something, and what (None: the way is free).
Contacts = Callable[[np.ndarray, np.ndarray, np.ndarray], "tuple[int, Touch] | None"]


class Takes(Protocol):
    """What happens to the objects during a take (:class:`studio.controller.scene.SceneActions`)."""

    def begin_take(self) -> None: ...
    def end_take(self, recording: Recording) -> Sequence[WorldEvent]: ...
    def cancel_take(self) -> None: ...


class Teaching:
    """The live robot and the recorder. Only one recording runs at a time, across all tabs; the open session
    cannot change while one runs.

    Args:
        takes: keeps each take's object events with its demonstration.
        motion_guard: refuses (raises, in plain words) moving by hand or recording ("before {doing}") during a
            run on the robot or an emergency stop.
        keep: keeps a discarded take (and its object events) for Undo.
        unsaved: keeps trying to save a take its session refused for want of space (its recorder, the session
            folder, the take, its object events).
        contacts: where a move by hand would first touch something (the scene's
            :meth:`~studio.controller.scene.SceneActions.first_contact`); the arm stops before it.
    """

    def __init__(
        self,
        ctx: Context,
        backend: RobotBackend,
        takes: Takes,
        motion_guard: Callable[[str], None] = lambda doing: None,
        keep: Callable[[Recording, Sequence[WorldEvent]], None] = lambda recording, events: None,
        unsaved: Callable[[Recorder, Path, Recording, Sequence[WorldEvent]], None] | None = None,
        contacts: Contacts = lambda q, gripper, q_now: None,
    ) -> None:
        self.ctx = ctx
        self.contacts = contacts
        self.backend = backend
        self.display = ctx.display
        self.takes = takes
        self.motion_guard = motion_guard
        #: Keeps a discarded take for Undo.
        self.keep = keep
        self.unsaved = unsaved
        self.reach: dict[Arm, Reach] = {}
        self._targets: dict[Arm, np.ndarray] = {}
        self._ik_lock = {arm: threading.Lock() for arm in ARMS}
        self._recorder: Recorder | None = None
        self._session: Session = ctx.session
        self._unsubscribe: Callable[[], None] | None = None
        ctx.on_leave(self._check_leave)
        ctx.events.on(Topic.SESSION, self.forget_reach)
        self._saving = False
        self._owner: object | None = None  # the browser tab that started the running take
        self._discard_asked: float | None = None

    # -- the live robot ------------------------------------------------------------------------------------
    def start_robot(self) -> None:
        """Follow the backend's joint states and start it streaming."""
        self._unsubscribe = self.backend.subscribe(self._on_batch)
        self.backend.start()
        st = self.backend.state()
        self.display.live.set(st.t, st.q, st.gripper)

    def stop_robot(self) -> None:
        """Stop following the robot and stop it."""
        unsub, self._unsubscribe = self._unsubscribe, None
        if unsub is not None:
            try:
                unsub()
            except Exception:  # the backend may already be gone at shutdown
                pass
        self.backend.stop()

    def _on_batch(self, batch: JointStateBatch) -> None:
        # Runs on the backend's thread at up to 1 kHz: keep only the newest sample.
        if len(batch):
            self.display.live.set(float(batch.t[-1]), batch.q[-1], batch.gripper[-1])

    def robot_q(self) -> np.ndarray:
        """(14,) latest joint angles of the live robot, radians (order ALL_ARM_JOINTS)."""
        return self.display.live.get()[2].copy()

    def robot_gripper(self) -> np.ndarray:
        """(2,) latest gripper openings of the live robot, percent."""
        return self.display.live.get()[3].copy()

    def arm_q(self, arm: Arm) -> np.ndarray:
        return self.robot_q()[arm_columns(arm)]

    # -- arms ----------------------------------------------------------------------------------------------
    @property
    def selected_arms(self) -> tuple[Arm, ...]:
        """The taught arm(s), as the open session keeps them."""
        return self.ctx.arms

    def set_arms(self, arms: tuple[str, ...]) -> None:
        """Choose the taught arm(s): "left", "right" or both (remembered with the session)."""
        try:
            arms = normalize_arms(arms)
        except InvalidInput:
            raise StudioError("Choose at least one arm to teach.") from None
        with self.ctx.lock:
            if self._recorder is not None and arms != self.selected_arms:
                raise StudioError("Stop the recording before changing the arms to teach.")
            if tuple(self.ctx.session.arms) != arms:
                self.ctx.session.set_arms(arms)
        self.ctx.emit(Topic.ARMS)

    def _check_leave(self, doing: str) -> None:
        """Refuse to change the open session while a take is recorded into it (decided under ``ctx.lock``)."""
        if self._recorder is not None:
            raise StudioError(f'Stop the recording before {doing}: it is being recorded into "{self._session.name}".')

    # -- moving the robot ----------------------------------------------------------------------------------
    def move_gripper(self, arm: Arm, position: np.ndarray, wxyz: np.ndarray) -> IkResult:
        """IK to the handle's pose from the arm's current joints, then command the robot.

        The IK keeps the arm off its joint limits and near its home posture, and tries other starts when the
        arm's own is not enough (:func:`studio.core.posture_ik.reach_pose`), so whether a pose is within reach
        does not depend on where the arm was. An unreachable target still moves the arm to the closest pose
        found; :attr:`reach` says so (:attr:`Topic.REACH`). Returns the IK result.
        """
        self.motion_guard("moving the robot by hand")
        self.display.show_live()
        with self._ik_lock[arm]:  # one solve per arm at a time (a drag sends many updates)
            found = reach_pose(self.ctx.baxter, arm, position, wxyz, self._target_arm(arm), rest=self.home_q(arm))
            res = found.result
            q, touch = self.free_way(arm, np.asarray(res.q))
            self.command_arm(arm, q)
        p = np.asarray(position, dtype=float)
        blocked = blocked_words(touch) if touch is not None else ""
        ok = bool(res.converged) and touch is None
        self._set_reach(arm, Reach(ok, (float(p[0]), float(p[1]), float(p[2])), time.monotonic(), blocked))
        return res if touch is None else replace(res, q=readonly(q), converged=False)

    def free_way(self, arm: Arm, q_to: np.ndarray) -> tuple[np.ndarray, Touch | None]:
        """Where ``arm`` can go on its way from where it is going now to ``q_to`` (7,) without touching the table,
        an object (its fingers may close around one) or the other arm: ``q_to`` itself and None, or the last pose
        before the first contact and that contact. Poses are checked every :data:`CHECK_STEP_M` of the gripper's
        way (decision 087)."""
        start = np.concatenate([self._target_arm(a) for a in ARMS])
        cols = arm_columns(arm)
        end = start.copy()
        end[cols] = q_to
        b = self.ctx.baxter
        way = float(np.linalg.norm(b.fk(arm, q_to)[0] - b.fk(arm, start[cols])[0]))
        way = max(way, 0.5 * float(np.max(np.abs(end - start))))  # an elbow swings farther than the gripper
        n = int(min(max(math.ceil(way / CHECK_STEP_M), 1), CHECK_POSES))
        Q = start + np.linspace(0.0, 1.0, n + 1)[:, None] * (end - start)
        hit = self.contacts(Q, self.robot_gripper()[None, :], self.robot_q())
        if hit is None:
            return np.asarray(q_to, dtype=np.float64), None
        k, touch = hit
        return Q[k - 1, cols].copy(), touch

    def _set_reach(self, arm: Arm, reach: Reach) -> None:
        old = self.reach.get(arm)
        self.reach[arm] = reach
        if old is None or old != reach:
            self.ctx.emit(Topic.REACH)

    def forget_reach(self, arms: tuple[Arm, ...] = ARMS, *, older_than: float | None = None) -> None:
        """Stop telling that ``arms`` could not reach their handle (all of it, or what was decided more than
        ``older_than`` seconds ago): the arm was moved otherwise, or the handle is back on the gripper."""
        now = time.monotonic()
        gone = [a for a in arms if a in self.reach and (older_than is None or now - self.reach[a].at > older_than)]
        for a in gone:
            self.reach.pop(a, None)
        if gone:
            self.ctx.emit(Topic.REACH)

    def unreachable(self, arm: Arm) -> bool:
        r = self.reach.get(arm)
        return r is not None and not r.ok

    def reach_message(self) -> str:
        """Plain words about the last handle target an arm could not reach, or where it stopped because it would
        touch something ("" when all were reached)."""
        for arm in ARMS:
            r = self.reach.get(arm)
            if arm in self.selected_arms and r is not None and r.blocked:
                return r.blocked
        for arm in ARMS:
            if arm in self.selected_arms and self.unreachable(arm):
                return f"The {arm} gripper cannot reach the handle's position: the arm stops at the closest pose."
        return ""

    def home_q(self, arm: Arm) -> np.ndarray:
        """(7,) the arm's home posture: the one the studio starts in (the Baxter SDK's untuck pose), radians."""
        return self.ctx.baxter.neutral(arm)

    def home(self, arms: Sequence[Arm] | None = None) -> None:
        """Send the taught arms (or ``arms``) back to their home posture."""
        self.motion_guard("moving the robot by hand")
        self.display.show_live()
        arms = tuple(self.selected_arms if arms is None else arms)
        self.forget_reach(arms)
        for arm in arms:
            self.command_arm(arm, self.home_q(arm))

    def target_q(self, arm: Arm) -> np.ndarray:
        """(7,) the joints the arm was last sent to (where it is going), or where it is; radians."""
        return self._target_arm(arm)

    def _target_arm(self, arm: Arm) -> np.ndarray:
        with self.ctx.lock:
            t = self._targets.get(arm)
        return np.array(t) if t is not None else self.arm_q(arm)

    def command_arm(self, arm: Arm, q: np.ndarray) -> None:
        with self.ctx.lock:
            self._targets[arm] = np.array(q, dtype=np.float64)
        self.backend.command_joints(arm, q)

    def move_joint(self, index: int, value: float) -> None:
        """Move one of the 14 joints (order ALL_ARM_JOINTS) to ``value`` radians, the others held."""
        self.motion_guard("moving the robot by hand")
        self.display.show_live()
        arm = arm_of_joint(index)
        self.forget_reach((arm,))
        q = self._target_arm(arm)
        q[index % 7] = value
        q, touch = self.free_way(arm, q)
        self.command_arm(arm, q)
        if touch is not None:
            p = self.ctx.baxter.fk(arm, q)[0]
            self._set_reach(
                arm, Reach(False, (float(p[0]), float(p[1]), float(p[2])), time.monotonic(), blocked_words(touch))
            )

    def set_gripper(self, arm: Arm, width: float) -> None:
        """Gripper opening in percent (0 = closed, 100 = open)."""
        self.motion_guard("moving the gripper by hand")
        self.display.show_live()
        self.backend.command_gripper(arm, float(width))

    def forget_targets(self) -> None:
        """The robot moved by itself (a run on the robot): the next move by hand starts from where it is."""
        with self.ctx.lock:
            self._targets.clear()

    def gripper_width(self, arm: Arm) -> float:
        return float(self.robot_gripper()[gripper_column(arm)])

    # -- recording -----------------------------------------------------------------------------------------
    @property
    def recorder(self) -> Recorder | None:
        """The running recorder (read its ``elapsed``, ``n_samples``, ``arms``), or None."""
        return self._recorder

    @property
    def recording(self) -> bool:
        return self._recorder is not None

    @property
    def saving(self) -> bool:
        """A stopped take is being written into the session (between Stop and "Demonstration saved")."""
        return self._saving

    def start_recording(self, by: object | None = None) -> None:
        """Start recording the taught arm(s); only one recording runs at a time (across all tabs). ``by``: the
        browser tab that started it (see :meth:`discard_recording`)."""
        with self.ctx.lock:
            if self._recorder is not None:
                if by is not None and _tab_id(by) == self._owner:
                    return  # a double click on Record: the take this tab started goes on
                where = " in another browser tab" if by is not None else ""
                raise StudioError(f"A recording is already running{where}. Stop it first.")
            if self._saving:
                raise StudioError(
                    f"The last demonstration is still being saved: {self.ctx.say(Control.RECORD)} again in a moment."
                )
            self.motion_guard("recording")
            session = self.ctx.session
            if session.read_only:  # refused before the take, never after it
                raise ReadOnly(session.name)
            self.display.show_live()
            rec = Recorder(
                self.backend,
                session.recording_dir,
                self.selected_arms,
                name=self._next_demo_name(),
                on_full=lambda words: self.ctx.notify("The disk is full", words, kind="warning"),
            )
            rec.start()
            self._recorder, self._session = rec, session  # the take is saved where it was started
            self._owner, self._discard_asked = _tab_id(by), None
            self.takes.begin_take()
        self.ctx.emit(Topic.RECORDING)

    def _next_demo_name(self) -> str:
        names = {r.name for r in self.ctx.session.recordings}
        i = len(names) + 1
        while f"demo {i}" in names:
            i += 1
        return f"demo {i}"

    def stop_recording(self) -> None:
        """Stop, save the demonstration into the session (on disk at once) and draw it."""
        with self.ctx.lock:
            rec = self._recorder
            if rec is None:
                raise StudioError("Nothing is being recorded.")
            self._recorder = None
            self._saving = True
            self.ctx.emit(Topic.RECORDING)  # the views say "Saving…" at once
            try:
                try:
                    recording = rec.stop()
                except Exception:
                    self.takes.cancel_take()
                    raise
                events = self.takes.end_take(recording)
                try:
                    self._session.add_recording(recording, events=events)
                except StorageError as exc:  # the take stays whole: in its file and (the rest) in memory
                    if self.unsaved is None:
                        raise StorageError(f"{exc} {_kept_words(recording, rec.unsaved, later=False)}") from exc
                    self.unsaved(rec, self._session.path, recording, events)
                    raise StorageError(f"{exc} {_kept_words(recording, rec.unsaved, later=True)}") from exc
                except InvalidInput:
                    # One sample is not a demonstration: nothing to keep. Any other take the session refuses
                    # stays on disk; the next open sets it aside by name (crash recovery), never lost.
                    if len(recording) < 2:
                        rec.discard()
                    raise
                rec.discard()
            finally:
                self._saving = False
                self.ctx.emit(Topic.RECORDING)
        for msg in rec.messages:
            self.ctx.notify("Recording", msg, kind="warning")
        self.ctx.emit(Topic.DEMOS)
        self.ctx.notify("Demonstration saved", take_words(recording), kind="success")

    def discard_recording(self, by: object | None = None, *, now: float | None = None) -> bool:
        """Throw the running take away. From another browser tab than the one recording (``by``), the first
        click asks and a second one within :data:`DISCARD_CONFIRM_S` discards. Returns True when discarded."""
        now = time.monotonic() if now is None else now
        with self.ctx.lock:
            other = by is not None and self._recorder is not None and _tab_id(by) != self._owner
            asked = self._discard_asked
            if other and (asked is None or now - asked > DISCARD_CONFIRM_S):
                self._discard_asked = now
                self.ctx.notify(
                    "Discard the recording of another tab?",
                    f"This recording was started in another browser tab. {self.ctx.say(Control.DISCARD, first=True)} "
                    "again within "
                    f"{DISCARD_CONFIRM_S:.0f} seconds to throw it away.",
                    kind="warning",
                    client=by,
                )
                return False
            rec, self._recorder = self._recorder, None
            kept = self._stop_for_undo(rec) if rec is not None else None
        if rec is not None:
            rec.discard()
        self.ctx.emit(Topic.RECORDING)
        if kept is not None:
            self.keep(*kept)
            self.ctx.notify(
                "Recording thrown away",
                f'"{kept[0].name}" was thrown away. {self.ctx.say(Control.UNDO, first=True)} to keep it after all.',
                kind="info",
            )
        return rec is not None

    def _stop_for_undo(self, rec: Recorder) -> tuple[Recording, Sequence[WorldEvent]] | None:
        """Stop a take that is thrown away, keeping what it recorded for Undo (None when there is nothing)."""
        try:
            recording = rec.stop()
        except Exception:
            log.debug("a discarded take could not be read back", exc_info=True)
            self.takes.cancel_take()
            return None
        events = self.takes.end_take(recording)
        return (recording, events) if len(recording) >= 2 else None

    def save_running_recording(self) -> None:
        """Keep a take that is still running (when the studio stops); failures are logged."""
        if self._recorder is None:
            return
        try:
            self.stop_recording()
        except Exception:
            log.exception("saving the running recording at shutdown")


def _kept_words(recording: Recording, in_memory: int, *, later: bool) -> str:
    """What became of a take its session could not save (disk full), with its length."""
    where = (
        f"{in_memory:,} of its samples wait in the studio's memory, the rest in its recording file"
        if in_memory
        else "it is whole in its recording file"
    )
    when = "as soon as the disk has space (free some space), or " if later else ""
    return (
        f'The take "{recording.name}" ({recording.duration:.1f} s, {len(recording):,} samples) is not saved yet: '
        f"{where}. It is added to the session {when}the next time the session opens."
    )


def take_words(recording: Recording) -> str:
    """A saved take in words, with the rate its joint states really came at (as the robot stamped them)."""
    n, d = len(recording), recording.duration
    words = f"{recording.name}: {d:.1f} s, {n:,} samples"
    if n < 3 or d <= 0:
        return words + "."
    gaps = np.diff(np.asarray(recording.t))
    words += f", {(n - 1) / d:.0f} a second as the robot sent them"
    if gaps.max() > max(5 * float(np.median(gaps)), 0.05):
        words += f" (the longest gap between two was {gaps.max():.2f} s)"
    return words + "."


def _tab_id(tab: object | None) -> object | None:
    """Who clicked a button: viser's tab handle has a ``client_id`` (None: the studio itself, or a script)."""
    return getattr(tab, "client_id", tab)
