"""Quality benchmark: how close the learned skill is to the demonstrations, on shapes and tasks (prints figures).

    .venv/bin/python bench/bench_quality.py [--quick] [--no-suggest] [--skip-timing]

Suite (issue 11 §8): continuous shapes from :mod:`studio.shapes` (circle, figure-eight, zigzag with sharp corners,
spiral, handwriting loops, a signature-like wave) at 3 cm, 15 cm and 60 cm, drawn in 2 s and in 20 s, with a
person's variation (time warp, hesitations, offsets, deformation, tremor), 3 and 7 demonstrations each; and the
scripted teacher's tasks (:mod:`studio.teacher`): stack-cup, pick-place, pick-place with both arms.

Methods, measured in the same run on the same demonstrations:
  B1        the time-normalised mean of the demos (the bar: F/B1 = 1 by definition)
  DBA       tslearn's dtw_barycenter_averaging of the demos' positions (250 points, 10 iterations)
  paper-old the paper's spline ("paper" mode) with the old fixed thresholds
  paper     "paper" mode with the automatic thresholds
  default   the studio's default: "aligned-mean" mode, automatic thresholds (nothing touched)
  suggest   after Suggest (studio.core.autotune.suggest; held-out fidelity search)
Measures (studio.core.quality): G/R (paper's squared DTW, normalised), F/B1 (discrete Fréchet ÷ B1's), the worst
shared-corner distance, start/end error, grasp/release error.

Timing (3 demos × 30,000 samples): slider re-extract + re-cluster (this module's k-means vs scikit-learn's, same
run), the live preview path, learn_skill, Suggest (in the calling thread, 2 threads, 2 spawned processes).
--quick: 15 cm shapes drawn in 2 s with 3 demos, the tasks with 3 demos, fewer timing repeats (~1–2 min).
"""

from __future__ import annotations

import argparse
import itertools
import logging
import math
import multiprocessing
import statistics
import sys
import time
import warnings
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor, wait
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studio.core import autotune
from studio.core import quality as Q
from studio.core.errors import StudioError
from studio.core.keypoints import KeypointCache
from studio.core.kinematics import Baxter
from studio.core.pipeline import demo_from_recording, learn_skill, preview_path
from studio.core.thresholds import auto_params
from studio.core.types import Demo, KeypointParams
from studio.shapes import SHAPES, ShapeSpec, shape_demos
from studio.teacher import recording_from_plan, teach

METHODS = ("B1", "DBA", "paper-old", "paper", "default", "suggest")


def _load() -> str:
    try:
        return "load average " + " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:  # pragma: no cover - not Linux
        return "load average unknown"


def _dba(demos: list[Demo]) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from tslearn.barycenters import dtw_barycenter_averaging
    X = []
    for d in demos:
        p = Q.smoothed(d)
        grid = np.linspace(d.t[0], d.t[-1], 250)
        X.append(np.column_stack([np.interp(grid, d.t, p[:, k]) for k in range(3)]))
    return np.asarray(dtw_barycenter_averaging(np.stack(X), barycenter_size=250, max_iter=10))


def _score_path(path_pos: np.ndarray, curves, r, b1f, demos, traj: Demo | None, size: float) -> dict:
    c = Q.arc_resample(path_pos)
    f = Q.fidelity(c, curves, r=r, b1_frechet=b1f)
    out = {"G/R": f.g_over_r, "F/B1": f.f_over_b1, "corner": math.nan, "ends": math.nan, "grip": math.nan}
    if traj is not None:
        corners = Q.corner_checks(traj, demos, size)
        out["corner"] = max((x.error for x in corners), default=math.nan)
        starts = np.mean([d.position[0] for d in demos], axis=0)
        ends = np.mean([d.position[-1] for d in demos], axis=0)
        out["ends"] = max(np.linalg.norm(traj.position[0] - starts), np.linalg.norm(traj.position[-1] - ends))
        g, _ = Q.gripper_checks(traj, demos)
        out["grip"] = max((x.error for x in g), default=math.nan)
    return out


