"""The studio's exception tree.

Every message is written for the person in front of the browser, not for a programmer: it says what
went wrong in plain words and what to do about it.
"""

from __future__ import annotations


class StudioError(Exception):
    """Base of every error the studio raises on purpose."""


class InvalidInput(StudioError, ValueError):
    """An argument has the wrong shape, contains NaN, or names something that does not exist."""


class IkFailed(StudioError):
    """The arm cannot reach a requested pose."""


class NotEnoughData(StudioError):
    """Too few demonstrations, key-points or samples to learn from."""


class LearningFailed(StudioError):
    """A learning stage could not produce a result from the given demonstrations."""


class SessionFormatError(StudioError):
    """A session file is missing, damaged or not a Teaching Studio file."""


class RecordingError(StudioError):
    """Recording could not start, continue or be saved."""
