"""What "not farther than the plain mean" (decision 083) costs: learn_skill and the live preview with it and
without it (the share patched to 0), alternating in one process; the guard's memory emptied before each cold run.

    .venv/bin/python bench/bench_guard.py [--repeat 5]

Sets: 7 loosely drawn 15 cm spirals (1.5 s each; the guard moves this path), the scripted teacher's pick-place
× 3 (1 kHz, ~22 s each); Suggest's CPU on 3 × 30,000 samples (bench_suggest's demos, renamed each time so nothing
is cached). Medians; ratios against "without" from the same run.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import statistics
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import studio.core.generalize as G
import studio.core.pipeline as P
from studio.core.caches import LearningCaches
from studio.core.kinematics import Baxter
from studio.core.learn_settings import LearnSettings
from studio.core.thresholds import auto_params
from studio.core.types import Demo
from studio.shapes import ShapeSpec, shape_demos
from studio.teacher import recording_from_plan, teach
from tests.core.execution_demos import hard_cartesian_pick_place


def _sets() -> dict[str, list[Demo]]:
    b = Baxter.load()
    tasks = [P.demo_from_recording(recording_from_plan(teach("pick-place", s)), "left", b) for s in range(3)]
    return {
        "loose spiral 15 cm × 7": list(shape_demos(ShapeSpec("spiral", 0.15, 1.5, style="loose"), 7)),
        "pick-place × 3 (1 kHz)": tasks,
        "issue 19's hard pick-place, seed 11": list(hard_cartesian_pick_place(11)),
    }


@contextlib.contextmanager
def _share(decide: Callable[..., float]) -> Iterator[Callable[..., float]]:
    """The guard's decision replaced by ``decide`` (:func:`_off`: never moved) inside the block; yields the studio's."""
    plain = G._plain_mean_share
    G._plain_mean_share = decide
    try:
        yield plain
    finally:
        G._plain_mean_share = plain


def _off(*a: Any) -> float:
    return 0.0


def _largest_move(demos: list[Demo]) -> float:
    """The most the guard moves the learned path at one instant, m."""
    with _share(_off):
        without = P.learn_skill(demos).trajectory.position
    return float(np.max(np.linalg.norm(P.learn_skill(demos).trajectory.position - without, axis=1)))


def _median_s(run: Callable[[], object], repeat: int, before: Callable[[], None]) -> float:
    out = []
    for _ in range(repeat):
        before()
        t0 = time.perf_counter()
        run()
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def _suggest_cpu(repeat: int) -> dict[str, float]:
    from bench_quality import _long_demos
    from bench_suggest import _renamed

    from studio.core import autotune

    demos = _long_demos()
    cpu: dict[str, list[float]] = {"without": [], "with": []}
    for rep in range(repeat):
        for label, decide in (("without", _off), ("with", G._plain_mean_share)):
            with _share(decide):
                ds = _renamed(demos, f"{label}-{rep}")
                c0 = time.process_time()
                autotune.suggest(ds, budget_s=math.inf)
                cpu[label].append(time.process_time() - c0)
    return {k: statistics.median(v) for k, v in cpu.items()}


def main() -> None:
    from bench_quality import ONE_THREAD

    if any(os.environ.get(k) != v for k, v in ONE_THREAD.items()):
        os.execve(sys.executable, [sys.executable, *sys.argv], {**os.environ, **ONE_THREAD})
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print("| set | what | without | with | ratio | share taken, largest move |\n|---|---|---|---|---|---|")
    for name, demos in _sets().items():
        move = _largest_move(demos)
        for what, f, taken in _measure(demos, args.repeat):
            print(
                f"| {name} | {what} | {f['without'] * 1e3:.0f} ms | {f['with'] * 1e3:.0f} ms | "
                f"×{f['with'] / f['without']:.2f} | {taken[0] if taken else '—'}, {move * 1e3:.1f} mm |"
            )
    f = _suggest_cpu(args.repeat)
    print(
        f"| 3 × 30,000 samples | Suggest, CPU (calling thread) | {f['without']:.2f} s | {f['with']:.2f} s | "
        f"×{f['with'] / f['without']:.2f} | |"
    )


def _measure(demos: list[Demo], repeat: int) -> list[tuple[str, dict[str, float], list[float]]]:
    plain = G._plain_mean_share
    settings = LearnSettings(params=auto_params(demos))
    caches = LearningCaches()
    P.learn_skill(demos, settings, caches=caches)  # warm the series and DTW caches: what is timed is the rest
    taken: list[float] = []

    def spy(*a: Any) -> float:
        taken.append(plain(*a))
        return taken[-1]

    def train() -> None:
        P.learn_skill(demos, settings, caches=caches)

    def move() -> None:
        P.preview_path(demos, settings, caches=caches)

    figures: dict[str, dict[str, float]] = {"Train (learn_skill), cold": {}, "slider move (preview_path)": {}}
    for label, decide in (("without", _off), ("with", spy)):
        with _share(decide):
            figures["Train (learn_skill), cold"][label] = _median_s(train, repeat, caches.shares.clear)
            move()  # the first move fills the guard's memory; the next ones find it
            figures["slider move (preview_path)"][label] = _median_s(move, repeat, lambda: None)
    return [(what, f, taken) for what, f in figures.items()]


if __name__ == "__main__":
    main()
