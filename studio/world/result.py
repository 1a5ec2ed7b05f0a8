"""The task result: what the demonstrations did with each object (:func:`task_goal`) and whether a run does
the same, in plain words (:func:`task_result`): "The cup ended 0.6 cm from where you put it — the skill works",
"The block was never picked up: the gripper closed 3 cm above it"."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from studio.core.types import Arm
from studio.world.events import ObjectPose, WorldEvent
from studio.world.geometry import GRASP_XY_TOL, SUCCESS_TOL
from studio.world.simulation import WorldRun


def format_distance(d: float) -> str:
    """A distance in plain words: "less than 1 mm", "0.6 cm" under 1 cm, "3 cm" above, "1.2 m" beyond a metre."""
    d = abs(float(d))
    if d >= 1.0:
        return f"{d:.1f} m"
    if d < 0.001:
        return "less than 1 mm"
    if d < 0.0095:
        return f"{d * 100:.1f} cm"
    return f"{d * 100:.0f} cm"


def describe_offset(v: Sequence[float] | np.ndarray, ref: str = "it") -> str:
    """Where something is relative to ``ref``, in the robot's directions: "3 cm above it", "4 cm to the
    robot's left of where you put it and 2 cm below it" (the one or two largest components of ``v``)."""
    a = np.asarray(v, dtype=np.float64)
    words = {
        (2, 1): "{d} above {ref}",
        (2, -1): "{d} below {ref}",
        (0, 1): "{d} beyond {ref}, away from the robot",
        (0, -1): "{d} short of {ref}, towards the robot",
        (1, 1): "{d} to the robot's left of {ref}",
        (1, -1): "{d} to the robot's right of {ref}",
    }
    order = sorted(range(3), key=lambda i: -abs(a[i]))
    parts: list[str] = []
    for i in order[:2]:
        if parts and abs(a[i]) < 0.01:
            break
        parts.append(words[(i, 1 if a[i] >= 0 else -1)].format(d=format_distance(a[i]), ref=ref))
    return " and ".join(parts)


@dataclass(frozen=True)
class ObjectGoal:
    """What the demonstrations did with one object.

    Attributes:
        name, kind: the object.
        arm: the arm that grasped it.
        start: where it was at the start (bottom centre, m).
        releases: where it came to rest after each release, in order (mean over the demonstrations).
        landed_on: what it landed on after each release ("table", "pad", ...; the first demonstration's).
        final: where it ended (mean).
        spread: largest distance of one demonstration's end position from ``final`` (m).
        demos: how many demonstrations agree on this (the others grasped it a different number of times).
        relative_to: for a skill that follows the objects, the object each release is measured from (None: a
            spot on the table); then ``releases`` and ``final`` are where the objects are now.
    """

    name: str
    kind: str
    arm: Arm
    start: tuple[float, float, float]
    releases: tuple[tuple[float, float, float], ...]
    final: tuple[float, float, float]
    spread: float
    demos: int
    landed_on: tuple[str | None, ...] = ()
    relative_to: tuple[str | None, ...] = ()

    def where(self, k: int = -1) -> str:
        """Where release ``k`` should put the object, in words: "where you put it (on the pad)"."""
        on = self.relative_to[k] if self.relative_to else None
        return f"where you put it on the {on}" if on else "where you put it"


@dataclass(frozen=True)
class TaskGoal:
    """The objects the demonstrations moved (:class:`ObjectGoal`), from ``demos`` demonstrations with events."""

    objects: tuple[ObjectGoal, ...]
    demos: int
    notes: tuple[str, ...] = ()


def _vec(p: Sequence[float]) -> tuple[float, float, float]:
    return (float(p[0]), float(p[1]), float(p[2]))


def task_goal(demos: Sequence[Sequence[WorldEvent]]) -> TaskGoal:
    """The task as the demonstrations show it: for each object they grasped, where each release left it and
    where it ended. ``demos`` are the demonstrations' event lists (as the session stores them); a demonstration
    without events (recorded before objects existed) is left out."""
    demos = [list(d) for d in demos if d]
    names: list[str] = []
    for d in demos:
        for e in d:
            if e.kind == "grasp" and e.object is not None and e.object not in names:
                names.append(e.object)
    goals: list[ObjectGoal] = []
    notes: list[str] = []
    for name in names:
        per_demo = []
        for d in demos:
            grasps = [e for e in d if e.kind == "grasp" and e.object == name]
            releases = [e for e in d if e.kind == "release" and e.object == name]
            first_pose = next((e.pose(name) for e in d if e.kind == "start" and e.pose(name) is not None), None)
            last_pose = next((e.pose(name) for e in reversed(d) if e.pose(name) is not None), None)
            rests = [e.pose(name) for e in releases]
            per_demo.append((grasps, rests, first_pose, last_pose))
        counts = [len(g) for g, _, _, _ in per_demo]
        k = max(set(counts), key=lambda c: (counts.count(c), c))
        if k == 0:
            continue
        agree = [p for p in per_demo if len(p[0]) == k]
        if len(agree) < len(per_demo):
            notes.append(
                f"{len(agree)} of {len(per_demo)} demonstrations pick up the {name} {_times(k)}; "
                "the others are left out of the check."
            )
        arms = [p[0][0].arm for p in agree if p[0][0].arm]
        arm = max(set(arms), key=arms.count) if arms else "left"
        n_rel = min(len(p[1]) for p in agree)
        rel = tuple(
            _vec(np.mean([p[1][i].position for p in agree], axis=0))  # type: ignore[union-attr]
            for i in range(n_rel)
        )
        ends = np.array([p[3].position for p in agree if p[3] is not None])
        final = _vec(ends.mean(axis=0)) if len(ends) else (rel[-1] if rel else (0.0, 0.0, 0.0))
        spread = float(np.max(np.linalg.norm(ends - np.asarray(final), axis=1))) if len(ends) else 0.0
        starts = [p[2] for p in agree if p[2] is not None]
        start_at = _vec(starts[0].position) if starts else final
        first = agree[0][0][0]
        kind = next((pp.kind for pp in first.poses if pp.name == name), "block")
        landed = tuple(r.on if r is not None else None for r in agree[0][1][:n_rel])
        goals.append(ObjectGoal(name, kind, arm, start_at, rel, final, spread, len(agree), landed))
    return TaskGoal(tuple(goals), len(demos), tuple(notes))


