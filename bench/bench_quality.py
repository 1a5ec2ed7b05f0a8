"""Quality benchmark: the learned skill against the demonstrations and against peer methods, in one run.

    bash scripts/bootstrap.sh "test,bench"   # the peers: tslearn, movement-primitives, gmr
    nice -n 5 .venv/bin/python bench/bench_quality.py --jobs 2 --out /tmp/quality.json [--quick] [--no-suggest]
    .venv/bin/python bench/bench_quality.py --report /tmp/quality.json   # the tables again, nothing computed

Sets (human-like teacher, :mod:`studio.shapes`): six shapes at 3, 15 and 60 cm, 3 and 7 demos, drawn
"careful" in 2 s and in 20 s and "loose" in 1.5 s (pen lands away from the start, no rest at the ends);
multi-modal sets: 2 or 3 routes around obstacles at the same sizes, 3 and 7 demos, both styles; the
scripted teacher's tasks (stack-cup, pick-place, both arms). ``--seed`` draws other demonstrations.

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
Where the default's F/B1 is above 1, the least F/B1 any path that starts and ends on the demos' mean can have.
Multi-modal: routes found; each method measured against the demos of the route its path is nearest to, and
whether it follows one route (not between them).

Speed: every process computes with one BLAS thread (several threads spin against each other on a loaded
machine: gmr's EM took 20× longer); ``--jobs`` runs sets in forked processes; the peers' results are kept
per set of demonstrations in ``--cache`` (they do not change when the studio does).
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import logging
import math
import multiprocessing
import os
import resource
import statistics
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor, as_completed, wait
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _timer import median_ms

from studio.core import autotune
from studio.core import quality as Q
from studio.core.caches import LearningCaches
from studio.core.errors import StudioError
from studio.core.keypoints import KeypointCache
from studio.core.kinematics import Baxter
from studio.core.learn_settings import LearnSettings
from studio.core.pipeline import demo_from_recording, learn_path, learn_skill, preview_path
from studio.core.thresholds import auto_params
from studio.core.types import Demo
from studio.shapes import SHAPES, ShapeSpec, route_demos, shape_demos
from studio.teacher import recording_from_plan, teach

PEERS = ("mean", "DBA", "ProMP", "DMP", "GMR", "paper")
STUDIO = ("default",)
N_PEER = 250
#: Change it when a peer's fit or a measure changes: the peers' cache is keyed on it.
PEER_VERSION = "2"
CACHE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "teaching-studio" / "bench-quality"
#: Two figures closer than this count as a tie.
TIE = 5e-4


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
        return np.asarray(learn_path(demos, LearnSettings(generalization=mode), rate_hz=200.0).position)

    return fit


FIT: dict[str, Callable[[list[Demo]], np.ndarray]] = {
    "mean": peer_mean,
    "DBA": peer_dba,
    "ProMP": peer_promp,
    "DMP": peer_dmp,
    "GMR": peer_gmr,
    "paper": studio_path("paper"),
}
#: Methods whose results are kept in the cache (the studio's own are always computed again).
CACHED = ("mean", "DBA", "ProMP", "DMP", "GMR")


# -- the sets ----------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One set of demonstrations: ``kind`` "shape", "routes" or "task"; ``what`` the shape, the number of routes
    or the task; the demos are drawn in the process that measures them."""

    kind: str
    what: str
    size: float | None
    style: str
    dur: float
    n: int
    seed: int = 0
    arm: str = "left"
    side: str = "left"

    @property
    def label(self) -> str:
        if self.kind == "task":
            both = f" both arms, {self.side}" if self.arm == "both" else ""
            return f"{self.what}{both} ×{self.n}"
        size = f"{(self.size or 0) * 100:.3g} cm"
        head = self.what if self.kind == "shape" else f"{self.what} routes"
        return f"{head} {size} {self.style} {self.dur:g} s ×{self.n}"

    def demos(self) -> tuple[list[Demo], tuple[int, ...] | None]:
        if self.kind == "shape":
            spec = ShapeSpec(self.what, float(self.size or 0), self.dur, style=self.style)
            return list(shape_demos(spec, self.n, first_seed=self.seed)), None
        if self.kind == "routes":
            size = float(self.size or 0)
            demos, labels = route_demos(
                int(self.what), size, self.dur, self.n, style=self.style, seed=round(size * 100) + self.n + self.seed
            )
            return list(demos), labels
        b = Baxter.load()
        plans = [teach(self.what, self.seed + s, arm=self.arm) for s in range(self.n)]
        return [demo_from_recording(recording_from_plan(p), self.side, b) for p in plans], None


