"""An open session: its demonstrations, parameters and learned skills, bound to its folder.

Every mutating method writes to disk at once (atomically) and leaves the other files untouched: a demo whose
content changes (trim) gets a new file, the manifest is switched to it atomically, then the old file is
removed, so a crash at any moment leaves a loadable session. Loading validates everything and never writes.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Concatenate, ParamSpec, TypeVar

import numpy as np

from studio.core.arms import normalize_arms
from studio.core.errors import InvalidInput, StorageError, StudioError
from studio.core.thresholds import ThresholdSettings
from studio.core.types import (
    ARMS,
    DEFAULT_GENERALIZATION,
    FRAMES,
    GENERALIZATIONS,
    Arm,
    Generalization,
    KeypointParams,
    Recording,
    Skill,
)
from studio.storage.atomic import atomic_write_bytes, atomic_write_npz
from studio.storage.format import (
    DEMO_DIR,
    MANIFEST,
    MAX_DEMOS,
    MAX_FILE_ID,
    MAX_NOTES_CHARS,
    MAX_SAMPLES,
    PRECISIONS,
    RECORDING_DIR,
    SKILL_DIR,
    check_demo_name,
    check_n_clusters,
    now,
    unique_name,
)
from studio.storage.fs import changing, check_changeable
from studio.storage.idle import idle_bounds
from studio.storage.limits import check_keepable, reworded
from studio.storage.manifest import DemoEntry, Manifest, SkillEntry
from studio.storage.objects import SessionObjects
from studio.world import Scene, WorldEvent

P = ParamSpec("P")
R = TypeVar("R")


def _locked(fn: Callable[Concatenate[Session, P], R]) -> Callable[Concatenate[Session, P], R]:
    """A Session mutator runs as one change (:meth:`Session.change`): serialised, and all or nothing in memory."""

    @functools.wraps(fn)
    def wrapper(self: Session, /, *args: P.args, **kwargs: P.kwargs) -> R:
        with self.change():
            return fn(self, *args, **kwargs)

    return wrapper


#: What a failed change puts back (the in-memory state; files on disk are written atomically, manifest last).
_STATE = (
    *("arms", "notes", "params", "n_clusters", "recordings", "hidden_demos", "pauses_kept", "skills", "skills_stale"),
    *("skill_info", "precision", "_files", "_next_id", "objects", "thresholds", "generalization", "frames"),
)


class ReadOnly(StudioError):
    """A change of a bundled example, refused in words that say how to change a copy instead."""

    def __init__(self, name: str) -> None:
        super().__init__(
            f'"{name}" is an example and stays as it is, so that it can always be opened again. To change it, type '
            "a name under Sessions → New name and press Duplicate: the copy is yours to change."
        )


@dataclass
class Session:
    """An open session. Attributes are for reading; change them through the methods.

    Attributes:
        name, path: the session's name and folder.
        arms: the taught arm(s).
        params, thresholds, n_clusters, generalization: the learning settings (see :class:`Manifest`).
        recordings: the demonstrations, in order; hidden_demos: names of those hidden from learning;
            pauses_kept: names of those whose pauses the teacher keeps.
        skills: arm -> learned :class:`Skill`; skill_info: arm -> what it was learned from and when.
        skills_stale: the demonstrations changed since the skills were learned.
        problems, recovery_message: plain-words notes from loading (skipped damaged files, crash recovery).
        opened_instead: why this session was opened in place of the one asked for ("" normally).
        objects: the task scene and each demonstration's object events (:class:`SessionObjects`).
        read_only: a bundled example the studio keeps as it is: every change is refused (:class:`ReadOnly`).
    """

    name: str
    path: Path
    arms: tuple[Arm, ...] = ("left",)
    created: str = field(default_factory=now)
    notes: str = ""
    params: KeypointParams = field(default_factory=KeypointParams)
    n_clusters: int | None = None
    thresholds: ThresholdSettings = field(default_factory=ThresholdSettings)
    generalization: Generalization = DEFAULT_GENERALIZATION
    frames: str = FRAMES[0]
    recordings: list[Recording] = field(default_factory=list)
    hidden_demos: set[str] = field(default_factory=set)
    pauses_kept: set[str] = field(default_factory=set)
    skills: dict[Arm, Skill] = field(default_factory=dict)
    precision: str = "float64"
    skills_stale: bool = False
    skill_info: dict[Arm, SkillEntry] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    recovery_message: str = ""
    opened_instead: str = ""
    objects: SessionObjects = field(default_factory=SessionObjects)
    read_only: bool = field(default=False, compare=False)
    _files: list[str] = field(default_factory=list, repr=False)
    _next_id: int = field(default=1, repr=False)
    _lock: threading.RLock = field(default_factory=threading.RLock, repr=False, compare=False)
    _changing: int = field(default=0, repr=False, compare=False)

    # -- reading ------------------------------------------------------------------------------------------
    @property
    def demo_names(self) -> list[str]:
        return [r.name for r in self.recordings]

    @property
    def demo_files(self) -> list[str]:
        """Relative paths of the demo files, in demo order."""
        return list(self._files)

    @property
    def recording_dir(self) -> Path:
        """Folder for the recorder's crash-safe files of this session."""
        return self.path / RECORDING_DIR

    def __len__(self) -> int:
        return len(self.recordings)

    def change(self) -> contextlib.AbstractContextManager[None]:
        """One change of the session, all or nothing in memory (see :func:`_change`)."""
        return _change(self)

    # -- demos --------------------------------------------------------------------------------------------
    def _check_index(self, i: int) -> int:
        if not isinstance(i, (int, np.integer)) or not 0 <= int(i) < len(self.recordings):
            raise InvalidInput(f"There is no demonstration number {i}; the session has {len(self.recordings)}.")
        return int(i)

    def _write_demo(self, rec: Recording) -> str:
        rel = new_demo_file(self)
        dt = PRECISIONS[self.precision]
        atomic_write_npz(
            self.path / rel,
            {"t": rec.t, "q": rec.q.astype(dt, copy=False), "gripper": rec.gripper.astype(dt, copy=False)},
        )
        return rel

    def _mark_stale(self) -> None:
        self.skills_stale = bool(self.skills) or self.skills_stale

    @_locked
    def add_recording(self, rec: Recording, name: str | None = None, events: Iterable[WorldEvent] = ()) -> int:
        """Add a demonstration (saved at once) and its object events; returns its index. Names are made unique."""
        if not isinstance(rec, Recording):
            raise InvalidInput("Only recordings can be added to a session.")
        if len(rec) < 2:
            raise InvalidInput("A demonstration needs at least two samples.")
        if len(rec) > MAX_SAMPLES:
            raise InvalidInput(
                f"This demonstration is too long to keep ({len(rec):,} samples, {rec.duration / 60:,.0f} minutes); "
                f"a demonstration may have {MAX_SAMPLES:,} samples (an hour at 1,000 a second). Trim it first."
            )
        if len(self.recordings) >= MAX_DEMOS:
            raise InvalidInput(f"A session holds at most {MAX_DEMOS} demonstrations.")
        check_keepable(rec, self.recordings)
        nm = unique_name(check_demo_name(name if name is not None else rec.name), set(self.demo_names))
        rec = Recording(t=rec.t, q=rec.q, gripper=rec.gripper, arms=rec.arms, name=nm)
        try:
            rel = self._write_demo(rec)
        except StorageError as exc:
            raise reworded(exc, self.path, f'The demonstration "{nm}"', "saved") from exc.__cause__
        self.recordings.append(as_stored(self.precision, rec))
        self._files.append(rel)
        self.objects.added(rel, events)
        self._mark_stale()
        self._write_manifest()
        return len(self.recordings) - 1

    @_locked
    def rename_demo(self, i: int, name: str) -> None:
        """Rename demonstration ``i`` (only the manifest changes)."""
        i = self._check_index(i)
        nm = check_demo_name(name)
        if nm != self.recordings[i].name and nm in self.demo_names:
            raise InvalidInput(f'Another demonstration is already called "{nm}".')
        r = self.recordings[i]
        self.recordings[i] = Recording(t=r.t, q=r.q, gripper=r.gripper, arms=r.arms, name=nm)
        if r.name in self.hidden_demos:
            self.hidden_demos = (self.hidden_demos - {r.name}) | {nm}
        if r.name in self.pauses_kept:
            self.pauses_kept = (self.pauses_kept - {r.name}) | {nm}
        self._write_manifest()

    @_locked
    def set_demo_hidden(self, i: int, hidden: bool) -> None:
        """Hide demonstration ``i`` from learning (kept on disk and in the list), or show it again."""
        name = self.recordings[self._check_index(i)].name
        self.hidden_demos = (self.hidden_demos | {name}) if hidden else (self.hidden_demos - {name})
        self._write_manifest()

    @_locked
    def set_demo_pauses(self, i: int, keep: bool) -> None:
        """Keep the pauses of demonstration ``i`` (learned as they were), or shorten them again (the default)."""
        name = self.recordings[self._check_index(i)].name
        self.pauses_kept = (self.pauses_kept | {name}) if keep else (self.pauses_kept - {name})
        self._mark_stale()
        self._write_manifest()

    @_locked
    def delete_demo(self, i: int) -> None:
        """Delete demonstration ``i``: the manifest stops listing it first, then its file is removed."""
        i = self._check_index(i)
        rel = self._files.pop(i)
        self.objects.removed(rel)
        gone = self.recordings.pop(i).name
        self.hidden_demos = self.hidden_demos - {gone}
        self.pauses_kept = self.pauses_kept - {gone}
        self._mark_stale()
        self._write_manifest()
        with contextlib.suppress(OSError):  # saved already; a file left behind is cleaned at the next open
            (self.path / rel).unlink()

    @_locked
    def trim_demo(self, i: int, t0: float, t1: float, events: Iterable[WorldEvent] | None = None) -> None:
        """Keep only the samples of demonstration ``i`` with t0 ≤ t ≤ t1 (seconds); times restart at 0 (object
        events: ``events``, by default those within the kept time)."""
        i = self._check_index(i)
        r = self.recordings[i]
        if not (np.isfinite(t0) and np.isfinite(t1)) or t1 <= t0:
            raise InvalidInput("To trim, choose a start time before the end time.")
        keep = (r.t >= t0 - 1e-9) & (r.t <= t1 + 1e-9)
        if np.count_nonzero(keep) < 2:
            raise InvalidInput("Trimming would leave fewer than two samples; choose a wider range.")
        new = Recording(t=r.t[keep] - r.t[keep][0], q=r.q[keep], gripper=r.gripper[keep], arms=r.arms, name=r.name)
        rel = self._write_demo(new)
        old = self._files[i]
        self._files[i] = rel
        self.objects.trimmed(old, rel, t0, t1, events)
        self.recordings[i] = as_stored(self.precision, new)
        self._mark_stale()
        self._write_manifest()
        with contextlib.suppress(OSError):
            (self.path / old).unlink()

    @_locked
    def trim_idle(
        self, i: int, *, threshold: float = 0.01, gripper_threshold: float = 1.0, margin: float = 0.2
    ) -> tuple[float, float]:
        """Cut the idle start and end of demonstration ``i`` (see :func:`idle_bounds`); returns (t0, t1) used."""
        i = self._check_index(i)
        r = self.recordings[i]
        t0, t1 = idle_bounds(r, threshold=threshold, gripper_threshold=gripper_threshold, margin=margin)
        if t0 > r.t[0] + 1e-9 or t1 < r.t[-1] - 1e-9:
            self.trim_demo(i, t0, t1)
        return t0, t1

    @_locked
    def set_scene(self, scene: Scene) -> None:
        self.objects.scene = scene
        self._write_manifest()

    # -- parameters, notes, skills ------------------------------------------------------------------------
    @_locked
    def set_params(
        self,
        params: KeypointParams | None = None,
        settings: ThresholdSettings | None = None,
        mode: Generalization | str | None = None,
    ) -> None:
        """Keep the ε values with the settings they come from (default: values off the old fixed defaults are the
        teacher's, the others automatic), and/or a ``mode``: "aligned-mean"/"paper" or ``FRAMES`` "objects"/"robot"."""
        modes = (None, *GENERALIZATIONS, *FRAMES)
        if (params is not None and not isinstance(params, KeypointParams)) or mode not in modes:
            raise InvalidInput('Key-point thresholds must be a KeypointParams, the mode "aligned-mean" or "paper".')
        self.frames = mode if mode in FRAMES else self.frames
        if params is not None:
            self.params, self.thresholds = params, settings or ThresholdSettings.from_params(params)
        if mode is not None and mode in GENERALIZATIONS:
            self.generalization = Generalization(mode)
        self._write_manifest()

    @_locked
    def set_n_clusters(self, k: int | None) -> None:
        """Remember k, the number of clusters chosen by hand (None: choose it automatically)."""
        self.n_clusters = check_n_clusters(k)
        self._write_manifest()

    @_locked
    def set_notes(self, notes: str) -> None:
        if not isinstance(notes, str) or len(notes) > MAX_NOTES_CHARS:
            raise InvalidInput("Notes must be text of at most 100,000 characters.")
        self.notes = notes
        self._write_manifest()

    @_locked
    def set_arms(self, arms: Iterable[str]) -> None:
        self.arms = normalize_arms(tuple(arms))
        self._write_manifest()

    @_locked
    def set_skills(
        self,
        skills: Mapping[Arm, Skill],
        params: KeypointParams | None = None,
        demos: Iterable[str] | Mapping[str, Iterable[str]] | None = None,
        *,
        stale: bool = False,
    ) -> None:
        """Save learned skills (arm -> Skill), replacing the previous ones.

        Args:
            params: the thresholds they were learned with (also become the session's parameters).
            demos: names of the demonstrations they were learned from: one list for every arm, or a mapping
                arm -> names (default: all of the session's).
            stale: the demonstrations changed while they were learned (the skills are saved marked stale).
        """
        for arm in skills:
            if arm not in ARMS:
                raise InvalidInput(f'Unknown arm "{arm}" for a skill.')
        if isinstance(demos, Mapping):
            per_arm = {arm: tuple(demos.get(arm, self.demo_names)) for arm in skills}
        else:
            names = tuple(demos) if demos is not None else tuple(self.demo_names)
            per_arm = {arm: names for arm in skills}
        for arm, sk in skills.items():
            atomic_write_npz(self.path / SKILL_DIR / f"{arm}.npz", dict(sk.to_arrays()))
        old = set(self.skills) - set(skills)
        if params is not None:
            self.params = params
        self.skills = dict(skills)
        learned = now()
        self.skill_info = {arm: SkillEntry.for_arm(arm, learned, self.params, per_arm[arm]) for arm in skills}
        self.skills_stale = stale
        self._write_manifest()
        for arm in old:
            with contextlib.suppress(OSError):
                (self.path / SKILL_DIR / f"{arm}.npz").unlink()

    # -- manifest -----------------------------------------------------------------------------------------
    def manifest(self) -> Manifest:
        """The manifest describing the session as it is now."""
        return _manifest(self)

    def _write_manifest(self) -> None:
        atomic_write_bytes(self.path / MANIFEST, self.manifest().to_bytes())


