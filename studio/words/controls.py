"""How each audience reaches the studio's controls. The controller names a :class:`Control` where a sentence tells
the person what to do next; the studio says "press Train", ``studio learn`` says "run `studio learn`"."""

from __future__ import annotations

from collections.abc import Mapping
from enum import StrEnum


class Control(StrEnum):
    """A control a sentence of the controller points the person to."""

    TRAIN = "Train"
    PREVIEW = "Preview"
    RECORD = "Record"
    DISCARD = "Discard"
    UNDO = "Undo"
    DELETE = "Delete"
    PLAY = "Play"
    STOP = "Stop"
    RUN = "Run on robot"
    RELEASE_ESTOP = "Release emergency stop"


#: How an audience says it reaches each :class:`Control` (a phrase in lower case: "press Train").
Controls = Mapping[Control, str]

#: In the browser: the buttons (Preview is a step, opened).
STUDIO_CONTROLS: dict[Control, str] = {c: f"press {c.value}" for c in Control} | {Control.PREVIEW: "open Preview"}

#: On the command line: ``studio learn`` trains; the rest is the studio's, named as such.
CLI_CONTROLS: dict[Control, str] = {c: f"use {c.value} in the studio" for c in Control} | {
    Control.TRAIN: "run `studio learn`",
    Control.PREVIEW: "open the session in the studio's Preview",
}


def say(controls: Controls, control: Control, *, first: bool = False) -> str:
    """How ``controls``' audience reaches ``control`` ("press Train"; "Press Train" at the start of a sentence)."""
    words = controls[control]
    return words[:1].upper() + words[1:] if first else words
