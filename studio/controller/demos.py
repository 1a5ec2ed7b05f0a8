"""The session's demonstrations as the studio shows them: colours, visibility, the 8-D Demo per arm (FK once,
cached), and the edits (hide, rename, trim, delete with a second click to confirm)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.core.errors import StudioError
from studio.core.frames import DemoObjects
from studio.core.pace import TakeClock, take_clock
from studio.core.types import Arm, Demo, Recording
from studio.storage.format import WORK_SAMPLES, check_demo_name, shown
from studio.words.controls import Control
from studio.world import WorldEvent

#: Demo colours (RGB), distinct on the light background, never red (red marks the cluster centroids) and never
#: cyan (the learned path).
PALETTE: tuple[tuple[int, int, int], ...] = (
    (31, 119, 180),
    (44, 160, 44),
    (255, 127, 14),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (120, 100, 20),
    (57, 59, 121),
)


def demo_color(i: int) -> tuple[int, int, int]:
    """The colour of demonstration ``i`` (RGB)."""
    return PALETTE[i % len(PALETTE)]


@dataclass(frozen=True)
class DemoSummary:
    """One row of the demo list."""

    index: int
    name: str
    color: tuple[int, int, int]
    duration: float
    samples: int
    arms: tuple[Arm, ...]
    visible: bool
    #: the demonstration as taught: first to last motion, pauses shortened unless kept (:class:`TakeClock`)
    clock: TakeClock | None = None


class Keep(Protocol):
    """Keeps a demonstration just thrown away, for Undo (:meth:`studio.controller.undo.Undo.keep`)."""

    def __call__(
        self, recording: Recording, events: Sequence[WorldEvent] = (), *, hidden: bool = False, what: str = ""
    ) -> None: ...


def _forget(recording: Recording, events: Sequence[WorldEvent] = (), *, hidden: bool = False, what: str = "") -> None:
    """No Undo: what is thrown away is gone."""


class Demos:
    """The open session's demonstrations; every edit is saved at once and announced as :attr:`Topic.DEMOS`
    (a new take too: :class:`~studio.controller.teaching.Teaching` emits it). Another session clears the cache."""

    def __init__(self, ctx: Context, keep: Keep | None = None) -> None:
        self.ctx = ctx
        #: Keeps a deleted demonstration for Undo.
        self.keep: Keep = keep or _forget
        self._cache: dict[tuple[int, str], tuple[Recording, Demo, int]] = {}
        self._clocks: dict[int, tuple[Recording, int, bool, TakeClock]] = {}
        self._taught: dict[tuple[int, str], tuple[TakeClock, Demo]] = {}
        self._told_stride = 1
        #: names given in this session, old → new: what became of a name a click in another tab still shows
        self._renamed: dict[str, str] = {}
        ctx.events.on(Topic.DEMOS, self._prune)
        ctx.events.on(Topic.SESSION, self.clear)

    # -- reading -------------------------------------------------------------------------------------------
    def recordings(self) -> list[Recording]:
        return list(self.ctx.session.recordings)

    def names(self) -> list[str]:
        return [r.name for r in self.recordings()]

    @property
    def hidden(self) -> set[str]:
        """Names of the hidden demonstrations (saved with the session)."""
        return self.ctx.session.hidden_demos

    @staticmethod
    def color(i: int) -> tuple[int, int, int]:
        return demo_color(i)

    def visible(self, i: int) -> bool:
        names = self.names()
        return 0 <= i < len(names) and names[i] not in self.hidden

    def duration(self, i: int) -> float:
        return float(self.recordings()[i].duration)

    def summaries(self) -> list[DemoSummary]:
        hidden = self.hidden
        return [
            DemoSummary(
                i, r.name, self.color(i), float(r.duration), len(r), tuple(r.arms), r.name not in hidden, self.clock(r)
            )
            for i, r in enumerate(self.recordings())
        ]

    def demo(self, i: int, arm: Arm) -> Demo:
        """The 8-D Demo of recording ``i`` for ``arm`` as taught (FK once, cached)."""
        return self.demo_of(self.recordings()[i], arm)

    def keeps_pauses(self, i: int) -> bool:
        """Whether demonstration ``i`` is learned with its pauses (the teacher kept them)."""
        names = self.names()
        return 0 <= i < len(names) and names[i] in self.ctx.session.pauses_kept

    def set_keep_pauses(self, i: int, keep: bool) -> None:
        """Learn demonstration ``i`` with its pauses as they were (``keep``), or shortened (the default)."""
        with self.ctx.lock:
            self.ctx.session.set_demo_pauses(i, keep)
        self.changed()

    def clock(self, rec: Recording) -> TakeClock:
        """How take ``rec`` becomes a demonstration (first to last motion of its arms, pauses shortened unless
        kept; cached)."""
        step, kept = self.stride(), rec.name in self.ctx.session.pauses_kept
        hit = self._clocks.get(id(rec))
        if hit is not None and hit[0] is rec and hit[1] == step and hit[2] == kept:
            return hit[3]
        clock = take_clock([self.take_of(rec, arm) for arm in rec.arms], keep=kept)
        self._clocks[id(rec)] = (rec, step, kept, clock)
        return clock

    def objects_of(self, arm: Arm, indices: Sequence[int]) -> list[DemoObjects] | str:
        """The objects and ``arm``'s contacts of demonstrations ``indices``, each contact at its moment in the
        demonstration as taught, or why a skill cannot follow them (plain words)."""
        from studio.controller.placed import demo_objects_of

        objs = demo_objects_of(self.ctx.session, arm, indices)
        if isinstance(objs, str):
            return objs
        recs = self.recordings()
        return [self.clock(recs[i]).objects(o) for i, o in zip(indices, objs, strict=True)]

    def stride(self) -> int:
        """Every how many samples the demonstrations are worked on: 1, or more when all of them together hold
        more than :data:`~studio.storage.format.WORK_SAMPLES` (the recordings themselves stay whole)."""
        total = sum(len(r) for r in self.recordings())
        return max(1, -(-total // WORK_SAMPLES))

    def demo_of(self, rec: Recording, arm: Arm) -> Demo:
        """The 8-D Demo of recording object ``rec`` for ``arm`` as taught (:meth:`clock`), at :meth:`stride`."""
        clock = self.clock(rec)
        hit = self._taught.get((id(rec), arm))
        if hit is not None and hit[0] is clock:  # a clock is made for one recording object, stride and choice
            return hit[1]
        d = clock.demo(self.take_of(rec, arm))
        self._taught[(id(rec), arm)] = (clock, d)
        return d

    def take_of(self, rec: Recording, arm: Arm) -> Demo:
        """The 8-D Demo of the whole take ``rec`` for ``arm`` (FK once, cached), at :meth:`stride`."""
        from studio.core.pipeline import demo_from_recording

        step = self.stride()
        key = (id(rec), arm)
        hit = self._cache.get(key)
        if hit is not None and hit[0] is rec and hit[2] == step:  # the same object, not one that reused its id
            return hit[1]
        src = rec
        if step > 1:
            self._tell_stride(step)
            src = Recording(t=rec.t[::step], q=rec.q[::step], gripper=rec.gripper[::step], arms=rec.arms, name=rec.name)
        d = demo_from_recording(src, arm, baxter=self.ctx.baxter)
        self._cache[key] = (rec, d, step)
        return d

    def _tell_stride(self, step: int) -> None:
        if self._told_stride == step:
            return
        self._told_stride = step
        total = sum(len(r) for r in self.recordings())
        nth = {2: "2nd", 3: "3rd"}.get(step, f"{step}th")
        self.ctx.notify(
            "Long demonstrations",
            f"These demonstrations hold {total:,} samples together. To stay within the computer's memory the "
            f"studio learns from and draws every {nth} sample ({-(-total // step):,}); the recordings are kept "
            "whole.",
            kind="info",
        )

    def gripper_marks(self, rec: Recording, arm: Arm) -> tuple[np.ndarray, np.ndarray]:
        """Where ``arm``'s gripper closed and where it opened in recording ``rec``: two (n, 3) arrays (m), with
        the same close/open rule as the objects (:func:`studio.world.gripper_actions`)."""
        from studio.world import gripper_actions

        d = self.demo_of(rec, arm)
        actions = gripper_actions(np.asarray(d.gripper))
        pos = np.asarray(d.position)
        closes = [pos[k] for k, a in actions if a == "close"]
        opens = [pos[k] for k, a in actions if a == "open"]
        return np.reshape(closes, (-1, 3)), np.reshape(opens, (-1, 3))

    def for_arm(self, arm: Arm) -> list[tuple[int, Demo]]:
        """(index, Demo) of every shown recording that taught ``arm`` (what learning uses)."""
        hidden = self.hidden
        return [
            (i, self.demo_of(r, arm))
            for i, r in enumerate(self.recordings())  # one list: a demo deleted meanwhile cannot shift rows
            if arm in r.arms and r.name not in hidden
        ]

    # -- edits ---------------------------------------------------------------------------------------------
    def set_visible(self, i: int, visible: bool) -> None:
        with self.ctx.lock:
            self.ctx.session.set_demo_hidden(i, not visible)
        self.changed()

    def rename(self, i: int, name: str) -> None:
        name = name.strip()
        if not name:
            raise StudioError("Give the demonstration a name (it cannot be empty).")
        name = check_demo_name(name)  # length and visible characters, before the name is shown anywhere
        names = self.names()
        if name in names and names[i] != name:
            raise StudioError(f'There is already a demonstration called "{name}"; choose another name.')
        with self.ctx.lock:
            old = self.ctx.session.recordings[i].name if 0 <= i < len(self.ctx.session.recordings) else None
            self.ctx.session.rename_demo(i, name)  # a hidden demo stays hidden under its new name
            if old is not None and old != name:
                self._renamed[old] = name
        self.changed()

    def trim(self, i: int, t0: float, t1: float) -> None:
        """Keep demonstration ``i`` from ``t0`` to ``t1`` s; its objects are played again from its start so the
        trimmed take starts with them as they were at ``t0``."""
        from studio.world import trimmed_events

        with self.ctx.lock:
            session = self.ctx.session
            events = None
            if 0 <= i < len(session.recordings) and t0 < t1:
                r = session.recordings[i]
                old = session.objects.events(session.demo_files[i])
                scene = session.objects.scene
                events = trimmed_events(old, r.t, r.q, r.gripper, scene, t0, t1, baxter=self.ctx.baxter)
            session.trim_demo(i, t0, t1, events=events)
        self.changed()

    def renamed_to(self, name: str) -> str | None:
        """The name the demonstration called ``name`` has now, when it was renamed since (None otherwise)."""
        seen, new = {name}, self._renamed.get(name)
        while new is not None and new in self._renamed and new not in seen:
            seen.add(new)
            new = self._renamed[new]
        return new if new is not None and new in self.names() else None

    def gone(self, name: str) -> str:
        """What became of the demonstration called ``name``, which is no longer listed, in words."""
        new = self.renamed_to(name)
        if new is not None:
            return f"{shown(name)} was renamed to {shown(new)}"
        return f"{shown(name)} was deleted"

    def delete(self, i: int, *, name: str | None = None) -> None:
        """Delete demonstration ``i``; it is kept in memory a while for Undo (:mod:`studio.controller.undo`).
        ``name``: the one the teacher chose, deleted wherever it is in the list by now; when there is none of that
        name any more (another tab deleted or renamed it first), nothing is deleted and the teacher is told."""
        with self.ctx.lock:
            session = self.ctx.session
            names = [r.name for r in session.recordings]
            if name is not None:
                if name not in names:
                    new = self.renamed_to(name)
                    again = (
                        f" To delete it, choose {shown(new)} and {self.ctx.say(Control.DELETE)} again." if new else ""
                    )
                    raise StudioError(
                        f"{self.gone(name)} (in another tab?) before your click arrived; nothing was deleted.{again}"
                    )
                i = names.index(name)
            rec = session.recordings[i] if 0 <= i < len(session.recordings) else None
            events = session.objects.events(session.demo_files[i]) if rec is not None else ()
            hidden = rec is not None and rec.name in session.hidden_demos
            session.delete_demo(i)
        self.changed()
        if rec is not None:
            self.keep(rec, events, hidden=hidden)
            self.ctx.notify(
                "Demonstration deleted",
                f'"{rec.name}" was deleted. {self.ctx.say(Control.UNDO, first=True)} (in Teach) to bring it back.',
                kind="success",
            )

    def changed(self) -> None:
        """The set of demonstrations changed: tell the views (stale cache entries are dropped then)."""
        self.ctx.emit(Topic.DEMOS)

    def _prune(self) -> None:
        live = {id(r) for r in self.recordings()}
        self._cache = {k: v for k, v in self._cache.items() if k[0] in live}
        self._clocks = {k: v for k, v in self._clocks.items() if k in live}
        self._taught = {k: v for k, v in self._taught.items() if k[0] in live}

    def clear(self) -> None:
        """Forget everything cached (another session was opened)."""
        self._cache = {}
        self._clocks = {}
        self._taught = {}
        self._told_stride = 1
        self._renamed = {}