def evaluate(demos: list[Demo], *, suggest: bool) -> dict[str, dict]:
    size = Q.extent(demos)
    curves = [Q.curve(d) for d in demos]
    r = Q.spread(curves)[0]
    b1 = Q.time_normalised_mean(demos)
    b1c = Q.arc_resample(b1)
    b1f = float(np.mean([Q.frechet(b1c, c) for c in curves]))
    res: dict[str, dict] = {}
    res["B1"] = _score_path(b1, curves, r, b1f, demos, None, size)
    res["DBA"] = _score_path(_dba(demos), curves, r, b1f, demos, None, size)
    runs = {
        "paper-old": dict(params=KeypointParams(), generalization="paper"),
        "paper": dict(generalization="paper"),
        "default": {},
    }
    for name, kw in runs.items():
        try:
            sk = learn_skill(demos, **kw)
            res[name] = _score_path(sk.trajectory.position, curves, r, b1f, demos, sk.trajectory, size)
            res[name]["k"] = sk.n_clusters
        except StudioError as exc:
            res[name] = {"G/R": math.inf, "F/B1": math.inf, "error": str(exc)}
    if suggest:
        t0 = time.perf_counter()
        tr = autotune.suggest(demos)
        sk = learn_skill(demos, tr.params, n_clusters=tr.n_clusters)
        res["suggest"] = _score_path(sk.trajectory.position, curves, r, b1f, demos, sk.trajectory, size)
        res["suggest"].update(detail=tr.settings.detail, seconds=time.perf_counter() - t0)
    return res


def shape_cases(quick: bool, sizes: tuple[float, ...] | None = None):
    sizes = sizes or ((0.15,) if quick else (0.03, 0.15, 0.6))
    durs = (2.0,) if quick else (2.0, 20.0)
    counts = (3,) if quick else (3, 7)
    for shape, size, dur, n in itertools.product(SHAPES, sizes, durs, counts):
        yield f"{shape} {size * 100:.0f} cm {dur:.0f} s ×{n}", size, list(shape_demos(ShapeSpec(shape, size, dur), n))


def task_cases(quick: bool):
    b = Baxter.load()
    counts = (3,) if quick else (3, 7)
    for task, arm in (("stack-cup", "left"), ("pick-place", "left"), ("pick-place", "both")):
        for n in counts:
            plans = [teach(task, s, arm=arm) for s in range(n)]
            for a in ("left", "right") if arm == "both" else (arm,):
                label = f"{task}{' both arms, ' + a if arm == 'both' else ''} ×{n}"
                yield label, None, [demo_from_recording(recording_from_plan(p), a, b) for p in plans]


def _fmt(x: float, spec: str = ".2f") -> str:
    return "—" if x is None or not math.isfinite(x) else format(x, spec)


