"""Quality benchmark: the learned skill against the demonstrations and against peer methods, in one run.

    bash scripts/bootstrap.sh "test,bench"   # the peers: tslearn, movement-primitives, gmr
    .venv/bin/python bench/bench_quality.py [--quick] [--no-suggest] [--no-held] [--skip-timing] [--skip-quality]

Sets (human-like teacher, :mod:`studio.shapes`): six shapes at 3, 15 and 60 cm, 3 and 7 demos, drawn
"careful" in 2 s and in 20 s and "loose" in 1.5 s (pen lands away from the start, no rest at the ends);
multi-modal sets: 2 or 3 routes around obstacles at the same sizes, 3 and 7 demos, both styles; the
scripted teacher's tasks (stack-cup, pick-place, both arms).

Methods (positions; the peers from the demos' 50 ms smoothed positions over normalised time):
  mean      the plain (time-normalised) mean of the demos (B1: the Fréchet ratio's denominator)
  DBA       tslearn dtw_barycenter_averaging (250 points, 10 iterations)
  ProMP     movement_primitives ProMP mean trajectory (20 weights per dimension)
  DMP       movement_primitives DMP learned from the medoid demo, started and ended at the demos' means
  GMR       gmr: a GMM on (time, position), 10 components, position regressed on time
  paper     the studio's "paper" mode (automatic thresholds)
  default   the studio's default (nothing touched)
Measures: DTW ratio (G/R), Fréchet ratio (F/B1), held-out DTW ratio (learned without one demo, measured on it;
every demo left out with 3 demos, 3 of 7), start/end error. Per set, "wins" of the default over each peer.
Multi-modal: routes found, the learned path on one route. --quick: 15 cm, 3 demos, fewer sets (~2 min).
"""

from __future__ import annotations

import argparse
import itertools
import math
import statistics
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studio.core import autotune
from studio.core import quality as Q
from studio.core.errors import StudioError
from studio.core.keypoints import KeypointCache
from studio.core.kinematics import Baxter
from studio.core.pipeline import demo_from_recording, learn_path, learn_skill, preview_path
from studio.core.thresholds import auto_params
from studio.core.types import Demo
from studio.shapes import SHAPES, ShapeSpec, route_demos, shape_demos
from studio.teacher import recording_from_plan, teach

PEERS = ("mean", "DBA", "ProMP", "DMP", "GMR", "paper")
STUDIO = ("default",)
N_PEER = 250


def _load() -> str:
    try:
        return "load average " + " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:  # pragma: no cover - not Linux
        return "load average unknown"


# -- the peers ---------------------------------------------------------------------------------------------------


def _normalised(demos: list[Demo], n: int = N_PEER) -> np.ndarray:
    """(D, n, 3) the demos' smoothed positions over 0…1 of their own duration."""
    out = []
    for d in demos:
        p = Q.smoothed(d)
        u = (d.t - d.t[0]) / max(d.duration, 1e-12)
        grid = np.linspace(0.0, 1.0, n)
        out.append(np.column_stack([np.interp(grid, u, p[:, k]) for k in range(3)]))
    return np.stack(out)


def peer_mean(demos: list[Demo]) -> np.ndarray:
    return Q.time_normalised_mean(demos)


def peer_dba(demos: list[Demo]) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from tslearn.barycenters import dtw_barycenter_averaging
    return np.asarray(dtw_barycenter_averaging(_normalised(demos), barycenter_size=N_PEER, max_iter=10))


def peer_promp(demos: list[Demo]) -> np.ndarray:
    from movement_primitives.promp import ProMP

    Y = _normalised(demos)
    T = np.tile(np.linspace(0.0, 1.0, N_PEER), (len(demos), 1))
    p = ProMP(n_dims=3, n_weights_per_dim=20)
    p.imitate(T, Y)
    return np.asarray(p.mean_trajectory(T[0]))


def _medoid(Y: np.ndarray) -> int:
    cs = [Q.arc_resample(y, 200) for y in Y]
    cost = [sum(Q.ndtw(a, b) for b in cs) for a in cs]
    return int(np.argmin(cost))


