"""The studio's facts in plain words for the teacher: distances, routes, Suggest's outcome, the task and its
goal, grasps, frames, contacts and hits (the verdict on a skill: :mod:`studio.words.quality`).

The core and the world give the facts; the sentences are here, shared by the studio and ``studio learn``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Protocol

from studio.core.quality.judgement import GOOD_G_OVER_R, POOR_G_OVER_R
from studio.core.types import SkillRoute

if TYPE_CHECKING:
    from studio.core.autotune import TuneResult
    from studio.core.robot_geometry import Part
    from studio.core.segment_view import SegmentFit
    from studio.core.segments import FrameChoice
    from studio.core.touches import Touch


def length_words(metres: float) -> str:
    """A distance as a person says it: "4 mm", "2.5 cm", "1.2 m"."""
    m = abs(float(metres))
    if m < 0.0095:
        return f"{m * 1000:.0f} mm" if m >= 0.00095 else f"{max(m * 1000, 0.1):.1f} mm"
    if m < 1.0:
        cm = m * 100
        return f"{cm:.0f} cm" if cm >= 9.95 else f"{cm:.1f} cm".replace(".0 cm", " cm")
    return f"{m:.1f} m"


_COUNT = {2: "two", 3: "three"}
#: Per axis of Baxter's base frame (x forward, y to its left, z up): how the lower and the higher side are called.
_SIDES = (
    ("nearer the robot", "farther from the robot"),
    ("on the robot's right", "on the robot's left"),
    ("lower", "higher"),
)


def route_sides(routes: Sequence[SkillRoute]) -> tuple[str, ...]:
    """Where each way goes, as words: along the axis the ways differ most ("on the robot's left", "higher", …;
    a way between two others is "in the middle")."""
    at = [r.at for r in routes]
    if len(at) < 2:
        return tuple("" for _ in at)
    spans = [max(p[k] for p in at) - min(p[k] for p in at) for k in range(3)]
    axis = spans.index(max(spans))
    order = sorted(range(len(at)), key=lambda i: at[i][axis])
    low, high = _SIDES[axis]
    out = ["in the middle"] * len(at)
    out[order[0]], out[order[-1]] = low, high
    return tuple(out)


def route_label(routes: Sequence[SkillRoute], i: int) -> str:
    """One way and who went it: "on the robot's left: demo 1, demo 3"."""
    return f"{route_sides(routes)[i]}: {', '.join(routes[i].demos)}"


def routes_words(routes: Sequence[SkillRoute], route: int) -> str:
    """The ways the demonstrations went and the one learned: "Your demonstrations go two ways (…). I learned the
    way on the robot's left" (no full stop)."""
    sides = route_sides(routes)
    ways = "; ".join(route_label(routes, i) for i in range(len(routes)))
    return (
        f"Your demonstrations go {_COUNT.get(len(routes), str(len(routes)))} ways ({ways}). "
        f"I learned the way {sides[route]}"
    )


def _frame_words(role: str, robot: str = "the robot") -> str:
    """A segment's frame as a person says it: "the cup", "where the block stood", ``robot``."""
    kind, _, name = role.partition(":")
    if kind == "object":
        return f"the {name}"
    if kind == "start":
        return f"where the {name} stood"
    return robot


def _segment_name(fit: SegmentFit) -> str:
    what = (fit.start, fit.end)
    if what == ("start", "grasp"):
        return f"Reaching for the {fit.object}"
    if what == ("grasp", "release"):
        return f"Carrying the {fit.object} to {_frame_words(fit.role)}"
    if what == ("release", "grasp"):
        return f"Going back to the {fit.object}"
    if what == ("release", "end"):
        return f"Moving away from the {fit.object}"
    return f"From the {fit.start} to the {fit.end}"


def segment_lines(fits: Sequence[SegmentFit]) -> tuple[str, ...]:
    """One sentence per stretch of a skill that follows the objects: how closely it follows the demonstrations,
    measured relative to the object it is learned with, and whether that is good, fair or poor."""
    out = []
    for f in fits:
        if not math.isfinite(f.g_over_r) or f.g_over_r <= GOOD_G_OVER_R:
            level = "good"
        elif f.g_over_r <= POOR_G_OVER_R:
            level = "fair: a few more demonstrations of this part would help"
        else:
            level = "poor: your demonstrations of this part differ a lot; show it again the same way"
        out.append(
            f"{_segment_name(f)} (relative to {_frame_words(f.role)}): within {length_words(f.distance)} of your "
            f"demonstrations on average — {level}."
        )
    return tuple(out)


