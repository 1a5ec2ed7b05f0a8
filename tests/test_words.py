"""The verdict's words for each audience: every finding is worded, the studio names its controls, and
``studio learn`` names its options, never a control it does not have."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from studio import words as W
from studio.core.quality import Disagreement, GripperMismatch, Level, Verdict
from studio.core.quality.judgement import Close, CutsCorner, Loose, Strays
from studio.core.quality.notes import (
    KINDS,
    EndOff,
    GripperMissed,
    GripperOff,
    GripperUse,
    MissesHeldOut,
    OddDemo,
    OffPath,
    Slow,
    StartOff,
    Unreachable,
)
from studio.words import quality as WQ
from studio.words.quality import STUDIO_REMEDIES as STUDIO
from studio.words.quality import Remedy, cli_remedies

#: One finding of every kind, with figures.
EVERY_NOTE = (
    StartOff(0.004),
    EndOff(0.012),
    GripperUse(GripperMismatch(Disagreement.SKILL_DIFFERS, 1, 2)),
    GripperMissed("close"),
    GripperOff("open", 0.02, 1.5),
    Unreachable(0.1, 0.03, 2.0),
    OffPath(0.007, 0.1),
    Slow(5.0, 2.0, 2.5),
    MissesHeldOut(0.01),
    OddDemo("demo 4", 0.05),
)
HEADLINES = (
    Verdict(Level.POOR, Strays(0.03), EVERY_NOTE),
    Verdict(Level.FAIR, CutsCorner(0.02, 1.0)),
    Verdict(Level.FAIR, Loose(0.01)),
    Verdict(Level.FAIR, Close(0.002), EVERY_NOTE[:1]),
    Verdict(Level.GOOD, Close(0.002)),
)


def test_every_kind_of_finding_has_words() -> None:
    # no silent fallback: a kind of finding without an entry in the words table would fail the Train panel
    assert set(WQ.FINDING_WORDS) == set(KINDS) and len(KINDS) == len(set(KINDS))
    assert all(w.remedy is None or w.remedy in Remedy for w in WQ.FINDING_WORDS.values())


@pytest.mark.parametrize("remedies", [STUDIO, cli_remedies("my session", False), cli_remedies("x", True)])
def test_every_remedy_is_said(remedies: WQ.Remedies) -> None:
    assert set(remedies) == set(Remedy)
    assert all(r and r[0].islower() and not r.endswith(".") for r in remedies.values())


def test_every_finding_has_its_own_sentence() -> None:
    lines = WQ.verdict_lines(HEADLINES[0], STUDIO)
    assert len(lines) == 1 + len(EVERY_NOTE) and len(set(lines)) == len(lines)
    assert not any("nan" in line or "Issue." in line for line in lines)
    assert "The skill does not use the gripper as you did (1 gripper actions instead of 2)." in lines
    assert (
        "It never closes the gripper where you closed it — press Suggest, or move Detail towards more key-points."
        in lines
    )
    assert "The robot cannot follow 10 % of it (up to 3 cm off at 2.0 s) — teach it closer" in lines[6]
    assert (
        "The robot needs 5.0 s for it (your demonstrations took 2.0–2.5 s): its joints cannot move that fast." in lines
    )


def test_the_command_line_names_its_options_not_the_studio_controls() -> None:
    for auto in (False, True):
        remedies = cli_remedies("my session", auto)
        text = "\n".join(line for v in HEADLINES for line in WQ.verdict_lines(v, remedies))
        assert not re.search(r"\bpress\b|Suggest|Detail|Corner sharpness", text), text
    text = "\n".join(WQ.verdict_lines(HEADLINES[2], cli_remedies("my session", False)))
    assert 'learn again with `studio learn "my session" --auto`' in text
    assert "--auto already chose" in "\n".join(WQ.verdict_lines(HEADLINES[2], cli_remedies("my session", True)))
    studio_text = "\n".join(WQ.verdict_lines(HEADLINES[1], STUDIO))
    assert studio_text.endswith("— press Suggest, or lower Corner sharpness.")


def test_each_audience_says_every_control_and_the_command_line_never_says_press() -> None:
    from studio.words.controls import CLI_CONTROLS, STUDIO_CONTROLS, Control, say

    assert set(CLI_CONTROLS) == set(STUDIO_CONTROLS) == set(Control)
    assert not [v for v in CLI_CONTROLS.values() if re.search(r"\bpress", v, re.IGNORECASE)]
    assert say(STUDIO_CONTROLS, Control.TRAIN) == "press Train" and say(CLI_CONTROLS, Control.TRAIN, first=True) == (
        "Run `studio learn`"
    )


@pytest.mark.parametrize(
    ("layer", "pattern"),
    [
        ("core", re.compile(r"press|Suggest|Detail")),  # the core's facts name no control of the studio
        # issue 28: the controller, which `studio learn` runs too, names a Control; each audience says it
        ("controller", re.compile(r"press|open preview|train panel", re.IGNORECASE)),
    ],
)
def test_core_and_controller_name_no_control_of_the_studio(layer: str, pattern: re.Pattern[str]) -> None:
    root = Path(__file__).resolve().parent.parent / "studio" / layer
    found = [
        f"{p.relative_to(root.parent)}:{i}: {line.strip()}"
        for p in sorted(root.rglob("*.py"))
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if pattern.search(line)
    ]
    assert not found, "\n".join(found)


def test_suggest_says_where_the_skill_grasps_when_the_demos_grasp():
    from studio.core.autotune import Score, TuneResult
    from studio.core.thresholds import ThresholdSettings
    from studio.core.types import KeypointParams
    from studio.words import tune_summary

    def result(before: Score, after: Score, changed: bool) -> TuneResult:
        return TuneResult(ThresholdSettings(), KeypointParams(), None, before, after, 5, 0.5, False, True, changed)

    shapes = Score(0.7, 0.004, 20, 20, task=0.0)
    assert "grasps" not in tune_summary(result(shapes, shapes, False))
    task = Score(0.7, 0.004, 20, 20, task=0.0064)
    kept = tune_summary(result(task, task, False))
    assert kept.startswith("Your thresholds are already good") and "grasps and releases 6 mm from where you did" in kept
    better = tune_summary(result(Score(1.0, 0.01, 12, 12, task=0.009), Score(0.8, 0.008, 20, 20, task=0.007), True))
    assert "misses it by 8 mm" in better and "grasps and releases 7 mm from where you did, 9 mm before" in better


def test_each_stretch_of_a_skill_that_follows_the_objects_in_words():
    from studio.core.segment_view import SegmentFit

    fits = (
        SegmentFit("start", "grasp", "cup", "object:cup", 0.004, 0.3),
        SegmentFit("grasp", "release", "cup", "object:bottom cup", 0.03, 0.8),
        SegmentFit("release", "end", "cup", "robot", 0.08, 1.5),
    )
    lines = W.segment_lines(fits)
    assert (
        lines[0] == "Reaching for the cup (relative to the cup): within 4 mm of your demonstrations on average — good."
    )
    assert lines[1].startswith("Carrying the cup to the bottom cup (relative to the bottom cup): within 3 cm")
    assert "fair" in lines[1] and "poor" in lines[2] and "relative to the robot" in lines[2]


def test_the_goal_in_words():
    from studio.world import START, TABLE, Placement

    kinds = {"block": "block", "pad": "pad", "cup": "cup", "bottom cup": "cup"}
    assert W.goal_words((Placement("block", "pad"),), kinds) == "Put the block on the pad."
    assert W.goal_words((Placement("cup", "bottom cup"),), kinds) == "Put the cup into the bottom cup."
    there_and_back = (Placement("block", "pad"), Placement("block", START))
    assert W.goal_words(there_and_back, kinds) == "Put the block on the pad, then back where it started."
    assert W.goal_words((Placement("block", TABLE),), kinds) == "Put the block on the table where you put it."
    assert W.goal_words((), kinds) == ""


def test_how_the_frames_were_chosen_in_words():
    from studio.core.segments import FrameChoice

    one_place = (
        FrameChoice("grasp", "block", "object:block", "object:block", told=False),
        FrameChoice("release", "block", "object:pad", "object:pad", told=False),
    )
    assert W.frame_lines(one_place) == (
        "Every demonstration had the block in the same place: I will follow the block for the grasp and the pad for "
        "the release. Show me one more with the block somewhere else to be sure.",
    )
    against = (
        FrameChoice("grasp", "block", "object:block", "object:block"),
        FrameChoice("release", "block", "start:block", "object:pad", told=True, against=True),
    )
    assert W.frame_lines(against) == (
        "Your demonstrations put the block down relative to where the block stood, not the pad: I follow your "
        "demonstrations.",
    )
    agreed = (FrameChoice("grasp", "block", "object:block", "object:block"),)
    assert W.frame_lines(agreed) == ()  # the demonstrations show what the meaning says: nothing to tell
