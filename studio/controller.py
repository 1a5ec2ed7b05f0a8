"""The studio's controller: GUI state and orchestration over the core, the robot backend and the sessions.

It knows nothing of viser: :class:`studio.app.Studio` adds the server, the scene, the panels and the pose pump
on top of it, and overrides :meth:`Controller.notify` to show notifications in the browser tabs.

Threads:
    * the backend's thread delivers joint-state batches (only the newest sample is kept, in :attr:`live`);
    * one *work* thread runs heavy jobs (training, session files) one at a time (:meth:`Controller.submit`);
    * GUI callbacks (viser's thread pool) call the public methods; shared state is guarded by :attr:`lock`.
"""

from __future__ import annotations

import functools
import logging
import sys
import threading
import time
import traceback
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from studio.core.errors import InvalidInput, NotEnoughData, StudioError
from studio.core.kinematics import Baxter
from studio.core.types import ARMS, KeypointParams
from studio.robot_backend.base import JointStateBatch, RobotBackend
from studio.sessions import MAX_CLUSTERS, SessionStore

log = logging.getLogger("studio")

F = TypeVar("F", bound=Callable[..., Any])

#: Demo colours (RGB), distinct on the light background and never red (red marks the cluster centroids).
PALETTE: tuple[tuple[int, int, int], ...] = (
    (31, 119, 180),
    (44, 160, 44),
    (255, 127, 14),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
    (57, 59, 121),
)


RECOVERED = "Recovered recordings"


class Events:
    """A tiny observer list per topic; callbacks run on the caller's thread."""

    def __init__(self) -> None:
        self._subs: dict[str, list[Callable[[], None]]] = {}

    def on(self, topic: str, fn: Callable[[], None]) -> None:
        self._subs.setdefault(topic, []).append(fn)

    def emit(self, topic: str) -> None:
        for fn in list(self._subs.get(topic, ())):
            try:
                fn()
            except Exception:  # a broken view must not break the others
                log.exception("view update for %s failed", topic)


class PoseSource:
    """Where the scene's robot pose comes from: the live backend, a demo replay or the skill preview."""

    def __init__(self) -> None:
        self.q = np.zeros(14)
        self.gripper = np.full(2, 100.0)
        self.t = 0.0
        self.version = 0
        self._lock = threading.Lock()

    def set(self, t: float, q: np.ndarray, gripper: np.ndarray) -> None:
        with self._lock:
            self.t = float(t)
            self.q = np.asarray(q, dtype=np.float64)
            self.gripper = np.asarray(gripper, dtype=np.float64)
            self.version += 1

    def get(self) -> tuple[int, float, np.ndarray, np.ndarray]:
        with self._lock:
            return self.version, self.t, self.q, self.gripper

    def touch(self) -> None:
        """Mark the pose as new so the scene redraws it (after switching back to this source)."""
        with self._lock:
            self.version += 1


@dataclass
class KeypointItem:
    index: int
    arm: str
    name: str
    color: tuple[int, int, int]
    count: int
    points: np.ndarray


@dataclass
class KeypointView:
    """What the key-points panel draws: per-demo key-points, per-arm centroids (k, 8), notes."""

    demos: list[KeypointItem] = field(default_factory=list)
    centroids: dict[str, np.ndarray] = field(default_factory=dict)
    k: dict[str, int] = field(default_factory=dict)
    messages: list[str] = field(default_factory=list)


class Playback:
    """A recording streamed by a :class:`ReplayBackend` into a :class:`PoseSource` the scene can show."""

    def __init__(self, kind: str, recording: Any, speed: float = 1.0) -> None:
        from studio.robot_backend.replay import ReplayBackend

        self.kind = kind
        self.recording = recording
        self.backend = ReplayBackend(recording, speed=speed)
        self.source = PoseSource()
        st = self.backend.state()
        self.source.set(st.t, st.q, st.gripper)
        self._unsub = self.backend.subscribe(self._on_batch)

    def _on_batch(self, batch: JointStateBatch) -> None:
        if len(batch):
            self.source.set(float(batch.t[-1]), batch.q[-1], batch.gripper[-1])

    @property
    def position(self) -> float:
        return self.backend.position

    @property
    def playing(self) -> bool:
        return self.backend.running

    @property
    def finished(self) -> bool:
        return self.backend.finished

    def play(self) -> None:
        self.backend.start()

    def pause(self) -> None:
        self.backend.stop()

    def set_speed(self, speed: float) -> None:
        self.backend.speed = float(speed)

    def seek(self, t: float) -> None:
        self.backend.seek(t)
        i = int(np.clip(np.searchsorted(self.recording.t, t), 0, len(self.recording) - 1))
        self.source.set(float(self.recording.t[i]), self.recording.q[i], self.recording.gripper[i])

    def close(self) -> None:
        self._unsub()
        self.backend.stop()


