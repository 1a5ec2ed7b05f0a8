"""Data-collection benchmark: recorder throughput, session load time, the 1 kHz real-time claim, long takes.

Prints figures; never asserts on time. Run: ``.venv/bin/python bench/bench_data.py`` (about 2 minutes: the
real-time part runs 60 s of wall time). ``--quick`` shortens the real-time run to 10 s and skips the 2-hour
recording; ``--skip-long`` skips only the 2-hour recording.

1. Recorder: samples per second it absorbs, with FK of the taught arm(s) and disk writes (flush + fsync),
   fed 15-sample batches as fast as possible (the simulator's real rate is 1,000 per second).
2. Session load: ``SessionStore.open`` of a session with 10 demos x 100,000 samples (float64 and float32).
3. Real time: SimulatedBaxter streaming for 60 s of wall time into a recorder while two other threads keep
   the CPU busy: sample count, exactness of the time stamps, CPU used by the stream.
4. A 2-hour recording (7.2 M samples) in manual-step mode: time, file size and peak memory (RSS).
"""

from __future__ import annotations

import argparse
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from studio.core.kinematics import Baxter
from studio.core.types import Recording
from studio.recorder import Recorder
from studio.robot_backend.base import JointStateBatch, RobotBackend, RobotState
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore


class PushBackend(RobotBackend):
    def __init__(self) -> None:
        self.listeners: list = []

    def start(self) -> None: ...
    def stop(self) -> None: ...

    def subscribe(self, listener):  # type: ignore[no-untyped-def]
        self.listeners.append(listener)
        return lambda: self.listeners.remove(listener)

    def command_joints(self, arm, q) -> None: ...  # type: ignore[no-untyped-def]
    def command_gripper(self, arm, width) -> None: ...  # type: ignore[no-untyped-def]

    def state(self) -> RobotState:
        return RobotState(0.0, np.zeros(14), np.zeros(2))


def _walk(n: int, seed: int) -> np.ndarray:
    b = Baxter.load()
    q0 = np.concatenate([b.neutral("left"), b.neutral("right")])
    return q0 + np.cumsum(np.random.default_rng(seed).normal(0, 2e-4, (n, 14)), axis=0)


def bench_recorder(tmp: Path, arms: tuple[str, ...], seconds: int = 300) -> float:
    n = seconds * 1000
    q = _walk(n, 0)
    g = np.full((n, 2), 100.0)
    t = np.arange(n) / 1000.0
    batches = [JointStateBatch(t[s : s + 15], q[s : s + 15], g[s : s + 15]) for s in range(0, n, 15)]
    be = PushBackend()
    rec = Recorder(be, tmp / f"rec-{'-'.join(arms)}", arms=arms)
    t0 = time.perf_counter()
    rec.start()
    for b in batches:
        for fn in be.listeners:
            fn(b)
    r = rec.stop()
    dt = time.perf_counter() - t0
    assert len(r) == n
    rec.discard()
    return n / dt


def bench_sim_recorder(tmp: Path, seconds: int = 300) -> float:
    sim = SimulatedBaxter(sensor_noise=2.5e-4, quantum=2 * np.pi / 2**14)
    rec = Recorder(sim, tmp / "simrec", arms=("left",))
    targets = _walk(seconds * 1000, 1)
    t0 = time.perf_counter()
    rec.start()
    sim.run_targets(targets, batch=15)
    r = rec.stop()
    dt = time.perf_counter() - t0
    rec.discard()
    return len(r) / dt


def bench_load(tmp: Path, precision: str) -> tuple[float, float]:
    store = SessionStore(tmp / f"load-{precision}")
    s = store.create("ten demos", precision=precision)
    for i in range(10):
        n = 100_000
        q = _walk(n, 10 + i)
        s.add_recording(Recording(np.arange(n) / 1000.0, q, np.full((n, 2), 100.0), ("left",), f"demo {i + 1}"))
    size = sum(p.stat().st_size for p in s.path.rglob("*") if p.is_file()) / 1e6
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        loaded = store.open("ten demos")
        times.append(time.perf_counter() - t0)
        assert sum(len(r) for r in loaded.recordings) == 1_000_000
    return statistics.median(times), size


def bench_realtime(tmp: Path, seconds: float) -> dict[str, float]:
    stop = threading.Event()

    def hog() -> None:
        x = 0
        while not stop.is_set():
            x += 1

    hogs = [threading.Thread(target=hog, daemon=True) for _ in range(2)]
    for h in hogs:
        h.start()
    sim = SimulatedBaxter()
    got: list[JointStateBatch] = []
    sim.subscribe(got.append)
    rec = Recorder(sim, tmp / "rt", arms=("left",))
    rec.start()
    cpu0 = time.thread_time()  # this thread only; the stream's cost is measured below
    proc0 = time.process_time()
    sim.command_joints("left", np.zeros(7))
    t_start = time.perf_counter()  # before start(): the simulated clock starts inside it
    sim.start()
    time.sleep(seconds)
    sim.stop()
    wall = time.perf_counter() - t_start
    proc = time.process_time() - proc0 - (time.thread_time() - cpu0)
    stop.set()
    for h in hogs:
        h.join()
    r = rec.stop()
    rec.discard()
    t = np.concatenate([b.t for b in got])
    sizes = [len(b) for b in got]
    return {
        "wall": wall,
        "samples": float(t.shape[0]),
        "expected": wall * 1000,
        "exact": float(np.array_equal(t, np.arange(t.shape[0]) / 1000.0)),
        "recorded": float(len(r)),
        "batch_median": float(statistics.median(sizes)),
        "batch_max": float(max(sizes)),
        "cpu_incl_hogs": proc / wall,
    }


