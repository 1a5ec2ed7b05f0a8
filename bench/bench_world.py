"""Task-scene benchmark: what the world costs on a whole demonstration and on the live 1 kHz stream.

* ``simulate`` on a scripted pick-place demonstration (~23 s at 1 kHz, two grasps and two releases), against
  the baseline ``fk_batch`` of both arms over the same samples (what the recorder pays per demonstration);
* ``World.feed`` of 15-sample batches (as the simulated robot delivers them), idle and while carrying the
  block, against ``fk_batch`` of one arm over 15 samples (the recorder's per-batch cost).

Prints medians; never asserts on time. Run: ``.venv/bin/python bench/bench_world.py``.
"""

from __future__ import annotations

import statistics
import time

import numpy as np
from _timer import median_s

from studio.core.kinematics import Baxter
from studio.teacher import recording_from_plan, teach
from studio.world import World, preset, simulate


def main() -> None:
    b = Baxter.load()
    scene = preset("pick-place")
    rec = recording_from_plan(teach("pick-place", 0))
    n = len(rec.t)
    t_sim = median_s(lambda: simulate(rec.t, rec.q, rec.gripper, scene, baxter=b), 7)
    t_fk = median_s(
        lambda: [b.fk_batch(a, rec.q[:, s]) for a, s in (("left", slice(0, 7)), ("right", slice(7, 14)))], 7
    )
    print(f"simulate, pick-place demo of {n} samples ({rec.duration:.1f} s): median {t_sim * 1000:.1f} ms")
    print(f"  baseline fk_batch of both arms over the same samples: {t_fk * 1000:.1f} ms (ratio {t_sim / t_fk:.2f})")

    close = teach("pick-place", 0).event_poses("close")[0].time
    i_hold = int(np.searchsorted(rec.t, close + 1.0))

    def per_batch(start: int, count: int = 200) -> float:
        world = World(scene, b)
        world.feed(rec.t[:start], rec.q[:start], rec.gripper[:start])
        times = []
        for k in range(count):
            s = start + 15 * k
            t0 = time.perf_counter()
            world.feed(rec.t[s : s + 15], rec.q[s : s + 15], rec.gripper[s : s + 15])
            times.append(time.perf_counter() - t0)
        return statistics.median(times)

    idle = per_batch(1)
    carrying = per_batch(i_hold)
    q15 = rec.q[:15, :7]
    base = median_s(lambda: b.fk_batch("left", q15), 500)
    print(f"World.feed, 15-sample batch, nothing held: median {idle * 1e6:.0f} µs")
    print(f"World.feed, 15-sample batch, carrying the block: median {carrying * 1e6:.0f} µs")
    print(f"  baseline fk_batch of one arm over 15 samples: {base * 1e6:.0f} µs")
    print(f"  share of one core at 1 kHz (67 batches/s) while carrying: {carrying * 1000 / 15 * 100:.2f} %")


if __name__ == "__main__":
    main()
