"""The studio's exception tree.

Every message is written for the person in front of the browser, not for a programmer: it says what
went wrong in plain words and what to do about it.
"""

from __future__ import annotations


class Cancelled(Exception):
    """A job was stopped because nobody wants its result any more (the studio is stopping); never shown."""


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
    """A session file is missing, damaged or not a Teaching Studio file.

    Attributes:
        session: the session's name, when one file of a session is at fault (else None).
        file: that file, relative to the session folder (e.g. "demos/d0002.npz"), or None.
        problem: what is wrong with it, in plain words ("is missing", "ends early", ...), or None.
    """

    def __init__(
        self, message: str, *, session: str | None = None, file: str | None = None, problem: str | None = None
    ) -> None:
        super().__init__(message)
        self.session = session
        self.file = file
        self.problem = problem


class RecordingError(StudioError):
    """Recording could not start, continue or be saved."""


class StorageError(StudioError):
    """The computer cannot hold what was asked: the disk is full or cannot be written, or a session needs more
    memory than is free. Nothing was changed."""