def cases(
    quick: bool, sizes: tuple[float, ...] | None, counts: tuple[int, ...] | None, kinds: tuple[str, ...], seed: int
) -> Iterator[Case]:
    sizes = sizes or ((0.15,) if quick else (0.03, 0.15, 0.6))
    counts = counts or ((3,) if quick else (3, 7))
    if "shapes" in kinds:
        tempos = (("careful", 2.0), ("loose", 1.5)) if quick else (("careful", 2.0), ("careful", 20.0), ("loose", 1.5))
        for size, n, shape, (style, dur) in itertools.product(sizes, counts, SHAPES, tempos):
            yield Case("shape", shape, size, style, dur, n, seed)
    if "routes" in kinds:
        styles = (("careful", 2.0), ("loose", 1.5)) if quick else (("careful", 2.0), ("careful", 8.0), ("loose", 1.5))
        for size, n, routes, (style, dur) in itertools.product(sizes, counts, ("2", "3"), styles):
            yield Case("routes", routes, size, style, dur, n, seed)
    if "tasks" in kinds:
        for n, (task, arm) in itertools.product(
            counts, (("stack-cup", "left"), ("pick-place", "left"), ("pick-place", "both"))
        ):
            for side in ("left", "right") if arm == "both" else (arm,):
                yield Case("task", task, None, "", 0.0, n, seed, arm, side)


# -- measuring one set -------------------------------------------------------------------------------------------


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
        # No path that starts and ends on the demos' mean can be nearer a demo than its ends are.
        ends = [max(np.linalg.norm(self.start - c[0]), np.linalg.norm(self.end - c[-1])) for c in self.curves]
        self.floor = float(np.mean(ends)) / self.b1f if self.b1f > 0 else math.nan

    def score(self, pos: np.ndarray, among: list[int] | None = None) -> dict[str, float]:
        """G/R, F/B1 and the start/end error; ``among``: against these demos only (the ratios keep the whole
        set's spread and B1, so methods compare on one scale)."""
        curves = self.curves if among is None else [self.curves[i] for i in among]
        f = Q.fidelity(Q.arc_resample(pos), curves, r=self.r, b1_frechet=self.b1f)
        start, end = self.start, self.end
        if among is not None:  # the ends of the demos it follows
            start = np.mean([self.demos[i].position[0] for i in among], axis=0)
            end = np.mean([self.demos[i].position[-1] for i in among], axis=0)
        ends = max(np.linalg.norm(pos[0] - start), np.linalg.norm(pos[-1] - end))
        return {
            "G/R": f.g_over_r,
            "F/B1": f.f_over_b1,
            "ends": float(ends),
            "floor": self.floor if among is None else math.nan,
        }

    def held_out(self, fit: Callable[[list[Demo]], np.ndarray]) -> float:
        out = []
        for i in _folds(len(self.demos)):
            try:
                p = fit([d for j, d in enumerate(self.demos) if j != i])
            except StudioError:
                return math.inf
            out.append(Q.ndtw(Q.arc_resample(p), self.curves[i]))
        return float(np.mean(out)) / self.r


def _fingerprint(demos: list[Demo]) -> str:
    h = hashlib.blake2b(digest_size=16)
    h.update(PEER_VERSION.encode())
    for d in demos:
        for a in (d.t, d.position, d.orientation, d.gripper):
            h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()


class PeerCache:
    """The peers' results per set of demonstrations, one JSON file each (written whole, then renamed)."""

    def __init__(self, root: Path | None) -> None:
        self.root = root

    def get(self, key: str, method: str) -> dict | None:
        if self.root is None:
            return None
        f = self.root / f"{key}-{method}.json"
        try:
            return json.loads(f.read_text())
        except (OSError, ValueError):
            return None

    def put(self, key: str, method: str, value: dict) -> None:
        if self.root is None:
            return
        self.root.mkdir(parents=True, exist_ok=True)
        tmp = self.root / f".{key}-{method}.{os.getpid()}.tmp"
        tmp.write_text(json.dumps(value))
        tmp.replace(self.root / f"{key}-{method}.json")


