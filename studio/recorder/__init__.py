"""Recording demonstrations from the robot's joint-state stream, crash-safe.

    writer.py   Recorder: subscribes to a backend, appends samples (with FK poses) to a file as they arrive
    files.py    the append-only file format, reading it back, recovering takes a crash interrupted

The recorder knows nothing of sessions: a finished take is handed to anything with ``add_recording``
(:class:`DemoSink`), and the session store calls :func:`recover_recordings` when it opens a session.
"""

from studio.recorder.files import (
    RecordedDemo,
    discard_pending,
    pending_recordings,
    read_recording_file,
    recover_recordings,
)
from studio.recorder.writer import MAX_SECONDS, DemoSink, Recorder

__all__ = [
    "MAX_SECONDS",
    "DemoSink",
    "RecordedDemo",
    "Recorder",
    "discard_pending",
    "pending_recordings",
    "read_recording_file",
    "recover_recordings",
]
