"""Hostile and damaged session folders: what a crash, a hand edit, a link or a special file can leave on disk.

Each one opens (skipping what is damaged), or is refused in plain words; none hangs, crashes, reads without
limit, or makes the studio write or delete outside the session folder.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from studio.core.errors import SessionFormatError, StudioError
from studio.storage import Session, SessionStore
from tests.hostile.builders import MiB, assert_plain, big_demo_npz, make_rec, npy, raw_npy, studio_cli


@pytest.fixture
def store(tmp_path: Path) -> SessionStore:
    return SessionStore(tmp_path / "sessions")


@pytest.fixture
def three(store: SessionStore) -> Session:
    s = store.create("three")
    for i in range(3):
        s.add_recording(make_rec(seed=i, name=f"demo {i + 1}"))
    return s


def edit_manifest(s: Session, **changes: object) -> None:
    p = s.path / "session.json"
    m = json.loads(p.read_text())
    m.update(changes)
    p.write_text(json.dumps(m))


# -- what a manifest can hold --------------------------------------------------------------------------------
def test_a_manifest_nested_100k_deep_is_a_damaged_file(store: SessionStore, three: Session) -> None:
    (three.path / "session.json").write_bytes(b"[" * 100_000 + b"]" * 100_000)
    with pytest.raises(SessionFormatError, match=r'"session.json" of session "three" is damaged'):
        store.open("three")
    (three.path / "session.json").write_bytes(b'{"format": "teaching-studio-session", "x": ' + b"{" * 100_000)
    with pytest.raises(SessionFormatError, match=r'"session.json" of session "three" is damaged'):
        store.open("three")


def test_serve_and_learn_say_a_deep_manifest_is_damaged_without_a_traceback(
    store: SessionStore, three: Session
) -> None:
    (three.path / "session.json").write_bytes(b"[" * 100_000 + b"]" * 100_000)
    proc = studio_cli("learn", "three", "--sessions-dir", str(store.root))
    assert_plain(proc)
    assert "is damaged" in proc.stderr
    # The studio itself starts on a stand-in session and says why, in words (issue 21 §3).
    import signal
    import subprocess
    import sys

    from tests.conftest import free_port

    port = str(free_port())
    argv = [sys.executable, "-m", "studio", "serve", "--session", "three", "--port", port, "--meshes", "light"]
    serve = subprocess.Popen(
        [*argv, "--sessions-dir", str(store.root)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert serve.stdout is not None
        lines = []
        for line in serve.stdout:
            lines.append(line)
            if "is running" in line:
                break
        text = "".join(lines)
        assert "is damaged" in text and '"untitled"' in text and "Traceback" not in text, text
        serve.send_signal(signal.SIGTERM)
        assert serve.wait(timeout=30) == 0
    finally:
        if serve.poll() is None:
            serve.kill()
            serve.wait()
        if serve.stdout is not None:
            serve.stdout.close()


def test_a_huge_next_id_never_makes_the_session_unopenable(store: SessionStore, three: Session) -> None:
    edit_manifest(three, next_id=999_999_999)
    s = store.open("three")
    for i in range(3):
        s.add_recording(make_rec(seed=10 + i, name=f"more {i}"))
    again = store.open("three")
    assert len(again.recordings) == 6
    assert all(len(Path(f).stem) <= 10 for f in again.demo_files)
    edit_manifest(three, next_id=10**40)
    assert len(store.open("three").recordings) == 6


def test_two_demos_with_the_same_name_stay_two(store: SessionStore, three: Session) -> None:
    m = json.loads((three.path / "session.json").read_text())
    for d in m["demos"]:
        d["name"] = "same"
    (three.path / "session.json").write_text(json.dumps(m))
    s = store.open("three")
    assert len(set(s.demo_names)) == 3, s.demo_names
    s.set_demo_hidden(0, True)
    assert [r.name in s.hidden_demos for r in s.recordings] == [True, False, False]
    assert [r.name in s.hidden_demos for r in store.open("three").recordings] == [True, False, False]


@pytest.mark.parametrize("name", ["nl\n", "tab\t", "x\r", "ok\n\n"])
def test_a_session_name_with_a_line_break_is_refused(store: SessionStore, name: str) -> None:
    with pytest.raises(StudioError, match="cannot be a session name"):
        store.create(name)
    assert not store.root.exists() or not any(store.root.iterdir())


def test_import_csv_into_a_session_named_with_a_newline_is_refused(store: SessionStore, tmp_path: Path) -> None:
    from studio.csv_io import export_recording_csv

    export_recording_csv(make_rec(), tmp_path / "a.csv")
    proc = studio_cli("import-csv", str(tmp_path / "a.csv"), "--session", "nl\n", "--sessions-dir", str(store.root))
    assert_plain(proc)
    assert "cannot be a session name" in proc.stderr + proc.stdout
    assert not store.root.exists() or not any(store.root.iterdir())


# -- special files -------------------------------------------------------------------------------------------
def test_a_manifest_linked_to_dev_zero_is_not_read_without_limit(store: SessionStore, three: Session) -> None:
    (three.path / "session.json").unlink()
    (three.path / "session.json").symlink_to("/dev/zero")
    proc = studio_cli("learn", "three", "--sessions-dir", str(store.root), memory=768 * MiB, timeout=60)
    assert_plain(proc)
    assert '"session.json" of session "three"' in proc.stderr


@pytest.mark.parametrize("where", ["session.json", "demos/d0002.npz", "skills/left.npz"])
def test_a_fifo_never_hangs_the_studio(store: SessionStore, three: Session, where: str) -> None:
    p = three.path / where
    p.parent.mkdir(exist_ok=True)
    if p.exists():
        p.unlink()
    os.mkfifo(p)
    if where.startswith("skills"):
        m = json.loads((three.path / "session.json").read_text())
        m["skills"] = {"left": {"file": "skills/left.npz"}}
        (three.path / "session.json").write_text(json.dumps(m))
    proc = studio_cli("learn", "three", "--sessions-dir", str(store.root), timeout=60)
    assert_plain(proc)
    assert f'"{where}" of session "three"' in proc.stderr


def test_a_fifo_given_to_import_csv_never_hangs(store: SessionStore, tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "pipe.csv")
    proc = studio_cli("import-csv", str(tmp_path / "pipe.csv"), "--session", "x", "--sessions-dir", str(store.root))
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "pipe.csv" in proc.stdout and "not a regular file" in proc.stdout


# -- links inside a session ------------------------------------------------------------------------------------
def test_a_linked_demos_folder_is_refused_and_nothing_outside_is_touched(
    store: SessionStore, three: Session, tmp_path: Path
) -> None:
    outside = tmp_path / "outside"
    (three.path / "demos").rename(outside)
    (three.path / "demos").symlink_to(outside)
    before = sorted(p.name for p in outside.iterdir())
    with pytest.raises(SessionFormatError, match=r'"demos" of session "three".*link'):
        store.open("three")
    # A link made while the session is open: trim and delete refuse instead of writing/removing outside.
    (three.path / "demos").unlink()
    outside.rename(three.path / "demos")
    s = store.open("three")
    (three.path / "demos").rename(outside)
    (three.path / "demos").symlink_to(outside)
    with pytest.raises(StudioError, match="link"):
        s.trim_demo(0, 0.1, 1.0)
    with pytest.raises(StudioError, match="link"):
        s.delete_demo(1)
    assert sorted(p.name for p in outside.iterdir()) == before


def test_a_linked_skills_or_recording_folder_is_refused(store: SessionStore, three: Session, tmp_path: Path) -> None:
    for sub in ("skills", ".recording"):
        target = tmp_path / f"elsewhere-{sub}"
        target.mkdir()
        (three.path / sub).symlink_to(target)
        with pytest.raises(SessionFormatError, match=rf'"{sub}" of session "three".*link'):
            store.open("three")
        (three.path / sub).unlink()


def test_a_linked_session_folder_is_refused(store: SessionStore, three: Session, tmp_path: Path) -> None:
    (store.root / "alias").symlink_to(three.path)
    with pytest.raises(SessionFormatError, match="link"):
        store.open("alias")


def test_duplicate_copies_only_the_session_never_what_a_link_points_to(
    store: SessionStore, three: Session, tmp_path: Path
) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text("not yours")
    (three.path / "notes.txt").symlink_to(secret)
    (three.path / "extra").mkdir()
    (three.path / "extra" / "x.txt").symlink_to(secret)
    store.duplicate("three", "copy")
    copied = [p for p in (store.root / "copy").rglob("*") if p.is_file()]
    assert all("not yours" not in p.read_text(errors="replace") for p in copied)
    assert not any(p.is_symlink() for p in (store.root / "copy").rglob("*"))
    assert len(store.open("copy").recordings) == 3


# -- leftovers of a kill -9 ------------------------------------------------------------------------------------
def test_leftovers_of_an_interrupted_save_are_cleaned_when_the_session_opens(
    store: SessionStore, three: Session
) -> None:
    for d in ("", "demos", "skills"):
        (three.path / d).mkdir(exist_ok=True)
        (three.path / d / ".tmp-session.json-abc123").write_bytes(b"half")
    (three.path / "demos" / "d0099.npz").write_bytes((three.path / "demos" / "d0001.npz").read_bytes())
    (three.path / "skills" / "right.npz").write_bytes(b"half a skill")
    keep = sorted(str(p.relative_to(three.path)) for p in three.path.rglob("*") if not p.name.startswith(".tmp"))
    keep = [k for k in keep if k not in ("demos/d0099.npz", "skills/right.npz")]
    s = store.open("three")
    assert len(s.recordings) == 3 and not s.problems
    left = sorted(str(p.relative_to(three.path)) for p in three.path.rglob("*"))
    # The unlisted demo file is kept aside, never deleted (issue 21 §3); the half skill file goes.
    assert left == sorted([*keep, "recovered", "recovered/d0099.npz"])
    assert "1 recording was not in the session list" in s.recovery_message


def test_a_save_in_progress_is_never_cleaned_away(store: SessionStore, three: Session) -> None:
    """Another studio writing the same session holds it: its temporary and new files are left alone."""
    import fcntl

    tmp = three.path / "demos" / ".tmp-d0004.npz-xyz"
    tmp.write_bytes(b"being written")
    new = three.path / "demos" / "d0004.npz"
    new.write_bytes(b"written, manifest next")
    fd = os.open(three.path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        store.open("three")
        assert tmp.exists() and new.exists()
    finally:
        os.close(fd)
    store.open("three")
    assert not tmp.exists() and not new.exists()
    assert (three.path / "recovered" / "d0004.npz").read_bytes() == b"written, manifest next"


# -- array files ------------------------------------------------------------------------------------------------
def _demo_with_headers(s: Session, headers: dict[str, bytes]) -> None:
    p = s.path / s.demo_files[1]
    r = s.recordings[1]
    good = {"t": npy(r.t), "q": npy(r.q), "gripper": npy(r.gripper)}
    with zipfile.ZipFile(p, "w") as zf:
        for k in ("t", "q", "gripper"):
            zf.writestr(f"{k}.npy", headers.get(k, good[k]))


HEADER_EXAMPLES = [
    b"((((",
    b"{'descr': '<f8', 'fortran_order': False, 'shape': (((((((",
    b"{'descr': '<f8', 'fortran_order': False, 'shape': (1500,), " + b"'x': [" * 3000,
    b"{'descr': [('a', '<f8')] * 10**9, 'fortran_order': False, 'shape': (1500,), }",
    b"{'descr': '<f16', 'fortran_order': False, 'shape': (1500,), }",
    b"{'descr': '|O', 'fortran_order': False, 'shape': (1500,), }",
    b"{'descr': '<f8', 'fortran_order': False, 'shape': (-1,), }",
    b"{'descr': '<f8', 'fortran_order': False, 'shape': (10**100,), }",
    b"{'descr': '<f8', 'fortran_order': True, 'shape': (1500,), }",
    b"\xff\xfe\x00",
]


@pytest.mark.parametrize("header", HEADER_EXAMPLES, ids=lambda h: repr(h[:24]))
def test_a_hostile_array_header_is_a_damaged_file(store: SessionStore, three: Session, header: bytes) -> None:
    _demo_with_headers(three, {"t": raw_npy(header)})
    with pytest.raises(SessionFormatError, match=r'"demos/d0002.npz" of session "three"'):
        store.open("three")
    assert len(store.open("three", skip_damaged=True).recordings) == 2


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(header=st.binary(max_size=300) | st.text(alphabet="(){}[]'\":,0123456789.-e <>fiuOSUVbcx_ ", max_size=200))
@example(header=b"((((")
def test_fuzzed_array_headers_never_crash_loading(store: SessionStore, three: Session, header: bytes | str) -> None:
    raw = header.encode() if isinstance(header, str) else header
    _demo_with_headers(three, {"q": raw_npy(raw) if len(raw) < 60_000 else raw})
    try:
        s = store.open("three", recover=False)
    except SessionFormatError as exc:
        assert exc.file == "demos/d0002.npz", exc
    else:
        assert len(s.recordings) == 3  # a header that happens to be valid and matching


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(min_size=0, max_size=2000), cut=st.integers(0, 5000), flip=st.integers(0, 10**6))
def test_fuzzed_demo_files_never_crash_loading(
    store: SessionStore, three: Session, data: bytes, cut: int, flip: int
) -> None:
    p = three.path / three.demo_files[1]
    original = getattr(three, "_orig_bytes", None) or p.read_bytes()
    object.__setattr__(three, "_orig_bytes", original)
    mutated = bytearray(original[:cut] + data + original[cut + len(data) :])
    if mutated:
        mutated[flip % len(mutated)] ^= 0x5A
    p.write_bytes(bytes(mutated))
    try:
        store.open("three", recover=False)
    except SessionFormatError as exc:
        assert exc.file == "demos/d0002.npz", exc


# -- memory ----------------------------------------------------------------------------------------------------
def test_a_demo_at_the_sample_limit_is_refused_before_it_is_read(store: SessionStore, three: Session) -> None:
    """21.6 M samples, 2.9 GB of arrays, a 60 MB file: refused from the manifest's size, nothing read."""
    n = 21_600_000
    p = three.path / three.demo_files[1]
    with open(p, "wb") as f:
        big_demo_npz(f, n)
    m = json.loads((three.path / "session.json").read_text())
    m["demos"][1]["samples"] = n
    (three.path / "session.json").write_text(json.dumps(m))
    proc = studio_cli("learn", "three", "--sessions-dir", str(store.root), memory=1536 * MiB, timeout=120)
    assert_plain(proc)
    assert "memory" in proc.stderr or "too long" in proc.stderr