def _grasps(task: float) -> str:
    """Where the skill grasps and releases, held out, in words ("" without gripper actions)."""
    if task == 0.0 or math.isnan(task):
        return ""
    if math.isinf(task):
        return " and does not grasp and release as you did"
    return f" and grasps and releases {length_words(task)} from where you did"


def tune_summary(result: TuneResult) -> str:
    """Suggest's before and after figures in plain words (the path, and the grasps and releases when the
    demonstrations have them)."""
    b, a = result.before, result.after
    if not result.changed:
        return (
            "Your thresholds are already good: learned without each demonstration in turn, the skill misses it by "
            f"{length_words(b.distance)} on average{_grasps(b.task)}, and no other thresholds did better without "
            "doing worse elsewhere."
        )
    if not math.isfinite(b.distance):
        return (
            "Suggested: learned without each demonstration in turn, the skill misses it by "
            f"{length_words(a.distance)} on average{_grasps(a.task)}."
        )
    if a.same(b):
        return (
            "Automatic thresholds, which follow your demonstrations, do exactly as well as yours: learned without "
            f"each demonstration in turn, the skill misses it by {length_words(a.distance)} on average"
            f"{_grasps(a.task)} either way."
        )
    before = f"{length_words(b.distance)} with the current thresholds"
    same = round(a.keypoints) == round(b.keypoints)
    count = (
        f"the same number of key-points per demonstration, {a.keypoints:.0f}"
        if same
        else f"{a.keypoints:.0f} key-points per demonstration instead of {b.keypoints:.0f}"
    )
    if a.task > 0.0 and math.isfinite(a.task) and math.isfinite(b.task):
        return (
            f"Learned without each demonstration in turn, the skill misses it by {length_words(a.distance)} on "
            f"average with the suggestion, {before}; it grasps and releases {length_words(a.task)} from where you "
            f"did, {length_words(b.task)} before ({count})."
        )
    return (
        f"Learned without each demonstration in turn, the skill misses it by {length_words(a.distance)} on "
        f"average with the suggestion, {before} ({count})."
    )


def count_words(n: int, thing: str, plural: str | None = None) -> str:
    """ "1 demonstration", "3 demonstrations" (``plural``: when it is not ``thing`` + "s")."""
    return f"{n} {thing if n == 1 else (plural or thing + 's')}"


#: What each task set-up asks of the teacher, shown in the Teach step.
TASKS: dict[str, str] = {
    "stack-cup": "Take the cup I hand you (held up on the grey stand) and put it into the other cup.",
    "pick-place": "Pick up the block and put it on the green pad.",
    "empty table": "Show the robot a movement, or add objects and show it what to do with them.",
}
#: The task of a scene that is not one of the set-ups.
OWN_TASK = "Show the robot what to do with the objects on the table."


def task_words(preset: str | None) -> str:
    """The task of the scene set-up ``preset`` in one sentence for the teacher."""
    return TASKS.get(preset or "", OWN_TASK)


class GraspFacts(Protocol):
    """What a gripper's close did (:class:`studio.world.feedback.GraspNote`)."""

    @property
    def held(self) -> str | None: ...
    @property
    def near(self) -> str | None: ...
    @property
    def distance(self) -> float: ...
    @property
    def closer(self) -> float: ...
    @property
    def height(self) -> float: ...
    @property
    def toward(self) -> tuple[float, float]: ...


def grasp_words(note: GraspFacts) -> str:
    """What closing the gripper just did: "Holding the cup." or "Missed the cup by 3 cm — move 1 cm to the robot's
    left, …", the way in the room's terms."""
    if note.held is not None:
        return f"Holding the {note.held}."
    if note.near is None:
        return "The gripper closed on nothing: there is no cup or block free to pick up."
    by = length_words(note.distance)
    if note.closer > 0.0:
        fix = f"move {_sideways(note.toward)}"
        if note.height:
            fix += f", {_height_fix(note.height)}"
        return f"Missed the {note.near} by {by} — {fix}, open the gripper and close it again."
    off, fix = _height_off(note.height), _height_fix(note.height)
    return f"Missed the {note.near}: the gripper is {off} — {fix}, then close it again."


def _sideways(toward: tuple[float, float]) -> str:
    """A sideways move in the room's terms: "1 cm to the robot's left", "2 cm away from the robot and 1 cm to its
    right" (a part under 5 mm is left out, unless it is the larger one; at least 1 cm is said)."""
    dx, dy = toward
    x = f"{'away from' if dx > 0 else 'toward'} the robot"
    side = "left" if dy > 0 else "right"
    if abs(dx) >= 0.005 and abs(dy) >= 0.005:
        return f"{length_words(dx)} {x} and {length_words(dy)} to its {side}"
    if abs(dx) >= abs(dy):
        return f"{length_words(max(abs(dx), 0.01))} {x}"
    return f"{length_words(max(abs(dy), 0.01))} to the robot's {side}"


