"""The verdict on a skill in plain words: each kind of finding (:data:`studio.core.quality.notes.KINDS`) has
its sentence and the knob that would help in :data:`FINDING_WORDS`; each audience says the knob its own way
(:data:`STUDIO_REMEDIES` with the studio's controls, :func:`cli_remedies` with ``studio learn``'s options)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import StrEnum
from typing import Any, Generic, TypeVar

from studio.core.quality import DemoFit, Disagreement, Level, Misfit, Verdict
from studio.core.quality.judgement import Close, CutsCorner, Loose, Strays
from studio.core.quality.notes import (
    EndOff,
    Finding,
    GripperMissed,
    GripperOff,
    GripperUse,
    MissesHeldOut,
    OddDemo,
    OffPath,
    Routes,
    Slow,
    StartOff,
    Unreachable,
)
from studio.words import length_words, routes_words

F = TypeVar("F", bound=Finding)
_PAST = {"close": "closed", "open": "opened"}
_VERB = {"close": "closes", "open": "opens"}
_HEAD = {Level.GOOD: "Good", Level.FAIR: "Fair", Level.POOR: "Poor"}


class Remedy(StrEnum):
    """The knob that would help with a finding; each audience says how to reach it (:data:`STUDIO_REMEDIES`,
    :func:`cli_remedies`)."""

    MORE_KEYPOINTS = "more key-points"  #: search the thresholds, or more detail (more key-points)
    SHARPER_CORNERS = "sharper corners"  #: search the thresholds, or a lower corner-sharpness threshold
    MORE_DEMOS = "more demonstrations"  #: record one or two more
    REDO_DEMO = "redo the demonstration"  #: re-record or hide it
    WITHIN_REACH = "within reach"  #: teach closer to the robot, the gripper in a direction the arm can hold
    CHOOSE_ROUTE = "choose the way"  #: choose which way the skill learns


#: How an audience says each :class:`Remedy` (a phrase that follows a dash, lower case, no full stop).
Remedies = Mapping[Remedy, str]

#: Remedies said the same way everywhere.
SHARED_REMEDIES: dict[Remedy, str] = {
    Remedy.MORE_DEMOS: "record one or two more demonstrations",
    Remedy.WITHIN_REACH: "teach it closer to the robot, with the gripper in a direction the arm can hold",
}
#: The remedies said with the studio's own controls.
STUDIO_REMEDIES: dict[Remedy, str] = {
    **SHARED_REMEDIES,
    Remedy.MORE_KEYPOINTS: "press Suggest, or move Detail towards more key-points",
    Remedy.SHARPER_CORNERS: "press Suggest, or lower Corner sharpness",
    Remedy.REDO_DEMO: "re-record or hide it",
    Remedy.CHOOSE_ROUTE: "choose another way under Way",
}


def cli_remedies(session: str, auto: bool) -> Remedies:
    """The remedies said with ``studio learn``'s options (it has no Suggest or Detail)."""
    again = f'learn again with `studio learn "{session}" --auto`, which searches for better thresholds'
    search = "record one or two more demonstrations (--auto already chose the thresholds)" if auto else again
    return {
        **SHARED_REMEDIES,
        Remedy.MORE_KEYPOINTS: search,
        Remedy.SHARPER_CORNERS: search,
        Remedy.REDO_DEMO: "re-record it, or hide it in the studio",
        Remedy.CHOOSE_ROUTE: "open the session in the studio to choose another way (Train, How the skill is made)",
    }


@dataclass(frozen=True)
class Wording(Generic[F]):
    """How one kind of finding is said: ``say`` gives the sentence without its end (a headline's after "Good: "),
    ``remedy`` is the knob that would help (said after ``then``, then a full stop)."""

    say: Callable[[F], str]
    remedy: Remedy | None = None
    then: str = " — "


def _gripper_use(f: GripperUse) -> str:
    m = f.mismatch
    if m.kind is Disagreement.DEMOS_DIFFER:
        return "Your demonstrations do not use the gripper the same way (not the same closes and opens)"
    if m.kind is Disagreement.UNTAUGHT:
        return "The skill moves the gripper though your demonstrations do not"
    return (
        f"The skill does not use the gripper as you did ({m.skill_actions} gripper actions instead of {m.demo_actions})"
    )