def peer_dmp(demos: list[Demo]) -> np.ndarray:
    from movement_primitives.dmp import DMP

    Y = _normalised(demos)
    T = np.linspace(0.0, 1.0, N_PEER)
    d = DMP(n_dims=3, execution_time=1.0, dt=1.0 / (N_PEER - 1), n_weights_per_dim=30)
    d.imitate(T, Y[_medoid(Y)])
    d.configure(start_y=Y[:, 0].mean(axis=0), goal_y=Y[:, -1].mean(axis=0))
    return np.asarray(d.open_loop()[1])


def peer_gmr(demos: list[Demo]) -> np.ndarray:
    from gmr import GMM

    Y = _normalised(demos)
    T = np.linspace(0.0, 1.0, N_PEER)
    scale = max(float(np.ptp(Y.reshape(-1, 3), axis=0).max()), 1e-9)
    X = np.column_stack([np.tile(T, len(demos)), (Y.reshape(-1, 3) - Y[0, 0]) / scale])
    g = GMM(n_components=10, random_state=np.random.RandomState(0))
    g.from_samples(X)
    return np.asarray(g.predict(np.array([0]), T[:, None])) * scale + Y[0, 0]


def studio_path(mode: str) -> Callable[[list[Demo]], np.ndarray]:
    def fit(demos: list[Demo]) -> np.ndarray:
        return np.asarray(learn_path(demos, generalization=mode, rate_hz=200.0).position)

    return fit


FIT: dict[str, Callable[[list[Demo]], np.ndarray]] = {
    "mean": peer_mean,
    "DBA": peer_dba,
    "ProMP": peer_promp,
    "DMP": peer_dmp,
    "GMR": peer_gmr,
    "paper": studio_path("paper"),
}


# -- one set -----------------------------------------------------------------------------------------------------


def _folds(n: int) -> list[int]:
    return list(range(n)) if n <= 3 else sorted({round(x) for x in np.linspace(0, n - 1, 3)})


class Ref:
    """The demos' curves, spread and B1's Fréchet distance (shared by every method of one set)."""

    def __init__(self, demos: list[Demo]) -> None:
        self.demos = demos
        self.curves = [Q.curve(d) for d in demos]
        self.r = Q.spread(self.curves)[0]
        b1c = Q.arc_resample(Q.time_normalised_mean(demos))
        self.b1f = float(np.mean([Q.frechet(b1c, c) for c in self.curves]))
        self.start = np.mean([d.position[0] for d in demos], axis=0)
        self.end = np.mean([d.position[-1] for d in demos], axis=0)

    def score(self, pos: np.ndarray) -> dict:
        f = Q.fidelity(Q.arc_resample(pos), self.curves, r=self.r, b1_frechet=self.b1f)
        ends = max(np.linalg.norm(pos[0] - self.start), np.linalg.norm(pos[-1] - self.end))
        return {"G/R": f.g_over_r, "F/B1": f.f_over_b1, "ends": float(ends), "path": pos}

    def held_out(self, fit: Callable[[list[Demo]], np.ndarray]) -> float:
        out = []
        for i in _folds(len(self.demos)):
            try:
                p = fit([d for j, d in enumerate(self.demos) if j != i])
            except StudioError:
                return math.inf
            out.append(Q.ndtw(Q.arc_resample(p), self.curves[i]))
        return float(np.mean(out)) / self.r