def quality_suite(quick: bool, suggest: bool, sizes: tuple[float, ...] | None = None, tasks: bool = True) -> None:
    methods = [m for m in METHODS if suggest or m != "suggest"]
    rows: list[tuple[str, float | None, dict]] = []
    print("\n== quality: G/R (lower is better; exact mean of n noisy copies: (n−1)/2n) and F/B1 (B1 = 1) ==")
    head = f"{'case':<34}" + "".join(f"{m:>16}" for m in methods) + f"{'corner mm':>11}{'ends mm':>9}{'grip mm':>9}"
    print(head)
    t0 = time.perf_counter()
    for label, size, demos in itertools.chain(shape_cases(quick, sizes), task_cases(quick) if tasks else ()):
        res = evaluate(demos, suggest=suggest)
        rows.append((label, size, res))
        d = res["default"]
        cells = "".join(f"{_fmt(res[m]['G/R']):>7} {_fmt(res[m]['F/B1']):>7} " for m in methods)
        print(
            f"{label:<34}{cells}{_fmt(d['corner'] * 1000, '.1f'):>11}{_fmt(d['ends'] * 1000, '.1f'):>9}"
            f"{_fmt(d['grip'] * 1000, '.1f'):>9}",
            flush=True,
        )
    print(f"({len(rows)} cases in {time.perf_counter() - t0:.0f} s; cells are G/R F/B1)")
    print("\n== summary over the suite ==")
    print(
        f"{'method':<12}{'median G/R':>12}{'median F/B1':>13}{'worst F/B1':>12}{'corners@15cm':>14}"
        f"{'start/end':>11}{'grasp':>9}"
    )
    for m in methods:
        g = np.array([x[2][m]["G/R"] for x in rows])
        f = np.array([x[2][m]["F/B1"] for x in rows])
        c15 = [x[2][m].get("corner", math.nan) for x in rows if x[1] == 0.15]
        c15 = [c for c in c15 if math.isfinite(c)]
        ends = [x[2][m].get("ends", math.nan) for x in rows]
        ends = [e for e in ends if math.isfinite(e)]
        grip = [x[2][m].get("grip", math.nan) for x in rows]
        grip = [e for e in grip if math.isfinite(e)]
        print(
            f"{m:<12}{_fmt(float(np.median(g))):>12}{_fmt(float(np.median(f))):>13}{_fmt(float(np.max(f))):>12}"
            f"{(_fmt(max(c15) * 1000, '.1f') + ' mm') if c15 else '—':>14}"
            f"{(_fmt(max(ends) * 1000, '.1f') + ' mm') if ends else '—':>11}"
            f"{(_fmt(max(grip) * 1000, '.1f') + ' mm') if grip else '—':>9}"
        )
    print("targets: median G/R ≤ 0.60, median F/B1 ≤ 1.0, worst F/B1 ≤ 1.5, corners at 15 cm ≤ 5 mm, start/end ≤ 2 mm,")
    print("         grasp/release ≤ 10 mm — for 'default' and 'suggest'")
    for m in ("default", "suggest"):
        if m not in methods:
            continue
        g = np.median([x[2][m]["G/R"] for x in rows])
        f = [x[2][m]["F/B1"] for x in rows]
        c15 = [x[2][m]["corner"] for x in rows if x[1] == 0.15 and math.isfinite(x[2][m]["corner"])]
        ends = max(x[2][m]["ends"] for x in rows)
        grip = [x[2][m]["grip"] for x in rows if math.isfinite(x[2][m]["grip"])]
        checks = [
            ("median G/R", g, 0.60),
            ("median F/B1", float(np.median(f)), 1.0),
            ("worst F/B1", float(np.max(f)), 1.5),
            ("corners@15cm m", max(c15) if c15 else 0.0, 0.005),
            ("start/end m", ends, 0.002),
            ("grasp m", max(grip) if grip else 0.0, 0.01),
        ]
        print(f"  {m}: " + "; ".join(f"{n} {v:.4g} {'met' if v <= lim else 'MISSED'}" for n, v, lim in checks))
    if suggest:
        secs = [x[2]["suggest"]["seconds"] for x in rows]
        details = [x[2]["suggest"]["detail"] for x in rows]
        print(
            f"  Suggest: median {statistics.median(secs):.1f} s a case (max {max(secs):.1f} s); Detail chosen: "
            + ", ".join(f"{d:+.1f}×{details.count(d)}" for d in sorted(set(details)))
        )


def _long_demos() -> list[Demo]:
    """3 demos × 30,000 samples: handwriting loops, 15 cm, drawn in ~28 s (1 kHz)."""
    return [replace_name(d) for d in shape_demos(ShapeSpec("handwriting", 0.15, 28.0), 3)]


def replace_name(d: Demo) -> Demo:
    n = min(len(d), 30_000)
    return Demo(d.t[:n], d.position[:n], d.orientation[:n], d.gripper[:n], name=d.name)


def _median_ms(fn, repeat: int) -> float:
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts) * 1e3