def _nearest(pos: np.ndarray, curves: list[np.ndarray], truth: tuple[int, ...]) -> tuple[int, bool]:
    """The route a path is nearest to (mean Fréchet to its demos) and whether it follows that route alone (less
    than half as far from it as from any other)."""
    c = Q.arc_resample(pos)
    per = {r: float(np.mean([Q.frechet(c, curves[i]) for i, t in enumerate(truth) if t == r])) for r in set(truth)}
    near = min(per, key=lambda r: per[r])
    return near, per[near] < 0.5 * min(v for r, v in per.items() if r != near)


def _measure(
    fit: Callable[[list[Demo]], np.ndarray],
    ref: Ref,
    held: bool,
    truth: tuple[int, ...] | None = None,
) -> dict[str, Any]:
    t0 = time.perf_counter()
    try:
        pos = fit(ref.demos)
    except StudioError as exc:
        return {"G/R": math.inf, "F/B1": math.inf, "ends": math.inf, "held": math.nan, "error": str(exc)}
    out: dict[str, Any] = ref.score(pos)
    if truth is not None:  # against the demos of the route it follows
        near, one = _nearest(pos, ref.curves, truth)
        out.update(ref.score(pos, [i for i, t in enumerate(truth) if t == near]), route=near, one=one, held=math.nan)
    else:
        out["held"] = ref.held_out(fit) if held else math.nan
    out["seconds"] = time.perf_counter() - t0
    return out


def evaluate(case: Case, *, suggest: bool, held: bool, cache: PeerCache) -> dict[str, Any]:
    """Every method on one set: {"res": {method: figures}, "found": routes found…} (JSON-able)."""
    t_start = time.perf_counter()
    demos, truth = case.demos()
    ref = Ref(demos)
    key = _fingerprint(demos) + ("-r" if truth else "") + ("-h" if held else "")
    res: dict[str, dict[str, Any]] = {}
    for name, fit in FIT.items():
        hit = cache.get(key, name) if name in CACHED else None
        res[name] = hit if hit is not None else _measure(fit, ref, held, truth)
        if hit is None and name in CACHED:
            cache.put(key, name, res[name])
    t0 = time.perf_counter()
    sk = learn_skill(demos)
    pos = np.asarray(sk.trajectory.position)
    d = res["default"] = _measure(lambda _: pos, ref, False, truth)
    if held and truth is None:
        d["held"] = ref.held_out(studio_path("aligned-mean"))
    d["seconds"] = time.perf_counter() - t0
    size = Q.extent(demos)
    d["corner"] = max((x.error for x in Q.corner_checks(sk.trajectory, demos, size)), default=math.nan)
    d["grip"] = max((x.error for x in Q.gripper_checks(sk.trajectory, demos)[0]), default=math.nan)
    row: dict[str, Any] = {"case": asdict(case), "label": case.label, "res": res}
    if truth is not None:
        index = {x.name: i for i, x in enumerate(demos)}
        groups = sorted(tuple(index[n] for n in r.demos) for r in sk.routes)
        want = sorted(tuple(i for i, t in enumerate(truth) if t == r) for r in sorted(set(truth)))
        row["found"] = groups == want
    if suggest and truth is None:
        row["res"]["suggest"] = _suggest(demos, ref, held)
    row["seconds"] = time.perf_counter() - t_start
    return row


def _suggest(demos: list[Demo], ref: Ref, held: bool) -> dict[str, Any]:
    t0 = time.perf_counter()
    tr = autotune.suggest(demos)
    secs = time.perf_counter() - t0
    sk2 = learn_skill(demos, LearnSettings(params=tr.params, n_clusters=tr.n_clusters))
    out: dict[str, Any] = ref.score(np.asarray(sk2.trajectory.position))
    out.update(changed=tr.changed, seconds=secs, before=tr.before.g_over_r, after=tr.after.g_over_r)
    # held out as the default's figure is (studio_path): the thresholds resolved on the demos each fold learns
    # from, the same rate (the very same figure when Suggest kept the thresholds)
    out["held"] = (
        ref.held_out(
            lambda dd: np.asarray(
                learn_path(
                    dd, LearnSettings(params=tr.settings.resolve(dd), n_clusters=tr.n_clusters), rate_hz=200.0
                ).position
            )
        )
        if held
        else math.nan
    )
    return out