def _times(k: int) -> str:
    return {1: "once", 2: "twice"}.get(k, f"{k} times")


def _ordinal(k: int) -> str:
    return ["first", "second", "third", "fourth", "fifth"][k] if k < 5 else f"{k + 1}th"


@dataclass(frozen=True)
class ObjectResult:
    """How one object fared: ``verdict`` is "works", "never picked up", "still held", "dropped early",
    "wrong place" or "moved"; ``text`` says it in plain words; ``distance`` is how far it ended (or landed)
    from where the demonstrations put it (m), when it got that far."""

    name: str
    ok: bool
    verdict: str
    text: str
    distance: float | None


@dataclass(frozen=True)
class TaskResult:
    """The task result in plain words: ``text`` for the teacher, ``ok`` when every object ended where the
    demonstrations put it, and one :class:`ObjectResult` per object."""

    ok: bool
    text: str
    objects: tuple[ObjectResult, ...]


def task_result(run: WorldRun, goal: TaskGoal) -> TaskResult:
    """Judge a run (e.g. the skill preview played through the scene) against what the demonstrations did.

    The first thing that went wrong with each object is reported: never picked up (and where the gripper closed
    instead), still held at the end, dropped early (the gripper opened on the way and then went on to where
    the demonstrations let go), released in the wrong place, or ended away from where the demonstrations
    left it; otherwise how close it ended: "The cup ended 0.6 cm from where you put it — the skill works."
    """
    if not goal.objects:
        text = (
            "There is nothing to check: your demonstrations did not pick up any object. "
            "Put objects in the scene and record demonstrations that move them."
        )
        return TaskResult(False, text, ())
    results = [_object_result(run, g) for g in goal.objects]
    bad = [r for r in results if not r.ok]
    text = " ".join(r.text for r in (bad or results))
    return TaskResult(not bad, text, tuple(results))