L = length_words
#: Every kind of finding (:data:`studio.core.quality.notes.KINDS`), said; a test checks none is missing.
FINDING_WORDS: dict[type[Finding], Wording[Any]] = {
    Close: Wording(lambda f: f"the skill follows your demonstrations closely (within {L(f.distance)} on average)"),
    Loose: Wording(
        lambda f: (
            f"the skill stays within {L(f.distance)} of your demonstrations on average, but they are closer "
            "to each other than that"
        ),
        Remedy.MORE_KEYPOINTS,
    ),
    CutsCorner: Wording(lambda f: f"it cuts the corner at {f.time:.1f} s by {L(f.distance)}", Remedy.SHARPER_CORNERS),
    Strays: Wording(
        lambda f: f"the skill strays from your demonstrations ({L(f.distance)} on average)", Remedy.MORE_KEYPOINTS
    ),
    Routes: Wording(lambda f: f"{routes_words(f.routes, f.route)}, never a path between them", Remedy.CHOOSE_ROUTE),
    StartOff: Wording(lambda f: f"It starts {L(f.distance)} away from where your demonstrations start"),
    EndOff: Wording(lambda f: f"It ends {L(f.distance)} away from where your demonstrations end"),
    GripperUse: Wording(_gripper_use),
    GripperMissed: Wording(
        lambda f: f"It never {_VERB[f.action][:-1]}s the gripper where you {_PAST[f.action]} it", Remedy.MORE_KEYPOINTS
    ),
    GripperOff: Wording(
        lambda f: (
            f"It {_VERB[f.action]} the gripper {L(f.distance)} away from where you {_PAST[f.action]} it "
            f"(at {f.time:.1f} s)"
        ),
        Remedy.MORE_KEYPOINTS,
    ),
    Unreachable: Wording(
        lambda f: f"The robot cannot follow {100 * f.share:.0f} % of it (up to {L(f.distance)} off at {f.time:.1f} s)",
        Remedy.WITHIN_REACH,
    ),
    OffPath: Wording(
        lambda f: f"The robot strays up to {L(f.distance)} from it (at {f.time:.1f} s)", Remedy.WITHIN_REACH
    ),
    Slow: Wording(
        lambda f: (
            f"The robot needs {f.robot:.1f} s for it (your demonstrations took {f.shortest:.1f}–"
            f"{f.longest:.1f} s): its joints cannot move that fast"
        )
    ),
    MissesHeldOut: Wording(
        lambda f: f"Learned without one of your demonstrations, it misses that one by {L(f.distance)} on average",
        Remedy.MORE_DEMOS,
        ": ",
    ),
    OddDemo: Wording(lambda f: f"{f.demo} differs a lot from the others", Remedy.REDO_DEMO),
}


def finding_words(f: Finding, remedies: Remedies, *, end: str = ".") -> str:
    """One finding as a sentence, with the remedy said for this audience (``end`` closes one without a
    remedy)."""
    w = FINDING_WORDS[type(f)]
    return f"{w.say(f)}{w.then}{remedies[w.remedy]}." if w.remedy is not None else f"{w.say(f)}{end}"


def verdict_lines(v: Verdict, remedies: Remedies) -> tuple[str, ...]:
    """The verdict in plain words: the headline ("Good: …", "Fair: …" or "Poor: …"; ", but:" when notes follow
    it), then one line per note."""
    head = f"{_HEAD[v.level]}: {finding_words(v.headline, remedies, end=', but:' if v.notes else '.')}"
    return (head, *(finding_words(f, remedies) for f in v.notes))


def fit_note(fit: DemoFit) -> str:
    """Why a demonstration fits the skill poorly ("" when it fits well)."""
    if fit.why is Misfit.SHAPE:
        return "It differs a lot from the others."
    if fit.why is Misfit.LIKELIHOOD:
        return "The skill's model finds it much less likely than the others."
    if fit.why is Misfit.FAR:
        return f"The learned path stays {length_words(fit.distance)} from it on average, far more than from the others."
    return ""
