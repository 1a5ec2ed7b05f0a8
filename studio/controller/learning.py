"""Learning settings: the ε thresholds (automatic ones follow the demonstrations, the teacher's are kept, one
Detail control moves the automatic ones together) and k, with the live key-point view recomputed off the GUI
threads (the newest request wins). Training is in :mod:`studio.controller.training`."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from studio.controller.context import Context
from studio.controller.demos import demo_color
from studio.controller.events import Topic
from studio.core.errors import StudioError
from studio.core.frames import DemoObjects
from studio.core.keypoints import KeypointCache
from studio.core.thresholds import NAMES, DemoStats, ThresholdSettings
from studio.core.types import Arm, Demo, KeypointParams
from studio.storage import MAX_CLUSTERS, Session

#: The thresholds are written to the session once they rested this long (never per slider step).
PERSIST_AFTER_S = 1.0


@dataclass(frozen=True)
class KeypointItem:
    """The key-points of one shown demonstration for one arm: ``points`` (count, 3) positions, m."""

    index: int
    arm: Arm
    name: str
    color: tuple[int, int, int]
    count: int
    points: np.ndarray


@dataclass(frozen=True)
class KeypointView:
    """What the key-points panel draws: per-demo key-points, per-arm centroids (k, 8) and k, notes; the
    thresholds it was computed with (``params`` per arm in real units, ``settings``) and a ``version`` that
    grows with every request (a newer request makes an older view stale)."""

    demos: tuple[KeypointItem, ...] = ()
    centroids: dict[Arm, np.ndarray] = field(default_factory=dict)
    k: dict[Arm, int] = field(default_factory=dict)
    messages: tuple[str, ...] = ()
    params: dict[Arm, KeypointParams] = field(default_factory=dict)
    settings: ThresholdSettings = field(default_factory=ThresholdSettings)
    version: int = 0
    #: arm -> the key-point indices of each shown demo (in the order of ``demos``).
    indices: dict[Arm, list[np.ndarray]] = field(default_factory=dict)
    #: arms whose key-points and centroids are drawn in the frames the skill learns them in (each stretch
    #: relative to the object it acts on, placed where the objects are now).
    in_frames: frozenset[Arm] = frozenset()


class ShownDemos(Protocol):
    """The shown demonstrations of an arm (:meth:`studio.controller.demos.Demos.for_arm`) and their objects
    (:meth:`~studio.controller.demos.Demos.objects_of`: contacts on the demonstrations' clock)."""

    def for_arm(self, arm: Arm) -> list[tuple[int, Demo]]: ...
    def objects_of(self, arm: Arm, indices: Sequence[int]) -> list[DemoObjects] | str: ...


#: Work done on the key-point thread after each new view while no newer request waits: ``follower(view,
#: stale)``, where ``stale()`` says a newer request arrived (stop early, the result would be old).
Follower = Callable[[KeypointView, Callable[[], bool]], None]


class KeypointTuning:
    """The threshold settings and k of the open session, and the key-points and centroids they give.

    The settings (:class:`~studio.core.thresholds.ThresholdSettings`) hold Detail and the thresholds the teacher
    set by hand; every other threshold follows the shown demonstrations of each arm (:meth:`params`). Changes
    are kept in memory and written to the session once they rested :data:`PERSIST_AFTER_S` (and on a session
    switch, training and shutdown), so moving a slider never waits for the disk. A change :meth:`request`\\ s a
    recomputation on the key-point thread, where only the newest request is served; the result is
    :attr:`view` and :attr:`Topic.KEYPOINTS` is emitted, then the followers run (the live path).
    """

    def __init__(self, ctx: Context, demos: ShownDemos) -> None:
        self.ctx = ctx
        self.demos = demos
        #: per-demo derived series, reused across ε changes (weak keys; the controller's, shared with learning)
        self.cache: KeypointCache = ctx.caches.keypoints
        self.view: KeypointView | None = None
        self.followers: list[Follower] = []
        self._session: Session = ctx.session  # the session the settings belong to
        self._settings: ThresholdSettings = ctx.session.thresholds
        self._k: int | None = ctx.session.n_clusters
        self._stats: dict[str, tuple[tuple[Demo, ...], DemoStats]] = {}
        self._framed: dict[Arm, tuple[object, object, tuple, list[Demo] | None]] = {}  # per session, scene, demos
        self._dirty = False
        self._changed = 0.0
        self._version = 0
        self._pending = threading.Event()
        self._stop = threading.Event()
        self._worker: threading.Thread | None = None
        ctx.on_leave(lambda doing: self.persist())  # unsaved values belong to the session being left
        ctx.events.on(Topic.SESSION, self._on_session)
        for topic in (Topic.DEMOS, Topic.SESSION, Topic.ARMS):
            ctx.events.on(topic, self.request)
        ctx.events.on(Topic.SCENE, self._on_frames)  # the objects moved: the view in their frames follows
        ctx.events.on(Topic.TRAINING, self._on_frames)  # "follow the objects" chosen or not

    def arms(self) -> tuple[Arm, ...]:
        return self.ctx.arms

    def add_follower(self, follower: Follower) -> None:
        """Run ``follower`` on the key-point thread after each new view (see :data:`Follower`)."""
        self.followers.append(follower)

    # -- thresholds and k ----------------------------------------------------------------------------------
    def settings(self) -> ThresholdSettings:
        with self.ctx.lock:
            return self._settings

    def shown_arm(self) -> Arm | None:
        """The arm whose values the sliders show: the first taught arm with shown demonstrations."""
        arms = self.arms()
        for arm in arms:
            if self.demos.for_arm(arm):
                return arm
        return arms[0] if arms else None

    def stats(self, arm: Arm) -> DemoStats | None:
        """What the automatic thresholds of ``arm`` follow (None without shown demonstrations); cached per set
        of demonstrations."""
        demos = tuple(d for _, d in self.demos.for_arm(arm))
        if not demos:
            return None
        hit = self._stats.get(arm)
        if hit is not None and len(hit[0]) == len(demos) and all(a is b for a, b in zip(hit[0], demos, strict=True)):
            return hit[1]
        st = DemoStats.of(demos)
        self._stats[arm] = (demos, st)
        return st

    def params(self, arm: Arm | None = None, settings: ThresholdSettings | None = None) -> KeypointParams:
        """The fourteen values in real units for ``arm``'s shown demonstrations (default: :meth:`shown_arm`)."""
        settings = settings or self.settings()
        arm = arm or self.shown_arm()
        st = self.stats(arm) if arm is not None else None
        if st is None:  # nothing to follow yet: the defaults, with the teacher's own values
            return KeypointParams(**{**KeypointParams().as_dict(), **settings.teacher})
        return settings.resolve(st)

    @property
    def k(self) -> int | None:
        """k chosen by hand, or None: automatic."""
        return self._k

    def _change(self, settings: ThresholdSettings, k: int | None, *, announce: bool) -> None:
        with self.ctx.lock:
            self._settings = settings
            self._k = k
            self._dirty = True
            self._changed = time.monotonic()
        self.request()
        if announce:
            self.ctx.emit(Topic.THRESHOLDS)

    def set_param(self, name: str, value: float) -> None:
        """The teacher set one ε threshold (real units): it is kept as theirs until made automatic again."""
        self._change(self.settings().set(name, float(value)), self._k, announce=False)

    def set_auto(self, name: str) -> None:
        """One threshold follows the demonstrations again."""
        if name not in NAMES:
            raise StudioError(f"Unknown key-point threshold {name}.")
        self._change(self.settings().auto(name), self._k, announce=True)

    def all_auto(self) -> None:
        """Every threshold follows the demonstrations again (Detail is kept)."""
        self._change(self.settings().all_auto(), self._k, announce=True)

    def set_detail(self, detail: float) -> None:
        """Fewer (−) ↔ more (+) key-points: moves the automatic thresholds together, keeps the teacher's."""
        self._change(self.settings().with_detail(float(detail)), self._k, announce=True)

    def reset(self) -> None:
        """Every threshold automatic, Detail 0, k automatic."""
        self._change(ThresholdSettings(), None, announce=True)

    def restore(self, settings: ThresholdSettings, k: int | None) -> None:
        """Settings and k at once (Suggest applied, or undone)."""
        if k is not None:
            self._check_k(k)
        self._change(settings, k, announce=True)

    @staticmethod
    def _check_k(k: int) -> None:
        if k < 1:
            raise StudioError("The number of clusters must be at least 1.")
        if k > MAX_CLUSTERS:
            raise StudioError(f"The number of clusters can be at most {MAX_CLUSTERS:,}.")

    def set_k(self, k: int | None) -> None:
        """Choose k, the number of clusters (None: automatic); kept with the session like the ε values."""
        if k is not None:
            self._check_k(k)
        self._change(self.settings(), k, announce=False)

    def persist(self, force: bool = False) -> None:
        """Write changed settings (with the values they resolve to now, for older studios) and k; with
        ``force`` whatever differs from the session's, changed here or not."""
        with self.ctx.lock:
            if not (self._dirty or force):
                return
            self._dirty = False
            settings, k, session = self._settings, self._k, self._session
        if session.read_only:  # an example keeps its own settings; these stay in memory while it is open
            return
        params = self.params(settings=settings)
        if settings != session.thresholds or params != session.params:
            session.set_params(params, settings)
        if k != session.n_clusters:
            session.set_n_clusters(k)

    def _on_session(self) -> None:
        """Another session is open: take its settings and k (the old ones were kept before it changed)."""
        with self.ctx.lock:
            if self.ctx.session is self._session:  # the same session again: its settings here are the newest
                return
            session = self._session = self.ctx.session
            self._settings = session.thresholds
            self._k = session.n_clusters
            self._dirty = False
            self._stats.clear()

    # -- the key-point view ----------------------------------------------------------------------------------
    def compute(self) -> KeypointView:
        """Key-points of every shown demo and the k-means centroids per taught arm, for the current settings."""
        from studio.core.clustering import cluster_keypoints

        settings, k, version = self.settings(), self._k, self._version
        items: list[KeypointItem] = []
        centroids: dict[Arm, np.ndarray] = {}
        ks: dict[Arm, int] = {}
        used: dict[Arm, KeypointParams] = {}
        indices: dict[Arm, list[np.ndarray]] = {}
        messages: list[str] = []
        framed: set[Arm] = set()
        for arm in self.arms():
            demos = self.demos.for_arm(arm)
            if not demos:
                continue
            params = used[arm] = self.params(arm, settings)
            idx = indices[arm] = [np.asarray(self.cache.extract(d, params)) for _, d in demos]
            shown = self.in_frames(arm, demos)
            if shown is None:
                shown = [d for _, d in demos]
            else:
                framed.add(arm)
            items += [_item(i, arm, d, ix) for (i, _), d, ix in zip(demos, shown, idx, strict=True)]
            try:
                c = cluster_keypoints(shown, idx, n_clusters=k, seed=0)
            except StudioError as exc:
                messages.append(f"{arm.capitalize()} arm: {exc}")
                continue
            centroids[arm] = np.asarray(c)
            ks[arm] = len(c)
        return KeypointView(
            tuple(items), centroids, ks, tuple(messages), used, settings, version, indices, frozenset(framed)
        )

    def in_frames(self, arm: Arm, demos: Sequence[tuple[int, Demo]]) -> list[Demo] | None:
        """The shown demos of ``arm`` as a skill that follows the objects learns them (each stretch in its
        object's frame, placed where the objects are now), or None when the session's skills keep fixed places
        or these demos cannot follow the objects."""
        from studio.controller.placed import rules_of
        from studio.core.segment_view import demos_in_frames
        from studio.world.relative import objects_now

        session = self.ctx.session
        if session.frames != "objects":
            return None
        scene = session.objects.scene
        sig = tuple((i, id(d), len(d)) for i, d in demos)
        hit = self._framed.get(arm)
        if hit is not None and hit[0] is session and hit[1] is scene and hit[2] == sig:  # same objects, not equal
            return hit[3]
        indices = [i for i, _ in demos]
        objs = self.demos.objects_of(arm, indices)
        moved = None
        if not isinstance(objs, str):
            rules = rules_of(session, objs, indices)
            moved = demos_in_frames([d for _, d in demos], objs, objects_now(scene), rules=rules)
        self._framed[arm] = (session, scene, sig, moved)
        return moved

    def _on_frames(self) -> None:
        """The objects moved, or the way skills are placed changed: recompute when the view depends on it."""
        view = self.view
        if self.ctx.session.frames == "objects" or (view is not None and view.in_frames):
            self.request()

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
        with self.ctx.lock:
            self._version += 1
        self._pending.set()

    def stale(self) -> bool:
        """A newer request waits: work for the current view would be out of date."""
        return self._pending.is_set() or self._stop.is_set()

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
            if not self._pending.wait(timeout=0.25):
                self._persist_if_rested()
                continue
            self._pending.clear()
            if self._stop.is_set():  # the studio is stopping: the views may already be gone
                return
            try:
                view = self.refresh()
            except Exception as exc:
                self.ctx.report(exc, title="Could not find the key-points")
                continue
            self._follow(view, self.followers)

    def _follow(self, view: KeypointView, followers: Sequence[Follower]) -> None:
        for follower in followers:
            if self.stale():
                return
            try:
                follower(view, self.stale)
            except Exception as exc:
                self.ctx.report(exc, title="Could not draw the learned path")

    def _persist_if_rested(self) -> None:
        if self._dirty and time.monotonic() - self._changed >= PERSIST_AFTER_S:
            try:
                self.persist()
            except Exception as exc:
                self.ctx.report(exc, title="Could not save the key-point settings")


def _item(i: int, arm: Arm, d: Demo, ix: np.ndarray) -> KeypointItem:
    points = np.asarray(d.position)[ix] if len(ix) else np.zeros((0, 3))
    return KeypointItem(index=i, arm=arm, name=d.name, color=demo_color(i), count=len(ix), points=points)
