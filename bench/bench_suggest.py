"""Suggest thresholds: how long it takes and what it changes, against an earlier version of it in the same run.

    nice -n 5 .venv/bin/python bench/bench_suggest.py [--repeat 5] [--against main]

Demos: 3 × 30,000 samples (handwriting loops, 15 cm, 28 s at 1 kHz), and the scripted teacher's stack-cup and
pick-place (3 demos). For each version (``studio/core/autotune.py`` at ``--against``, loaded from git, and the
working tree's), alternating: a first search on new demo names (nothing cached), in the calling thread and on
two threads as the studio runs it; medians of wall and CPU seconds (CPU: the whole process, every thread),
candidates scored, and the held-out figures before and after.
"""

from __future__ import annotations

import argparse
import importlib.util
import logging
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from types import ModuleType

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_quality import ONE_THREAD, _load, _long_demos

from studio.core import autotune
from studio.core.types import Demo

ROOT = Path(__file__).resolve().parents[1]


def earlier(rev: str) -> ModuleType:
    """``studio/core/autotune.py`` as it was at ``rev``, as a module of its own."""
    src = subprocess.run(
        ["git", "-C", str(ROOT), "show", f"{rev}:studio/core/autotune.py"], capture_output=True, text=True, check=True
    ).stdout
    path = Path(tempfile.mkdtemp()) / "autotune_earlier.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("autotune_earlier", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _renamed(demos: list[Demo], tag: str) -> list[Demo]:
    return [Demo(d.t, d.position, d.orientation, d.gripper, q=d.q, name=f"{d.name}-{tag}") for d in demos]


def _task_demos(task: str) -> list[Demo]:
    from studio.core.kinematics import Baxter
    from studio.core.pipeline import demo_from_recording
    from studio.teacher import recording_from_plan, teach

    b = Baxter.load()
    return [demo_from_recording(recording_from_plan(teach(task, s)), "left", b) for s in range(3)]


def main() -> None:
    if any(os.environ.get(k) != v for k, v in ONE_THREAD.items()):
        os.execve(sys.executable, [sys.executable, *sys.argv], {**os.environ, **ONE_THREAD})
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--against", default="main", help="the git revision to compare with (default main)")
    args = ap.parse_args()
    logging.getLogger("hmmlearn").setLevel(logging.ERROR)
    versions = {f"{args.against} (earlier)": earlier(args.against), "this tree": autotune}
    sets = {"3 × 30,000 samples": _long_demos(), "stack-cup ×3": _task_demos("stack-cup")}
    sets["pick-place ×3"] = _task_demos("pick-place")
    print(f"machine: {_load()} at start (2 cores shared); median of {args.repeat} first searches")
    with ThreadPoolExecutor(2) as threads:
        for name, demos in sets.items():
            print(f"\n== {name} ==")
            rows: dict[tuple[str, str], dict[str, list[float]]] = {}
            last: dict[tuple[str, str], object] = {}
            for rep in range(args.repeat):
                for vname, mod in versions.items():
                    for where, ex in (("calling thread", None), ("2 threads", threads)):
                        ds = _renamed(demos, f"{vname}-{where}-{rep}")
                        c0, t0 = time.process_time(), time.perf_counter()
                        r = mod.suggest(ds, executor=ex, budget_s=math.inf)
                        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                        row = rows.setdefault((vname, where), {"wall": [], "cpu": []})
                        row["wall"].append(wall)
                        row["cpu"].append(cpu)
                        last[(vname, where)] = r
            base = statistics.median(rows[(next(iter(versions)), "calling thread")]["wall"])
            for (vname, where), row in rows.items():
                r = last[(vname, where)]
                wall, cpu = statistics.median(row["wall"]), statistics.median(row["cpu"])
                task = ""
                if hasattr(r.before, "task"):
                    task = f", task {r.before.task * 1e3:.2f} → {r.after.task * 1e3:.2f} mm"
                print(
                    f"{vname:<16} {where:<15} wall {wall:5.2f} s (×{wall / base:4.2f})  CPU {cpu:5.2f} s  "
                    f"{r.evaluated:2d} candidates, changed {r.changed!s:<5}  held-out G/R {r.before.g_over_r:.3f} → "
                    f"{r.after.g_over_r:.3f}{task}"
                )
            autotune.shutdown()
    print(f"\n({_load()} at the end)")


if __name__ == "__main__":
    main()