def evaluate(demos: list[Demo], *, suggest: bool, held: bool = True) -> dict[str, dict]:
    ref = Ref(demos)
    res: dict[str, dict] = {}
    for name, fit in FIT.items():
        t0 = time.perf_counter()
        try:
            res[name] = ref.score(fit(demos))
        except StudioError as exc:
            res[name] = {"G/R": math.inf, "F/B1": math.inf, "ends": math.inf, "error": str(exc)}
        res[name]["held"] = ref.held_out(fit) if held else math.nan
        res[name]["seconds"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    sk = learn_skill(demos)
    d = res["default"] = ref.score(np.asarray(sk.trajectory.position))
    d["skill"] = sk
    d["held"] = ref.held_out(studio_path("aligned-mean")) if held else math.nan
    d["seconds"] = time.perf_counter() - t0
    size = Q.extent(demos)
    corners = Q.corner_checks(sk.trajectory, demos, size)
    d["corner"] = max((x.error for x in corners), default=math.nan)
    g, _ = Q.gripper_checks(sk.trajectory, demos)
    d["grip"] = max((x.error for x in g), default=math.nan)
    if suggest:
        t0 = time.perf_counter()
        tr = autotune.suggest(demos)
        sk2 = learn_skill(demos, tr.params, n_clusters=tr.n_clusters)
        res["suggest"] = ref.score(np.asarray(sk2.trajectory.position))
        res["suggest"].update(
            changed=tr.changed,
            seconds=time.perf_counter() - t0,
            before=tr.before.g_over_r,
            after=tr.after.g_over_r,
        )
        res["suggest"]["held"] = (
            ref.held_out(lambda dd: np.asarray(learn_path(dd, tr.params, n_clusters=tr.n_clusters).position))
            if held
            else math.nan
        )
    return res


# -- the sets ----------------------------------------------------------------------------------------------------


def shape_cases(quick: bool, sizes: tuple[float, ...] | None = None):
    """(label, size, demos, route labels or None)."""
    sizes = sizes or ((0.15,) if quick else (0.03, 0.15, 0.6))
    counts = (3,) if quick else (3, 7)
    tempos = (("careful", 2.0), ("loose", 1.5)) if quick else (("careful", 2.0), ("careful", 20.0), ("loose", 1.5))
    for shape, size, (style, dur), n in itertools.product(SHAPES, sizes, tempos, counts):
        spec = ShapeSpec(shape, size, dur, style=style)
        label = f"{shape} {size * 100:.0f} cm {style} {dur:g} s ×{n}"
        yield label, size, list(shape_demos(spec, n)), None


def route_cases(quick: bool, sizes: tuple[float, ...] | None = None):
    sizes = sizes or ((0.15,) if quick else (0.03, 0.15, 0.6))
    counts = (3,) if quick else (3, 7)
    styles = (("careful", 2.0), ("loose", 1.5)) if quick else (("careful", 2.0), ("careful", 8.0), ("loose", 1.5))
    for routes, size, (style, dur), n in itertools.product((2, 3), sizes, styles, counts):
        demos, labels = route_demos(routes, size, dur, n, style=style, seed=round(size * 100) + n)
        yield f"{routes} routes {size * 100:.0f} cm {style} {dur:g} s ×{n}", size, list(demos), labels


def task_cases(quick: bool):
    b = Baxter.load()
    counts = (3,) if quick else (3, 7)
    for task, arm in (("stack-cup", "left"), ("pick-place", "left"), ("pick-place", "both")):
        for n in counts:
            plans = [teach(task, s, arm=arm) for s in range(n)]
            for a in ("left", "right") if arm == "both" else (arm,):
                label = f"{task}{' both arms, ' + a if arm == 'both' else ''} ×{n}"
                yield label, None, [demo_from_recording(recording_from_plan(p), a, b) for p in plans], None


def _fmt(x: float | None, spec: str = ".2f") -> str:
    return "—" if x is None or not math.isfinite(x) else format(x, spec)


# -- routes ------------------------------------------------------------------------------------------------------


def route_check(res: dict, demos: list[Demo], truth: tuple[int, ...]) -> dict:
    """Were the routes found (the same grouping as the teacher's), does the learned path follow one route?"""
    sk = res["default"]["skill"]
    index = {d.name: i for i, d in enumerate(demos)}
    groups = [tuple(index[n] for n in r.demos) for r in sk.routes]
    want = sorted(tuple(i for i, t in enumerate(truth) if t == r) for r in sorted(set(truth)))
    found = sorted(groups) == want
    # the learned path is on one route: much closer to that route's demos than to any other route's
    c = Q.arc_resample(np.asarray(sk.trajectory.position))
    curves = [Q.curve(d) for d in demos]
    per_route = {r: np.mean([Q.frechet(c, curves[i]) for i, t in enumerate(truth) if t == r]) for r in set(truth)}
    near = min(per_route, key=lambda r: per_route[r])
    others = [v for r, v in per_route.items() if r != near]
    one = per_route[near] < 0.5 * min(others)
    return {"found": found, "one": one, "route": near}


# -- the tables --------------------------------------------------------------------------------------------------


def _row(label: str, res: dict, methods: list[str]) -> str:
    d = res["default"]
    cells = "".join(f"{_fmt(res[m]['G/R']):>6}{_fmt(res[m]['F/B1']):>6}{_fmt(res[m]['held']):>6} " for m in methods)
    return f"{label:<36}{cells}{_fmt(d['ends'] * 1000, '.2f'):>8}"


def _summary(rows: list[tuple[str, float | None, dict]], methods: list[str], title: str) -> None:
    print(f"\n-- {title}: {len(rows)} sets --")
    print(
        f"{'method':<9}{'med DTW':>9}{'med Fréchet':>12}{'worst Fré':>10}{'held-out':>9}{'ends mm':>9}"
        f"{'  default wins (DTW / Fréchet / held-out)':<40}"
    )
    for m in methods:
        g = np.array([x[2][m]["G/R"] for x in rows])
        f = np.array([x[2][m]["F/B1"] for x in rows])
        h = np.array([x[2][m]["held"] for x in rows])
        e = np.array([x[2][m]["ends"] for x in rows])
        wins = ""
        if m != "default":
            dg = np.array([x[2]["default"]["G/R"] for x in rows])
            df = np.array([x[2]["default"]["F/B1"] for x in rows])
            dh = np.array([x[2]["default"]["held"] for x in rows])
            wins = f"  {int(np.sum(dg < g))} / {int(np.sum(df < f))} / {int(np.sum(dh < h))} of {len(rows)}"
        print(
            f"{m:<9}{_fmt(float(np.median(g)), '.3f'):>9}{_fmt(float(np.median(f)), '.3f'):>12}"
            f"{_fmt(float(np.max(f)), '.3f'):>10}{_fmt(float(np.nanmedian(h)), '.3f'):>9}"
            f"{_fmt(float(np.max(e)) * 1000, '.2f'):>9}{wins}"
        )
    d = {k: np.array([x[2]["default"][k] for x in rows]) for k in ("G/R", "F/B1", "held", "ends")}
    ahead = []
    for m in methods:
        if m == "default":
            continue
        p = {k: np.array([x[2][m][k] for x in rows]) for k in ("G/R", "F/B1", "held")}
        ok = (
            np.median(d["G/R"]) < np.median(p["G/R"])
            and np.median(d["F/B1"]) < np.median(p["F/B1"])
            and np.max(d["F/B1"]) < np.max(p["F/B1"])
            and np.nanmedian(d["held"]) < np.nanmedian(p["held"])
        )
        ahead.append(f"{m} {'ahead' if ok else 'NOT ahead'}")
    print("  default vs peers (median DTW, median and worst Fréchet, held-out DTW): " + ", ".join(ahead))
    print(f"  default end error: worst {float(np.max(d['ends'])) * 1000:.3f} mm (target 0.1 mm)")


def quality_suite(
    quick: bool, suggest: bool, sizes: tuple[float, ...] | None = None, tasks: bool = True, held: bool = True
) -> None:
    methods = [*PEERS, *STUDIO, *(["suggest"] if suggest else [])]
    rows: list[tuple[str, float | None, dict]] = []
    routes: list[tuple[str, float | None, dict, dict]] = []
    print("\n== quality: per set, per method DTW ratio, Fréchet ratio, held-out DTW ratio ==")
    print(f"{'set':<36}" + "".join(f"{m:>18} " for m in methods) + f"{'ends mm':>8}")
    t0 = time.perf_counter()
    cases = itertools.chain(
        shape_cases(quick, sizes), route_cases(quick, sizes), task_cases(quick) if tasks and not sizes else ()
    )
    for label, size, demos, truth in cases:
        res = evaluate(demos, suggest=suggest, held=held)
        line = _row(label, res, methods)
        if truth is not None:
            rc = route_check(res, demos, truth)
            routes.append((label, size, res, rc))
            line += f"  routes {'found' if rc['found'] else 'MISSED'}, {'one route' if rc['one'] else 'BETWEEN'}"
        else:
            rows.append((label, size, res))
        print(line, flush=True)
    print(f"({len(rows) + len(routes)} sets in {time.perf_counter() - t0:.0f} s)")
    print("\n== summary ==")
    shapes = [x for x in rows if x[1] is not None]
    for size in sorted({x[1] for x in shapes}):
        for n in (3, 7):
            sub = [x for x in shapes if x[1] == size and x[0].endswith(f"×{n}")]
            if sub:
                _summary(sub, methods, f"human-like shapes, {size * 100:.0f} cm, {n} demos")
    if shapes:
        _summary(shapes, methods, "human-like shapes, all")
    tk = [x for x in rows if x[1] is None]
    if tk:
        _summary(tk, methods, "the scripted teacher's tasks")
    if routes:
        _summary([(a, b, c) for a, b, c, _ in routes], methods, "multi-modal sets (measured against every demo)")
        found = sum(x[3]["found"] for x in routes)
        one = sum(x[3]["one"] for x in routes)
        print(f"  routes found in {found} of {len(routes)} sets ({100 * found / len(routes):.0f} %, target ≥ 95 %);")
        print(f"  the learned path follows one route in {one} of {len(routes)}")
    if suggest:
        secs = [x[2]["suggest"]["seconds"] for x in rows]
        worse = [x[0] for x in rows if x[2]["suggest"]["held"] > x[2]["default"]["held"] * 1.0001]
        changed = sum(bool(x[2]["suggest"]["changed"]) for x in rows)
        print(
            f"  Suggest: median {statistics.median(secs):.1f} s a set (max {max(secs):.1f} s); changed the thresholds "
            f"in {changed} of {len(rows)} sets; held-out DTW worse than the default in {len(worse)} "
            + (f"({', '.join(worse[:5])})" if worse else "")
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
    results = {}
    for label, w in (
        ("in this process (1 core)", 1),
        (f"{autotune.WORKERS} forked worker processes", autotune.WORKERS),
    ):
        autotune.shutdown()  # forget the demos: a first search
        t0 = time.perf_counter()
        autotune.suggest(demos, workers=w)
        first = time.perf_counter() - t0
        t0 = time.perf_counter()
        r = autotune.suggest(demos, workers=w)
        again = time.perf_counter() - t0
        results[label] = (first, again)
        print(
            f"Suggest, {label}: first search {first:5.2f} s, same demos again {again:5.2f} s  (budget 5 s; "
            f"{r.evaluated} candidates × {min(3, len(demos))} folds)"
        )
    (f1, _), (f2, _) = results.values()
    print(f"  workers ÷ one process, first search: ×{f1 / f2:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="a subset (15 cm, 2 s, 3 demos; tasks with 3 demos)")
    ap.add_argument("--no-suggest", action="store_true", help="skip Suggest in the quality suite")
    ap.add_argument("--skip-timing", action="store_true")
    ap.add_argument("--skip-quality", action="store_true")
    ap.add_argument("--sizes", type=float, nargs="+", help="shape sizes in metres, 0.005-0.8 (default 0.03 0.15 0.6)")
    ap.add_argument("--no-tasks", action="store_true", help="only the shapes (e.g. with --sizes 0.8)")
    ap.add_argument("--no-held", action="store_true", help="skip the held-out figures (faster)")
    args = ap.parse_args()
    print(f"machine: {_load()} at start (2 cores shared)")
    if not args.skip_timing:
        timing(args.quick)
    if not args.skip_quality:
        quality_suite(
            args.quick,
            not args.no_suggest,
            tuple(args.sizes) if args.sizes else None,
            not args.no_tasks,
            not args.no_held,
        )
    autotune.shutdown()


if __name__ == "__main__":
    main()
