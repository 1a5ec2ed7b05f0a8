"""Task-scene benchmark: what the world costs on a whole demonstration and on the live 1 kHz stream.

* ``simulate`` on a scripted pick-place demonstration (~23 s at 1 kHz, two grasps and two releases), against
  the baseline ``fk_batch`` of both arms over the same samples (what the recorder pays per demonstration);
* ``World.feed`` of 15-sample batches (as the simulated robot delivers them), idle and while carrying the
  block, against ``fk_batch`` of one arm over 15 samples (the recorder's per-batch cost);
* cups have walls (decision 086): ``simulate`` of a stack-cup demonstration (the carried cup's way down into the
  bottom cup checked about every 10 ms) and the same feed while carrying the cup; how far off the bottom cup's
  axis the scripted teacher's takes cross its rim, and how many of them the world nests.

Prints medians; never asserts on time. Run: ``.venv/bin/python bench/bench_world.py``.
"""

from __future__ import annotations

import statistics
import time

import numpy as np
from _timer import median_s

from studio.core.kinematics import Baxter
from studio.teacher import recording_from_plan, teach
from studio.world import CUP_GRASP_HEIGHT, World, preset, simulate


def whole_demo(b: Baxter, task: str, repeat: int):
    """``simulate`` of the scripted teacher's first ``task`` demonstration against ``fk_batch`` of both arms over
    the same samples (printed); returns the recording."""
    scene = preset(task)
    rec = recording_from_plan(teach(task, 0))
    t_sim = median_s(lambda: simulate(rec.t, rec.q, rec.gripper, scene, baxter=b), repeat)
    t_fk = median_s(
        lambda: [b.fk_batch(a, rec.q[:, s]) for a, s in (("left", slice(0, 7)), ("right", slice(7, 14)))], repeat
    )
    print(f"simulate, {task} demo of {len(rec.t)} samples ({rec.duration:.1f} s): median {t_sim * 1000:.1f} ms")
    print(f"  baseline fk_batch of both arms over the same samples: {t_fk * 1000:.1f} ms (ratio {t_sim / t_fk:.2f})")
    return rec


def per_batch(world: World, rec, start: int, count: int = 200) -> float:
    """Median seconds of ``world.feed`` of 15-sample batches of ``rec`` from sample ``start`` on (fed up to it)."""
    world.feed(rec.t[:start], rec.q[:start], rec.gripper[:start])
    times = []
    for k in range(count):
        s = start + 15 * k
        t0 = time.perf_counter()
        world.feed(rec.t[s : s + 15], rec.q[s : s + 15], rec.gripper[s : s + 15])
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    b = Baxter.load()
    scene = preset("pick-place")
    rec = recording_from_plan(teach("pick-place", 0))
    whole_demo(b, "pick-place", 7)

    close = teach("pick-place", 0).event_poses("close")[0].time
    i_hold = int(np.searchsorted(rec.t, close + 1.0))
    idle = per_batch(World(scene, b), rec, 1)
    carrying = per_batch(World(scene, b), rec, i_hold)
    q15 = rec.q[:15, :7]
    base = median_s(lambda: b.fk_batch("left", q15), 500)
    print(f"World.feed, 15-sample batch, nothing held: median {idle * 1e6:.0f} µs")
    print(f"World.feed, 15-sample batch, carrying the block: median {carrying * 1e6:.0f} µs")
    print(f"  baseline fk_batch of one arm over 15 samples: {base * 1e6:.0f} µs")
    print(f"  share of one core at 1 kHz (67 batches/s) while carrying: {carrying * 1000 / 15 * 100:.2f} %")
    walls(b)


def walls(b: Baxter, seeds: int = 40) -> None:
    """A carried cup's way into the bottom cup: what it costs, and the teacher's takes against the opening."""
    scene = preset("stack-cup")
    rec = whole_demo(b, "stack-cup", 5)
    close = teach("stack-cup", 0).event_poses("close")[0].time
    carrying = per_batch(World(scene, b), rec, int(np.searchsorted(rec.t, close + 1.0)))
    print(f"World.feed, 15-sample batch, carrying a cup over another: median {carrying * 1e6:.0f} µs")
    bottom = scene.object("bottom cup")
    rim = bottom.position[2] + bottom.size[2]
    offsets, nested = [], 0
    for seed in range(seeds):
        plan = teach("stack-cup", seed)
        p, _ = b.fk_batch("left", np.asarray(plan.q)[::10, :7])
        base = p[:, 2] - CUP_GRASP_HEIGHT  # the held cup's bottom (the teacher holds it 3 cm below its rim)
        d = np.hypot(p[:, 0] - bottom.position[0], p[:, 1] - bottom.position[1])
        offsets += [float(d[k]) for k in range(1, len(p)) if base[k] < rim <= base[k - 1] and d[k] < bottom.size[0]]
        r = recording_from_plan(plan)
        release = next(e for e in simulate(r.t, r.q, r.gripper, scene, baxter=b).events if e.kind == "release")
        nested += release.pose("cup").on == "bottom cup"
    print(
        f"the teacher's {seeds} stack-cup takes cross the bottom cup's rim {np.median(offsets) * 100:.1f} cm off its "
        f"axis (median; largest {max(offsets) * 100:.1f} cm, the rim's radius {bottom.size[0] * 50:.1f} cm); "
        f"nested by the world: {nested}/{seeds}"
    )


if __name__ == "__main__":
    main()
