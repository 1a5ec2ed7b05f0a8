"""Issue 21 §5: memory stays bounded for what is derived from a demonstration, not only for the bytes read.

Each attack runs in a fresh process limited in memory (:func:`~tests.hostile.builders.run_limited`) or is
measured by the peak of its process; the full-size versions (a 10 M-row CSV, a 3 M-sample demonstration) are
``bench/bench_hostile.py --part memory``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from studio.controller import Controller
from studio.csv_io import CSV_COLUMNS
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore
from tests.conftest import RecordingNotifier
from tests.hostile.builders import MiB, make_rec, run_limited

#: Many key-points: a path that zig-zags at every sample, in three demonstrations.
MANY_KEYPOINTS = """
    import numpy as np
    from studio.core.clustering import cluster
    from studio.core.errors import StudioError
    from studio.core.types import Demo
    rng = np.random.default_rng(0)
    demos, kps = [], []
    for d in range(3):
        n = {n}
        t = np.arange(n) / 100.0
        pos = rng.normal(0, 0.2, (n, 3))
        ori = np.tile([1.0, 0, 0, 0], (n, 1))
        demos.append(Demo(t, pos, ori, rng.uniform(0, 100, n)))
        kps.append(np.arange(n))
    try:
        c = cluster(demos, kps, {k})
        print("clustered", c.n_clusters)
    except StudioError as exc:
        print("refused:", exc)
"""


def test_clustering_too_many_keypoints_is_refused_in_words_not_by_running_out_of_memory() -> None:
    """Today's regression: a noisy 3 M-sample demonstration gave 28,924 key-points and k-means allocated a
    28,924² matrix (6.2 GiB): 'Something unexpected went wrong (MemoryError…)'."""
    proc = run_limited(MANY_KEYPOINTS.format(n=10_000, k=None), memory=1536 * MiB, timeout=120)
    assert proc.returncode == 0, proc.stderr[-1500:]
    assert "refused: The demonstrations have 30,000 key-points together; at most 4,000" in proc.stdout, proc.stdout
    # Within the bounds, k-means works on a bounded sample for its seeding: 3,900 key-points fit in the limit.
    proc = run_limited(MANY_KEYPOINTS.format(n=1_300, k=40), memory=1536 * MiB, timeout=120)
    assert proc.returncode == 0, proc.stderr[-1500:]
    assert "clustered 40" in proc.stdout, proc.stdout
    proc = run_limited(MANY_KEYPOINTS.format(n=1_000, k=1_000), memory=1536 * MiB, timeout=120)
    assert "refused: 1,000 clusters are more than a skill can be learned with" in proc.stdout, proc.stdout


def test_long_demonstrations_are_worked_on_at_a_bounded_number_of_samples(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import studio.controller.demos as demos_module

    monkeypatch.setattr(demos_module, "WORK_SAMPLES", 20_000)
    store = SessionStore(tmp_path / "sessions")
    s = store.create("long")
    for i in range(2):
        s.add_recording(make_rec(n=30_000, seed=i, name=f"long {i + 1}"))
    told = RecordingNotifier()
    ctl = Controller(store=store, session="long", backend=SimulatedBaxter(), notifier=told)
    try:
        assert ctl.demos.stride() == 3
        d = ctl.demos.demo(0, "left")
        assert len(d) == 10_000 and d.t[1] == pytest.approx(3 * (s.recordings[0].t[1]))
        assert d.duration == pytest.approx(s.recordings[0].duration, abs=0.003)
        assert len(ctl.session.recordings[0]) == 30_000  # the recording itself stays whole
        assert any("every 3rd sample (20,000)" in body for _, _, body in told.notes), told.notes
        view = ctl.keypoints.refresh()
        assert view.k.get("left"), view.messages
    finally:
        ctl.shutdown()


def _csv(path: Path, rows: int) -> None:
    rng = np.random.default_rng(0)
    t = np.arange(rows) / 1000.0
    q = np.tile([0.1, -0.5, 0.0, 1.0, 0.0, 0.5, 0.0], (rows, 2)) + rng.normal(0, 1e-3, (rows, 14))
    cols = np.column_stack([t, q[:, :7], np.full(rows, 100.0), q[:, 7:], np.zeros(rows)])
    with open(path, "w") as f:
        f.write(",".join(CSV_COLUMNS) + "\n")
        for s in range(0, rows, 50_000):
            np.savetxt(f, cols[s : s + 50_000], fmt="%.6f", delimiter=",")


PEAK_OF_IMPORT = """
    import resource
    import studio.csv_io as c
    {patch}
    from studio.core.kinematics import Baxter
    Baxter.load()
    def hwm():
        return int([l for l in open("/proc/self/status") if l.startswith("VmHWM")][0].split()[1]) * 1024
    open("/proc/self/clear_refs", "w").write("5")
    before = hwm()
    try:
        r = c.import_csv({path!r})
        print("imported", len(r))
    except Exception as exc:
        print(type(exc).__name__, exc)
    print("grew", hwm() - before)
"""


def _grew(out: str) -> int:
    return int(out.split("grew ")[1].split()[0])


def test_csv_import_holds_about_the_data_not_several_copies(tmp_path: Path) -> None:
    """Today: a 10 M-row CSV imported with a 5 GB peak (the numbers parsed into a list, copied, filtered, copied)."""
    rows = 400_000
    p = tmp_path / "long.csv"
    _csv(p, rows)
    proc = run_limited(PEAK_OF_IMPORT.format(patch="", path=str(p)), memory=2048 * MiB, timeout=180)
    assert f"imported {rows}" in proc.stdout, proc.stdout + proc.stderr[-1500:]
    data = rows * 17 * 8
    assert _grew(proc.stdout) < 2.5 * data, (_grew(proc.stdout) / data, proc.stdout)


def test_a_csv_longer_than_a_demonstration_is_refused_before_it_is_parsed(tmp_path: Path) -> None:
    p = tmp_path / "too-long.csv"
    _csv(p, 200_000)
    patch = "c.MAX_SAMPLES = 100_000"
    proc = run_limited(PEAK_OF_IMPORT.format(patch=patch, path=str(p)), memory=2048 * MiB, timeout=180)
    assert '"too-long.csv" holds 200,000 rows: longer than a demonstration the studio keeps' in proc.stdout, (
        proc.stdout + proc.stderr[-1500:]
    )
    assert _grew(proc.stdout) < 8 * MiB, proc.stdout  # nothing was parsed