def _fmt(x: float | None, spec: str = ".2f") -> str:
    return "—" if x is None or not math.isfinite(x) else format(x, spec)


# -- the tables --------------------------------------------------------------------------------------------------


def _row(row: dict, methods: list[str]) -> str:
    res = row["res"]
    cells = "".join(
        f"{_fmt(res[m]['G/R']):>6}{_fmt(res[m]['F/B1']):>6}{_fmt(res[m]['held']):>6} " for m in methods if m in res
    )
    line = f"{row['label']:<36}{cells}{_fmt(res['default']['ends'] * 1000, '.2f'):>8}"
    if "found" in row:
        on = "one route" if res["default"].get("one") else "BETWEEN"
        line += f"  routes {'found' if row['found'] else 'MISSED'}, {on}"
    return line


def _compare(d: np.ndarray, p: np.ndarray, worst: bool = False) -> str:
    a, b = (float(np.max(d)), float(np.max(p))) if worst else (float(np.nanmedian(d)), float(np.nanmedian(p)))
    if not (math.isfinite(a) and math.isfinite(b)):
        return "—"
    if abs(a - b) <= TIE:
        return "tied"
    return "ahead" if a < b else f"behind by {a - b:.3f}"


def summary(rows: list[dict], methods: list[str], title: str, held: bool = True) -> None:
    methods = [m for m in methods if all(m in r["res"] for r in rows)]
    print(f"\n-- {title}: {len(rows)} sets --")
    print(
        f"{'method':<9}{'med DTW':>9}{'med Fréchet':>12}{'worst Fré':>10}{'held-out':>9}{'ends mm':>9}"
        f"{'  default wins (DTW / Fréchet / held-out)':<40}"
    )

    def col(m: str, k: str) -> np.ndarray:
        return np.array([r["res"][m][k] for r in rows], dtype=float)

    for m in methods:
        g, f, h, e = (col(m, k) for k in ("G/R", "F/B1", "held", "ends"))
        wins = ""
        if m != "default":
            dg, df, dh = (col("default", k) for k in ("G/R", "F/B1", "held"))
            wins = f"  {int(np.sum(dg < g))} / {int(np.sum(df < f))} / {int(np.sum(dh < h))} of {len(rows)}"
        one = ""
        if "one" in rows[0]["res"][m]:
            one = f"  on one route in {sum(bool(r['res'][m].get('one')) for r in rows)}"
        hm = float(np.nanmedian(h)) if held and np.isfinite(h).any() else math.nan
        print(
            f"{m:<9}{_fmt(float(np.median(g)), '.3f'):>9}{_fmt(float(np.median(f)), '.3f'):>12}"
            f"{_fmt(float(np.max(f)), '.3f'):>10}{_fmt(hm, '.3f'):>9}"
            f"{_fmt(float(np.max(e)) * 1000, '.2f'):>9}{wins}{one}"
        )
    for m in methods:
        if m == "default":
            continue
        parts = [
            f"DTW {_compare(col('default', 'G/R'), col(m, 'G/R'))}",
            f"Fréchet {_compare(col('default', 'F/B1'), col(m, 'F/B1'))}",
            f"worst Fréchet {_compare(col('default', 'F/B1'), col(m, 'F/B1'), worst=True)}",
        ]
        if held:
            parts.append(f"held-out {_compare(col('default', 'held'), col(m, 'held'))}")
        print(f"  default vs {m}: " + ", ".join(parts))
    print(f"  default end error: worst {float(np.max(col('default', 'ends'))) * 1000:.3f} mm (target 0.1 mm)")
    floor = np.array([r["res"]["default"].get("floor", math.nan) for r in rows], dtype=float)
    f = col("default", "F/B1")
    above = [i for i in range(len(rows)) if f[i] > 1.0 + TIE]
    if above and np.isfinite(floor).any():
        at = [i for i in above if f[i] - floor[i] <= TIE]
        print(
            f"  default Fréchet ratio above the plain mean's in {len(above)} sets; in {len(at)} of them no path that "
            "starts and ends on the demos' mean can be nearer: "
            + ", ".join(f"{rows[i]['label']} {f[i]:.4f} (least {floor[i]:.4f})" for i in above)
        )


