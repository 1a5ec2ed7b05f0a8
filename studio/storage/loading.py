"""Opening a session folder: everything validated, its cost checked before anything large is read, never a write.

Order: the folder (no links), the manifest (a regular file of bounded size), what the session will take in
memory (from the manifest's sample counts and the skills' array headers) against the session limit and the
memory free right now, then each file. Two demonstrations listed under one name (a hand-edited manifest) get
distinct names, so that hiding or renaming one never touches the other.
"""

from __future__ import annotations

from pathlib import Path

from studio.core.errors import SessionFormatError
from studio.storage.format import (
    DEMO_BYTES_PER_SAMPLE,
    MANIFEST,
    MAX_DEMO_BYTES,
    MAX_SKILL_BYTES,
    skipped_note,
    unique_name,
)
from studio.storage.fs import check_session_folder
from studio.storage.limits import check_memory
from studio.storage.manifest import Manifest, settings_of
from studio.storage.npz import declared_bytes, load_demo, load_skill
from studio.storage.objects import SessionObjects
from studio.storage.session import Session
from studio.world import Scene


def demos_bytes(m: Manifest) -> int:
    """Bytes the demonstrations ``m`` lists take once loaded (float64); those beyond the per-demo limit are left
    out (loading refuses or skips them before reading them)."""
    sizes = (d.samples * DEMO_BYTES_PER_SAMPLE for d in m.demos)
    return sum(b for b in sizes if b <= MAX_DEMO_BYTES)


def skills_bytes(path: Path, m: Manifest) -> int:
    """Bytes the skills ``m`` lists declare in their array headers (unreadable ones are left out)."""
    need = 0
    for info in m.skills.values():
        try:
            need += declared_bytes(path / info.file, path.name, info.file, max_bytes=MAX_SKILL_BYTES)
        except SessionFormatError:
            continue
    return need


def load_session(path: Path, *, skip_damaged: bool = False) -> Session:
    """Load and validate the session in folder ``path`` (never writes).

    Args:
        skip_damaged: load what is valid and list the damaged demo/skill files in ``problems`` instead of
            raising (the manifest itself must be valid).

    Raises:
        SessionFormatError: a file is missing, damaged, of another version, or hostile; a folder is a link.
        StorageError: the session needs more memory than the session limit or than the computer has free.
    """
    path = Path(path)
    name = path.name
    check_session_folder(path, name)
    m = Manifest.read(path / MANIFEST, name)
    check_memory(demos_bytes(m) + skills_bytes(path, m), f'Session "{name}"')
    s = Session(
        name=name,
        path=path,
        arms=m.arms,
        created=m.created,
        notes=m.notes,
        params=m.params,
        n_clusters=m.n_clusters,
        thresholds=settings_of(m),
        generalization=m.generalization,
        frames=m.frames,
        precision=m.precision,
        skills_stale=m.skills_stale,
        objects=SessionObjects(m.scene if m.scene is not None else Scene()),
    )
    s._next_id = m.next_id

    def skip_or_raise(exc: SessionFormatError) -> None:
        if not skip_damaged:
            raise exc
        s.problems.append(skipped_note(exc))

    names: set[str] = set()
    for entry in m.demos:
        try:
            rec = load_demo(path / entry.file, name, entry)
        except SessionFormatError as exc:
            skip_or_raise(exc)
            continue
        if rec.name in names:
            rec = type(rec)(t=rec.t, q=rec.q, gripper=rec.gripper, arms=rec.arms, name=unique_name(rec.name, names))
        names.add(rec.name)
        s.recordings.append(rec)
        s._files.append(entry.file)
        s.objects.by_file[entry.file] = entry.events
        if entry.hidden:
            s.hidden_demos.add(rec.name)
        if entry.keep_pauses:
            s.pauses_kept.add(rec.name)
    for arm, info in m.skills.items():
        try:
            s.skills[arm] = load_skill(path / info.file, name, info.file)
        except SessionFormatError as exc:
            skip_or_raise(exc)
            continue
        s.skill_info[arm] = info
    if len(s.recordings) != len(m.demos):
        s.skills_stale = bool(s.skills) or s.skills_stale
    return s
