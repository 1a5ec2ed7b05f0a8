"""The GUI-free core: the paper's pipeline over numpy arrays (never imports viser or threading)."""

from studio.core.errors import (
    IkFailed,
    InvalidInput,
    LearningFailed,
    NotEnoughData,
    RecordingError,
    SessionFormatError,
    StudioError,
)
from studio.core.types import ALL_ARM_JOINTS, ARM_JOINTS, ARMS, Demo, KeypointParams, Recording

__all__ = [
    "ALL_ARM_JOINTS",
    "ARMS",
    "ARM_JOINTS",
    "Demo",
    "IkFailed",
    "InvalidInput",
    "KeypointParams",
    "LearningFailed",
    "NotEnoughData",
    "Recording",
    "RecordingError",
    "SessionFormatError",
    "StudioError",
]