def timing(quick: bool) -> None:
    from studio.core.clustering import cluster

    rep = 5 if quick else 15
    demos = _long_demos()
    print(f"\n== timing: 3 demos × {len(demos[0])} samples ({_load()}) ==")
    cache = KeypointCache()
    base = auto_params(demos)
    cache.extract_all(demos, base)
    i = 0

    def slider(backend: str) -> None:
        nonlocal i
        i += 1
        p = replace(base, eps5=base.eps5 * (1.0 + 0.05 * (i % 5)))
        kps = cache.extract_all(demos, p)
        cluster(demos, kps, seed=0, backend=backend)

    for b in ("numpy", "sklearn", "numpy", "sklearn"):
        ms = _median_ms(lambda b=b: slider(b), rep)
        print(f"slider move (re-extract + re-cluster), k-means {b:<8}: median {ms:6.1f} ms  (budget 30 ms)")
    preview_path(demos, base, cache=cache)  # DTW maps cached, as during a slider drag

    def prev() -> None:
        nonlocal i
        i += 1
        preview_path(demos, replace(base, eps5=base.eps5 * (1.0 + 0.05 * (i % 5))), cache=cache)

    print(f"live preview path (preview_path, warm caches): median {_median_ms(prev, rep):6.1f} ms  (budget 150 ms)")
    ms = _median_ms(lambda: learn_skill(demos, base, cache=cache), max(3, rep // 3))
    print(f"learn_skill (warm key-point cache):            median {ms:6.1f} ms")
    _suggest_timing(demos)


def _quiet() -> None:
    logging.getLogger("hmmlearn").setLevel(logging.ERROR)  # as the studio's processes (studio/cli.py)


def _suggest_timing(demos: list[Demo]) -> None:
    """Suggest where the studio runs it (the calling thread, or an executor the caller gives): a first search
    (new demos) and the same demos again, alternately, against the calling thread alone in the same run."""
    spawn = multiprocessing.get_context("spawn")
    with ThreadPoolExecutor(2) as threads, ProcessPoolExecutor(2, mp_context=spawn, initializer=_quiet) as processes:
        wait([processes.submit(autotune.warm_up) for _ in range(2)])  # warm: started, the pipeline loaded
        where: dict[str, Executor | None] = {
            "in the calling thread": None,
            "2 threads (the studio's helpers)": threads,
            "2 spawned processes (warm)": processes,
        }
        firsts: dict[str, list[float]] = {k: [] for k in where}
        agains: dict[str, list[float]] = {k: [] for k in where}
        for rep in range(3):
            for label, ex in where.items():
                renamed = [
                    Demo(d.t, d.position, d.orientation, d.gripper, name=f"{d.name}-{label}-{rep}") for d in demos
                ]
                t0 = time.perf_counter()
                autotune.suggest(renamed, executor=ex)
                firsts[label].append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                r = autotune.suggest(renamed, executor=ex)
                agains[label].append(time.perf_counter() - t0)
    base = statistics.median(firsts["in the calling thread"])
    for label in where:
        first, again = statistics.median(firsts[label]), statistics.median(agains[label])
        print(
            f"Suggest, {label:<33}: first search {first:5.2f} s (×{first / base:4.2f}), same demos again {again:5.2f} s"
            f"  (median of 3; budget 5 s; {r.evaluated} candidates × {min(3, len(demos))} folds)"
        )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="a subset (15 cm, 2 s, 3 demos; tasks with 3 demos)")
    ap.add_argument("--no-suggest", action="store_true", help="skip Suggest in the quality suite")
    ap.add_argument("--skip-timing", action="store_true")
    ap.add_argument("--skip-quality", action="store_true")
    ap.add_argument("--sizes", type=float, nargs="+", help="shape sizes in metres, 0.005-0.8 (default 0.03 0.15 0.6)")
    ap.add_argument("--no-tasks", action="store_true", help="only the shapes (e.g. with --sizes 0.8)")
    args = ap.parse_args()
    _quiet()
    print(f"machine: {_load()} at start (2 cores shared)")
    if not args.skip_timing:
        timing(args.quick)
    if not args.skip_quality:
        quality_suite(args.quick, not args.no_suggest, tuple(args.sizes) if args.sizes else None, not args.no_tasks)
    autotune.shutdown()


if __name__ == "__main__":
    main()
