"""The task's goal as data: which object goes onto which (:class:`Placement`), as a task set-up declares it
(:func:`declared`), as the demonstrations show it (:func:`read_goal`), and the goal a session is judged by
(:func:`session_goal`: the declared or confirmed goal, each placement matched to the release that does it)."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from studio.core.errors import InvalidInput
from studio.core.frames import CONTRADICT_M, DECIDE_M, YAW_M_PER_RAD, ObjectAt, frame_of, to_local
from studio.world.events import ObjectPose, WorldEvent
from studio.world.geometry import SUCCESS_TOL, finite

#: ``Placement.onto`` for "back where it started" and for "a spot on the table" (a fixed place).
START = "where it started"
TABLE = "a spot on the table"
#: Where an object comes to rest is not a target of its own.
SURFACES = frozenset({"table", "floor", "hand"})
#: How many placements a goal holds at most (a bound on what a session stores).
MAX_PLACEMENTS = 40


@dataclass(frozen=True)
class Placement:
    """One step of a goal: ``object`` put onto ``onto`` — another object's name, :data:`START` or :data:`TABLE`.

    ``spot``: where on it (x, y, z, heading in the target's frame: the object's, where ``object`` started, or
    the robot's for the table); None: the target's centre (or exactly where it started). The n-th placement
    of an object in a goal is its n-th release.
    """

    object: str
    onto: str
    spot: tuple[float, float, float, float] | None = None

    @property
    def target(self) -> str:
        """What ``onto`` is: "object", "start" or "table"."""
        return {START: "start", TABLE: "table"}.get(self.onto, "object")

    def to_dict(self) -> dict[str, Any]:
        return {"object": self.object, "onto": self.onto, "spot": None if self.spot is None else list(self.spot)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Placement:
        spot = d.get("spot")
        s = None if spot is None else finite("goal spot", spot, 4)
        obj, onto = str(d["object"]), str(d["onto"])
        if not obj or not onto or len(obj) > 60 or len(onto) > 60:
            raise InvalidInput("A goal names an object of 1 to 60 characters.")
        return cls(obj, onto, None if s is None else (s[0], s[1], s[2], s[3]))


@dataclass(frozen=True)
class Goal:
    """The goal a run is judged by.

    Attributes:
        placements: in order; an object's n-th placement is its n-th release.
        source: "set-up" (the task set-up's), "you" (confirmed or corrected by the teacher), "demonstrations"
            (read from them, not confirmed yet) or "" (there is none).
        arms: (object, arm) the arm that carried each object in the demonstrations.
        notes: facts worth telling ("2 of 3 demonstrations pick up the block once …").
        differs: the declared placements no demonstration did (the teacher may want to correct the goal).
    """

    placements: tuple[Placement, ...] = ()
    source: str = ""
    arms: tuple[tuple[str, str], ...] = ()
    notes: tuple[str, ...] = ()
    differs: tuple[Placement, ...] = field(default=())

    @property
    def objects(self) -> list[str]:
        """The objects the goal moves, in the order they first appear."""
        return list(dict.fromkeys(p.object for p in self.placements))

    def of(self, name: str) -> tuple[Placement, ...]:
        return tuple(p for p in self.placements if p.object == name)

    def arm(self, name: str) -> str:
        return dict(self.arms).get(name, "left")


def declared(preset: str, names: Sequence[str]) -> tuple[Placement, ...]:
    """The goal a task set-up states, for the objects ``names`` of its scene: "pick-place" puts each block on
    the pad, "stack-cup" each handed-over cup into its bottom cup (() for any other set-up)."""
    have = set(names)
    out = []
    for tag in ("", " (left)", " (right)"):
        if preset == "pick-place" and f"block{tag}" in have and "pad" in have:
            out.append(Placement(f"block{tag}", "pad"))
        elif preset == "stack-cup" and f"cup{tag}" in have and f"bottom cup{tag}" in have:
            out.append(Placement(f"cup{tag}", f"bottom cup{tag}"))
    return tuple(out)


def placements_from(raw: object) -> tuple[Placement, ...]:
    """A scene's saved goal (a list of dicts); raises InvalidInput when it is not one."""
    if not isinstance(raw, list) or len(raw) > MAX_PLACEMENTS:
        raise InvalidInput("The task's goal must be a list of at most 40 placements.")
    return tuple(Placement.from_dict(p) for p in raw)


# -- reading the goal from the demonstrations -------------------------------------------------------------------


def _at(p: ObjectPose) -> ObjectAt:
    return ObjectAt(p.name, p.kind, p.position, p.yaw, p.on)


@dataclass(frozen=True)
class _Landing:
    """One release of an object over the demonstrations that agree: where it landed in each, on what, and where
    it stood at the start of each (and the poses of everything just after the release)."""

    name: str
    landed: tuple[ObjectPose, ...]
    starts: tuple[ObjectPose | None, ...]
    after: tuple[tuple[ObjectPose, ...], ...]

    def count(self, onto: str) -> int:
        """How many demonstrations put it onto ``onto``."""
        if onto == START:
            return sum(self._back(i) for i in range(len(self.landed)))
        return sum(p.on == onto for p in self.landed)

    def _back(self, i: int) -> bool:
        s = self.starts[i]
        return s is not None and math.dist(s.position, self.landed[i].position) <= SUCCESS_TOL

    def spot(self, onto: str) -> tuple[float, float, float, float] | None:
        """Where the demonstrations that put it onto ``onto`` left it, in that target's frame (None: none did)."""
        rows = []
        for i, p in enumerate(self.landed):
            f = self._frame(i, onto)
            if f is None or (onto not in (START, TABLE) and p.on != onto):
                continue
            rows.append([*to_local(f, np.asarray(p.position)), _wrap(p.yaw - f[3])])
        if not rows:
            return None
        a = np.array(rows)
        m = a.mean(axis=0)
        return (float(m[0]), float(m[1]), float(m[2]), float(np.angle(np.mean(np.exp(1j * a[:, 3])))))

    def _frame(self, i: int, onto: str) -> np.ndarray | None:
        if onto == TABLE:
            return np.zeros(4)
        if onto == START:
            s = self.starts[i]
            return None if s is None else frame_of(_at(s))
        t = next((p for p in self.after[i] if p.name == onto), None)
        return None if t is None else frame_of(_at(t))

    def spread(self, onto: str) -> float | None:
        """How far apart (m, headings counted as :data:`YAW_M_PER_RAD`) the demonstrations left it in the frame
        of ``onto`` (None when a demonstration lacks that frame)."""
        rows = []
        for i, p in enumerate(self.landed):
            f = self._frame(i, onto)
            if f is None:
                return None
            rows.append([*to_local(f, np.asarray(p.position)), _wrap(p.yaw - f[3])])
        a = np.array(rows)
        d = np.linalg.norm(a[:, :3] - a[:, :3].mean(axis=0), axis=1)
        yaw = 0.0 if self.landed[0].kind == "cup" else float(np.max(np.abs(_wrap_all(a[:, 3] - a[0, 3]))))
        return float(d.max()) + YAW_M_PER_RAD * yaw

    def starts_moved(self) -> bool:
        """The demonstrations had the object in places far enough apart to tell "where it started" from the
        table."""
        at = [s.position[:2] for s in self.starts if s is not None]
        if len(at) < 2:
            return False
        a = np.array(at)
        return bool(np.max(np.linalg.norm(a - a.mean(axis=0), axis=1)) >= DECIDE_M)

    def read(self) -> Placement:
        """What this release does, as the demonstrations show it: onto the object more than half of them put it
        on; else back where it started; else a spot on the table — measured from where it started only when
        the demonstrations had it in different places and clearly agree better that way."""
        n = len(self.landed)
        on = Counter(p.on for p in self.landed if p.on is not None and p.on not in SURFACES)
        top = on.most_common(1)
        if top and 2 * top[0][1] > n:
            return Placement(self.name, top[0][0], self.spot(top[0][0]))
        if 2 * self.count(START) > n:
            return Placement(self.name, START)
        s_start, s_table = self.spread(START), self.spread(TABLE)
        if self.starts_moved() and s_start is not None and s_table is not None and s_start + CONTRADICT_M < s_table:
            return Placement(self.name, START, self.spot(START))
        return Placement(self.name, TABLE, self.spot(TABLE))


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def _wrap_all(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a))


def _times(k: int) -> str:
    return {1: "once", 2: "twice"}.get(k, f"{k} times")


def _landings(demos: Sequence[Sequence[WorldEvent]]) -> tuple[dict[str, list[_Landing]], dict[str, str], list[str]]:
    """Per object the demonstrations grasped: its releases (over the demonstrations that release it as often as
    most do), the arm that carried it, and notes on the demonstrations left out."""
    demos = [list(d) for d in demos if d]
    names: list[str] = []
    for d in demos:
        for e in d:
            if e.kind == "grasp" and e.object is not None and e.object not in names:
                names.append(e.object)
    out: dict[str, list[_Landing]] = {}
    arms: dict[str, str] = {}
    notes: list[str] = []
    for name in names:
        per = []
        for d in demos:
            grasps = [e for e in d if e.kind == "grasp" and e.object == name]
            releases = [e for e in d if e.kind == "release" and e.object == name and e.pose(name) is not None]
            start = next((e.pose(name) for e in d if e.kind == "start" and e.pose(name) is not None), None)
            per.append((grasps, releases, start))
        counts = [len(r) for _, r, _ in per]
        k = max(set(counts), key=lambda c: (counts.count(c), c))
        if k == 0:
            continue
        agree = [p for p in per if len(p[1]) == k]
        if len(agree) < len(per):
            notes.append(
                f"{len(agree)} of {len(per)} demonstrations put the {name} down {_times(k)}; "
                "the others are left out of the goal."
            )
        used = [a for p in agree for a in (e.arm for e in p[0]) if a]
        arms[name] = max(set(used), key=used.count) if used else "left"
        out[name] = [
            _Landing(
                name,
                tuple(p[1][i].pose(name) for p in agree),  # type: ignore[misc]
                tuple(p[2] for p in agree),
                tuple(p[1][i].poses for p in agree),
            )
            for i in range(k)
        ]
    return out, arms, notes


def read_goal(demos: Sequence[Sequence[WorldEvent]]) -> Goal:
    """The goal as the demonstrations' object events show it (see :meth:`_Landing.read`); a demonstration
    without events (recorded before objects existed) is left out."""
    landings, arms, notes = _landings(demos)
    placements = tuple(r.read() for rs in landings.values() for r in rs)
    return Goal(placements, "demonstrations" if placements else "", tuple(arms.items()), tuple(notes))


def session_goal(
    preset: str, goal: Sequence[Placement], names: Sequence[str], demos: Sequence[Sequence[WorldEvent]]
) -> Goal:
    """The goal a session's skill is judged by: the scene's ``goal`` (declared by its set-up ``preset`` or
    confirmed by the teacher; placements naming an object not in ``names`` are left out) with each placement
    matched to the release of the demonstrations (``demos``' events) that does it — the one most of them put
    onto its target, else the last one not matched — and the other releases as the demonstrations show them.
    Without a goal in the scene: :func:`read_goal`."""
    have = set(names)
    stated = [p for p in goal if p.object in have and (p.onto in (START, TABLE) or p.onto in have)]
    landings, arms, notes = _landings(demos)
    if not stated:
        placements = tuple(r.read() for rs in landings.values() for r in rs)
        return Goal(placements, "demonstrations" if placements else "", tuple(arms.items()), tuple(notes))
    source = "set-up" if tuple(stated) == declared(preset, names) else "you"
    out: list[Placement] = []
    differs: list[Placement] = []
    order = list(dict.fromkeys([*landings, *(p.object for p in stated)]))
    for name in order:
        rs = landings.get(name, [])
        mine = [p for p in stated if p.object == name]
        if not mine:
            out += [r.read() for r in rs]
            continue
        if len(mine) >= len(rs):  # every release stated (a confirmed goal): as stated, spots from the demos
            for i, p in enumerate(mine):
                spot = rs[i].spot(p.onto) if i < len(rs) and p.spot is None and p.onto != START else None
                out.append(replace(p, spot=spot) if spot is not None else p)
                if i < len(rs) and rs[i].count(p.onto) == 0:
                    differs.append(p)
            continue
        chosen: dict[int, Placement] = {}
        for p in mine:
            free = [i for i in range(len(rs)) if i not in chosen]
            i = max(free, key=lambda j: (rs[j].count(p.onto), j))
            if rs[i].count(p.onto) == 0:
                i = free[-1]
                differs.append(p)
            spot = rs[i].spot(p.onto) if p.spot is None and p.onto != START else None
            chosen[i] = replace(p, spot=spot) if spot is not None else p
        out += [chosen.get(i) or r.read() for i, r in enumerate(rs)]
    return Goal(tuple(out), source, tuple(arms.items()), tuple(notes), tuple(differs))


def alternatives(goal: Goal, names: Sequence[str], kinds: Mapping[str, str]) -> list[tuple[Placement, ...]]:
    """Other goals the teacher may choose instead of ``goal``: the last placement of each object it moves put
    onto another object of the scene (``names``, their ``kinds``: never onto itself, a pad onto nothing), back
    where it started, or on a spot of the table."""
    out: list[tuple[Placement, ...]] = []
    for name in goal.objects:
        mine = [i for i, p in enumerate(goal.placements) if p.object == name]
        last = mine[-1]
        now = goal.placements[last]
        targets = [n for n in names if n != name and kinds.get(n) in ("pad", "cup", "block")] + [START, TABLE]
        for onto in targets:
            if onto == now.onto:
                continue
            spot = now.spot if onto == TABLE and now.onto == TABLE else None
            new = list(goal.placements)
            new[last] = Placement(name, onto, spot)
            out.append(tuple(new))
    return out
