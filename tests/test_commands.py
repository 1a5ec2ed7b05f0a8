"""Headless commands: import-csv, export-csv, learn, make-examples, and the committed example sessions."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from studio import commands
from studio.cli import main
from studio.commands import EXAMPLES, build_example
from studio.core.types import ARMS, Arm, Demo, KeypointParams, Recording
from studio.csv_io import export_recording_csv
from studio.storage import DEFAULT_ROOT, SessionStore
from tests.conftest import RecordingNotifier


def _csv(path: Path, n: int = 800, seed: int = 0) -> Path:
    rng = np.random.default_rng(seed)
    q = np.tile([0.08, -1.0, -1.19, 1.94, 0.67, 1.03, -0.5] * 2, (n, 1)) + np.cumsum(
        rng.normal(0, 1e-3, (n, 14)), axis=0
    )
    export_recording_csv(Recording(np.arange(n) / 100.0, q, np.full((n, 2), 100.0)), path)
    return path


def test_import_csv_creates_the_session_and_keeps_good_files(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    a = _csv(tmp_path / "take_a.csv")
    b = _csv(tmp_path / "take_b.csv", seed=1)
    bad = tmp_path / "bad.csv"
    bad.write_text("not,a,recording\n")
    sessions = tmp_path / "sessions"
    code = main(["import-csv", str(a), str(bad), str(b), "--session", "real baxter", "--sessions-dir", str(sessions)])
    out = capsys.readouterr().out
    assert code == 1  # one file failed ...
    assert "bad.csv" in out and "not imported" in out
    s = SessionStore(sessions).open("real baxter")
    assert s.demo_names == ["take_a", "take_b"]  # ... the good ones are in
    assert len(s.recordings[0]) == 800
    assert main(["import-csv", str(a), "--session", "real baxter", "--sessions-dir", str(sessions)]) == 0
    assert SessionStore(sessions).open("real baxter").demo_names == ["take_a", "take_b", "take_a (2)"]


def test_import_csv_names_a_file_the_session_refuses_and_keeps_going(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    a = _csv(tmp_path / "take_a.csv")
    long = _csv(tmp_path / ("x" * 120 + ".csv"))
    tab = _csv(tmp_path / "bad\tname.csv")  # reads fine, but a tab cannot be in a demo name
    b = _csv(tmp_path / "take_b.csv", seed=1)
    sessions = tmp_path / "sessions"
    code = main(["import-csv", str(a), str(long), str(tab), str(b), "--session", "s", "--sessions-dir", str(sessions)])
    out = capsys.readouterr().out
    assert code == 1
    assert f"{tab}: A demonstration name must be 1 to 100 printable characters." in out
    assert SessionStore(sessions).open("s").demo_names == ["take_a", "x" * 100, "take_b"]


def test_export_csv_without_a_skill_says_what_to_do(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    sessions = tmp_path / "sessions"
    main(["import-csv", str(_csv(tmp_path / "x.csv")), "--session", "s", "--sessions-dir", str(sessions)])
    code = main(["export-csv", "s", "--out", str(tmp_path / "out.csv"), "--sessions-dir", str(sessions)])
    assert code == 2
    assert "Learn it first: studio learn" in capsys.readouterr().err
    assert not (tmp_path / "out.csv").exists()


def test_unknown_session_is_a_plain_error(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["learn", "nothing here", "--sessions-dir", str(tmp_path)]) == 2
    assert 'no session called "nothing here"' in capsys.readouterr().err


def test_committed_example_sessions_load_and_look_like_the_paper() -> None:
    store = SessionStore(DEFAULT_ROOT)
    for task in EXAMPLES:
        s = store.open(task, recover=False)
        assert len(s.recordings) == 3
        for r in s.recordings:
            assert 20.0 <= r.duration <= 30.0
            assert np.allclose(np.diff(r.t), 1e-3)  # 1 kHz, no gaps
            assert r.arms == ("left",)
            assert np.ptp(r.arm_q("left"), axis=0).max() > 0.3  # the taught arm moves
            assert np.ptp(r.arm_gripper("left")) > 40  # and grasps
        # ... the task's objects, moved by every demonstration as the task says
        obj = {"stack-cup": "cup", "pick-place": "block"}[task]
        assert s.objects.scene.preset == task
        for f in s.demo_files:
            moves = [(e.kind, e.object) for e in s.objects.events(f) if e.kind in ("grasp", "release", "miss")]
            assert moves == [("grasp", obj), ("release", obj)] * (1 if task == "stack-cup" else 2)


def test_make_examples_is_reproducible(tmp_path: Path) -> None:
    # Rebuilding "stack-cup" from the scripted teacher through simulator + recorder gives the committed files.
    store = SessionStore(tmp_path)
    with open(tmp_path / "log.txt", "w") as log:
        s = build_example(store, "stack-cup", learn_skill=False, out=log)
    committed = SessionStore(DEFAULT_ROOT).open("stack-cup", recover=False)
    assert s.demo_files == committed.demo_files
    assert s.objects.scene == committed.objects.scene
    assert [s.objects.events(f) for f in s.demo_files] == [committed.objects.events(f) for f in s.demo_files]
    for f in s.demo_files:
        assert (s.path / f).read_bytes() == (committed.path / f).read_bytes(), (
            "the committed example differs from what the teacher makes now: run `studio make-examples`"
        )
    assert not list(tmp_path.glob(".tmp-*"))  # no temporary folders left


def test_learn_saves_the_skill_and_prints_a_report(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    pytest.importorskip("studio.core.pipeline")
    store = SessionStore(tmp_path)
    src = SessionStore(DEFAULT_ROOT).open("stack-cup", recover=False)
    s = store.create("learn me", precision="float32")
    for r in src.recordings:
        s.add_recording(r)
    assert main(["learn", "learn me", "--sessions-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "k = " in out and "reference" in out and "key-points" in out and "log-likelihood" in out
    assert "How good is the left arm's skill?" in out
    assert "Good: the skill follows your demonstrations closely (within " in out
    loaded = store.open("learn me")
    assert set(loaded.skills) == {"left"} and not loaded.skills_stale
    csv = tmp_path / "skill.csv"
    assert main(["export-csv", "learn me", "--out", str(csv), "--sessions-dir", str(tmp_path)]) == 0
    assert csv.read_text().startswith("time,left_s0,")


def test_learn_needs_two_demos(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    sessions = tmp_path / "sessions"
    main(["import-csv", str(_csv(tmp_path / "x.csv")), "--session", "one", "--sessions-dir", str(sessions)])
    capsys.readouterr()
    assert main(["learn", "one", "--sessions-dir", str(sessions)]) == 2
    assert "at least two" in capsys.readouterr().err


def test_learn_uses_the_sessions_k_and_remembers_each_arms_demos(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    learn = pytest.importorskip("studio.core.learn")
    calls: list[dict] = []

    class FakeSkill:  # what `studio learn` saves and reports, without learning
        def __init__(self, names: tuple[str, ...]) -> None:
            self.demo_names = names
            self.keypoints: list[np.ndarray] = []
            self.loglik = np.zeros(0)
            self.reference = 0
            self.n_clusters = 0
            self.params = KeypointParams()
            self.trajectory = Demo(np.arange(2.0), np.zeros((2, 3)), np.tile([1.0, 0, 0, 0], (2, 1)), np.full(2, 100.0))
            self.joint_trajectory = None
            self.frames = None

        def to_arrays(self) -> dict[str, np.ndarray]:
            return {"x": np.zeros(1)}

    def fake_learn_skill(demos, settings, *, arm="left", **kwargs):
        calls.append({"arm": arm, "n_clusters": settings.n_clusters})
        return FakeSkill(tuple(d.name for d in demos))

    monkeypatch.setattr(learn, "learn_skill", fake_learn_skill)
    verdict = SimpleNamespace(level="fake")
    judged = SimpleNamespace(verdict=verdict, fits=(), segments=(), choices=())
    monkeypatch.setattr(learn, "judge", lambda skill, demos, *a, **kw: judged)
    monkeypatch.setattr(commands, "verdict_words", lambda v, remedies: ("fits",) if v is verdict else ())
    store = SessionStore(tmp_path)
    s = store.create("both arms", arms=("left", "right"))
    n = 300
    q = np.tile([0.08, -1.0, -1.19, 1.94, 0.67, 1.03, -0.5] * 2, (n, 1))
    taught: list[tuple[str, tuple[Arm, ...]]] = [("l1", ("left",)), ("r1", ("right",)), ("l2", ("left",)), ("b", ARMS)]
    for name, arms in taught:
        s.add_recording(Recording(np.arange(n) / 100.0, q, np.full((n, 2), 100.0), arms=arms, name=name))
    s.set_n_clusters(4)
    assert main(["learn", "both arms", "--sessions-dir", str(tmp_path)]) == 0
    assert calls == [{"arm": "left", "n_clusters": 4}, {"arm": "right", "n_clusters": 4}]
    info = json.loads((s.path / "session.json").read_text())["skills"]  # the fake skill files do not load back
    assert info["left"]["demos"] == ["l1", "l2", "b"] and info["right"]["demos"] == ["r1", "b"]
    assert "How good is the right arm's skill?\n  fits" in capsys.readouterr().out


def test_learn_auto_suggests_thresholds_first_and_keeps_them(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:

    store = SessionStore(tmp_path)
    src = SessionStore(DEFAULT_ROOT).open("stack-cup", recover=False)
    s = store.create("auto", precision="float32")
    for r in src.recordings[:3]:
        s.add_recording(r)
    s.set_params(KeypointParams(eps5=0.4, eps7=0.4))  # a teacher's far too coarse travel distance
    assert main(["learn", "auto", "--auto", "--sessions-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "Left arm — suggested thresholds (Detail " in out and "misses it by" in out
    assert "How good is the left arm's skill?" in out
    loaded = store.open("auto")
    assert loaded.params.eps5 < 0.2  # the suggestion was applied and saved
    assert loaded.skills["left"].params == loaded.params


@pytest.mark.parametrize(
    ("task", "hidden"), [("stack-cup", ()), ("pick-place", ()), ("stack-cup", ("demo 2",))], ids=str
)
def test_studio_learn_and_the_train_button_learn_the_same_skill(
    tmp_path: Path, capsys: pytest.CaptureFixture, task: str, hidden: tuple[str, ...]
) -> None:
    pytest.importorskip("studio.core.pipeline")
    from studio.controller import Controller
    from studio.robot_backend.simulated import SimulatedBaxter

    stores = {}
    for side in ("cli", "studio"):
        shutil.copytree(DEFAULT_ROOT / task, tmp_path / side / task)
        stores[side] = SessionStore(tmp_path / side)
        s = stores[side].open(task)
        for name in hidden:  # hidden in the studio: left out of learning by both
            s.set_demo_hidden(s.demo_names.index(name), True)
    assert main(["learn", task, "--sessions-dir", str(tmp_path / "cli")]) == 0
    assert "How good is the left arm's skill?" in capsys.readouterr().out
    ctl = Controller(store=stores["studio"], session=task, backend=SimulatedBaxter(), notifier=RecordingNotifier())
    try:
        ctl.training.train().result(timeout=120)
    finally:
        ctl.close()
        ctl.shutdown()
    by_cli, by_studio = (stores[side].open(task, recover=False) for side in ("cli", "studio"))
    assert set(by_cli.skills) == set(by_studio.skills) == {"left"}
    a, b = by_cli.skills["left"], by_studio.skills["left"]
    names = [n for n in by_cli.demo_names if n not in hidden]
    assert list(a.demo_names) == list(b.demo_names) == names
    assert a.n_clusters == b.n_clusters and a.params == b.params and by_cli.params == by_studio.params
    assert len(a.trajectory) == len(b.trajectory) > 100
    for field in ("t", "position", "orientation", "gripper"):
        np.testing.assert_allclose(getattr(a.trajectory, field), getattr(b.trajectory, field), rtol=0, atol=1e-9)
    assert a.joint_trajectory is not None and b.joint_trajectory is not None
    np.testing.assert_allclose(a.joint_trajectory.q, b.joint_trajectory.q, rtol=0, atol=1e-9)
