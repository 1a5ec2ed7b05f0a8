"""``session.json``: the session's manifest as frozen dataclasses, validated when read from JSON.

To extend the format: an optional field gets a default, is read with it when absent and always written (no
version change: an older studio ignores unknown keys). A change an older studio would misread bumps
:data:`~studio.storage.format.FORMAT_VERSION` and adds ``UPGRADES[old]`` (raw JSON of ``old`` to ``old + 1``),
applied before validation. A newer manifest is refused in plain words; loading never writes (docs/decisions/023)."""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from studio.core.errors import InvalidInput, StudioError
from studio.core.thresholds import ThresholdSettings
from studio.core.types import (
    ARMS,
    DEFAULT_FRAMES,
    DEFAULT_GENERALIZATION,
    FRAMES,
    GENERALIZATIONS,
    Arm,
    Generalization,
    KeypointParams,
)
from studio.storage.format import (
    DEMO_FILE_RE,
    FORMAT,
    FORMAT_VERSION,
    MANIFEST,
    MAX_DEMOS,
    MAX_FILE_ID,
    MAX_LISTED_SAMPLES,
    MAX_MANIFEST_BYTES,
    PRECISIONS,
    SKILL_DIR,
    SKILL_FILE_RE,
    check_demo_name,
    check_n_clusters,
    damaged,
    decode_manifest,
    finite_number,
)
from studio.storage.fs import read_capped
from studio.world import Scene, WorldEvent, events_from_dict, events_to_dict


def _scene_added(raw: dict[str, Any]) -> dict[str, Any]:
    """Version 1 -> 2: a session from before task scenes stands on an empty table (no ``scene``, no events)."""
    return {**raw, "version": 2, "scene": None}


def _frames_added(raw: dict[str, Any]) -> dict[str, Any]:
    """Version 2 -> 3: a session with skills (paths in the robot's frame) keeps learning them that way."""
    return {**raw, "version": 3, "frames": "robot" if raw.get("skills") else DEFAULT_FRAMES}


#: Upgrades of older manifests: ``UPGRADES[v]`` turns the raw JSON of version ``v`` into version ``v + 1``.
UPGRADES: dict[int, Callable[[dict[str, Any]], dict[str, Any]]] = {1: _scene_added, 2: _frames_added}


@dataclass(frozen=True)
class DemoEntry:
    """One demonstration as the manifest lists it (its arrays are in ``file``)."""

    file: str
    name: str
    arms: tuple[Arm, ...]
    samples: int
    duration: float
    #: Hidden by the teacher: drawn faintly and left out of learning (optional, default False).
    hidden: bool = False
    #: What happened to the objects (start, grasps, releases, misses, end; format 2, optional: none before).
    events: tuple[WorldEvent, ...] = ()
    #: The teacher keeps its pauses (optional, default False: they are shortened, decision 094).
    keep_pauses: bool = False

    def to_json(self) -> dict[str, object]:
        out: dict[str, object] = {
            "file": self.file,
            "name": self.name,
            "arms": list(self.arms),
            "samples": self.samples,
            "duration": round(self.duration, 6),
            "hidden": self.hidden,
        }
        if self.events:
            out["objects"] = events_to_dict(self.events)
        if self.keep_pauses:
            out["keep_pauses"] = True
        return out


@dataclass(frozen=True)
class SkillEntry:
    """One learned skill as the manifest lists it: its file, when and from what it was learned."""

    file: str
    #: When it was learned (UTC, ISO 8601).
    learned: str = ""
    #: The ε thresholds it was learned with (KeypointParams field -> value).
    params: Mapping[str, float] = field(default_factory=dict)
    #: Names of the demonstrations it was learned from, in the skill's order.
    demos: tuple[str, ...] = ()

    @staticmethod
    def for_arm(arm: Arm, learned: str, params: KeypointParams, demos: tuple[str, ...]) -> SkillEntry:
        return SkillEntry(file=f"{SKILL_DIR}/{arm}.npz", learned=learned, params=params.as_dict(), demos=demos)

    def to_json(self) -> dict[str, object]:
        return {"file": self.file, "learned": self.learned, "params": dict(self.params), "demos": list(self.demos)}