class Controller:
    """GUI state and orchestration of the studio: teaching, recording, demos, key-points, training, playback,
    sessions. Every public method is one action a panel can bind a handle to.

    Attributes:
        baxter: the kinematic model (FK/IK).
        backend: the robot (started by :meth:`start_robot`).
        store: the sessions on disk; ``session`` is the open one.
        events: topics the views subscribe to ("arms", "demos", "session", "sessions", "recording",
            "training", "skill", "playback").
        live / display: the live robot pose, and the pose source the scene draws (live, replay or preview).
    """

    def __init__(
        self, *, store: SessionStore, session: str, backend: RobotBackend, baxter: Baxter | None = None
    ) -> None:
        self.events = Events()
        self.lock = threading.RLock()
        self.baxter = baxter if baxter is not None else Baxter.load()
        self.store = store
        self.session = self._open_or_create(session)
        self.backend = backend
        self.live = PoseSource()
        self.display = self.live  # the pump draws whichever source is active
        self.selected_arms: tuple[str, ...] = self._session_arms()
        self.recorder: Any = None
        self._delete_pending: tuple[str, float] | None = None  # (demo name, time of the first Delete press)
        self._demo_cache: dict[tuple[int, str], tuple[Any, Any]] = {}
        self._targets: dict[str, np.ndarray] = {}
        from studio.core.keypoints import KeypointCache

        self._kp_cache = KeypointCache()  # per-demo derived series, reused across ε changes (weak keys)
        self._params: KeypointParams = self.session.params
        self._params_dirty = False
        self.k_override: int | None = self.session.n_clusters
        self.training = False
        self._playback: Playback | None = None
        self._work = ThreadPoolExecutor(max_workers=1, thread_name_prefix="studio-work")
        self._unsubscribe: Callable[[], None] | None = None
        self._startup_notes = self._session_notes(self.session)

    # -- lifecycle ---------------------------------------------------------------------------------------
    def start_robot(self) -> None:
        """Follow the backend's joint states and start it streaming."""
        self._unsubscribe = self.backend.subscribe(self._on_batch)
        self.backend.start()
        st = self.backend.state()
        self.live.set(st.t, st.q, st.gripper)

    def save_running_recording(self) -> None:
        """Keep a take that is still running (used when the studio stops); failures are logged."""
        if self.recorder is None:
            return
        try:
            self.stop_recording()
        except Exception:
            log.exception("saving the running recording at shutdown")

    def shutdown(self) -> None:
        """Stop following the robot, stop it, and drop queued work."""
        unsub, self._unsubscribe = self._unsubscribe, None
        if unsub is not None:
            try:
                unsub()
            except Exception:
                pass
        self.backend.stop()
        self._work.shutdown(wait=False, cancel_futures=True)

    def startup_notes(self) -> list[tuple[str, str]]:
        """(title, body) warnings from opening the session (crash recovery, damaged files), for a new tab."""
        return list(self._startup_notes)

    def startup_notes_shown(self) -> None:
        """A tab got the notes: a recovery is told once, damaged files to every new tab."""
        self._startup_notes = [n for n in self._startup_notes if n[0] != RECOVERED]

    def _session_notes(self, session: Any) -> list[tuple[str, str]]:
        notes = []
        if getattr(session, "recovery_message", ""):
            notes.append((RECOVERED, session.recovery_message))
        for p in getattr(session, "problems", []) or []:
            notes.append(("Part of the session could not be read", p))
        return notes

    # -- setup -------------------------------------------------------------------------------------------
    def _open_or_create(self, name: str) -> Any:
        try:
            return self.store.open(name)
        except StudioError:
            if name in self.store.list_sessions():
                raise
            return self.store.create(name)

    def _session_arms(self) -> tuple[str, ...]:
        arms = tuple(getattr(self.session, "arms", ("left",)) or ("left",))
        return tuple(a for a in ARMS if a in arms) or ("left",)

    # -- robot state -------------------------------------------------------------------------------------
    def _on_batch(self, batch: JointStateBatch) -> None:
        # Runs on the backend's thread at up to 1 kHz: keep only the newest sample.
        if len(batch):
            self.live.set(float(batch.t[-1]), batch.q[-1], batch.gripper[-1])

    def robot_q(self) -> np.ndarray:
        """(14,) latest joint angles of the live robot, radians (order ALL_ARM_JOINTS)."""
        return self.live.get()[2].copy()

    def robot_gripper(self) -> np.ndarray:
        return self.live.get()[3].copy()

    def arm_q(self, arm: str) -> np.ndarray:
        q = self.robot_q()
        return q[:7] if arm == "left" else q[7:]

    def display_label(self) -> str:
        """What the drawn robot shows, in plain words."""
        pb = self._playback
        if self.display is self.live or pb is None:
            return "Showing the robot live."
        what = "the learned skill (preview)" if pb.kind == "preview" else f'demonstration "{pb.recording.name}"'
        state = "playing" if pb.playing else "paused"
        return f"Showing {what}, {state}."

    def show_live(self) -> None:
        """Let the scene follow the live robot again (after a replay or preview)."""
        self.display = self.live
        self.live.touch()

    # -- failures and background work --------------------------------------------------------------------
    def notify(self, title: str, body: str, *, kind: str = "error", client: Any = None) -> None:
        """Tell the user something in plain words; without a GUI it is only logged (the studio shows it)."""
        if kind in ("error", "warning"):
            log.warning("%s: %s", title, body)
        else:
            log.info("%s: %s", title, body)

    def report(self, exc: BaseException, *, title: str = "That did not work", client: Any = None) -> None:
        if isinstance(exc, StudioError):
            self.notify(title, str(exc), client=client)
        else:
            traceback.print_exception(exc, file=sys.stderr)
            self.notify(
                title,
                f"Something unexpected went wrong ({type(exc).__name__}: {exc}). Your work is kept; you can try again.",
                client=client,
            )

    def guarded(self, title: str = "That did not work") -> Callable[[F], F]:
        """Decorator for GUI callbacks: any failure becomes a notification; the studio keeps running."""

        def deco(fn: F) -> F:
            @functools.wraps(fn)
            def wrapper(*args: Any, **kwargs: Any) -> Any:
                try:
                    return fn(*args, **kwargs)
                except Exception as exc:
                    client = getattr(args[0], "client", None) if args else None
                    self.report(exc, title=title, client=client)
                    return None

            return wrapper  # type: ignore[return-value]

        return deco

    def submit(
        self,
        job: Callable[[], Any],
        *,
        done: Callable[[Any], None] | None = None,
        title: str = "That did not work",
    ) -> Future:
        """Run ``job`` on the work thread; ``done(result)`` runs there too; failures are notifications."""

        def run() -> Any:
            try:
                result = job()
                if done is not None:
                    done(result)
                return result
            except Exception as exc:
                self.report(exc, title=title)
                return None

        return self._work.submit(run)

    # -- session ---------------------------------------------------------------------------------------
    def set_session(self, session: Any) -> None:
        """Make ``session`` the open one and redraw every view."""
        self._switch(session)

    # -- teaching: moving the robot ----------------------------------------------------------------------
    def set_arms(self, arms: tuple[str, ...]) -> None:
        """Choose the taught arm(s): "left", "right" or both."""
        arms = tuple(a for a in ARMS if a in arms)
        if not arms:
            raise StudioError("Choose at least one arm to teach.")
        with self.lock:
            if self.recorder is not None and arms != self.selected_arms:
                raise StudioError("Stop the recording before changing the arms to teach.")
            self.selected_arms = arms
            if tuple(self.session.arms) != arms:
                self.session.set_arms(arms)  # remembered with the session
        self.events.emit("arms")

    def move_gripper(self, arm: str, position: np.ndarray, wxyz: np.ndarray) -> Any:
        """IK to the handle's pose from the arm's current joints, then command the robot.

        Returns the IK result; an unreachable target still moves the arm to the closest pose found.
        """
        self.show_live()
        res = self.baxter.ik(arm, position, wxyz, self._target_arm(arm), max_iterations=60)
        self.command_arm(arm, np.asarray(res.q))
        return res

    def _target_arm(self, arm: str) -> np.ndarray:
        with self.lock:
            t = self._targets.get(arm)
        return np.array(t) if t is not None else self.arm_q(arm)

    def command_arm(self, arm: str, q: np.ndarray) -> None:
        with self.lock:
            self._targets[arm] = np.array(q, dtype=np.float64)
        self.backend.command_joints(arm, q)

    def move_joint(self, index: int, value: float) -> None:
        """Move one of the 14 joints (order ALL_ARM_JOINTS) to ``value`` radians, the others held."""
        self.show_live()
        arm = "left" if index < 7 else "right"
        q = self._target_arm(arm)
        q[index % 7] = value
        self.command_arm(arm, q)

    def set_gripper(self, arm: str, width: float) -> None:
        """Gripper opening in percent (0 = closed, 100 = open)."""
        self.show_live()
        self.backend.command_gripper(arm, float(width))

    # -- recording ---------------------------------------------------------------------------------------
    def start_recording(self) -> None:
        """Start recording the taught arm(s); only one recording runs at a time (across all tabs)."""
        from studio.recorder import Recorder

        with self.lock:
            if self.recorder is not None:
                raise StudioError("A recording is already running (maybe in another tab). Stop it first.")
            self.show_live()
            name = self._next_demo_name()
            rec = Recorder(self.backend, self.session.recording_dir, self.selected_arms, name=name)
            rec.start()
            self.recorder = rec
        self.events.emit("recording")

    def _next_demo_name(self) -> str:
        names = set(self.demo_names())
        i = len(names) + 1
        while f"demo {i}" in names:
            i += 1
        return f"demo {i}"

    def stop_recording(self) -> None:
        """Stop, save the demonstration into the session (on disk at once) and draw it."""
        with self.lock:
            rec = self.recorder
            if rec is None:
                raise StudioError("Nothing is being recorded.")
            self.recorder = None
            try:
                recording = rec.stop()
                try:
                    self.session.add_recording(recording)
                except InvalidInput:
                    # One sample is not a demonstration: nothing to keep. Any other take the session refuses
                    # stays on disk; the next open sets it aside by name (recover_recordings), never lost.
                    if len(recording) < 2:
                        rec.discard()
                    raise
                rec.discard()
            finally:
                self.events.emit("recording")
        for msg in rec.messages:
            self.notify("Recording", msg, kind="warning")
        self.demos_changed()
        self.notify(
            "Demonstration saved",
            f"{recording.name}: {recording.duration:.1f} s, {len(recording):,} samples.",
            kind="success",
        )

    def discard_recording(self) -> None:
        with self.lock:
            rec = self.recorder
            self.recorder = None
        if rec is not None:
            rec.discard()
        self.events.emit("recording")

    # -- demonstrations ----------------------------------------------------------------------------------
    def recordings(self) -> list[Any]:
        return list(self.session.recordings)

    def demo_names(self) -> list[str]:
        return [r.name for r in self.recordings()]

    def demo_color(self, i: int) -> tuple[int, int, int]:
        return PALETTE[i % len(PALETTE)]

    def demo_visible(self, i: int) -> bool:
        names = self.demo_names()
        return 0 <= i < len(names) and names[i] not in self.hidden_demos

    def demo_duration(self, i: int) -> float:
        return float(self.recordings()[i].duration)

    def demo_summaries(self) -> list[tuple[str, tuple[int, int, int], float, int, tuple[str, ...], bool]]:
        return [
            (r.name, self.demo_color(i), float(r.duration), len(r), tuple(r.arms), r.name not in self.hidden_demos)
            for i, r in enumerate(self.recordings())
        ]

    def demo(self, i: int, arm: str) -> Any:
        """The 8-D Demo of recording ``i`` for ``arm`` (FK once, cached)."""
        return self.demo_of(self.recordings()[i], arm)

    def demo_of(self, rec: Any, arm: str) -> Any:
        """The 8-D Demo of recording object ``rec`` for ``arm`` (FK once, cached)."""
        from studio.core.pipeline import demo_from_recording

        key = (id(rec), arm)
        hit = self._demo_cache.get(key)
        if hit is not None and hit[0] is rec:  # the same object, not a new one that reused a freed id
            return hit[1]
        d = demo_from_recording(rec, arm, baxter=self.baxter)
        self._demo_cache[key] = (rec, d)
        return d

    def demos_for(self, arm: str) -> list[tuple[int, Any]]:
        """(index, Demo) of every shown recording that taught ``arm``."""
        return [
            (i, self.demo_of(r, arm))
            for i, r in enumerate(self.recordings())  # one list: a demo deleted meanwhile cannot shift rows
            if arm in r.arms and r.name not in self.hidden_demos
        ]

    @property
    def hidden_demos(self) -> set[str]:
        """Names of the hidden demonstrations (saved with the session)."""
        return self.session.hidden_demos

    def set_demo_visible(self, i: int, visible: bool) -> None:
        with self.lock:
            self.session.set_demo_hidden(i, not visible)
        self.demos_changed()

    def rename_demo(self, i: int, name: str) -> None:
        name = name.strip()
        if not name:
            raise StudioError("Give the demonstration a name (it cannot be empty).")
        if name in self.demo_names() and self.demo_names()[i] != name:
            raise StudioError(f'There is already a demonstration called "{name}"; choose another name.')
        with self.lock:
            self.session.rename_demo(i, name)  # a hidden demo stays hidden under its new name
        self.demos_changed()

    def trim_demo(self, i: int, t0: float, t1: float) -> None:
        with self.lock:
            self.session.trim_demo(i, t0, t1)
        self.demos_changed()

    def delete_demo(self, i: int) -> None:
        with self.lock:
            self.session.delete_demo(i)
        self.demos_changed()

    #: Seconds within which a second Delete press confirms the first.
    DELETE_CONFIRM_S = 5.0

    def delete_demo_confirmed(self, i: int, *, now: float | None = None) -> bool:
        """The Delete button: the first press asks, a second press on the same demo within
        :attr:`DELETE_CONFIRM_S` deletes it for good. Returns True when the demo was deleted."""
        now = time.monotonic() if now is None else now
        name = self.demo_names()[i]
        pending = self._delete_pending
        if pending is not None and pending[0] == name and now - pending[1] <= self.DELETE_CONFIRM_S:
            self._delete_pending = None
            self.delete_demo(i)
            self.notify("Demonstration deleted", f'"{name}" was deleted.', kind="success")
            return True
        self._delete_pending = (name, now)
        self.notify(
            "Delete for good?",
            f'Press Delete again within {self.DELETE_CONFIRM_S:.0f} seconds to delete "{name}" from disk. '
            "To keep it but leave it out of learning, untick \"Show in the scene\" instead.",
            kind="warning",
        )
        return False

    def demos_changed(self) -> None:
        """The set of demonstrations changed: drop stale caches and redraw traces and key-points."""
        live = {id(r) for r in self.recordings()}
        self._demo_cache = {k: v for k, v in self._demo_cache.items() if k[0] in live and v[0] is not None}
        self.events.emit("demos")

    # -- key-points --------------------------------------------------------------------------------------
    def params(self) -> KeypointParams:
        with self.lock:
            return self._params

    def set_param(self, name: str, value: float) -> None:
        """Change one ε threshold (kept in the session; written to disk by the key-point thread)."""
        with self.lock:
            self._params = replace(self._params, **{name: float(value)})
            self._params_dirty = True

    def reset_params(self) -> None:
        with self.lock:
            self._params = KeypointParams()
            self.k_override = None
            self._params_dirty = True

    def set_k(self, k: int | None) -> None:
        """Choose k, the number of clusters (None: automatic); kept with the session like the ε values."""
        if k is not None and k < 1:
            raise StudioError("The number of clusters must be at least 1.")
        if k is not None and k > MAX_CLUSTERS:
            raise StudioError(f"The number of clusters can be at most {MAX_CLUSTERS:,}.")
        with self.lock:
            self.k_override = k
            self._params_dirty = True

    def persist_params(self) -> None:
        with self.lock:
            if not self._params_dirty:
                return
            self._params_dirty = False
            params, k = self._params, self.k_override
            session = self.session
        if params != session.params:
            session.set_params(params)
        if k != session.n_clusters:
            session.set_n_clusters(k)

    def keypoint_view(self) -> KeypointView:
        """Key-points of every shown demo and the k-means centroids per taught arm, for the current ε."""
        from studio.core.clustering import cluster_keypoints

        params = self.params()
        k = self.k_override
        view = KeypointView()
        for arm in self.selected_arms:
            demos = self.demos_for(arm)
            if not demos:
                continue
            idx = [np.asarray(self._kp_cache.extract(d, params)) for _, d in demos]
            for (i, d), ix in zip(demos, idx, strict=True):
                view.demos.append(
                    KeypointItem(
                        index=i,
                        arm=arm,
                        name=d.name,
                        color=self.demo_color(i),
                        count=len(ix),
                        points=np.asarray(d.position)[ix] if len(ix) else np.zeros((0, 3)),
                    )
                )
            try:
                centroids = cluster_keypoints([d for _, d in demos], idx, n_clusters=k, seed=0)
            except StudioError as exc:
                view.messages.append(f"{arm.capitalize()} arm: {exc}")
                continue
            view.centroids[arm] = np.asarray(centroids)
            view.k[arm] = len(centroids)
        self.persist_params()
        return view

    # -- training -----------------------------------------------------------------------------------------
    def skills(self) -> dict[str, Any]:
        return dict(self.session.skills)

    def skill_demo_names(self, arm: str) -> list[str]:
        """Names of the demonstrations the current skill of ``arm`` was learned from, in the skill's order
        (the order of its log-likelihoods and key-points), as they were called then."""
        sk = self.session.skills.get(arm)
        if sk is None:
            return []
        info = getattr(self.session, "skill_info", {}).get(arm, {})
        return [str(n) for n in (getattr(sk, "demo_names", None) or info.get("demos") or [])]

    def skill_demos(self, arm: str) -> list[tuple[str, int | None, Any]]:
        """(name, index, Demo) per demonstration the current skill of ``arm`` was learned from, in the skill's
        order; index and Demo are None for one renamed or deleted since."""
        by_name = {r.name: (i, r) for i, r in enumerate(self.recordings())}
        out: list[tuple[str, int | None, Any]] = []
        for nm in self.skill_demo_names(arm):
            hit = by_name.get(nm)
            if hit is not None and arm in hit[1].arms:
                out.append((nm, hit[0], self.demo_of(hit[1], arm)))
            else:
                out.append((nm, None, None))
        return out

    def train(self) -> Future:
        """Learn the skill of every taught arm from the shown demos on the work thread."""
        from studio.core.pipeline import learn_skill

        with self.lock:
            if self.training:
                raise StudioError("Training is already running; wait for it to finish.")
            arms = self.selected_arms
            per_arm = {arm: self.demos_for(arm) for arm in arms}
            for arm, demos in per_arm.items():
                if len(demos) < 2:
                    raise NotEnoughData(
                        f"The {arm} arm needs at least two shown demonstrations to learn from "
                        f"(it has {len(demos)}). Record more, or show hidden ones."
                    )
            params, k = self.params(), self.k_override
            session = self.session  # the skill belongs to the session it was learned from
            self.training = True
        self.events.emit("training")

        def job() -> dict[str, Any]:
            skills = {}
            for arm, demos in per_arm.items():
                skills[arm] = learn_skill(
                    [d for _, d in demos],
                    params,
                    n_clusters=k,
                    seed=0,
                    arm=arm,
                    baxter=self.baxter,
                    cache=self._kp_cache,
                )
            return skills

        def done(skills: dict[str, Any] | None) -> None:
            if skills is None:
                return
            demos = {arm: [d.name for _, d in per_arm[arm]] for arm in skills}
            with self.lock:
                session.set_skills(skills, params=params, demos=demos)
                current = session is self.session
                if current and self._params != params:  # ε changed while training: keep the new values
                    self._params_dirty = True
                self.training = False  # only now: sessions cannot be switched while training
            self.events.emit("training")
            if not current:
                self.notify("Training finished", f'The skill was learned for session "{session.name}".', kind="info")
                return
            self.persist_params()
            self._stop_preview()  # the loaded preview shows the previous skill
            self.events.emit("skill")
            self.notify("Training finished", "The robot learned the skill: open Preview to watch it.", kind="success")

        def job_done(result: Any) -> None:
            done(result)

        fut = self.submit(job, done=job_done, title="Training failed")
        fut.add_done_callback(lambda f: self._training_finished())
        return fut

    def _training_finished(self) -> None:
        if self.training:  # the job failed: done() never ran
            self.training = False
            self.events.emit("training")

    def ik_failures(self, arm: str) -> np.ndarray:
        """(n, 3) positions of the learned path the arm cannot reach exactly."""
        sk = self.session.skills.get(arm)
        jt = getattr(sk, "joint_trajectory", None)
        if sk is None or jt is None:
            return np.zeros((0, 3))
        bad = ~np.asarray(jt.converged, dtype=bool)
        if not bad.any():
            return np.zeros((0, 3))
        tr = sk.trajectory
        pos = np.column_stack([np.interp(jt.t, tr.t, tr.position[:, c]) for c in range(3)])
        return pos[bad]

    # -- preview and replay (the scene follows a ReplayBackend) ------------------------------------------
    def _preview_recording(self) -> Any:
        """The learned joint trajectories of all arms as one Recording (arms without a skill hold still)."""
        from studio.core.types import Recording

        skills = {a: s for a, s in self.session.skills.items() if getattr(s, "joint_trajectory", None) is not None}
        if not skills:
            raise NotEnoughData("There is no learned skill to preview yet: press Train first.")
        t_end = max(float(s.joint_trajectory.t[-1] - s.joint_trajectory.t[0]) for s in skills.values())
        n = max(2, int(t_end * 100.0) + 1)
        t = np.linspace(0.0, max(t_end, 0.01), n)
        q = np.tile(self.robot_q(), (n, 1))
        g = np.tile(self.robot_gripper(), (n, 1))
        for arm, s in skills.items():
            jt = s.joint_trajectory
            ts = np.asarray(jt.t) - float(jt.t[0])
            cols = slice(0, 7) if arm == "left" else slice(7, 14)
            tq = np.minimum(t, ts[-1])
            q[:, cols] = np.column_stack([np.interp(tq, ts, np.asarray(jt.q)[:, j]) for j in range(7)])
            tr = s.trajectory
            tg = np.asarray(tr.t) - float(tr.t[0])
            g[:, 0 if arm == "left" else 1] = np.interp(np.minimum(t, tg[-1]), tg, np.asarray(tr.gripper))
        return Recording(t=t, q=q, gripper=np.clip(g, 0, 100), arms=tuple(skills), name="learned skill")

    def _start_playback(self, kind: str, recording: Any, speed: float = 1.0) -> Playback:
        self._stop_playback()
        pb = Playback(kind, recording, speed)
        self._playback = pb
        self.display = pb.source
        pb.play()
        self.events.emit("playback")
        return pb

    def _stop_preview(self) -> None:
        """Unload the skill preview (if loaded) and show the live robot again."""
        pb = self._playback
        if pb is not None and pb.kind == "preview":
            self._stop_playback()
            self.show_live()

    def _stop_playback(self) -> None:
        pb, self._playback = self._playback, None
        if pb is not None:
            pb.close()
            self.events.emit("playback")

    def playback_kind(self) -> str | None:
        """The loaded playback ("preview" or "replay", playing or paused), or None when the scene is live."""
        pb = self._playback
        return pb.kind if pb is not None else None

    def preview_play(self, speed: float = 1.0) -> None:
        pb = self._playback
        if pb is not None and pb.kind == "preview":
            if pb.finished:
                pb.seek(0.0)
            pb.set_speed(speed)
            self.display = pb.source
            pb.play()
            return
        self._start_playback("preview", self._preview_recording(), speed)

    def preview_pause(self) -> None:
        pb = self._playback
        if pb is not None and pb.kind == "preview":
            pb.pause()

    def preview_speed(self, speed: float) -> None:
        pb = self._playback
        if pb is not None and pb.kind == "preview":
            pb.set_speed(speed)

    def preview_seek(self, t: float) -> None:
        pb = self._playback
        if pb is None or pb.kind != "preview":
            pb = self._start_playback("preview", self._preview_recording())
            pb.pause()
        pb.seek(t)
        self.display = pb.source

    def preview_position(self) -> float | None:
        pb = self._playback
        return pb.position if pb is not None and pb.kind == "preview" and pb.playing else None

    def preview_duration(self) -> float:
        skills = [s for s in self.session.skills.values() if getattr(s, "joint_trajectory", None) is not None]
        return max((float(s.joint_trajectory.t[-1] - s.joint_trajectory.t[0]) for s in skills), default=0.0)

    def replay_demo(self, i: int, speed: float = 1.0) -> float:
        """Replay recorded demonstration ``i`` on the (drawn) robot; returns its duration."""
        pb = self._playback
        rec = self.recordings()[i]
        if pb is not None and pb.kind == "replay" and pb.recording is rec:
            if pb.finished:
                pb.seek(0.0)
            self.display = pb.source
            pb.play()
        else:
            self._start_playback("replay", rec, speed)
        return float(rec.duration)

    def preview_stop(self) -> None:
        """Unload the preview and show the live robot again."""
        self._stop_preview()
        self.show_live()

    def replay_pause(self) -> None:
        pb = self._playback
        if pb is not None and pb.kind == "replay":
            pb.pause()

    def replay_stop(self) -> None:
        if self._playback is not None and self._playback.kind == "replay":
            self._stop_playback()
        self.show_live()

    def replay_seek(self, t: float) -> None:
        pb = self._playback
        if pb is None or pb.kind != "replay":
            raise StudioError("Press Play first to choose a demonstration to replay.")
        pb.seek(t)
        self.display = pb.source

    def replay_position(self) -> float | None:
        pb = self._playback
        return pb.position if pb is not None and pb.kind == "replay" and pb.playing else None

    # -- sessions -----------------------------------------------------------------------------------------
    def session_names(self) -> list[str]:
        return self.store.list_sessions()

    def _check_can_switch(self, doing: str) -> None:
        """Refuse, in plain words, to change the open session while recording or training."""
        if self.recorder is not None:
            raise StudioError(f"Stop the recording before {doing}.")
        if self.training:
            raise StudioError(f"Wait for the training to finish before {doing}.")

    def open_session(self, name: str) -> None:
        self._check_can_switch("opening another session")
        session = self.store.open(name)
        self._switch(session)
        self._startup_notes = self._session_notes(session)
        for title, body in self._startup_notes:
            self.notify(title, body, kind="warning")
        self.startup_notes_shown()  # told to every open tab

    def new_session(self, name: str) -> None:
        from studio.sessions import check_session_name

        self._check_can_switch("starting a new session")
        name = check_session_name(_typed_name(name))
        session = self.store.create(name, arms=self.selected_arms)
        self._switch(session)
        self.events.emit("sessions")

    def save_session(self) -> None:
        self.persist_params()
        self.store.save(self.session)
        self.notify("Saved", f'Session "{self.session.name}" is saved.', kind="success")

    def duplicate_session(self, new_name: str) -> None:
        from studio.sessions import check_session_name

        self._check_can_switch("copying the session")
        new_name = check_session_name(_typed_name(new_name))
        if self.store.path_of(new_name).exists():  # checked before "Saved" is shown
            raise InvalidInput(f'A session called "{new_name}" already exists; choose another name.')
        self.save_session()
        copy = self.store.duplicate(self.session.name, new_name)
        self._switch(copy)
        self.events.emit("sessions")

    def session_zip(self) -> tuple[str, bytes]:
        self.persist_params()
        self.store.save(self.session)
        return f"{self.session.name}.zip", self.store.export_zip(self.session.name)

    def import_session_zip(self, filename: str, data: bytes) -> str:
        """Add an uploaded session archive (validated first: a bad file changes nothing) and open it."""
        self._check_can_switch("uploading a session")  # checked first so that a refused upload adds nothing
        name = self.store.import_zip(data, archive=filename)
        self.events.emit("sessions")
        self.open_session(name)
        self.notify("Session uploaded", f'"{filename}" was added as session "{name}" and opened.', kind="success")
        return name

    def joint_trajectory_csv(self) -> tuple[str, bytes]:
        import tempfile

        from studio.csv_io import export_joint_trajectory_csv

        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / f"{self.session.name}-trajectory.csv"
            export_joint_trajectory_csv(self.session.skills, path)
            return path.name, path.read_bytes()

    def _switch(self, session: Any) -> None:
        if self.training and session is not self.session:  # a raced click (the actions check first)
            raise StudioError("Wait for the training to finish before changing the session.")
        self.persist_params()  # unsaved ε values belong to the session being left
        self._stop_playback()
        with self.lock:
            self.session = session
            self._params = session.params
            self._params_dirty = False
            self.k_override = session.n_clusters
            self._demo_cache = {}
            self.selected_arms = self._session_arms()
        self.show_live()
        self.events.emit("session")


def _typed_name(name: str | None) -> str:
    """A name typed in "New name", stripped; empty gets plain words instead of a format message."""
    name = (name or "").strip()
    if not name:
        raise InvalidInput("Type a name in 'New name' first.")
    return name
