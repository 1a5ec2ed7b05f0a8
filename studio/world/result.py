"""The task result: whether a run did the task's goal (:mod:`studio.world.goal`), in plain words and by how much
(:func:`task_result`): "The block ended on the pad, 0.4 cm from its centre.", "The block ended beside the pad,
9 cm from its centre — the skill did not do the task.", "The block was never picked up: the gripper closed 3 cm
above it."."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from studio.core.frames import to_world
from studio.world.events import ObjectPose, WorldEvent
from studio.world.geometry import GRASP_XY_TOL, SUCCESS_TOL
from studio.world.goal import START, SURFACES, TABLE, Goal, Placement
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


def _ordinal(k: int) -> str:
    return ["first", "second", "third", "fourth", "fifth"][k] if k < 5 else f"{k + 1}th"


@dataclass(frozen=True)
class ObjectResult:
    """How one object fared: ``verdict`` is "works", "never picked up", "still held", "dropped early",
    "wrong place" or "moved"; ``text`` says it in plain words; ``distance`` is how far it ended (or landed)
    from the spot on its target (m), when it got that far."""

    name: str
    ok: bool
    verdict: str
    text: str
    distance: float | None


@dataclass(frozen=True)
class TaskResult:
    """The task result in plain words: ``text`` for the teacher, ``ok`` when the goal holds for every object,
    and one :class:`ObjectResult` per object."""

    ok: bool
    text: str
    objects: tuple[ObjectResult, ...]


#: What the task result says when there is no goal to judge.
NOTHING = (
    "There is nothing to check: your demonstrations did not pick up any object. "
    "Put objects in the scene and record demonstrations that move them."
)
#: How a run that did not do the task ends its words.
NOT_DONE = " — the skill did not do the task."


def task_result(run: WorldRun, goal: Goal) -> TaskResult:
    """Judge a run (the skill's preview played through the scene, or the robot's run) against the task's goal
    only (:class:`~studio.world.goal.Goal`): each object's n-th release must put it onto the n-th target the
    goal gives it, and it must still be there at the end. The first thing that went wrong with an object is
    said with how far off it was ("The block ended beside the pad, 9 cm from its centre — the skill did not do
    the task."); otherwise where it ended ("The block ended on the pad, 0.4 cm from its centre."). How far from
    where the demonstrations put it on the target is a detail of the words, never the criterion."""
    if not goal.placements:
        return TaskResult(False, NOTHING, ())
    return _combined(tuple(_object_result(run, goal, name) for name in goal.objects))


def _combined(results: tuple[ObjectResult, ...]) -> TaskResult:
    """The objects' results as one (the one place where a further check of the run joins them)."""
    bad = [r for r in results if not r.ok]
    return TaskResult(not bad, " ".join(r.text for r in (bad or results)), results)


@dataclass(frozen=True)
class _Check:
    """Whether a placement holds for an object's pose: ``distance`` (m) from the spot on the target (across
    the table for an object target), ``target`` that spot in the room."""

    ok: bool
    distance: float
    target: np.ndarray


def _check(pl: Placement, pose: ObjectPose, poses: Sequence[ObjectPose], start: ObjectPose | None) -> _Check:
    here = np.asarray(pose.position, dtype=np.float64)
    if pl.onto in (START, TABLE):
        if pl.onto == TABLE:
            f = np.zeros(4)
        elif start is not None:
            f = np.array([*start.position, 0.0 if start.kind == "cup" else start.yaw])
        else:
            return _Check(False, math.inf, here)
        if pl.spot is None and pl.onto == TABLE:  # any spot on the table
            return _Check(pose.on == "table", 0.0, here)
        target = to_world(f, np.asarray(pl.spot[:3])) if pl.spot is not None else np.asarray(start.position)  # type: ignore[union-attr]
        d = float(np.linalg.norm(here - target))
        return _Check(d <= SUCCESS_TOL, d, target)
    t = next((p for p in poses if p.name == pl.onto), None)
    if t is None:
        return _Check(False, math.inf, here)
    f = np.array([*t.position, 0.0 if t.kind == "cup" else t.yaw])
    centre = _reference(pl) == "its centre"
    spot = np.array([0.0, 0.0, t.size[2]]) if centre or pl.spot is None else np.asarray(pl.spot[:3])
    target = to_world(f, spot)
    return _Check(pose.on == pl.onto, float(math.hypot(*(here[:2] - target[:2]))), target)


def _on(name: str, poses: Sequence[ObjectPose]) -> str:
    """ "on" or "in" (a cup) the object ``name``."""
    kind = next((p.kind for p in poses if p.name == name), "")
    return "in" if kind == "cup" else "on"


def _reference(pl: Placement) -> str:
    """What the distance of a placement is measured from: "its centre", "where you put it on it", …"""
    if pl.onto == START:
        return "it" if pl.spot is None else "where you put it"
    if pl.onto == TABLE:
        return "that spot"
    return "its centre" if pl.spot is None or math.hypot(pl.spot[0], pl.spot[1]) < 0.01 else "where you put it on it"


def _done(pl: Placement, c: _Check, poses: Sequence[ObjectPose]) -> tuple[str, str]:
    """Where an object is, said of a placement that holds, and how close: ("on the pad", "0.4 cm from its
    centre")."""
    d = format_distance(c.distance)
    if pl.onto == START:
        head = "back where it started" if pl.spot is None else "where you put it, relative to where it started"
        return head, f"{d} from {_reference(pl)}"
    if pl.onto == TABLE:
        return "on the table where you put it", (f"{d} from that spot" if pl.spot is not None else "")
    return f"{_on(pl.onto, poses)} the {pl.onto}", f"{d} from {_reference(pl)}"


def _went(where: tuple[str, str]) -> str:
    """A stop on the way in words: "went onto the pad (0.3 cm from its centre), then "."""
    head, detail = where
    if head.startswith(("on ", "in ")):
        head = head[:2] + "to" + head[2:]
    return f"went {head}" + (f" ({detail})" if detail else "") + ", then "


def _missed(pl: Placement, c: _Check, pose: ObjectPose, poses: Sequence[ObjectPose]) -> str:
    """Where an object is, said of a placement that does not hold: "beside the pad, 9 cm from its centre"."""
    if pl.onto in (START, TABLE):
        ref = "where it started" if pl.onto == START and pl.spot is None else "where you put it"
        if not math.isfinite(c.distance):
            return f"away from {ref}"
        return describe_offset(np.asarray(pose.position) - c.target, ref)
    if not math.isfinite(c.distance):
        return f"away from the {pl.onto}: the {pl.onto} is not on the table"
    d = format_distance(c.distance)
    centre = "its centre" if _reference(pl) == "its centre" else "where you put it on it"
    if pose.on == "floor":
        return f"on the floor, {d} from the {pl.onto}: it fell off the table"
    if pose.on is not None and pose.on not in SURFACES:
        return f"{_on(pose.on, poses)} the {pose.on}, not {_on(pl.onto, poses)} the {pl.onto} ({d} from {centre})"
    return f"beside the {pl.onto}, {d} from {centre}"


def _object_result(run: WorldRun, goal: Goal, name: str) -> ObjectResult:
    events = run.events
    places = goal.of(name)
    arm = goal.arm(name)
    grasps = [e for e in events if e.kind == "grasp" and e.object == name]
    releases = [e for e in events if e.kind == "release" and e.object == name]
    start = next((e.pose(name) for e in events if e.kind == "start" and e.pose(name) is not None), None)
    t_prev = -math.inf
    n = len(places)
    done: list[tuple[str, str]] = []
    for k, pl in enumerate(places):
        when = f" the {_ordinal(k)} time" if n > 1 else ""
        if k >= len(grasps):
            return ObjectResult(name, False, "never picked up", _not_picked(run, name, arm, k, t_prev) + ".", None)
        if k >= len(releases) or releases[k].t < grasps[k].t:
            text = f"The {name} was still in the gripper at the end: the gripper never opened{when}."
            return ObjectResult(name, False, "still held", text, None)
        rel = releases[k]
        pose = rel.pose(name)
        assert pose is not None
        c = _check(pl, pose, rel.poses, start)
        if not c.ok:
            where = _missed(pl, c, pose, rel.poses)
            d = c.distance if math.isfinite(c.distance) else None
            if _early(run, rel, arm, pose, c.target):
                text = (
                    f"The {name} was dropped early{when}: it landed {where}, because the gripper opened before it "
                    f"got there{NOT_DONE}"
                )
                return ObjectResult(name, False, "dropped early", text, d)
            if k < n - 1:
                text = f"The {name} was released in the wrong place{when}: it landed {where}{NOT_DONE}"
            else:
                text = f"The {name} ended {where}{NOT_DONE}"
            return ObjectResult(name, False, "wrong place", text, d)
        if k < n - 1:
            done.append(_done(pl, c, rel.poses))
        t_prev = rel.t
    fp = next((p for p in run.final if p.name == name), None)
    if fp is None:  # pragma: no cover - the run's scene lacks the object
        return ObjectResult(name, False, "never picked up", f"The {name} is not in the scene.", None)
    if fp.held_by is not None:
        text = f"The {name} was still in the gripper at the end: the gripper never let go of it."
        return ObjectResult(name, False, "still held", text, None)
    last = places[-1]
    c = _check(last, fp, run.final, start)
    if not c.ok:
        again = ": it was picked up again afterwards" if len(grasps) > n else ""
        d = c.distance if math.isfinite(c.distance) else None
        text = f"The {name} ended {_missed(last, c, fp, run.final)}{again}{NOT_DONE}"
        return ObjectResult(name, False, "moved", text, d)
    head, detail = _done(last, c, run.final)
    text = f"The {name} {''.join(_went(w) for w in done)}ended {head}" + (f", {detail}." if detail else ".")
    return ObjectResult(name, True, "works", text, c.distance)


def _early(run: WorldRun, rel: WorldEvent, arm: str, pose: ObjectPose, target: np.ndarray) -> bool:
    """Whether the gripper let go far from ``target`` and then went on to it (it opened too soon)."""
    let_go = np.asarray(rel.gripper if rel.gripper is not None else pose.position)
    if math.hypot(let_go[0] - target[0], let_go[1] - target[1]) <= 2 * GRASP_XY_TOL:
        return False
    t_next = min(
        (e.t for e in run.events if e.t > rel.t and e.arm == arm and e.kind in ("grasp", "miss")), default=math.inf
    )
    sel = (run.path_t > rel.t) & (run.path_t <= t_next)
    p = run.path.get(arm, np.zeros((0, 3)))[sel] if arm in run.path else np.zeros((0, 3))
    if not len(p):
        return False
    return float(np.hypot(p[:, 0] - target[0], p[:, 1] - target[1]).min()) <= 2 * GRASP_XY_TOL


def _not_picked(run: WorldRun, name: str, arm: str, k: int, t_prev: float) -> str:
    """Why object ``name`` was not picked up (for the k-th time): where the gripper closed instead, in words
    (no full stop)."""
    head = f"The {name} was never picked up" if k == 0 else f"The {name} was not picked up the {_ordinal(k)} time"
    after = [e for e in run.events if e.t > t_prev and e.arm == arm]
    other = next((e for e in after if e.kind == "grasp" and e.object != name), None)
    misses = [e for e in after if e.kind == "miss" and e.gripper is not None and e.pose(name) is not None]
    if not misses:
        if other is not None:
            return f"{head}: the gripper picked up the {other.object} instead"
        return f"{head}: the gripper never closed" if k == 0 else f"{head}: the gripper did not close again"

    def offset(e: WorldEvent) -> np.ndarray:
        pose = e.pose(name)
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
    return f"{head}: the gripper closed {where}"