@dataclass(frozen=True)
class Manifest:
    """Everything ``session.json`` holds. Build one with :meth:`from_json` (validates) or directly (writes)."""

    name: str
    arms: tuple[Arm, ...]
    created: str
    notes: str
    params: KeypointParams
    demos: tuple[DemoEntry, ...] = ()
    skills: Mapping[Arm, SkillEntry] = field(default_factory=dict)
    #: k chosen by hand (None: automatic).
    n_clusters: int | None = None
    precision: str = "float64"
    #: Number of the next demo file (demos/d<next_id>.npz); never reused within a session.
    next_id: int = 1
    #: The demonstrations changed since the skills were learned.
    skills_stale: bool = False
    modified: str = ""
    robot: str = "baxter"
    version: int = FORMAT_VERSION
    #: The task scene (format 2); None for a session from before scenes (it opens on an empty table).
    scene: Scene | None = None
    # -- learning settings (issue 11; optional: absent in older sessions) --------------------------------------
    #: Detail and the thresholds the teacher set by hand; the others follow the demonstrations. None when the
    #: file predates it: :func:`settings_of` then derives it from ``params``.
    thresholds: ThresholdSettings | None = None
    #: The generalisation mode training uses ("aligned-mean" or "paper").
    generalization: Generalization = DEFAULT_GENERALIZATION
    frames: str = DEFAULT_FRAMES  # where skills keep their path: "objects" (they follow them) or "robot"

    # -- writing ----------------------------------------------------------------------------------------------
    def to_json(self) -> dict[str, object]:
        return {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "name": self.name,
            "robot": self.robot,
            "arms": list(self.arms),
            "created": self.created,
            "modified": self.modified,
            "notes": self.notes,
            "params": self.params.as_dict(),
            "n_clusters": self.n_clusters,
            "precision": self.precision,
            "next_id": self.next_id,
            "demos": [d.to_json() for d in self.demos],
            "skills": {arm: s.to_json() for arm, s in self.skills.items()},
            "skills_stale": self.skills_stale,
            "scene": None if self.scene is None else self.scene.to_dict(),
            **self._learning_json(),
        }

    def files(self) -> set[str]:
        """Every file the manifest lists (demos and skills), relative to the session folder."""
        return {d.file for d in self.demos} | {s.file for s in self.skills.values()}

    def _learning_json(self) -> dict[str, object]:
        out: dict[str, object] = {"generalization": self.generalization, "frames": self.frames}
        if self.thresholds is not None:
            out["thresholds"] = self.thresholds.as_dict()
        return out

    def to_bytes(self) -> bytes:
        """The file's bytes; refused if it could not be opened again (the reading limit), so nothing is written."""
        data = json.dumps(self.to_json(), indent=2, ensure_ascii=False).encode("utf-8") + b"\n"
        if len(data) > MAX_MANIFEST_BYTES:
            raise InvalidInput(
                f"This change would make the session's description {len(data) / 2**20:.1f} MB, more than the "
                f"{MAX_MANIFEST_BYTES / 2**20:.0f} MB a session can be opened with; nothing was changed. Delete "
                "demonstrations you no longer need or remove objects from the table, or start a new session."
            )
        return data

    # -- reading ----------------------------------------------------------------------------------------------
    @classmethod
    def read(cls, path: Path, session: str) -> Manifest:
        """Read and validate the manifest file ``path`` of session ``session`` (never writes)."""
        if not path.exists() and not path.is_symlink():
            raise damaged(session, MANIFEST, "is missing (this folder is not a Teaching Studio session)")
        # A regular file of bounded size only: a link to /dev/zero or a FIFO is refused before it is read.
        return cls.from_json(read_capped(path, MAX_MANIFEST_BYTES, session=session, rel=MANIFEST), session)

    @classmethod
    def from_json(cls, raw: bytes, session: str) -> Manifest:
        """Validate the bytes of a manifest; every problem is a :class:`SessionFormatError` in plain words."""
        m = _Reader(decode_manifest(raw, session), session)
        version = m.version()
        for v in range(version, FORMAT_VERSION):
            m = _Reader(UPGRADES[v](m.raw), session)
        # Checked in this order, so that the first problem of a manifest is the one reported.
        arms = m.arms()
        name: str = m.need("name", str)
        created: str = m.need("created", str)
        notes: str = m.need("notes", str)
        robot = m.robot()
        params = m.params()
        n_clusters = m.n_clusters()
        precision = m.precision()
        demos = m.demos()
        max_id = max((_file_id(d.file) for d in demos), default=0)
        nid = m.raw.get("next_id", max_id + 1)
        if not isinstance(nid, int) or isinstance(nid, bool) or nid < 1:
            raise m.bad('has an invalid "next_id"')
        if nid > MAX_FILE_ID:  # no file can have that number: start after the highest one listed instead
            nid = max_id + 1
        return cls(
            name=name,
            arms=arms,
            created=created,
            notes=notes,
            params=params,
            demos=demos,
            skills=m.skills(),
            n_clusters=n_clusters,
            precision=precision,
            next_id=max(nid, max_id + 1),
            skills_stale=bool(m.raw.get("skills_stale", False)),
            modified=str(m.raw.get("modified", "")),
            robot=robot,
            version=version,
            scene=m.scene(),
            thresholds=m.thresholds(),
            generalization=Generalization(m.choice("generalization", GENERALIZATIONS, DEFAULT_GENERALIZATION)),
            frames=m.choice("frames", FRAMES, DEFAULT_FRAMES),
        )