def _height_off(h: float) -> str:
    return f"{length_words(h)} too {'high' if h > 0 else 'low'}"


def _height_fix(h: float) -> str:
    return f"{'lower' if h > 0 else 'raise'} it {length_words(max(abs(h), 0.01))}"


class PlacementFacts(Protocol):
    """One step of a task's goal (:class:`studio.world.goal.Placement`)."""

    @property
    def object(self) -> str: ...
    @property
    def onto(self) -> str: ...
    @property
    def target(self) -> str: ...


def _onto(p: PlacementFacts, kinds: Mapping[str, str]) -> str:
    if p.target == "start":
        return "back where it started"
    if p.target == "table":
        return "on the table where you put it"
    return f"{'into' if kinds.get(p.onto) == 'cup' else 'on'} the {p.onto}"


def goal_words(placements: Sequence[PlacementFacts], kinds: Mapping[str, str]) -> str:
    """A task's goal in plain words: "Put the block on the pad, then back where it started." (``kinds``: each
    object's kind, "cup" is put into); "" without one."""
    steps: dict[str, list[str]] = {}
    for p in placements:
        steps.setdefault(p.object, []).append(_onto(p, kinds))
    return " ".join(f"Put the {name} {', then '.join(where)}." for name, where in steps.items())


GOAL_SOURCES = {
    "set-up": "The goal of this set-up:",
    "you": "The goal you chose:",
    "demonstrations": "The goal, as I read it from your demonstrations:",
}


def _role_words(role: str) -> str:
    """A frame as the teacher says where something goes: "the pad", "where the block stood", "a fixed place"."""
    return _frame_words(role, "a fixed place on the table")


def frame_lines(choices: Sequence[FrameChoice]) -> tuple[str, ...]:
    """How a skill that follows the objects chose what each grasp and release follows, when the demonstrations
    could not decide it ("Every demonstration had the block in the same place: I will follow the block for the
    grasp and the pad for the release. …") or when they contradicted the task's meaning (then followed)."""
    out = []
    unsure = [c for c in choices if c.rule and not c.told]
    if unsure:
        held = list(dict.fromkeys(c.object for c in choices if c.kind == "grasp"))
        things = " and the ".join(held) or "objects"
        parts = []
        for kind, word in (("grasp", "grasp"), ("release", "release")):
            mine = [c for c in choices if c.kind == kind]
            if not mine:
                continue
            plural = f"{word}s" if len(mine) > 1 else word
            roles = list(dict.fromkeys(_role_words(c.role) for c in mine))
            parts.append(f"{' and '.join(roles)} for the {plural}")
        out.append(
            f"Every demonstration had the {things} in the same place: I will follow {' and '.join(parts)}. "
            f"Show me one more with the {held[0] if held else 'objects'} somewhere else to be sure."
        )
    for c in choices:
        if c.against:
            out.append(
                f"Your demonstrations put the {c.object} down relative to {_role_words(c.role)}, not "
                f"{_role_words(c.rule)}: I follow your demonstrations."
            )
    return tuple(out)


def moved_words(name: str, distance: float) -> str:
    """An object a fixed-places skill will not follow: "The bottom cup is 11 cm from where it stood when you
    taught; your skill repeats the taught motion."."""
    return (
        f"The {name} is {length_words(distance)} from where it stood when you taught; your skill repeats the "
        "taught motion, so it will not follow it. Put it back, or choose Places: Follow the objects and train again."
    )


# -- contacts: what the robot touches (facts: studio.core.touches.Touch, studio.world.contacts) --------------


def part_words(p: Part) -> str:
    """ "the left fingers", "the right forearm", "the robot's torso", "the table", "the block"."""
    if p.robot:
        return f"the {p.arm} {p.part}" if p.arm else f"the robot's {p.part}"
    return f"the {p.part}"


def _verb(p: Part, one: str, many: str) -> str:
    return many if p.robot and p.part == "fingers" else one


def _when(x: Touch) -> str:
    if x.t_end - x.t_start < 0.05:
        return f"{x.t_start:.1f} s"
    return f"{x.t_start:.1f}–{x.t_end:.1f} s"


def touch_words(x: Touch, tense: str = "would") -> str:
    """One contact: "the block would go 6.8 cm into the table" (``tense``: "would" for a skill, "did" for a run,
    "now" for the arm moved by hand: "the left fingers touch the table")."""
    a, b = part_words(x.a), part_words(x.b)
    deep = x.depth >= 0.001
    if tense == "now":
        return f"{a} {_verb(x.a, 'touches', 'touch')} {b}"
    if tense == "did":
        return f"{a} went {length_words(x.depth)} into {b}" if deep else f"{a} touched {b}"
    return f"{a} would go {length_words(x.depth)} into {b}" if deep else f"{a} would touch {b}"