def bench_idle_cpu(seconds: float = 10.0) -> float:
    """CPU share of a real-time stream alone (no hogs), with a recorder attached."""
    tmp = Path(tempfile.mkdtemp())
    try:
        sim = SimulatedBaxter()
        rec = Recorder(sim, tmp, arms=("left",))
        rec.start()
        p0, w0 = time.process_time(), time.perf_counter()
        sim.start()
        time.sleep(seconds)
        sim.stop()
        share = (time.process_time() - p0) / (time.perf_counter() - w0)
        rec.stop()
        rec.discard()
        return share
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def bench_long(tmp: Path, hours: float = 2.0) -> dict[str, float]:
    n = int(hours * 3600 * 1000)
    sim = SimulatedBaxter(sensor_noise=2.5e-4)
    rec = Recorder(sim, tmp / "long", arms=("left",), max_seconds=hours * 3600 + 10)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    t0 = time.perf_counter()
    rec.start()
    chunk = 60_000
    peak_rec = 0.0
    for s in range(0, n, chunk):
        m = min(chunk, n - s)
        sim.command_joints("left", Baxter.load().neutral("left") + 0.3 * np.sin(s / 1e5))
        sim.step(m)
        if s % (20 * chunk) == 0:
            peak_rec = max(peak_rec, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
    rec.flush()
    t_rec = time.perf_counter() - t0
    rss_rec = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    size = rec.path.stat().st_size / 1e9  # type: ignore[union-attr]
    r = rec.stop()
    t_all = time.perf_counter() - t0
    rss_stop = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    assert len(r) == n
    del r
    rec.discard()
    return {
        "samples": float(n),
        "record_s": t_rec,
        "stop_s": t_all - t_rec,
        "file_gb": size,
        "rss_before_mb": rss0,
        "rss_recording_mb": rss_rec,
        "rss_after_stop_mb": rss_stop,
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--skip-long", action="store_true")
    ap.add_argument("--only-realtime", action="store_true")
    ap.add_argument("--only-long", action="store_true", help="(internal) the 2-hour recording in this process")
    a = ap.parse_args()
    Baxter.load()
    tmp = Path(tempfile.mkdtemp(prefix="bench-data-"))
    try:
        if a.only_long:
            lg = bench_long(tmp)
            print(
                f"  recorded in {lg['record_s']:.0f} s, stop() (read back) {lg['stop_s']:.1f} s, "
                f"file {lg['file_gb']:.2f} GB; peak RSS before {lg['rss_before_mb']:.0f} MB, while recording "
                f"{lg['rss_recording_mb']:.0f} MB, after stop() returned the 7.2 M-sample Recording "
                f"{lg['rss_after_stop_mb']:.0f} MB"
            )
            return
        if a.only_realtime:
            rt = bench_realtime(tmp, 10.0 if a.quick else 60.0)
            print(rt)
            return
        print("== recorder throughput (FK + append + flush/fsync), 300 s of 1 kHz data in 15-sample batches")
        for arms in (("left",), ("left", "right")):
            rates = [bench_recorder(tmp, arms) for _ in range(3)]
            print(f"  {'+'.join(arms):<11} {statistics.median(rates):>12,.0f} samples/s (median of 3)")
        rates = [bench_sim_recorder(tmp) for _ in range(3)]
        print(f"  simulator (manual steps) + recorder, left: {statistics.median(rates):,.0f} samples/s")

        print("== session load: 10 demos x 100,000 samples")
        for prec in ("float64", "float32"):
            t, size = bench_load(tmp, prec)
            print(f"  {prec}: {t * 1000:.0f} ms (median of 5), {size:.0f} MB on disk")

        secs = 10.0 if a.quick else 60.0
        print(f"== real time: {secs:.0f} s wall, recorder attached, two busy threads competing for the CPU")
        rt = bench_realtime(tmp, secs)
        print(
            f"  {rt['samples']:,.0f} samples in {rt['wall']:.3f} s (expected {rt['expected']:,.0f}); "
            f"timestamps exact and gap-free: {bool(rt['exact'])}; recorded {rt['recorded']:,.0f}; "
            f"batch size median {rt['batch_median']:.0f}, max {rt['batch_max']:.0f}"
        )
        share = bench_idle_cpu(5.0 if a.quick else 10.0)
        print(f"  stream + recorder alone (no busy threads): {share * 100:.1f} % of one core")

        if not (a.quick or a.skip_long):
            print("== a 2-hour recording (7.2 M samples), manual steps, left arm (fresh process for clean RSS)")
            sys.stdout.flush()
            subprocess.run([sys.executable, __file__, "--only-long"], check=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