def _manifest(session: Session) -> Manifest:
    """The manifest describing ``session`` as it is now."""
    return Manifest(
        name=session.name,
        arms=session.arms,
        created=session.created,
        modified=now(),
        notes=session.notes,
        params=session.params,
        n_clusters=session.n_clusters,
        precision=session.precision,
        next_id=session._next_id,
        demos=tuple(
            DemoEntry(
                file=f,
                name=r.name,
                arms=r.arms,
                samples=len(r),
                duration=r.duration,
                hidden=r.name in session.hidden_demos,
                keep_pauses=r.name in session.pauses_kept,
                events=session.objects.events(f),
            )
            for f, r in zip(session._files, session.recordings, strict=True)
        ),
        skills=dict(session.skill_info),
        skills_stale=session.skills_stale,
        scene=session.objects.scene,
        thresholds=session.thresholds,
        generalization=session.generalization,
        frames=session.frames,
    )


@contextlib.contextmanager
def _change(s: Session) -> Iterator[None]:
    """One change of session ``s``: one thread at a time, the folder held against other processes (so that
    opening it elsewhere never cleans away a file being written), refused if a folder of the session became a
    link, and undone in memory if it fails (the files stay as the last complete save left them)."""
    with s._lock:
        if s._changing:
            yield
            return
        if s.read_only:
            raise ReadOnly(s.name)
        error = check_changeable(s.path, s.name)
        if error is not None:
            raise error
        saved = {k: copy.copy(getattr(s, k)) for k in _STATE}
        s._changing = 1
        try:
            with changing(s.path):
                yield
        except BaseException:
            for k, v in saved.items():
                setattr(s, k, v)
            raise
        finally:
            s._changing = 0


def new_demo_file(s: Session) -> str:
    """The next demo file of session ``s``: numbers are not reused; once past the largest possible, the lowest
    one neither listed nor on disk."""
    if s._next_id <= MAX_FILE_ID:
        s._next_id += 1
        return f"{DEMO_DIR}/d{s._next_id - 1:04d}.npz"
    used = {int(f[len(DEMO_DIR) + 2 : -4]) for f in s._files}
    for i in range(1, MAX_FILE_ID + 1):
        rel = f"{DEMO_DIR}/d{i:04d}.npz"
        if i not in used and not (s.path / rel).exists():
            return rel
    raise InvalidInput("This session has used every demonstration file number; copy it to a new session.")


def as_stored(precision: str, rec: Recording) -> Recording:
    """The recording as it will load back (float32 precision rounds the joints)."""
    if precision == "float64":
        return rec
    dt = PRECISIONS[precision]
    return Recording(
        t=rec.t,
        q=rec.q.astype(dt).astype(np.float64),
        gripper=rec.gripper.astype(dt).astype(np.float64),
        arms=rec.arms,
        name=rec.name,
    )
