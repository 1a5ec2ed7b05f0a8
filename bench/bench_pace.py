"""Pace benchmark (issue 18): how long the examples' skills last as taught, with their pauses removed, and at
other skill speeds, with the task result of each; what retiming costs against the timing the training does.

* per example (stack-cup, pick-place): the skill's duration as learned (the baseline), learned with Remove
  pauses, and played at ½×, 2× and 3× (the ratios are against the baseline); whether the task still works;
* ``at_speed`` (2×) on the learned joint trajectory against ``retime`` at 1× of the same path (what training pays).

Prints medians; never asserts on time. Run: ``.venv/bin/python bench/bench_pace.py``.
"""

from __future__ import annotations

import shutil
import statistics
import tempfile
from pathlib import Path

import numpy as np
from _timer import median_s

from studio.controller import Controller
from studio.core.pace import _pieces, at_speed, without_pauses
from studio.core.timing import retime
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore

ROOT = Path(__file__).resolve().parents[1]


def _task(ctl: Controller) -> str:
    r = ctl.scene.task_result()
    return "works" if r is not None and r.ok else f"misses ({r.text if r else 'no result'})"


def example(name: str, tmp: Path) -> None:
    shutil.copytree(ROOT / "sessions" / name, tmp / name)
    ctl = Controller(store=SessionStore(tmp), session=name, backend=SimulatedBaxter())
    try:
        demos = [d for _, d in ctl.demos.for_arm("left")]
        kept = [float(without_pauses(d)[-1] - d.t[0]) / d.duration for d in demos]
        print(f"{name}: demonstrations {', '.join(f'{d.duration:.1f}' for d in demos)} s; "
              f"without pauses {100 * statistics.median(kept):.0f} % of their length (median)")  # fmt: skip
        ctl.training.train().result()
        base = ctl.playback.preview_duration()
        print(f"  skill as learned: {base:.1f} s, task {_task(ctl)}")
        for speed in (0.5, 2.0, 3.0):
            ctl.placed.set_speed(speed)
            d = ctl.playback.preview_duration()
            print(f"  at {speed:g}x: {d:.1f} s (ratio {d / base:.2f}), task {_task(ctl)}")
        ctl.placed.set_speed(1.0)
        ctl.training.set_remove_pauses(True)
        ctl.training.train().result()
        d = ctl.playback.preview_duration()
        print(f"  learned without pauses: {d:.1f} s (ratio {d / base:.2f}), task {_task(ctl)}")
        jt = next(iter(ctl.session.skills.values())).joint_trajectory
        assert jt is not None and jt.skill_time is not None
        b = ctl.baxter
        v, a = b.velocity_limits("left"), b.acceleration_limits("left")
        pieces = _pieces(np.asarray(jt.skill_time), np.asarray(jt.q))
        rate = 1.0 / float(np.median(np.diff(jt.t)))
        t_base = median_s(lambda: retime(pieces, v, a, rate_hz=rate), 3)
        t_fast = median_s(lambda: at_speed(jt, 2.0, v, a), 3)
        print(
            f"  at_speed 2x on {len(jt.t):,} samples: median {t_fast * 1000:.0f} ms; baseline retime at 1x of the same "
            f"path {t_base * 1000:.0f} ms (ratio {t_fast / t_base:.2f})"
        )
    finally:
        ctl.close()
        ctl.shutdown()


def main() -> None:
    with tempfile.TemporaryDirectory() as d:
        for name in ("stack-cup", "pick-place"):
            example(name, Path(d))


if __name__ == "__main__":
    main()