def settings_of(m: Manifest) -> ThresholdSettings:
    """The threshold settings of a manifest; for a file saved before they existed, values that differ from the
    old fixed defaults are the teacher's and the others follow the demonstrations."""
    return m.thresholds if m.thresholds is not None else ThresholdSettings.from_params(m.params)


def _file_id(rel: str) -> int:
    match = DEMO_FILE_RE.fullmatch(rel)
    return int(match.group(1)) if match else 0


class _Reader:
    """Validates one field of the raw JSON at a time, each problem worded for the person."""

    def __init__(self, raw: dict[str, Any], session: str) -> None:
        self.raw = raw
        self.session = session

    def bad(self, problem: str) -> Exception:
        return damaged(self.session, MANIFEST, problem)

    def need(self, key: str, typ: type) -> Any:
        val = self.raw.get(key)
        if not isinstance(val, typ) or (isinstance(val, bool) and typ is not bool):
            raise self.bad(f'has a missing or invalid "{key}"')
        return val

    def version(self) -> int:
        v = self.raw.get("version")
        if not isinstance(v, int) or isinstance(v, bool):
            raise self.bad("has no valid format version")
        if v > FORMAT_VERSION:
            raise self.bad(
                f"was written by a newer Teaching Studio (format {v}; this one reads format {FORMAT_VERSION})"
            )
        if v < 1:
            raise self.bad(f"has an unknown format version {v}")
        return v

    def arms(self) -> tuple[Arm, ...]:
        arms = self.need("arms", list)
        if not arms or any(a not in ARMS for a in arms) or len(set(arms)) != len(arms):
            raise self.bad('has invalid "arms" (must be "left" and/or "right")')
        return tuple(arms)

    def robot(self) -> str:
        robot: str = self.need("robot", str)
        if robot != "baxter":
            raise self.bad(f'is for a robot this studio does not know ("{robot}")')
        return robot

    def params(self) -> KeypointParams:
        try:
            return KeypointParams.from_dict(self.need("params", dict))
        except (InvalidInput, TypeError, ValueError, OverflowError) as exc:
            raise self.bad(f"has invalid key-point thresholds ({exc})") from exc

    def thresholds(self) -> ThresholdSettings | None:
        raw = self.raw.get("thresholds")
        if raw is None:
            return None
        try:
            return ThresholdSettings.from_dict(raw)
        except (InvalidInput, TypeError, ValueError) as exc:
            raise self.bad(f'has invalid "thresholds" ({exc})') from exc

    def choice(self, key: str, allowed: tuple[str, ...], default: str) -> str:
        value = self.raw.get(key, default)
        if value not in allowed:
            raise self.bad(f'has an unknown "{key}" {value!r}')
        return str(value)

    def n_clusters(self) -> int | None:
        try:
            return check_n_clusters(self.raw.get("n_clusters"))
        except InvalidInput as exc:
            raise self.bad(f'has an invalid "n_clusters" ({exc})') from exc

    def precision(self) -> str:
        prec = self.raw.get("precision", "float64")
        if prec not in PRECISIONS:
            raise self.bad(f'has an unknown "precision" {prec!r}')
        return str(prec)

    def demos(self) -> tuple[DemoEntry, ...]:
        demos = self.need("demos", list)
        if len(demos) > MAX_DEMOS:
            raise self.bad(f"lists an absurd number of demonstrations ({len(demos)})")
        out: list[DemoEntry] = []
        seen: set[str] = set()
        for i, d in enumerate(demos):
            entry = self._demo(i, d)
            if entry.file in seen:
                raise self.bad(f"lists the file {entry.file} twice")
            seen.add(entry.file)
            out.append(entry)
        return tuple(out)

    def _demo(self, i: int, d: object) -> DemoEntry:
        if not isinstance(d, dict):
            raise self.bad(f"has an invalid entry for demonstration {i + 1}")
        f = d.get("file")
        if not isinstance(f, str) or not DEMO_FILE_RE.fullmatch(f):
            raise self.bad(f"names an unsafe or invalid file for demonstration {i + 1}: {f!r}")
        try:
            name = check_demo_name(d.get("name"), typed=False)  # a session saved before invisible ones were refused
        except InvalidInput as exc:
            raise self.bad(f"has an invalid name for demonstration {i + 1}") from exc
        da = d.get("arms")
        if not isinstance(da, list) or not da or any(a not in ARMS for a in da):
            raise self.bad(f"has invalid taught arms for demonstration {i + 1}")
        s = d.get("samples")
        if not isinstance(s, int) or isinstance(s, bool) or not 0 < s <= MAX_LISTED_SAMPLES:
            raise self.bad(f"has an invalid sample count for demonstration {i + 1}")
        hidden = d.get("hidden", False)
        if not isinstance(hidden, bool):
            raise self.bad(f'has an invalid "hidden" mark for demonstration {i + 1}')
        keep = d.get("keep_pauses", False)
        if not isinstance(keep, bool):
            raise self.bad(f'has an invalid "keep_pauses" mark for demonstration {i + 1}')
        dur = d.get("duration", 0.0)
        duration = finite_number(dur) or 0.0
        objects = d.get("objects")
        try:
            events = tuple(events_from_dict(objects)) if isinstance(objects, dict) or objects is None else None
        except StudioError as exc:
            raise self.bad(f"has damaged object events for demonstration {i + 1} ({exc})") from exc
        if events is None:
            raise self.bad(f"has invalid object events for demonstration {i + 1}")
        return DemoEntry(f, name, tuple(da), s, duration, hidden, events, keep)

    def scene(self) -> Scene | None:
        raw = self.raw.get("scene")
        if raw is None:
            return None
        if not isinstance(raw, dict):
            raise self.bad('has an invalid task scene ("scene")')
        try:
            return Scene.from_dict(raw)
        except StudioError as exc:
            raise self.bad(f"has a damaged task scene ({exc})") from exc

    def skills(self) -> dict[Arm, SkillEntry]:
        skills = self.raw.get("skills", {})
        if not isinstance(skills, dict):
            raise self.bad('has invalid "skills"')
        out: dict[Arm, SkillEntry] = {}
        for arm, s in skills.items():
            if arm not in ARMS or not isinstance(s, dict) or not isinstance(s.get("file"), str):
                raise self.bad(f"has an invalid skill entry {arm!r}")
            if not SKILL_FILE_RE.fullmatch(s["file"]) or s["file"] != f"{SKILL_DIR}/{arm}.npz":
                raise self.bad(f"names an unsafe or invalid skill file: {s['file']!r}")
            out[arm] = _skill_entry(s)
        return out


def _skill_entry(s: Mapping[str, object]) -> SkillEntry:
    """The optional parts of a skill entry are informative: what is malformed is left out, not refused."""
    learned, params, demos = s.get("learned"), s.get("params"), s.get("demos")
    return SkillEntry(
        file=str(s["file"]),
        learned=learned if isinstance(learned, str) else "",
        params={
            str(k): v
            for k, v in ((k, finite_number(v)) for k, v in (params.items() if isinstance(params, dict) else ()))
            if v is not None
        },
        demos=tuple(str(n) for n in demos) if isinstance(demos, list) else (),
    )