def test_a_session_larger_than_the_free_memory_is_refused_in_plain_words(
    store: SessionStore, three: Session, monkeypatch: pytest.MonkeyPatch
) -> None:
    from studio.storage import limits

    monkeypatch.setattr(limits, "available_memory", lambda: 200_000)
    with pytest.raises(StudioError, match=r"(?i)memory"):
        store.open("three")


def test_a_skill_whose_time_axis_is_stretched_is_refused(store: SessionStore, three: Session, tmp_path: Path) -> None:
    """×10⁶ on the time axis: 6 months of trajectory that export and Preview would sample."""
    from studio.core.learn_settings import LearnSettings
    from tests.core.teacher_demos import skills_of

    skills = skills_of(three.recordings, LearnSettings(params=three.params), arms=("left",))
    three.set_skills(skills)
    p = three.path / "skills" / "left.npz"
    with np.load(p) as z:
        arrays = {k: z[k] for k in z.files}
    for k in ("trajectory_t", "joint_t", "centroid_times", "path_times"):
        if k in arrays:
            arrays[k] = arrays[k] * 1e6
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    p.write_bytes(buf.getvalue())
    proc = studio_cli("export-csv", "three", "--out", str(tmp_path / "x.csv"), "--sessions-dir", str(store.root))
    assert_plain(proc)
    assert '"skills/left.npz"' in proc.stderr and not (tmp_path / "x.csv").exists()
    s = store.open("three", skip_damaged=True)
    assert not s.skills and len(s.recordings) == 3


def test_sampling_refuses_a_skill_that_lasts_for_months() -> None:
    from studio.core import sampling

    class Jt:
        t = np.array([0.0, 1e7])

    class Sk:
        joint_trajectory = Jt()

    with pytest.raises(StudioError, match="hours"):
        sampling.duration({"left": Sk()})  # type: ignore[dict-item]
    with pytest.raises(StudioError):
        sampling.sample_joints({}, np.zeros(50_000_000), np.zeros(14), np.zeros(2))
