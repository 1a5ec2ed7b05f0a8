"""Learning: the ε thresholds and k with the live key-point view (recomputed off the GUI threads, the newest
request wins), then training the skill of every taught arm and what the panels show about it."""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field, replace

import numpy as np

from studio.controller.context import Context
from studio.controller.demos import Demos
from studio.controller.events import Topic
from studio.controller.playback import Player
from studio.core.errors import NotEnoughData, StudioError
from studio.core.keypoints import KeypointCache
from studio.core.types import Demo, KeypointParams, Skill
from studio.storage import MAX_CLUSTERS, Session


@dataclass(frozen=True)
class KeypointItem:
    """The key-points of one shown demonstration for one arm: ``points`` (count, 3) positions, m."""

    index: int
    arm: str
    name: str
    color: tuple[int, int, int]
    count: int
    points: np.ndarray


@dataclass(frozen=True)
class KeypointView:
    """What the key-points panel draws: per-demo key-points, per-arm centroids (k, 8) and k, notes."""

    demos: tuple[KeypointItem, ...] = ()
    centroids: dict[str, np.ndarray] = field(default_factory=dict)
    k: dict[str, int] = field(default_factory=dict)
    messages: tuple[str, ...] = ()


class KeypointTuning:
    """The ε thresholds and k of the open session, and the key-points and centroids they give.

    Changes are kept in memory and written to the session by :meth:`persist` (after each recomputation, on a
    session switch and at shutdown), so dragging a slider never writes to disk per step. A change
    (threshold, k, demos, arms, session) :meth:`request`\\ s a recomputation on the key-point thread, where
    only the newest request is served; the result is :attr:`view` and :attr:`Topic.KEYPOINTS` is emitted.
    """

    def __init__(self, ctx: Context, demos: Demos, arms: Callable[[], tuple[str, ...]]) -> None:
        self.ctx = ctx
        self.demos = demos
        self.arms = arms
        self.cache = KeypointCache()  # per-demo derived series, reused across ε changes (weak keys)
        self.view: KeypointView | None = None
        self._params: KeypointParams = ctx.session.params
        self._k: int | None = ctx.session.n_clusters
        self._dirty = False
        self._pending = threading.Event()
        self._stop = threading.Event()
        self._worker: threading.Thread | None = None
        for topic in (Topic.DEMOS, Topic.SESSION, Topic.ARMS):
            ctx.events.on(topic, self.request)

    # -- thresholds and k ----------------------------------------------------------------------------------
    def params(self) -> KeypointParams:
        with self.ctx.lock:
            return self._params

    @property
    def k(self) -> int | None:
        """k chosen by hand, or None: automatic."""
        return self._k

    def set_param(self, name: str, value: float) -> None:
        """Change one ε threshold (kept with the session)."""
        with self.ctx.lock:
            self._params = replace(self._params, **{name: float(value)})
            self._dirty = True
        self.request()

    def reset(self) -> None:
        """Every threshold back to its default, k automatic."""
        with self.ctx.lock:
            self._params = KeypointParams()
            self._k = None
            self._dirty = True
        self.request()

    def set_k(self, k: int | None) -> None:
        """Choose k, the number of clusters (None: automatic); kept with the session like the ε values."""
        if k is not None and k < 1:
            raise StudioError("The number of clusters must be at least 1.")
        if k is not None and k > MAX_CLUSTERS:
            raise StudioError(f"The number of clusters can be at most {MAX_CLUSTERS:,}.")
        with self.ctx.lock:
            self._k = k
            self._dirty = True
        self.request()

    def keep_if_changed(self, learned_with: KeypointParams) -> None:
        """A skill was saved with ``learned_with`` as the session's thresholds: if the current ones differ
        (changed while training), they still have to be written."""
        with self.ctx.lock:
            if self._params != learned_with:
                self._dirty = True

    def persist(self) -> None:
        """Write changed thresholds and k to the open session."""
        with self.ctx.lock:
            if not self._dirty:
                return
            self._dirty = False
            params, k, session = self._params, self._k, self.ctx.session
        if params != session.params:
            session.set_params(params)
        if k != session.n_clusters:
            session.set_n_clusters(k)

    def on_session(self, session: Session) -> None:
        """Another session is open: take its thresholds and k (persist the old ones first)."""
        with self.ctx.lock:
            self._params = session.params
            self._k = session.n_clusters
            self._dirty = False

    # -- the key-point view ----------------------------------------------------------------------------------
    def compute(self) -> KeypointView:
        """Key-points of every shown demo and the k-means centroids per taught arm, for the current ε."""
        from studio.core.clustering import cluster_keypoints

        params, k = self.params(), self._k
        items: list[KeypointItem] = []
        centroids: dict[str, np.ndarray] = {}
        ks: dict[str, int] = {}
        messages: list[str] = []
        for arm in self.arms():
            demos = self.demos.for_arm(arm)
            if not demos:
                continue
            idx = [np.asarray(self.cache.extract(d, params)) for _, d in demos]
            items += [_item(i, arm, d, ix) for (i, d), ix in zip(demos, idx, strict=True)]
            try:
                c = cluster_keypoints([d for _, d in demos], idx, n_clusters=k, seed=0)
            except StudioError as exc:
                messages.append(f"{arm.capitalize()} arm: {exc}")
                continue
            centroids[arm] = np.asarray(c)
            ks[arm] = len(c)
        self.persist()
        return KeypointView(tuple(items), centroids, ks, tuple(messages))

    def refresh(self) -> KeypointView:
        """Compute the view now, keep it as :attr:`view`, tell the views, and notify its messages."""
        view = self.compute()
        self.view = view
        self.ctx.emit(Topic.KEYPOINTS)
        for msg in view.messages:  # e.g. too few key-points to form the clusters
            self.ctx.notify("Key-points", msg, kind="warning")
        return view

    def request(self) -> None:
        """Recompute on the key-point thread soon (several requests before it runs count as one)."""
        self._pending.set()

    def start(self) -> None:
        """Start the key-point thread (it serves a first request at once)."""
        if self._worker is None:
            self._worker = threading.Thread(target=self._loop, name="studio-keypoints", daemon=True)
            self._worker.start()
            self.request()

    def close(self) -> None:
        self._stop.set()
        self._pending.set()
        if self._worker is not None:
            self._worker.join(timeout=5.0)

    def _loop(self) -> None:
        while not self._stop.is_set():
            if not self._pending.wait(timeout=0.5):
                continue
            self._pending.clear()
            if self._stop.is_set():  # the studio is stopping: the views may already be gone
                return
            try:
                self.refresh()
            except Exception as exc:
                self.ctx.report(exc, title="Could not find the key-points")