def report(rows: list[dict], suggest: bool) -> None:
    methods = [*PEERS, *STUDIO, *(["suggest"] if suggest else [])]
    print("\n== summary ==")
    kinds = {k: [r for r in rows if r["case"]["kind"] == k] for k in ("shape", "routes", "task")}
    shapes = kinds["shape"]
    for size in sorted({r["case"]["size"] for r in shapes}):
        for n in sorted({r["case"]["n"] for r in shapes}):
            sub = [r for r in shapes if r["case"]["size"] == size and r["case"]["n"] == n]
            if sub:
                summary(sub, methods, f"human-like shapes, {size * 100:.3g} cm, {n} demos")
    if shapes:
        summary(shapes, methods, "human-like shapes, all")
        for style, dur in sorted({(r["case"]["style"], r["case"]["dur"]) for r in shapes}):
            sub = [r for r in shapes if r["case"]["style"] == style and r["case"]["dur"] == dur]
            summary(sub, methods, f"human-like shapes, {style} {dur:g} s")
    if kinds["task"]:
        summary(kinds["task"], methods, "the scripted teacher's tasks")
    routes = kinds["routes"]
    if routes:
        summary(
            routes, methods, "multi-modal sets (against the demos of the route each path is nearest to)", held=False
        )
        found = sum(bool(r["found"]) for r in routes)
        print(f"  routes found in {found} of {len(routes)} sets ({100 * found / len(routes):.0f} %, target ≥ 95 %)")
    if suggest:
        sg = [r for r in rows if "suggest" in r["res"] and r["case"]["kind"] != "routes"]
        secs = [r["res"]["suggest"]["seconds"] for r in sg]
        worse = [r["label"] for r in sg if r["res"]["suggest"]["held"] > r["res"]["default"]["held"] * 1.0001]
        changed = sum(bool(r["res"]["suggest"]["changed"]) for r in sg)
        print(
            f"  Suggest (one process): median {statistics.median(secs):.1f} s a set (max {max(secs):.1f} s); changed "
            f"the thresholds in {changed} of {len(sg)} sets; held-out DTW worse than the default's in {len(worse)}"
            + (f" ({', '.join(worse[:5])})" if worse else "")
        )


def _work(case: Case, suggest: bool, held: bool, cache_dir: str | None) -> dict:
    return evaluate(case, suggest=suggest, held=held, cache=PeerCache(Path(cache_dir) if cache_dir else None))


def _warm() -> None:
    """Compile tslearn's numba code once, before the workers fork (each would compile it again)."""
    peer_dba(list(shape_demos(ShapeSpec("circle", 0.15, 1.0), 2)))


def quality_suite(args: argparse.Namespace) -> list[dict]:
    suggest, held = not args.no_suggest, not args.no_held
    methods = [*PEERS, *STUDIO, *(["suggest"] if suggest else [])]
    kinds = tuple(k for k in ("shapes", "routes", "tasks") if k not in (args.skip or ()))
    todo = list(
        cases(args.quick, tuple(args.sizes) if args.sizes else None, tuple(args.counts or ()), kinds, args.seed)
    )
    cache_dir = None if args.no_cache else str(args.cache)
    print(f"\n== quality: {len(todo)} sets, per method DTW ratio, Fréchet ratio, held-out DTW ratio ==")
    print(f"{'set':<36}" + "".join(f"{m:>18} " for m in methods) + f"{'ends mm':>8}")
    t0 = time.perf_counter()
    rows: list[dict] = []
    if args.jobs > 1:
        _warm()
        ctx = multiprocessing.get_context("fork")
        with ProcessPoolExecutor(args.jobs, mp_context=ctx) as pool:
            futs = [pool.submit(_work, c, suggest, held, cache_dir) for c in todo]
            for f in as_completed(futs):
                rows.append(f.result())
                print(_row(rows[-1], methods), flush=True)
    else:
        for c in todo:
            rows.append(_work(c, suggest, held, cache_dir))
            print(_row(rows[-1], methods), flush=True)
    order = {c.label + str(c.seed): i for i, c in enumerate(todo)}
    rows.sort(key=lambda r: order[r["label"] + str(r["case"]["seed"])])
    print(f"({len(rows)} sets in {time.perf_counter() - t0:.0f} s, {_load()})")
    return rows


