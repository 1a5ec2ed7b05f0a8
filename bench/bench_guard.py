"""What "not farther than the plain mean" (decision 083) costs: learn_skill and the live preview with it and
without it (the share patched to 0), alternating in one process; the guard's memory emptied before each cold run.

    .venv/bin/python bench/bench_guard.py [--repeat 5]

Sets: 7 loosely drawn 15 cm spirals (1.5 s each; the guard moves this path), the scripted teacher's pick-place
× 3 (1 kHz, ~22 s each). Medians; ratios against "without" from the same run.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import studio.core.pipeline as P
from studio.core.kinematics import Baxter
from studio.core.thresholds import auto_params
from studio.core.types import Demo
from studio.shapes import ShapeSpec, shape_demos
from studio.teacher import recording_from_plan, teach


def _sets() -> dict[str, list[Demo]]:
    b = Baxter.load()
    tasks = [P.demo_from_recording(recording_from_plan(teach("pick-place", s)), "left", b) for s in range(3)]
    return {
        "loose spiral 15 cm × 7": list(shape_demos(ShapeSpec("spiral", 0.15, 1.5, style="loose"), 7)),
        "pick-place × 3 (1 kHz)": tasks,
    }


def _median_s(run: Callable[[], object], repeat: int, before: Callable[[], None]) -> float:
    out = []
    for _ in range(repeat):
        before()
        t0 = time.perf_counter()
        run()
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print("| set | what | without | with | ratio | share taken |\n|---|---|---|---|---|---|")
    for name, demos in _sets().items():
        for what, f, taken in _measure(demos, args.repeat):
            print(
                f"| {name} | {what} | {f['without'] * 1e3:.0f} ms | {f['with'] * 1e3:.0f} ms | "
                f"×{f['with'] / f['without']:.2f} | {taken[0] if taken else '—'} |"
            )


def _measure(demos: list[Demo], repeat: int) -> list[tuple[str, dict[str, float], list[float]]]:
    plain = P._plain_mean_share
    params = auto_params(demos)
    P.learn_skill(demos, params)  # warm the series and DTW caches: what is timed is the rest
    taken: list[float] = []

    def spy(*a: Any) -> float:
        taken.append(plain(*a))
        return taken[-1]

    def train() -> None:
        P.learn_skill(demos, params)

    def move() -> None:
        P.preview_path(demos, params)

    figures: dict[str, dict[str, float]] = {"Train (learn_skill), cold": {}, "slider move (preview_path)": {}}
    try:
        for label, share in (("without", lambda *a: 0.0), ("with", spy)):
            P._plain_mean_share = share
            figures["Train (learn_skill), cold"][label] = _median_s(train, repeat, P._GUARD_SHARES.clear)
            move()  # the first move fills the guard's memory; the next ones find it
            figures["slider move (preview_path)"][label] = _median_s(move, repeat, lambda: None)
    finally:
        P._plain_mean_share = plain
    return [(what, f, taken) for what, f in figures.items()]


if __name__ == "__main__":
    main()