def _item(i: int, arm: str, d: Demo, ix: np.ndarray) -> KeypointItem:
    points = np.asarray(d.position)[ix] if len(ix) else np.zeros((0, 3))
    return KeypointItem(index=i, arm=arm, name=d.name, color=Demos.color(i), count=len(ix), points=points)


@dataclass(frozen=True)
class UsedDemo:
    """A demonstration a skill was learned from: its name then, and its index and Demo now (None when it was
    renamed or deleted since)."""

    name: str
    index: int | None
    demo: Demo | None


class Training:
    """Learns the skill of every taught arm on the work thread, and answers what the panels show about it."""

    def __init__(
        self, ctx: Context, demos: Demos, tuning: KeypointTuning, arms: Callable[[], tuple[str, ...]], player: Player
    ) -> None:
        self.ctx = ctx
        self.demos = demos
        self.tuning = tuning
        self.arms = arms
        self.player = player
        self.busy = False

    def skills(self) -> dict[str, Skill]:
        return dict(self.ctx.session.skills)

    def train(self) -> Future[dict[str, Skill] | None]:
        """Learn the skill of every taught arm from the shown demos on the work thread."""
        from studio.core.pipeline import learn_skill

        with self.ctx.lock:
            if self.busy:
                raise StudioError("Training is already running; wait for it to finish.")
            per_arm = {arm: self.demos.for_arm(arm) for arm in self.arms()}
            for arm, demos in per_arm.items():
                if len(demos) < 2:
                    raise NotEnoughData(
                        f"The {arm} arm needs at least two shown demonstrations to learn from "
                        f"(it has {len(demos)}). Record more, or show hidden ones."
                    )
            params, k = self.tuning.params(), self.tuning.k
            session = self.ctx.session  # the skill belongs to the session it was learned from
            self.busy = True
        self.ctx.emit(Topic.TRAINING)
        baxter, cache = self.ctx.baxter, self.tuning.cache

        def job() -> dict[str, Skill]:
            return {
                arm: learn_skill(
                    [d for _, d in demos], params, n_clusters=k, seed=0, arm=arm, baxter=baxter, cache=cache
                )
                for arm, demos in per_arm.items()
            }

        def done(skills: dict[str, Skill]) -> None:
            names = {arm: [d.name for _, d in per_arm[arm]] for arm in skills}
            with self.ctx.lock:
                session.set_skills(skills, params=params, demos=names)
                current = session is self.ctx.session
                if current:  # ε changed while training: keep the new values
                    self.tuning.keep_if_changed(params)
                self.busy = False  # only now: sessions cannot be switched while training
            self.ctx.emit(Topic.TRAINING)
            if not current:
                self.ctx.notify(
                    "Training finished", f'The skill was learned for session "{session.name}".', kind="info"
                )
                return
            self.tuning.persist()
            self.player.unload_preview()  # the loaded preview shows the previous skill
            self.ctx.emit(Topic.SKILL)
            self.ctx.notify(
                "Training finished", "The robot learned the skill: open Preview to watch it.", kind="success"
            )

        fut = self.ctx.submit(job, done=done, title="Training failed")
        fut.add_done_callback(lambda f: self._finished())
        return fut

    def _finished(self) -> None:
        if self.busy:  # the job failed: done() never ran
            self.busy = False
            self.ctx.emit(Topic.TRAINING)

    def skill_demo_names(self, arm: str) -> list[str]:
        """Names of the demonstrations the current skill of ``arm`` was learned from, in the skill's order
        (the order of its log-likelihoods and key-points), as they were called then."""
        sk = self.ctx.session.skills.get(arm)
        if sk is None:
            return []
        info = self.ctx.session.skill_info.get(arm)
        return [str(n) for n in (sk.demo_names or (info.demos if info is not None else ()))]

    def skill_demos(self, arm: str) -> list[UsedDemo]:
        """Every demonstration the current skill of ``arm`` was learned from, in the skill's order."""
        by_name = {r.name: (i, r) for i, r in enumerate(self.demos.recordings())}
        out: list[UsedDemo] = []
        for nm in self.skill_demo_names(arm):
            hit = by_name.get(nm)
            if hit is not None and arm in hit[1].arms:
                out.append(UsedDemo(nm, hit[0], self.demos.demo_of(hit[1], arm)))
            else:
                out.append(UsedDemo(nm, None, None))
        return out

    def ik_failures(self, arm: str) -> np.ndarray:
        """(n, 3) positions of the learned path the arm cannot reach exactly."""
        sk = self.ctx.session.skills.get(arm)
        jt = sk.joint_trajectory if sk is not None else None
        if sk is None or jt is None:
            return np.zeros((0, 3))
        bad = ~np.asarray(jt.converged, dtype=bool)
        if not bad.any():
            return np.zeros((0, 3))
        tr = sk.trajectory
        pos = np.column_stack([np.interp(jt.t, tr.t, tr.position[:, c]) for c in range(3)])
        return pos[bad]
