"""Benchmark of the learning pipeline (prints figures; asserts nothing).

    .venv/bin/python bench/bench_pipeline.py [--quick]

Measures, on scripted teacher demonstrations (pick-and-place, 1 kHz):
  1. slider move: re-extract key-points + re-cluster for 3 demos × 30,000 samples after one ε changes
     (derived series cached), against the literal per-sample reference implementation;
  2. learn_skill for 3 × 30,000 samples (cold: series computed inside) and with a warm key-point cache;
  3. learn_skill for 10 demos × 100,000 samples;
  4. peak memory of DTW on the longest series it is ever given, and of a whole learn_skill.
Medians of repeated runs; ratios from the same run.
"""

from __future__ import annotations

import argparse
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _timer import median_ms

from studio.core.alignment import MAX_POINTS
from studio.core.caches import LearningCaches
from studio.core.clustering import cluster
from studio.core.keypoints import KeypointCache
from studio.core.kinematics import Baxter
from studio.core.pipeline import demo_from_recording, learn_skill
from studio.core.types import Demo, KeypointParams
from studio.teacher import recording_from_plan, teach
from tests.core.oracles import extract_keypoints_reference


def _demo_of_length(seeds: list[int], n: int, name: str) -> Demo:
    """Chain scripted pick-place demonstrations (each starts and ends at home) and cut to n samples."""
    b = Baxter.load()
    parts = [demo_from_recording(recording_from_plan(teach("pick-place", s)), "left", b) for s in seeds]
    pos = np.concatenate([p.position for p in parts])
    ori = np.concatenate([p.orientation * np.sign(p.orientation[0] @ parts[0].orientation[0]) for p in parts])
    grip = np.concatenate([p.gripper for p in parts])
    q = np.concatenate([p.q for p in parts])
    while pos.shape[0] < n:  # rest at the end
        pos, ori = np.vstack([pos, pos[-1:]]), np.vstack([ori, ori[-1:]])
        grip, q = np.append(grip, grip[-1]), np.vstack([q, q[-1:]])
    t = np.arange(n) / 1000.0
    return Demo(t, pos[:n], ori[:n], grip[:n], q[:n], name=name)