def _long_demos() -> list[Demo]:
    """3 demos × 30,000 samples: handwriting loops, 15 cm, drawn in ~28 s (1 kHz)."""
    return [replace_name(d) for d in shape_demos(ShapeSpec("handwriting", 0.15, 28.0), 3)]


def replace_name(d: Demo) -> Demo:
    n = min(len(d), 30_000)
    return Demo(d.t[:n], d.position[:n], d.orientation[:n], d.gripper[:n], name=d.name)


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
        ms = median_ms(lambda b=b: slider(b), rep)
        print(f"slider move (re-extract + re-cluster), k-means {b:<8}: median {ms:6.1f} ms  (budget 30 ms)")
    caches = LearningCaches(cache)
    preview_path(demos, LearnSettings(params=base), caches=caches)  # DTW maps cached, as during a slider drag

    def prev() -> None:
        nonlocal i
        i += 1
        moved = replace(base, eps5=base.eps5 * (1.0 + 0.05 * (i % 5)))
        preview_path(demos, LearnSettings(params=moved), caches=caches)

    print(f"live preview path (preview_path, warm caches): median {median_ms(prev, rep):6.1f} ms  (budget 150 ms)")
    ms = median_ms(lambda: learn_skill(demos, LearnSettings(params=base), caches=caches), max(3, rep // 3))
    print(f"learn_skill (warm key-point cache):            median {ms:6.1f} ms")
    suggest_timing(demos, 1 if quick else 3)


def _quiet() -> None:
    logging.getLogger("hmmlearn").setLevel(logging.ERROR)  # as the studio's processes (studio/cli.py)


def _cpu() -> float:
    """CPU seconds of this process and of its children that ended (what a quiet machine would take)."""
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + ch.ru_utime + ch.ru_stime


def suggest_timing(demos: list[Demo], repeat: int) -> None:
    """Suggest where the studio runs it (the calling thread, or an executor the caller gives): a first search
    (new demos) and the same demos again, against the calling thread alone in the same run. The CPU seconds of
    the calling thread's search are what it takes on a quiet core (the wall time here waits for the CPU)."""
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
        cpu: list[float] = []
        for rep in range(repeat):
            for label, ex in where.items():
                renamed = [
                    Demo(d.t, d.position, d.orientation, d.gripper, name=f"{d.name}-{label}-{rep}") for d in demos
                ]
                c0, t0 = _cpu(), time.perf_counter()
                r = autotune.suggest(renamed, executor=ex)
                firsts[label].append(time.perf_counter() - t0)
                if ex is None:
                    cpu.append(_cpu() - c0)
                t0 = time.perf_counter()
                autotune.suggest(renamed, executor=ex)
                agains[label].append(time.perf_counter() - t0)
    base = statistics.median(firsts["in the calling thread"])
    for label in where:
        first, again = statistics.median(firsts[label]), statistics.median(agains[label])
        print(
            f"Suggest, {label:<33}: first search {first:5.2f} s (×{first / base:4.2f}), same demos again {again:5.2f} s"
            f"  (median of {repeat}; {r.evaluated} candidates × {min(3, len(demos))} folds, "
            f"{'complete' if r.complete else 'CUT SHORT'})"
        )
    print(
        f"Suggest in the calling thread, CPU: median {statistics.median(cpu):5.2f} s (budget 2 s on a quiet machine; "
        f"{_load()})"
    )


def why_loose(sizes: tuple[float, ...] | None, counts: tuple[int, ...] | None, seed: int) -> None:
    """Per demonstration of each "loose" set: the default's and B1's Fréchet distance and the part its start
    forces (any path that starts at the demos' mean start is at least that far from a demo that lands elsewhere)."""
    print("\n# Why the worst Fréchet ratio sits at 1.00 on loose sets (per demo: default / B1 / start bound, mm)")
    tally = {"start-bound (tie)": 0, "default closer": 0, "B1 closer": 0}
    excess: list[float] = []
    for case in cases(False, sizes, counts, ("shapes",), seed):
        if case.style != "loose":
            continue
        demos, _ = case.demos()
        ref = Ref(demos)
        pos = np.asarray(learn_skill(demos).trajectory.position)
        ours = Q.arc_resample(pos)
        b1 = Q.arc_resample(Q.time_normalised_mean(demos))
        cells = []
        for c in ref.curves:
            fo, fb = Q.frechet(ours, c), Q.frechet(b1, c)
            bound = float(np.linalg.norm(ours[0] - c[0]))
            kind = (
                "start-bound (tie)"
                if abs(fo - fb) <= 1e-4 + 0.002 * fb
                else ("default closer" if fo < fb else "B1 closer")
            )
            tally[kind] += 1
            if kind == "B1 closer":
                excess.append((fo - fb) / max(fb, 1e-12))
            cells.append(f"{fo * 1e3:.1f}/{fb * 1e3:.1f}/{bound * 1e3:.1f}")
        ratio = ref.score(pos)["F/B1"]
        print(f"{case.label:34s} F/B1 {ratio:.3f}  " + "  ".join(cells), flush=True)
    print("demos:", tally)
    if excess:
        print(f"where B1 is closer: by {np.median(excess) * 100:.1f} % (median), {max(excess) * 100:.1f} % (largest)")


#: One BLAS thread per process (set before numpy loads: the bench runs itself again with them when missing).
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def main() -> None:
    if any(os.environ.get(k) != v for k, v in ONE_THREAD.items()):
        os.execve(sys.executable, [sys.executable, *sys.argv], {**os.environ, **ONE_THREAD})
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="a subset (15 cm, 2 s, 3 demos; tasks with 3 demos)")
    ap.add_argument("--no-suggest", action="store_true", help="skip Suggest in the quality suite")
    ap.add_argument("--skip-timing", action="store_true")
    ap.add_argument("--skip-quality", action="store_true")
    ap.add_argument("--sizes", type=float, nargs="+", help="shape sizes in metres, 0.005-0.8 (default 0.03 0.15 0.6)")
    ap.add_argument("--counts", type=int, nargs="+", help="demos per set (default 3 7)")
    ap.add_argument("--skip", nargs="+", choices=("shapes", "routes", "tasks"), help="leave out these kinds of sets")
    ap.add_argument("--seed", type=int, default=0, help="draw other demonstrations (default 0)")
    ap.add_argument("--no-held", action="store_true", help="skip the held-out figures (faster)")
    ap.add_argument("--jobs", type=int, default=1, help="sets measured at once in forked processes")
    ap.add_argument("--cache", type=Path, default=CACHE, help=f"the peers' results (default {CACHE})")
    ap.add_argument("--no-cache", action="store_true", help="compute the peers again, keep nothing")
    ap.add_argument("--out", type=Path, help="write every set's figures as JSON (for --report)")
    ap.add_argument("--report", type=Path, help="print the tables of a --out file; compute nothing")
    ap.add_argument("--why-loose", action="store_true", help="per demo of the loose sets: what sets the Fréchet ratio")
    args = ap.parse_args()
    if args.report:
        data = json.loads(args.report.read_text())
        report(data["rows"], data["suggest"])
        return
    _quiet()
    print(f"machine: {_load()} at start (2 cores shared)")
    if args.why_loose:
        why_loose(tuple(args.sizes) if args.sizes else None, tuple(args.counts) if args.counts else None, args.seed)
        return
    if not args.skip_timing:
        timing(args.quick)
    if not args.skip_quality:
        rows = quality_suite(args)
        if args.out:
            args.out.write_text(json.dumps({"argv": sys.argv[1:], "suggest": not args.no_suggest, "rows": rows}))
        report(rows, not args.no_suggest)
    autotune.shutdown()


if __name__ == "__main__":
    main()