def _skill_advice(x: Touch) -> str:
    b = x.b
    if x.new:
        return f"Move the {b.part} out of the way, or teach again with it where it is."
    if b.robot and b.arm is not None:
        return "Teach the two arms so that they keep apart."
    if b.robot:
        return "Teach that part farther from the robot's body."
    if b.part == "table":
        if x.a.robot and x.a.part not in ("fingers", "hand", "wrist"):
            return "Teach that part with the gripper higher, or the arm held differently."
        return "Teach that part higher above the table."
    return f"Teach that part so that it keeps clear of the {b.part}."


def contact_sentence(touches: Sequence[Touch], tense: str = "would") -> str:
    """What the robot touches along a skill or a run, the first contact first: "At 6.8–9.3 s the block would go
    6.8 cm into the table. Teach that part higher above the table." (a new object: "The new cup is in the way of
    the carry at 7.3 s: …"); "" when nothing."""
    if not touches:
        return ""
    x = next((t for t in touches if t.new), touches[0])
    more = len(touches) - 1
    tail = f" (and {count_words(more, 'more contact')} later)" if more else ""
    if x.new:
        way = f"the carry of the {x.carry}" if x.carry else f"the {x.a.arm} arm" if x.a.arm else "the skill"
        head = f"The new {x.b.part} is in the way of {way} at {x.at:.1f} s: {touch_words(x, tense)}"
    else:
        head = f"At {_when(x)} {touch_words(x, tense)}"
    advice = _skill_advice(x) if tense == "would" else ""
    return f"{head}{tail}. {advice}".strip()


def recorded_touch_words(touches: Sequence[Touch]) -> str:
    """A demonstration that went through something (imported, or recorded on a real robot): "At 4.1–4.6 s the block
    went 3 cm into the table" ("" when it touched nothing)."""
    if not touches:
        return ""
    x = touches[0]
    more = len(touches) - 1
    tail = f" (and {count_words(more, 'more contact')} later)" if more else ""
    return f"At {_when(x)} {touch_words(x, 'did')}{tail}."


def contact_advice(x: Touch) -> str:
    """What to do when an arm moved by hand stops at a contact: "lift the gripper first"."""
    a, b = x.a, x.b
    if not a.robot:
        return f"lift the {a.part} first, or open the gripper to put it down"
    if b.robot and b.arm is not None:
        return f"move the {b.arm} arm away first" if b.arm != a.arm else "move the gripper away from the arm first"
    if b.robot:
        return "move the gripper away from the robot's body first"
    if b.part == "table":
        return "lift the gripper first"
    return f"move the gripper away from the {b.part} first"


class HitFacts(Protocol):
    """An object the robot ran into (:class:`studio.world.hits.Hit`)."""

    @property
    def t(self) -> float: ...
    @property
    def name(self) -> str: ...
    @property
    def by(self) -> Part: ...
    @property
    def distance(self) -> float: ...
    @property
    def toppled(self) -> bool: ...


def hit_words(hits: Sequence[HitFacts]) -> str:
    """What the robot did to the objects it ran into: "The cup was knocked over by the left forearm at 7.3 s."."""
    out = []
    for name in dict.fromkeys(h.name for h in hits):
        mine = [h for h in hits if h.name == name]
        first, by = mine[0], part_words(mine[0].by)
        moved = length_words(sum(h.distance for h in mine))
        if any(h.toppled for h in mine):
            out.append(f"The {name} was knocked over by {by} at {first.t:.1f} s.")
        else:
            out.append(f"The {name} was pushed {moved} by {by} at {first.t:.1f} s.")
    return " ".join(out)


def blocked_words(x: Touch) -> str:
    """An arm moved by hand stopped at a contact: "The left fingers touch the table — lift the gripper first"."""
    said = touch_words(x, "now")
    return f"{said[:1].upper()}{said[1:]} — {contact_advice(x)}."


__all__ = [
    "GOAL_SOURCES",
    "OWN_TASK",
    "TASKS",
    "PlacementFacts",
    "blocked_words",
    "contact_advice",
    "contact_sentence",
    "count_words",
    "frame_lines",
    "goal_words",
    "grasp_words",
    "hit_words",
    "length_words",
    "moved_words",
    "part_words",
    "recorded_touch_words",
    "route_label",
    "route_sides",
    "routes_words",
    "segment_lines",
    "task_words",
    "touch_words",
    "tune_summary",
]
