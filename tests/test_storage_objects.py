"""The task scene and each demonstration's object events in the session (format 2): round trips, edits that
keep them with their demonstration, older sessions opening on an empty table, damaged and absurd entries."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from studio.core.errors import InvalidInput, SessionFormatError
from studio.core.types import Recording
from studio.storage import FORMAT_VERSION, SessionStore, load_session
from studio.storage.manifest import UPGRADES
from studio.world import MAX_EVENTS, MAX_OBJECTS, Scene, WorldEvent, preset


def make_rec(n: int = 2000, name: str = "demo") -> Recording:
    t = np.arange(n) / 1000.0
    q = np.tile([0.08, -1.0, -1.19, 1.94, 0.67, 1.03, -0.5] * 2, (n, 1)).astype(float)
    q[:, 0] += np.linspace(0, 0.3, n)
    return Recording(t=t, q=q, gripper=np.full((n, 2), 100.0), arms=("left",), name=name)


def events_for(scene: Scene) -> list[WorldEvent]:
    """Start, a grasp at 0.5 s, a release at 1.5 s (the block 10 cm further), end at 1.999 s."""
    start = tuple(_poses(scene, 0.0))
    moved = tuple(_poses(scene, 0.10))
    held = tuple(_poses(scene, 0.05, held=True))
    return [
        WorldEvent(0.0, "start", None, None, None, start),
        WorldEvent(0.5, "grasp", "left", "block", (0.72, 0.40, -0.03), held),
        WorldEvent(1.5, "release", "left", "block", (0.82, 0.40, -0.03), moved),
        WorldEvent(1.999, "end", None, None, None, moved),
    ]


def _poses(scene: Scene, dx: float, held: bool = False):
    from studio.world import ObjectPose

    for o in scene.objects:
        x, y, z = o.position
        if o.name == "block":
            yield ObjectPose(o.name, o.kind, o.size, (x + dx, y, z), (1.0, 0.0, 0.0, 0.0), "left" if held else None)
        else:
            yield ObjectPose(o.name, o.kind, o.size, o.position, (1.0, 0.0, 0.0, 0.0), None, "table")


@pytest.fixture
def store(tmp_path: Path) -> SessionStore:
    return SessionStore(tmp_path / "sessions")


@pytest.fixture
def session(store: SessionStore):
    s = store.create("with objects")
    scene = preset("pick-place")
    s.set_scene(scene)
    s.add_recording(make_rec(name="demo 1"), events=events_for(scene))
    s.add_recording(make_rec(name="demo 2"))  # recorded without objects
    return s


def test_scene_and_events_round_trip_through_the_manifest(store: SessionStore, session) -> None:
    again = store.open(session.name)
    assert again.objects.scene == preset("pick-place")
    assert again.objects.events(again.demo_files[0]) == tuple(events_for(preset("pick-place")))
    assert again.objects.events(again.demo_files[1]) == ()
    raw = json.loads((session.path / "session.json").read_text())
    assert raw["version"] == FORMAT_VERSION == 3
    assert raw["scene"]["preset"] == "pick-place"
    assert [e["kind"] for e in raw["demos"][0]["objects"]["events"]] == ["start", "grasp", "release", "end"]
    assert "objects" not in raw["demos"][1]  # nothing written for a demonstration without objects


def test_duplicate_and_zip_keep_the_objects(store: SessionStore, session) -> None:
    copy = store.duplicate(session.name, "copy")
    assert copy.objects.scene == session.objects.scene
    assert copy.objects.events(copy.demo_files[0]) == session.objects.events(session.demo_files[0])
    name = store.import_zip(store.export_zip(session.name), "unzipped")
    back = store.open(name)
    assert back.objects.scene == session.objects.scene
    assert back.objects.events(back.demo_files[0]) == session.objects.events(session.demo_files[0])


def test_edits_keep_the_events_with_their_demonstration(store: SessionStore, session) -> None:
    session.rename_demo(0, "first")
    assert len(session.objects.events(session.demo_files[0])) == 4
    session.trim_demo(0, 0.4, 1.6)  # keeps the grasp and the release, times restart at 0
    ev = session.objects.events(session.demo_files[0])
    assert [e.kind for e in ev] == ["start", "grasp", "release", "end"]
    assert [round(e.t, 3) for e in ev] == [0.0, 0.1, 1.1, 1.2]
    assert ev[0].poses == events_for(session.objects.scene)[0].poses  # the objects as they were at 0.4 s
    session.trim_demo(0, 0.2, 1.0)  # the release is cut off: the block ends held
    ev = session.objects.events(session.demo_files[0])
    assert [e.kind for e in ev] == ["start", "end"] and ev[-1].pose("block").held_by == "left"
    session.delete_demo(0)
    again = store.open(session.name)
    assert again.objects.events(again.demo_files[0]) == ()
    assert len(again.recordings) == 1


def test_a_version_1_session_opens_on_an_empty_table_and_is_written_in_the_current_version(
    store: SessionStore, session
) -> None:
    assert 1 in UPGRADES
    path = session.path / "session.json"
    raw = json.loads(path.read_text())
    raw["version"] = 1
    del raw["scene"]
    for d in raw["demos"]:
        d.pop("objects", None)
    path.write_text(json.dumps(raw))
    before = path.read_bytes()
    old = load_session(session.path)
    assert old.objects.scene == Scene()  # an empty table
    assert old.objects.scene.table is not None and not old.objects.scene.objects
    assert all(old.objects.events(f) == () for f in old.demo_files)
    assert path.read_bytes() == before  # loading never writes
    old.rename_demo(0, "renamed")
    assert json.loads(path.read_text())["version"] == FORMAT_VERSION


def test_a_version_2_session_keeps_its_skills_in_the_robots_frame(store: SessionStore, session) -> None:
    """Skills learned before format 3 are paths in the robot's frame: a session with them keeps learning that
    way; one without skills takes the default (skills that follow the objects)."""
    assert UPGRADES[2]({"version": 2, "skills": {"left": {"file": "skills/left.npz"}}})["frames"] == "robot"
    assert UPGRADES[2]({"version": 2, "skills": {}})["frames"] == "objects"
    path = session.path / "session.json"
    raw = json.loads(path.read_text())
    raw["version"] = 2
    raw.pop("frames", None)
    path.write_text(json.dumps(raw))
    old = load_session(session.path)
    assert old.frames == "objects"
    old.set_params(mode="robot")
    again = json.loads(path.read_text())
    assert again["version"] == FORMAT_VERSION and again["frames"] == "robot"
    assert load_session(session.path).frames == "robot"


def test_a_damaged_scene_or_event_list_is_named(store: SessionStore, session) -> None:
    path = session.path / "session.json"
    good = json.loads(path.read_text())
    cases = [
        (lambda r: r.__setitem__("scene", "a table"), "invalid task scene"),
        (lambda r: r["scene"]["objects"][0].__setitem__("kind", "piano"), "damaged task scene"),
        (lambda r: r["scene"]["objects"][0].__setitem__("position", [0, 0, float("nan")]), "damaged task scene"),
        (lambda r: r["demos"][0]["objects"]["events"][1].__setitem__("kind", "explode"), "damaged object events"),
        (lambda r: r["demos"][0].__setitem__("objects", [1, 2]), "invalid object events"),
        (
            lambda r: r["demos"][0]["objects"].__setitem__("events", r["demos"][0]["objects"]["events"] * MAX_EVENTS),
            "absurd number of object events",
        ),
    ]
    for damage, words in cases:
        raw = json.loads(json.dumps(good))
        damage(raw)
        path.write_text(json.dumps(raw))
        with pytest.raises(SessionFormatError, match=words) as err:
            store.open(session.name)
        assert 'The session file "session.json" of session "with objects"' in str(err.value)


def test_a_scene_holds_a_bounded_number_of_objects() -> None:
    scene = Scene()
    for i in range(MAX_OBJECTS):
        scene = scene.add("block", (0.5, -0.7 + 0.035 * i, -0.07))
    with pytest.raises(InvalidInput, match=f"at most {MAX_OBJECTS} objects"):
        scene.add("cup", (0.6, 0.0, -0.07))


def test_a_hostile_archive_with_an_absurd_scene_adds_nothing(store: SessionStore, session) -> None:
    data = store.export_zip(session.name)
    buf = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(data)) as zin, zipfile.ZipFile(buf, "w") as zout:
        for info in zin.infolist():
            body = zin.read(info)
            if info.filename.endswith("session.json"):
                raw = json.loads(body)
                raw["scene"]["objects"] = raw["scene"]["objects"] * (MAX_OBJECTS + 1)
                body = json.dumps(raw).encode()
            zout.writestr(info.filename, body)
    before = sorted(store.list_sessions())
    with pytest.raises(SessionFormatError):
        store.import_zip(buf.getvalue(), "hostile")
    assert sorted(store.list_sessions()) == before
