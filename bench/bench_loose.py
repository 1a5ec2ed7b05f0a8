"""Issue 22's last figure, the worst Fréchet ratio to the plain mean (F/B1) on the "loose" shape sets, for the
default and for variants of how the demos are aligned and averaged. Each variant runs in a fresh process with
the studio patched (so no cache carries over); the figures print as a table. Every variant but "default" runs
without decision 083's move toward the plain mean (they were measured against the aligned mean before it).

    .venv/bin/python bench/bench_loose.py [--only default dir2 ...] [--jobs 2]
"""

from __future__ import annotations

import argparse
import functools
import multiprocessing
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

#: name → what is changed (the default changes nothing).
VARIANTS = {
    "default": "the default (direction weight 0.5; moved toward the plain mean where that is nearer, decision 083)",
    "aligned": "the aligned mean alone (the default before decision 083)",
    "dir2": "direction of motion weighted ×2",
    "dir4": "direction of motion weighted ×4",
    "from-start": "positions taken from each demo's start",
    "from-mean": "positions taken from each demo's mean",
    "pin0.05": "the start-pin fade PIN_S 0.05 s (not 0.15)",
    "pin0.3": "the start-pin fade PIN_S 0.3 s",
    "penalty0.01": "dtaidistance's penalty on a non-diagonal step, 0.01",
    "penalty0.1": "the same penalty, 0.1",
    "penalty1": "the same penalty, 1",
    "penalty5": "the same penalty, 5",
    "penalty20": "the same penalty, 20",
    "penalty100": "the same penalty, 100",
    "window0.1": "a Sakoe–Chiba window of 10 % of the length",
    "window0.2": "a Sakoe–Chiba window of 20 % of the length",
    "dba1": "DBA-style: every demo aligned again to the aligned mean, averaged again, once",
    "dba2": "the same, twice",
}


def _patch(name: str) -> None:
    """Change the studio, in this process, as variant ``name`` says."""
    import studio.core.generalize as G
    import studio.core.pipeline as P

    if name != "default":
        G._plain_mean_share = lambda *a: 0.0
    if name.startswith("dir"):
        P.DTW_DIRECTION_WEIGHT *= float(name[3:])
    elif name.startswith("from-"):
        plain = P._dtw_series
        take = (lambda Y: Y[0, :3]) if name == "from-start" else (lambda Y: Y[:, :3].mean(axis=0))

        def centred(X, scale, ref_quat, feats):  # type: ignore[no-untyped-def]
            Y = plain(X, scale, ref_quat, feats)
            Y[:, :3] -= take(Y)
            return Y

        P._dtw_series = centred
    elif name.startswith("pin"):
        G.PIN_S = float(name[3:])
    elif name.startswith(("penalty", "window")):
        from dtaidistance import dtw as dtai

        plain_path = dtai.warping_path_fast
        value = float(name.removeprefix("penalty").removeprefix("window"))

        def path(a, b, **kw):  # type: ignore[no-untyped-def]
            if name.startswith("penalty"):
                kw["penalty"] = value
            else:
                kw["window"] = max(abs(len(a) - len(b)) + 2, int(value * max(len(a), len(b))))
            return plain_path(a, b, **kw)

        dtai.warping_path_fast = path
    elif name.startswith("dba"):
        G._aligned_mean = functools.partial(_realigned, int(name[3:]))


def _realigned(times: int, demos, fm, t, cache):  # type: ignore[no-untyped-def]
    """The aligned mean, then ``times`` rounds of: every demo aligned to it by DTW, averaged again."""
    import studio.core.generalize as G
    import studio.core.pipeline as P
    from studio.core import alignment
    from studio.core.clustering import FeatureScale
    from studio.core.types import Demo

    pose, grip = G._mean_pose(demos, fm.inverse, fm.ref, t, cache)
    scale = FeatureScale.for_demos(demos)
    ref_quat = np.asarray(demos[fm.ref].orientation[0], dtype=np.float64)
    rate = alignment.common_rate([d.duration for d in demos])
    gm = alignment.time_grid(t[0], t[-1], rate)
    for _ in range(times):
        mean = Demo(t, pose[:, :3], pose[:, 3:], grip)
        sm = P._dtw_series(alignment.resample(mean.t, mean.features, gm), scale, ref_quat, "shape")
        inverse = []
        for d in demos:
            g = alignment.time_grid(d.t[0], d.t[-1], rate)
            _, p = alignment.dtw(sm, P._dtw_series(alignment.resample(d.t, d.features, g), scale, ref_quat, "shape"))
            inverse.append(P._warp_to(alignment.time_map(p, gm, g), g, float(d.t[0]), gm - t[0], float(t[0])))
        pose, grip = G._mean_pose(demos, inverse, fm.ref, t, cache)
    return pose


def loose_ratios(name: str) -> list[float]:
    """F/B1 of the default, patched as ``name`` says, on each of the 36 loose shape sets (seed 0)."""
    os.environ.update({"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"})
    import bench_quality as B

    B._quiet()
    _patch(name)
    out = []
    for case in B.cases(False, None, None, ("shapes",), 0):
        if case.style == "loose":
            demos, _ = case.demos()
            out.append(B.Ref(demos).score(np.asarray(B.learn_skill(demos).trajectory.position))["F/B1"])
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", nargs="+", choices=tuple(VARIANTS), help="these variants (default: all)")
    ap.add_argument("--jobs", type=int, default=1, help="variants measured at once")
    args = ap.parse_args()
    names = args.only or list(VARIANTS)
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(args.jobs, mp_context=ctx, max_tasks_per_child=1) as pool:
        results = dict(zip(names, pool.map(loose_ratios, names), strict=True))
    print("| variant | worst F/B1 | loose sets above 1.000 (of 36) |\n|---|---|---|")
    for name, ratios in results.items():
        print(f"| {VARIANTS[name]} | {max(ratios):.3f} | {sum(r > 1.0005 for r in ratios)} |")


if __name__ == "__main__":
    main()