def _load() -> str:
    try:
        return "load average " + " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:  # pragma: no cover - not Linux
        return "load average unknown"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer repetitions, skip 10 × 100,000")
    args = ap.parse_args()
    rep = 5 if args.quick else 15
    print(f"machine: {_load()} at start (2 cores shared; wall-clock figures inflate under load)")

    demos3 = [_demo_of_length([s, s + 10], 30_000, f"demo {s}") for s in range(3)]
    print(f"3 demos × {len(demos3[0])} samples; key-points per demo with defaults:", end=" ")

    # 1. slider move ---------------------------------------------------------------------------------
    cache = KeypointCache()
    base = KeypointParams()
    kps = cache.extract_all(demos3, base)
    print([len(k) for k in kps])
    t0 = time.perf_counter()
    for d in demos3:
        cache.series(d)
    precompute_ms = (time.perf_counter() - t0) * 1e3  # already cached above; kept for the record
    cache2 = KeypointCache()
    t0 = time.perf_counter()
    for d in demos3:
        cache2.series(d)
    precompute_ms = (time.perf_counter() - t0) * 1e3

    values = np.linspace(0.08, 0.16, 9)
    i = [0]

    def slider_move() -> None:
        p = KeypointParams(eps5=float(values[i[0] % len(values)]), eps7=0.16)
        i[0] += 1
        k = cache.extract_all(demos3, p)
        cluster(demos3, k, seed=0)

    def extract_only() -> None:
        p = KeypointParams(eps5=float(values[i[0] % len(values)]), eps7=0.16)
        i[0] += 1
        cache.extract_all(demos3, p)

    slider_ms = median_ms(slider_move, rep * 4)
    slider_cpu = median_ms(slider_move, rep * 4, time.process_time)
    extract_ms = median_ms(extract_only, rep * 4)
    p_ref = KeypointParams(eps5=0.12, eps7=0.16)
    ref_ms = median_ms(lambda: [extract_keypoints_reference(d, p_ref, series=cache.series(d)) for d in demos3], 3)
    same = all(
        np.array_equal(cache.extract(d, p_ref), extract_keypoints_reference(d, p_ref, series=cache.series(d)))
        for d in demos3
    )
    print(f"derived series (once per demo, 3 demos):           {precompute_ms:8.1f} ms")
    print(
        f"slider move: re-extract + re-cluster, 3 × 30,000:  {slider_ms:8.2f} ms (median of {rep * 4}; "
        f"CPU time {slider_cpu:.2f} ms)"
    )
    print(f"  of which key-point re-extraction:                {extract_ms:8.2f} ms")
    print(
        f"literal per-sample reference, 3 × 30,000:           {ref_ms:8.1f} ms  -> speed-up {ref_ms / extract_ms:.0f}x"
        f" (same key-points: {same})"
    )

    # 2. learn_skill 3 × 30,000 -------------------------------------------------------------------------
    cold = median_ms(lambda: learn_skill(demos3), rep)
    cold_cpu = median_ms(lambda: learn_skill(demos3), rep, time.process_time)
    warm_cache = LearningCaches()
    learn_skill(demos3, caches=warm_cache)
    warm = median_ms(lambda: learn_skill(demos3, caches=warm_cache), rep)
    b = Baxter.load()
    with_ik = median_ms(lambda: learn_skill(demos3, arm="left", baxter=b), max(3, rep // 3))
    print(
        f"learn_skill 3 × 30,000 (series computed inside):   {cold:8.1f} ms (median of {rep}; CPU time "
        f"{cold_cpu:.1f} ms)"
    )
    print(f"learn_skill 3 × 30,000 (warm key-point cache):     {warm:8.1f} ms")
    print(f"learn_skill 3 × 30,000 + joint trajectory (IK):    {with_ik:8.1f} ms")

    # 4. memory --------------------------------------------------------------------------------------------
    # DTW runs in dtaidistance's C code, whose allocations tracemalloc cannot see: measure the process's peak
    # resident memory in a fresh interpreter instead.
    import subprocess

    code = (
        "import time, numpy as np\n"
        "from studio.core.alignment import MAX_POINTS, dtw\n"
        "hwm = lambda: int([l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1])\n"
        "rng = np.random.default_rng(0)\n"
        "a, c = rng.normal(size=(MAX_POINTS, 8)), rng.normal(size=(MAX_POINTS, 8))\n"
        "dtw(a[:5], c[:5]); h0 = hwm(); t0 = time.perf_counter(); dtw(a, c)\n"
        "print((time.perf_counter() - t0) * 1e3, (hwm() - h0) * 1024)\n"
    )
    root = str(Path(__file__).resolve().parents[1])
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root)
    dtw_ms, dtw_peak = map(float, out.stdout.split())
    tracemalloc.start()
    learn_skill(demos3)
    learn_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    print(
        f"DTW {MAX_POINTS} × {MAX_POINTS} (largest ever used, dtaidistance): {dtw_ms:8.1f} ms, peak resident memory "
        f"+{dtw_peak / 1e6:.1f} MB (a full float matrix would be {MAX_POINTS**2 * 8 / 1e6:.0f} MB; 30,000² 7.2 GB)"
    )
    print(f"learn_skill 3 × 30,000 peak traced memory:          {learn_peak / 1e6:8.1f} MB")

    # 3. 10 × 100,000 -----------------------------------------------------------------------------------------
    if not args.quick:
        demos10 = [_demo_of_length([s, s + 10, s + 20, s + 30], 100_000, f"long {s}") for s in range(10)]
        t0 = time.perf_counter()
        sk = learn_skill(demos10)
        long_ms = (time.perf_counter() - t0) * 1e3
        print(
            f"learn_skill 10 × 100,000:                          {long_ms:8.0f} ms "
            f"(k = {sk.n_clusters}, key-points {min(map(len, sk.keypoints))}–{max(map(len, sk.keypoints))})"
        )
    print(f"machine: {_load()} at end")


if __name__ == "__main__":
    main()
