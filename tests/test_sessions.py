"""Session store: round trips, atomic writes, edits that leave other files alone, every bad-file case."""

from __future__ import annotations

import hashlib
import io
import json
import os
import pickle
import zipfile
import zlib
from pathlib import Path
from typing import cast

import numpy as np
import pytest

from studio.core.errors import InvalidInput, SessionFormatError, StorageError
from studio.core.types import KeypointParams, Recording, Skill
from studio.storage import (
    FORMAT_VERSION,
    SessionStore,
    atomic_write_bytes,
    check_session_name,
    idle_bounds,
    load_session,
)


def make_rec(n: int = 1500, seed: int = 0, name: str = "demo", idle: tuple[int, int] = (0, 0)) -> Recording:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 1000.0
    s = np.clip((np.arange(n) - idle[0]) / max(n - idle[0] - idle[1], 1), 0, 1)
    q = np.tile([0.08, -1.0, -1.19, 1.94, 0.67, 1.03, -0.5] * 2, (n, 1)).astype(float)
    q[:, :7] += 0.4 * s[:, None] * rng.uniform(0.5, 1, 7)
    q += rng.normal(0, 1e-4, q.shape)
    g = np.full((n, 2), 100.0)
    g[n // 2 :, 0] = 40.0
    return Recording(t=t, q=q, gripper=g, arms=("left",), name=name)


def snapshot(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() + str(p.stat().st_mtime_ns)
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


@pytest.fixture
def store(tmp_path: Path) -> SessionStore:
    return SessionStore(tmp_path / "sessions")


@pytest.fixture
def three(store: SessionStore):
    s = store.create("three demos", notes="for tests")
    for i in range(3):
        s.add_recording(make_rec(seed=i, name=f"demo {i + 1}"))
    return s


# -- round trips -------------------------------------------------------------------------------------------
def test_save_load_round_trip_is_identical(store: SessionStore, three) -> None:
    params = KeypointParams(eps2=0.02, eps5=0.1)
    three.set_params(params)
    loaded = store.open("three demos")
    assert loaded.demo_names == ["demo 1", "demo 2", "demo 3"]
    assert loaded.params == params and loaded.notes == "for tests" and loaded.arms == ("left",)
    for a, b in zip(three.recordings, loaded.recordings, strict=True):
        assert np.array_equal(a.t, b.t) and np.array_equal(a.q, b.q) and np.array_equal(a.gripper, b.gripper)
        assert a.arms == b.arms
    m = json.loads((three.path / "session.json").read_text())
    assert m["version"] == FORMAT_VERSION and m["robot"] == "baxter"
    assert [d["samples"] for d in m["demos"]] == [1500] * 3
    assert m["params"]["eps2"] == 0.02


def test_float32_precision_is_close_and_smaller(store: SessionStore) -> None:
    s64 = store.create("f64")
    s32 = store.create("f32", precision="float32")
    rec = make_rec(20000)
    s64.add_recording(rec)
    s32.add_recording(rec)
    loaded = store.open("f32").recordings[0]
    assert np.array_equal(loaded.t, rec.t)
    assert np.abs(loaded.q - rec.q).max() < 1e-6
    assert np.array_equal(loaded.q, s32.recordings[0].q)  # what the session holds is what loads back
    size = lambda s: sum(p.stat().st_size for p in (s.path / "demos").iterdir())  # noqa: E731
    assert size(s32) < 0.7 * size(s64)


def test_store_save_and_list(store: SessionStore, three) -> None:
    assert store.list_sessions() == ["three demos"]
    (three.path / three.demo_files[1]).unlink()
    with pytest.raises(SessionFormatError, match="is missing"):
        store.open("three demos")
    store.save(three)  # rewrites the missing file
    assert len(store.open("three demos")) == 3
    [summary] = store.summaries()
    assert summary.demos == 3 and summary.notes == "for tests"


# -- editing ------------------------------------------------------------------------------------------------
def test_rename_delete_trim_touch_only_their_demo(store: SessionStore, three) -> None:
    others = {f: (three.path / f).read_bytes() for f in three.demo_files}
    three.rename_demo(0, "first")
    three.trim_demo(1, 0.2, 1.0)
    three.delete_demo(2)
    loaded = store.open("three demos")
    assert loaded.demo_names == ["first", "demo 2"]
    assert (three.path / three.demo_files[0]).read_bytes() == others[three.demo_files[0]]
    r = loaded.recordings[1]
    assert len(r) == 801 and r.t[0] == 0.0 and r.duration == pytest.approx(0.8)
    files = sorted(p.name for p in (three.path / "demos").iterdir())
    assert len(files) == 2  # the replaced and the deleted files are gone, nothing else left behind
    with pytest.raises(InvalidInput, match="already called"):
        three.rename_demo(1, "first")
    with pytest.raises(InvalidInput, match="no demonstration number 5"):
        three.delete_demo(5)
    with pytest.raises(InvalidInput, match="fewer than two"):
        three.trim_demo(0, 0.1, 0.1001)


def test_trim_idle_cuts_still_start_and_end(store: SessionStore) -> None:
    s = store.create("idle")
    s.add_recording(make_rec(5000, idle=(1500, 1000)))
    t0, t1 = idle_bounds(s.recordings[0], margin=0.1)
    assert t0 == pytest.approx(1.45, abs=0.1) and t1 == pytest.approx(4.1, abs=0.1)
    s.trim_idle(0, margin=0.1)
    assert store.open("idle").recordings[0].duration == pytest.approx(t1 - t0, abs=2e-3)


def test_duplicate_names_get_a_suffix(store: SessionStore) -> None:
    s = store.create("dup")
    assert s.add_recording(make_rec(name="take")) == 0
    s.add_recording(make_rec(name="take"))
    assert s.demo_names == ["take", "take (2)"]


def test_duplicate_long_names_stay_within_the_limit_and_reload(store: SessionStore) -> None:
    s = store.create("long")
    for _ in range(3):
        s.add_recording(make_rec(50, name="x" * 99))
    assert [len(n) for n in s.demo_names] == [99, 100, 100]
    assert s.demo_names[1] == "x" * 96 + " (2)" and s.demo_names[2] == "x" * 96 + " (3)"
    assert store.open("long").demo_names == s.demo_names


def test_duplicate_and_zip_round_trip(store: SessionStore, three) -> None:
    copy = store.duplicate("three demos", "copy")
    assert copy.demo_names == three.demo_names
    data = store.export_zip("three demos")
    name = store.import_zip(data)
    assert name == "three demos (2)"
    imported = store.open(name)
    assert np.array_equal(imported.recordings[2].q, three.recordings[2].q)


def test_atomic_write_keeps_old_file_when_interrupted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    f = tmp_path / "x.json"
    atomic_write_bytes(f, b"old")

    def boom(*_a, **_k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(StorageError, match=r'"x.json" could not be saved: there is no space left on the disk'):
        atomic_write_bytes(f, b"new")
    assert f.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["x.json"]  # no temporary file left


def test_skills_round_trip_through_to_arrays(store: SessionStore, three, monkeypatch) -> None:
    import studio.storage.npz as npz

    class FakeSkill:
        def __init__(self, a: np.ndarray) -> None:
            self.a = a

        def to_arrays(self) -> dict[str, np.ndarray]:
            return {"a": self.a, "arm": np.array("left")}

        @classmethod
        def from_arrays(cls, d):
            assert d["arm"].shape == () and str(d["arm"]) == "left"  # 0-d arrays stay 0-d
            if d["a"].ndim != 1:
                raise ValueError("bad a")
            return cls(d["a"])

    monkeypatch.setattr(npz, "Skill", FakeSkill)  # what loading builds from the arrays
    three.set_skills({"left": cast(Skill, FakeSkill(np.arange(5.0)))})
    loaded = store.open("three demos")
    assert np.array_equal(cast(FakeSkill, loaded.skills["left"]).a, np.arange(5.0))
    assert not loaded.skills_stale
    loaded.delete_demo(0)
    assert store.open("three demos").skills_stale  # learned from other demos than the session now holds
    np.savez(three.path / "skills" / "left.npz", a=np.zeros((2, 2)))
    with pytest.raises(SessionFormatError, match=r'"skills/left.npz".*not a valid learned skill'):
        store.open("three demos")


def test_number_of_clusters_is_kept_with_the_session(store: SessionStore, three) -> None:
    assert three.n_clusters is None and store.open("three demos").n_clusters is None  # automatic by default
    three.set_n_clusters(7)
    assert json.loads((three.path / "session.json").read_text())["n_clusters"] == 7
    assert store.open("three demos").n_clusters == 7
    dup = store.duplicate("three demos", "copy")
    assert dup.n_clusters == 7
    assert store.open(store.import_zip(store.export_zip("three demos"))).n_clusters == 7
    three.set_n_clusters(None)
    assert store.open("three demos").n_clusters is None
    for bad in (0, -3, 2.5, "7", True, 10**9):
        with pytest.raises(InvalidInput, match="number of clusters"):
            three.set_n_clusters(bad)
    assert store.open("three demos").n_clusters is None  # a refused value changes nothing


def test_manifests_without_n_clusters_still_load(store: SessionStore, three) -> None:
    m = json.loads((three.path / "session.json").read_text())
    del m["n_clusters"]
    (three.path / "session.json").write_text(json.dumps(m))
    loaded = store.open("three demos")
    assert loaded.n_clusters is None and loaded.demo_names == ["demo 1", "demo 2", "demo 3"]


def test_threshold_settings_and_mode_are_kept_with_the_session(store: SessionStore, three) -> None:
    from studio.core.thresholds import ThresholdSettings

    assert three.thresholds == ThresholdSettings() and three.generalization == "aligned-mean"  # automatic, default
    settings = ThresholdSettings(detail=1.5, teacher={"eps5": 0.03})
    three.set_params(KeypointParams(eps5=0.03, eps7=0.08), settings)
    three.set_params(mode="paper")
    m = json.loads((three.path / "session.json").read_text())
    assert m["thresholds"] == {"detail": 1.5, "teacher": {"eps5": 0.03}} and m["generalization"] == "paper"
    assert m["params"]["eps7"] == 0.08  # the values they resolved to, what an older studio reads
    loaded = store.open("three demos")
    assert loaded.thresholds == settings and loaded.generalization == "paper" and loaded.params.eps7 == 0.08
    assert store.duplicate("three demos", "copy").thresholds == settings
    assert store.open(store.import_zip(store.export_zip("three demos"))).generalization == "paper"
    with pytest.raises(InvalidInput, match="aligned-mean"):
        three.set_params(mode="spline")
    assert store.open("three demos").generalization == "paper"  # a refused value changes nothing


def test_sessions_saved_before_threshold_settings_still_load(store: SessionStore, three) -> None:
    from studio.core.thresholds import ThresholdSettings

    three.set_params(KeypointParams(eps5=0.05))
    m = json.loads((three.path / "session.json").read_text())
    del m["thresholds"], m["generalization"]
    (three.path / "session.json").write_text(json.dumps(m))
    loaded = store.open("three demos")
    # a value off the old fixed defaults was the teacher's; the others follow the demonstrations now
    assert loaded.thresholds == ThresholdSettings(0.0, {"eps5": 0.05}) and loaded.generalization == "aligned-mean"
    for key, value, pattern in (
        ("thresholds", {"detail": "lots"}, "thresholds"),
        ("thresholds", {"teacher": {"eps99": 1.0}}, "thresholds"),
        ("thresholds", [1, 2], "thresholds"),
        ("generalization", "spline", "generalization"),
    ):
        bad = dict(m, **{key: value})
        (three.path / "session.json").write_text(json.dumps(bad))
        _expect_error(store, "three demos", pattern)


def test_skills_remember_the_demos_of_each_arm(store: SessionStore, three, monkeypatch) -> None:
    import studio.storage.npz as npz

    class FakeSkill:
        def to_arrays(self) -> dict[str, np.ndarray]:
            return {"a": np.arange(3.0)}

        @classmethod
        def from_arrays(cls, d):
            return cls()

    monkeypatch.setattr(npz, "Skill", FakeSkill)
    fake = cast(Skill, FakeSkill())
    three.set_skills({"left": fake, "right": fake}, demos={"left": ["demo 2", "demo 3"]})
    info = store.open("three demos").skill_info
    assert info["left"].demos == ("demo 2", "demo 3")
    assert info["right"].demos == ("demo 1", "demo 2", "demo 3")  # not given: all of the session's
    m = json.loads((three.path / "session.json").read_text())
    assert m["skills"]["left"]["demos"] == ["demo 2", "demo 3"]  # a list of names in the manifest
    three.set_skills({"left": fake}, demos=["demo 1"])
    assert store.open("three demos").skill_info["left"].demos == ("demo 1",)


# -- bad files: every case names the file and the problem, and touches nothing -----------------------------
def test_hidden_demos_are_kept_with_the_session(store: SessionStore, three) -> None:
    three.set_demo_hidden(1, True)
    assert store.open("three demos").hidden_demos == {"demo 2"}
    three.rename_demo(1, "wobbly")  # still hidden under its new name
    assert store.open("three demos").hidden_demos == {"wobbly"}
    assert store.duplicate("three demos", "copy").hidden_demos == {"wobbly"}
    assert store.open(store.import_zip(store.export_zip("three demos"))).hidden_demos == {"wobbly"}
    three.set_demo_hidden(1, False)
    assert store.open("three demos").hidden_demos == set()
    three.set_demo_hidden(0, True)
    three.delete_demo(0)
    assert store.open("three demos").hidden_demos == set()
    m = json.loads((three.path / "session.json").read_text())
    assert all("hidden" in d for d in m["demos"])
    for d in m["demos"]:
        del d["hidden"]  # manifests written before the mark existed still load
    (three.path / "session.json").write_text(json.dumps(m))
    assert store.open("three demos").hidden_demos == set()
    m["demos"][0]["hidden"] = "yes"
    (three.path / "session.json").write_text(json.dumps(m))
    _expect_error(store, "three demos", 'invalid "hidden" mark for demonstration 1')


def _expect_error(store: SessionStore, name: str, pattern: str) -> SessionFormatError:
    before = snapshot(store.root)
    with pytest.raises(SessionFormatError, match=pattern) as ei:
        store.open(name)
    assert snapshot(store.root) == before
    msg = str(ei.value)
    assert "It was not loaded; your other files are untouched." in msg or "no session" in msg
    return ei.value


def _demo(three) -> Path:
    return three.path / three.demo_files[1]


def test_missing_demo(store: SessionStore, three) -> None:
    _demo(three).unlink()
    e = _expect_error(store, "three demos", r'"demos/d0002.npz".*is missing')
    assert e.file == "demos/d0002.npz"


def test_truncated_demo(store: SessionStore, three) -> None:
    p = _demo(three)
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
    _expect_error(store, "three demos", r'"demos/d0002.npz".*ends early')


def test_truncated_array_inside_an_intact_zip(store: SessionStore, three) -> None:
    p = _demo(three)
    with np.load(p) as z:
        d = dict(z)
    buf = io.BytesIO()
    np.save(buf, d["q"])
    raw = buf.getvalue()
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("t.npy", _npy(d["t"]))
        zf.writestr("q.npy", raw[: len(raw) // 2])
        zf.writestr("gripper.npy", _npy(d["gripper"]))
    _expect_error(store, "three demos", r'"demos/d0002.npz".*ends early')


def _npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


def test_wrong_version(store: SessionStore, three) -> None:
    m = json.loads((three.path / "session.json").read_text())
    m["version"] = FORMAT_VERSION + 1
    (three.path / "session.json").write_text(json.dumps(m))
    _expect_error(store, "three demos", r'"session.json".*newer Teaching Studio')


def test_truncated_manifest(store: SessionStore, three) -> None:
    p = three.path / "session.json"
    p.write_bytes(p.read_bytes()[:100])
    _expect_error(store, "three demos", r'"session.json".*ends early')


def test_missing_manifest(store: SessionStore, three) -> None:
    (three.path / "session.json").unlink()
    _expect_error(store, "three demos", r'"session.json".*is missing')


def test_wrong_shape(store: SessionStore, three) -> None:
    p = _demo(three)
    with np.load(p) as z:
        d = dict(z)
    np.savez(p, t=d["t"], q=d["q"][:, :7], gripper=d["gripper"])
    _expect_error(store, "three demos", r'"demos/d0002.npz".*q of the wrong shape \(1500, 7\), expected \(1500, 14\)')


def test_wrong_length_against_manifest(store: SessionStore, three) -> None:
    p = _demo(three)
    with np.load(p) as z:
        d = dict(z)
    np.savez(p, **{k: v[:1000] for k, v in d.items()})
    _expect_error(store, "three demos", r'"demos/d0002.npz".*wrong shape')


def test_nan_filled(store: SessionStore, three) -> None:
    p = _demo(three)
    with np.load(p) as z:
        d = dict(z)
    d["q"][100:200, 3] = np.nan
    np.savez(p, **d)
    _expect_error(store, "three demos", r'"demos/d0002.npz".*100 invalid values \(NaN')


def test_pickled_object_array(store: SessionStore, three) -> None:
    p = _demo(three)
    with np.load(p) as z:
        d = dict(z)
    obj = np.empty(1500, dtype=object)
    np.savez(p, t=d["t"], q=obj, gripper=d["gripper"])
    _expect_error(store, "three demos", r'"demos/d0002.npz".*pickle')


def test_raw_pickle_file(store: SessionStore, three) -> None:
    _demo(three).write_bytes(pickle.dumps({"t": [1, 2, 3]}))
    _expect_error(store, "three demos", r'"demos/d0002.npz".*pickle')


def test_absurd_size_declared_in_header(store: SessionStore, three) -> None:
    p = _demo(three)
    header = {"descr": "<f8", "fortran_order": False, "shape": (10**12, 14)}
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, header)
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("t.npy", _npy(np.arange(1500) / 1000.0))
        zf.writestr("q.npy", buf.getvalue() + b"\0" * 64)
        zf.writestr("gripper.npy", _npy(np.zeros((1500, 2))))
    _expect_error(store, "three demos", r'"demos/d0002.npz".*(absurd size|wrong shape)')


def test_zip_bomb_declared_size(store: SessionStore, three) -> None:
    p = _demo(three)
    with zipfile.ZipFile(p, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("t.npy", _npy(np.arange(1500) / 1000.0) + b"\0" * 50_000_000)
        zf.writestr("q.npy", _npy(np.zeros((1500, 14))))
        zf.writestr("gripper.npy", _npy(np.zeros((1500, 2))))
    _expect_error(store, "three demos", r'"demos/d0002.npz".*absurd size')


def test_manifest_names_a_file_outside_the_session(store: SessionStore, three) -> None:
    for bad in ("../other/demos/d0001.npz", "/etc/passwd", "demos/../../x.npz", "demos/sub/d0001.npz"):
        m = json.loads((three.path / "session.json").read_text())
        m["demos"][0]["file"] = bad
        (three.path / "session.json").write_text(json.dumps(m))
        _expect_error(store, "three demos", r'"session.json".*unsafe or invalid file')


def test_session_names_with_dots_or_slashes_are_refused(store: SessionStore, three) -> None:
    for bad in ("../three demos", "a/b", "..", ".hidden", "x\0y", ""):
        with pytest.raises(InvalidInput, match="cannot be a session name"):
            store.open(bad)
    with pytest.raises(InvalidInput):
        check_session_name("a" * 65)
    with pytest.raises(SessionFormatError, match="no session"):
        store.open("not there")


def test_hostile_zip_import_is_refused_and_adds_nothing(store: SessionStore, three) -> None:
    before = snapshot(store.root)
    for member in ("evil/../../escape.txt", "/abs/session.json", "evil/demos/x.sh"):
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w") as zf:
            zf.writestr("evil/session.json", "{}")
            zf.writestr(member, "x")
        with pytest.raises(SessionFormatError, match="Nothing was imported"):
            store.import_zip(buf.getvalue())
    with pytest.raises(SessionFormatError, match="not a session archive"):
        store.import_zip(b"not a zip")
    # A zip with a damaged session inside is unpacked to a temporary folder, refused, and cleaned up.
    data = store.export_zip("three demos")
    broken = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(data)) as src, zipfile.ZipFile(broken, "w") as dst:
        for i in src.infolist():
            payload = src.read(i)
            dst.writestr(i, payload[:50] if i.filename.endswith("d0002.npz") else payload)
    with pytest.raises(SessionFormatError, match=r"d0002\.npz"):
        store.import_zip(broken.getvalue())
    assert snapshot(store.root) == before


def test_damaged_archive_is_refused_in_plain_words_naming_it(store: SessionStore, three, tmp_path: Path) -> None:
    data = store.export_zip("three demos")
    before = snapshot(store.root)
    # A flipped byte inside a stored member: its CRC no longer matches.
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        info = next(i for i in zf.infolist() if i.filename.endswith("d0002.npz"))
    off = info.header_offset + 30 + len(info.filename) + len(info.extra) + 200
    bad = bytearray(data)
    bad[off] ^= 0xFF
    damaged = r'^The archive "copy\.zip" is damaged .*d0002\.npz.*Nothing was imported'
    with pytest.raises(SessionFormatError, match=damaged):
        store.import_zip(bytes(bad), archive="copy.zip")
    # A corrupt deflate stream in a compressed archive.
    deflated = tmp_path / "deflated.zip"
    with zipfile.ZipFile(io.BytesIO(data)) as src, zipfile.ZipFile(deflated, "w", zipfile.ZIP_DEFLATED) as dst:
        for i in src.infolist():
            dst.writestr(i.filename, src.read(i), compress_type=zipfile.ZIP_DEFLATED)
    _corrupt_deflate_stream(deflated, "three demos/demos/d0002.npz")
    with pytest.raises(SessionFormatError, match=r'archive of session "three demos" is damaged.*Nothing was imported'):
        store.import_zip(deflated.read_bytes())
    # A session that fails validation is named, never the temporary folder.
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(data)) as src, zipfile.ZipFile(out, "w") as dst:
        for i in src.infolist():
            payload = src.read(i)
            if i.filename.endswith("session.json"):
                payload = payload.replace(b'"robot": "baxter"', b'"robot": "pr2"')
            dst.writestr(i, payload)
    with pytest.raises(SessionFormatError) as ei:
        store.import_zip(out.getvalue(), archive="copy.zip")
    msg = str(ei.value)
    assert msg.startswith('The archive "copy.zip" cannot be imported.') and 'session "three demos"' in msg
    assert ".tmp-import" not in msg and msg.endswith("Nothing was imported.")
    assert snapshot(store.root) == before


def test_skip_damaged_loads_the_rest(store: SessionStore, three) -> None:
    _demo(three).write_bytes(b"garbage")
    s = store.open("three demos", skip_damaged=True)
    assert s.demo_names == ["demo 1", "demo 3"]
    assert len(s.problems) == 1 and "d0002.npz" in s.problems[0] and "skipped" in s.problems[0]


def _corrupt_deflate_stream(path: Path, member: str) -> None:
    """Flip one byte of ``member``'s compressed data so that decompressing it raises zlib.error."""
    data = path.read_bytes()
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo(member)
    assert info.compress_type == zipfile.ZIP_DEFLATED
    start = info.header_offset + 30 + len(info.filename) + len(info.extra)
    for k in range(info.compress_size):
        b = bytearray(data)
        b[start + k] ^= 0x5A
        try:
            with zipfile.ZipFile(io.BytesIO(bytes(b))) as zf:
                zf.read(member)
        except zlib.error:
            path.write_bytes(bytes(b))
            return
        except Exception:
            continue
    raise AssertionError("no corruption found that breaks decompression")


def test_corrupt_compressed_data_is_a_damaged_file(store: SessionStore, three) -> None:
    _corrupt_deflate_stream(_demo(three), "q.npy")
    _expect_error(store, "three demos", r'"demos/d0002.npz".*is damaged')
    s = store.open("three demos", skip_damaged=True)
    assert s.demo_names == ["demo 1", "demo 3"] and "d0002.npz" in s.problems[0]


def test_load_never_writes(store: SessionStore, three) -> None:
    before = snapshot(store.root)
    load_session(three.path)
    store.open("three demos")
    assert snapshot(store.root) == before


def test_bad_manifest_fields(store: SessionStore, three) -> None:
    cases = {
        "arms": (["middle"], "arms"),
        "params": ({"eps99": 1}, "key-point thresholds"),
        "robot": ("pr2", "robot"),
        "format": ("something else", "not a Teaching Studio"),
    }
    good = (three.path / "session.json").read_text()
    for key, (value, pattern) in cases.items():
        m = json.loads(good)
        m[key] = value
        (three.path / "session.json").write_text(json.dumps(m))
        _expect_error(store, "three demos", pattern)
    m = json.loads(good)
    m["demos"][0]["samples"] = 10**12
    (three.path / "session.json").write_text(json.dumps(m))
    _expect_error(store, "three demos", "invalid sample count")


def test_add_recording_refuses_bad_input(store: SessionStore) -> None:
    s = store.create("bad")
    with pytest.raises(InvalidInput):
        s.add_recording("not a recording")  # type: ignore[arg-type]  # on purpose
    with pytest.raises(InvalidInput, match="at least two"):
        s.add_recording(make_rec(1))
    with pytest.raises(InvalidInput, match="printable"):
        s.add_recording(make_rec(), name="bad\nname")
    with pytest.raises(InvalidInput, match="already exists"):
        store.create("bad")


@pytest.mark.parametrize("value", [0, -1, 2.5, "12", True, 10**9, [3]])
def test_invalid_n_clusters_in_the_manifest_is_named(store: SessionStore, three, value) -> None:
    m = json.loads((three.path / "session.json").read_text())
    m["n_clusters"] = value
    (three.path / "session.json").write_text(json.dumps(m))
    _expect_error(store, "three demos", '"session.json".*invalid "n_clusters"')


def test_a_change_that_would_make_the_manifest_unopenable_is_refused_and_nothing_is_lost(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import studio.storage.manifest as manifest

    store = SessionStore(tmp_path)
    s = store.create("big")
    monkeypatch.setattr(manifest, "MAX_MANIFEST_BYTES", 2500)  # a few demonstrations' worth
    kept = 0
    with pytest.raises(InvalidInput, match="nothing was changed"):
        for i in range(50):
            s.add_recording(make_rec(seed=i, name=f"d{i}"))
            kept += 1
    assert 0 < kept < 50 and len(s.recordings) == kept  # the refused one is undone in memory too
    assert (s.path / "session.json").stat().st_size <= 2500
    again = store.open("big")  # opens with every demonstration saved before the refusal
    assert [r.name for r in again.recordings] == [f"d{i}" for i in range(kept)]


def test_the_store_remembers_the_session_open_last(tmp_path) -> None:
    store = SessionStore(tmp_path)
    assert store.last_open() is None
    store.create("first")
    store.remember_open("first")
    assert store.last_open() == "first" and SessionStore(tmp_path).last_open() == "first"
    store.delete("first")
    assert store.last_open() is None  # gone since: the studio opens its default
    (tmp_path / ".last-session").write_bytes(b"\xff\xfe")
    assert store.last_open() is None
