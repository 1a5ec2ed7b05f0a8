"""Follow demonstrations through learning: trace :func:`studio.core.learn.learn_and_judge` (a skill in the robot's
frame, and one that follows the objects) and print, per core module, the call sites that enter it from another
module, and the chain of stages in the order they are entered. Decision 095.

An entry is a call site (calling function → called function) in another module, counted once however often a loop
runs it; callbacks a module hands out (its closures and lambdas, run by a cache or a fold) and dunder methods of
values are the module's own work, not entries.

    python bench/bench_learn_chain.py [--tree]
"""

from __future__ import annotations

import argparse
import sys
import types
from collections.abc import Callable

import numpy as np

#: Modules that do a stage of learning or judging (the rest are values and shared helpers: types, rotations,
#: kinematics, errors, the caches and the settings).
STAGES = (
    "learn",
    "pipeline",
    "segments",
    "segment_view",
    "routes",
    "thresholds",
    "keypoints",
    "clustering",
    "hmm",
    "alignment",
    "generalize",
    "execution",
    "ik_path",
    "quality.holdout",
    "quality.report",
    "quality.judgement",
)


def _short(module: str) -> str:
    return module.removeprefix("studio.core.")


def trace(run: Callable[[], object]) -> list[tuple[str, str, str, str, int]]:
    """(caller module, caller function, called module, called function, depth) of every first call from one core
    module into another while ``run`` runs."""
    seen: set[tuple[str, str, str, str]] = set()
    out: list[tuple[str, str, str, str, int]] = []
    stack: list[tuple[str, str]] = []
    codes: list[types.CodeType] = []

    def prof(frame: types.FrameType, event: str, arg: object) -> None:
        if event == "return":
            if codes and codes[-1] is frame.f_code:
                stack.pop()
                codes.pop()
            return
        if event != "call":
            return
        mod = str(frame.f_globals.get("__name__", ""))
        if not mod.startswith("studio.core"):
            return
        fn = frame.f_code.co_qualname
        caller = stack[-1] if stack else ("<top>", "")
        names = codes[-1].co_names if codes else (fn,)
        stack.append((mod, fn))
        codes.append(frame.f_code)
        name = fn.rsplit(".", 1)[-1]
        if caller[0] == mod or name not in names or (name.startswith("__") and name.endswith("__")):
            return  # within a module, a callback it handed out (not called by name there), or a value's dunder
        key = (caller[0], caller[1], mod, fn)
        if key not in seen:
            seen.add(key)
            out.append((_short(caller[0]), caller[1], _short(mod), fn, len(stack) - 1))

    sys.setprofile(prof)
    try:
        run()
    finally:
        sys.setprofile(None)
    return out


def robot_case() -> Callable[[], object]:
    from studio.core.kinematics import Baxter
    from studio.core.learn import learn_and_judge
    from studio.core.pipeline import demo_from_recording
    from studio.teacher import recording_from_plan, teach

    b = Baxter.load()
    demos = [demo_from_recording(recording_from_plan(teach("stack-cup", s)), "left", b) for s in (0, 1, 2)]
    return lambda: learn_and_judge(demos, arm="left", baxter=b)


def objects_case() -> Callable[[], object]:
    from bench.bench_objects import demonstrate
    from studio.core.kinematics import Baxter
    from studio.core.learn import TaughtObjects, learn_and_judge
    from studio.world import preset, session_goal
    from studio.world.relative import release_rules

    b = Baxter.load()
    demos, objs, events, _ = demonstrate("pick-place", 3, np.random.default_rng([1, 10]), b)
    scene = preset("pick-place", ("left",))
    goal = session_goal(scene.preset, scene.goal, scene.names(), events)
    taught = TaughtObjects(tuple(objs), rules=release_rules(goal, objs[0]))
    return lambda: learn_and_judge(demos, taught, arm="left", baxter=b)


def report(title: str, calls: list[tuple[str, str, str, str, int]], tree: bool) -> int:
    """Print, per module, the modules that enter it and the call sites; returns the most modules entering one stage
    module."""
    into: dict[str, set[str]] = {}
    for c in calls:
        into.setdefault(c[2], set()).add(c[0])
    print(f"\n== {title}")
    print("stage modules: entered from (modules) · call sites")
    for m in STAGES:
        if m in into:
            sites = sorted({f"{c[0]}.{c[1]} → {c[3]}" for c in calls if c[2] == m})
            print(f"  {m:18s} {len(into[m])} · {len(sites)}   " + "; ".join(sites))
    others = sorted(((m, len(f)) for m, f in into.items() if m not in STAGES), key=lambda x: -x[1])
    print("values and shared helpers, entered from (modules):", ", ".join(f"{m} {n}" for m, n in others))
    if tree:
        for c in calls:
            print("  " * c[4] + f"{c[0]}.{c[1]} → {c[2]}.{c[3]}")
    return max((len(into[m]) for m in STAGES if m in into), default=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", action="store_true", help="print every entry, indented by call depth")
    args = ap.parse_args()
    worst = 0
    for title, case in (
        ("robot's frame (stack-cup, 3 demos)", robot_case),
        ("objects (pick-place, 3 demos)", objects_case),
    ):
        worst = max(worst, report(title, trace(case()), args.tree))
    print(f"\nmost modules entering one stage module: {worst}")


if __name__ == "__main__":
    main()
