"""The verdict's words for each audience: every finding is worded, the studio names its controls, and
``studio learn`` names its options, never a control it does not have."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from studio import words as W
from studio.commands import cli_remedies
from studio.core.quality import Disagreement, Finding, GripperMismatch, Issue, Level, Remedy, Verdict
from studio.panels.train import REMEDIES as STUDIO

#: One finding of every kind, with figures.
EVERY_NOTE = (
    Finding(Issue.START_OFF, distance=0.004),
    Finding(Issue.END_OFF, distance=0.012),
    Finding(Issue.GRIPPER_MISMATCH, mismatch=GripperMismatch(Disagreement.SKILL_DIFFERS, 1, 2)),
    Finding(Issue.GRIPPER_MISSED, Remedy.MORE_KEYPOINTS, action="close"),
    Finding(Issue.GRIPPER_OFF, Remedy.MORE_KEYPOINTS, distance=0.02, time=1.5, action="open"),
    Finding(Issue.UNREACHABLE, Remedy.WITHIN_REACH, distance=0.03, time=2.0, share=0.1),
    Finding(Issue.OFF_PATH, Remedy.WITHIN_REACH, distance=0.007, time=0.1, share=0.0),
    Finding(Issue.SLOW, time=5.0, durations=(5.0, 2.0, 2.5)),
    Finding(Issue.HELD_OUT, Remedy.MORE_DEMOS, distance=0.01),
    Finding(Issue.OUTLIER, Remedy.REDO_DEMO, distance=0.05, demo="demo 4"),
)
HEADLINES = (
    Verdict(Level.POOR, Finding(Issue.STRAYS, Remedy.MORE_KEYPOINTS, distance=0.03), EVERY_NOTE),
    Verdict(Level.FAIR, Finding(Issue.CUTS_CORNER, Remedy.SHARPER_CORNERS, distance=0.02, time=1.0)),
    Verdict(Level.FAIR, Finding(Issue.LOOSE, Remedy.MORE_KEYPOINTS, distance=0.01)),
    Verdict(Level.FAIR, Finding(Issue.CLOSE, distance=0.002), EVERY_NOTE[:1]),
    Verdict(Level.GOOD, Finding(Issue.CLOSE, distance=0.002)),
)


@pytest.mark.parametrize("remedies", [STUDIO, cli_remedies("my session", False), cli_remedies("x", True)])
def test_every_remedy_is_said(remedies: W.Remedies) -> None:
    assert set(remedies) == set(Remedy)
    assert all(r and r[0].islower() and not r.endswith(".") for r in remedies.values())


def test_every_finding_has_its_own_sentence() -> None:
    lines = W.verdict_lines(HEADLINES[0], STUDIO)
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
        text = "\n".join(line for v in HEADLINES for line in W.verdict_lines(v, remedies))
        assert not re.search(r"\bpress\b|Suggest|Detail|Corner sharpness", text), text
    text = "\n".join(W.verdict_lines(HEADLINES[2], cli_remedies("my session", False)))
    assert 'learn again with `studio learn "my session" --auto`' in text
    assert "--auto already chose" in "\n".join(W.verdict_lines(HEADLINES[2], cli_remedies("my session", True)))
    studio_text = "\n".join(W.verdict_lines(HEADLINES[1], STUDIO))
    assert studio_text.endswith("— press Suggest, or lower Corner sharpness.")


def test_the_core_names_no_control_of_the_studio() -> None:
    # the issue's check: `grep -rn "press\|Suggest\|Detail" studio/core` finds nothing
    core = Path(__file__).resolve().parent.parent / "studio" / "core"
    found = [
        f"{p.relative_to(core.parent)}:{i}: {line.strip()}"
        for p in sorted(core.rglob("*.py"))
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if re.search(r"press|Suggest|Detail", line)
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