def _object_result(run: WorldRun, g: ObjectGoal) -> ObjectResult:
    name = g.name
    events = run.events
    grasps = [e for e in events if e.kind == "grasp" and e.object == name]
    releases = [e for e in events if e.kind == "release" and e.object == name]
    t_prev = -math.inf
    label = name[:1].upper() + name[1:]
    n = len(g.releases)
    for k in range(n):
        when = f" the {_ordinal(k)} time" if n > 1 else ""
        if k >= len(grasps):
            return ObjectResult(name, False, "never picked up", _not_picked(run, g, k, t_prev, label), None)
        if k >= len(releases) or releases[k].t < grasps[k].t:
            text = f"The {name} was still in the gripper at the end: the gripper never opened{when}."
            return ObjectResult(name, False, "still held", text, None)
        rel = releases[k]
        pose = rel.pose(name)
        assert pose is not None
        target = np.asarray(g.releases[k])
        d = float(np.linalg.norm(np.asarray(pose.position) - target))
        if d > SUCCESS_TOL:
            arm = rel.arm or g.arm
            let_go = np.asarray(rel.gripper if rel.gripper is not None else pose.position)
            t_next = min(
                (e.t for e in events if e.t > rel.t and e.arm == arm and e.kind in ("grasp", "miss")), default=math.inf
            )
            sel = (run.path_t > rel.t) & (run.path_t <= t_next)
            p = run.path[arm][sel]
            reach = np.hypot(p[:, 0] - target[0], p[:, 1] - target[1]) if len(p) else np.array([math.inf])
            short = math.hypot(let_go[0] - target[0], let_go[1] - target[1]) > 2 * GRASP_XY_TOL
            if short and float(reach.min()) <= 2 * GRASP_XY_TOL:
                text = (
                    f"The {name} was dropped early{when}: it landed {format_distance(d)} from where you put it, "
                    "because the gripper opened before it got there."
                )
                return ObjectResult(name, False, "dropped early", text, d)
            off = describe_offset(np.asarray(pose.position) - target, g.where(k))
            text = f"The {name} was released in the wrong place{when}: {off}"
            expected = g.landed_on[k] if k < len(g.landed_on) else None
            if expected is not None and pose.on != expected:
                text += f" (it landed on the {pose.on}, not on the {expected})"
            text += "."
            return ObjectResult(name, False, "wrong place", text, d)
        t_prev = rel.t
    end = run.final
    fp = next((p for p in end if p.name == name), None)
    if fp is None:  # pragma: no cover - the run's scene lacks the object
        return ObjectResult(name, False, "never picked up", f"The {name} is not in the scene.", None)
    if fp.held_by is not None:
        text = f"The {name} was still in the gripper at the end: the gripper never let go of it."
        return ObjectResult(name, False, "still held", text, None)
    d = float(np.linalg.norm(np.asarray(fp.position) - np.asarray(g.final)))
    if d > SUCCESS_TOL:
        off = describe_offset(np.asarray(fp.position) - np.asarray(g.final), g.where())
        again = ": it was picked up again afterwards" if len(grasps) > n else ""
        return ObjectResult(name, False, "moved", f"The {name} ended {off}{again}.", d)
    on = g.relative_to[-1] if g.relative_to else None
    if not on:  # what it stands on says that it was moved there (never "where you put it" alone)
        on = fp.on if fp.on not in (None, "table", "floor", "hand") else _pad_under(fp, end)
    back = _back_words(g, end) if math.dist(fp.position, g.start) <= SUCCESS_TOL else ""
    if on:
        text = f"The {name} ended on the {on}, {format_distance(d)} from where you put it — the skill works."
    elif back:  # it came back to where it started: say where it went, or it reads as if nothing happened
        text = (
            f"The {name} ended back where it started, {back}: {format_distance(d)} from {g.where()} — the skill works."
        )
    else:
        text = f"The {name} ended {format_distance(d)} from {g.where()} — the skill works."
    return ObjectResult(name, True, "works", text, d)


def _back_words(g: ObjectGoal, poses: Sequence[ObjectPose]) -> str:
    """Where an object that came back went on the way: "after its stop on the pad" ("" without a stop)."""
    stops = g.releases[:-1]
    if not stops:
        return ""
    probe = [ObjectPose(g.name, g.kind, (0.0, 0.0, 0.0), p, (1.0, 0.0, 0.0, 0.0)) for p in stops]
    pads = [n for n in (_pad_under(p, poses) for p in probe) if n is not None]
    if pads:
        return f"after its stop on the {pads[0]}"
    return "after its stop on the way" if len(stops) == 1 else f"after {len(stops)} stops on the way"


def _not_picked(run: WorldRun, g: ObjectGoal, k: int, t_prev: float, label: str) -> str:
    """Why object ``g`` was not picked up (for the k-th time): where the gripper closed instead, in words."""
    head = f"The {g.name} was never picked up" if k == 0 else f"The {g.name} was not picked up the {_ordinal(k)} time"
    after = [e for e in run.events if e.t > t_prev and e.arm == g.arm]
    other = next((e for e in after if e.kind == "grasp" and e.object != g.name), None)
    misses = [e for e in after if e.kind == "miss" and e.gripper is not None and e.pose(g.name) is not None]
    if not misses:
        if other is not None:
            return f"{head}: the gripper picked up the {other.object} instead."
        return f"{head}: the gripper never closed." if k == 0 else f"{head}: the gripper did not close again."

    def offset(e: WorldEvent) -> np.ndarray:
        pose = e.pose(g.name)
        assert pose is not None and e.gripper is not None
        gp, base = np.asarray(e.gripper), np.asarray(pose.position)
        v = np.zeros(3)
        h = np.array([gp[0] - base[0], gp[1] - base[1]])
        if np.hypot(*h) > GRASP_XY_TOL:
            v[:2] = h
        top = base[2] + pose.size[2]
        if gp[2] > top:
            v[2] = gp[2] - top
        elif gp[2] < base[2]:
            v[2] = gp[2] - base[2]
        return v

    best = min(misses, key=lambda e: float(np.linalg.norm(offset(e))))
    v = offset(best)
    where = describe_offset(v, "it") if np.linalg.norm(v) >= 0.001 else "right next to it"
    return f"{head}: the gripper closed {where}."


def _pad_under(p: ObjectPose, poses: Sequence[ObjectPose]) -> str | None:
    """The name of a pad whose footprint holds ``p``'s bottom centre (None when there is none)."""
    for o in poses:
        if o.kind != "pad" or o.name == p.name:
            continue
        c, s_ = math.cos(o.yaw), math.sin(o.yaw)
        dx, dy = p.position[0] - o.position[0], p.position[1] - o.position[1]
        u, v = c * dx + s_ * dy, -s_ * dx + c * dy
        if abs(u) <= o.size[0] / 2 and abs(v) <= o.size[1] / 2:
            return o.name
    return None
