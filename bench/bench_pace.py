"""Pace benchmark (issue 18): how long the examples' skills last as taught, with their pauses removed, and at
other skill speeds, with the task result of each; what retiming costs against the timing the training does.

* per example (stack-cup, pick-place): the skill's duration as learned (the baseline), learned with Remove
  pauses, and played at ½×, 2× and 3× (the ratios are against the baseline); whether the task still works;
* ``at_speed`` (2×) on the learned joint trajectory against ``retime`` at 1× of the same path (what training pays).

* ``--part teachers`` (issue 30): varied scripted teachers of pick-place (tempo ×1, ×0.3, ×0.12 — slow careful
  drags —, hesitating 0 or 10 s at the start, above the block, above the pad and at the end): the skill's length
  (what Preview plays) against the demonstrations' median length as taught (first to last motion, pauses
  removed), with the pauses removed (the default) and kept; how much of the inserted hesitation is left out, and how
  much real motion (faster than 5 mm/s) is wrongly taken for a pause.

Prints medians; never asserts on time. Run: ``.venv/bin/python bench/bench_pace.py [--part examples|teachers]``.
"""

from __future__ import annotations

import shutil
import statistics
import tempfile
from pathlib import Path

import numpy as np
from _timer import median_s

from studio.controller import Controller
from studio.core.pace import _pieces, at_speed, take_clock, without_pauses
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
        for i in range(len(ctl.demos.names())):
            ctl.demos.set_keep_pauses(i, True)
        ctl.training.train().result()
        d = ctl.playback.preview_duration()
        print(f"  learned with every pause kept: {d:.1f} s (ratio {d / base:.2f}), task {_task(ctl)}")
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


#: Real motion: the noise-free hand faster than this (m/s).
MOTION_M_S = 0.005
TEACHERS = (("usual", 1.0, 0.0), ("hesitant", 1.0, 10.0), ("slow", 0.3, 0.0), ("slow, hesitant", 0.3, 10.0))
TEACHERS += (("very slow drags", 0.12, 0.0),)


def _motion_taken_for_pause(plan: object, clock: object) -> tuple[float, float]:
    """(seconds of real motion inside a pause or the still ends, seconds of real motion) of one take."""
    from studio.core.kinematics import Baxter

    b = Baxter.load()
    t = np.asarray(plan.t)  # type: ignore[attr-defined]
    pos = np.array([b.fk("left", q[:7])[0] for q in np.asarray(plan.q)])  # type: ignore[attr-defined]
    speed = np.linalg.norm(np.gradient(pos, t, axis=0), axis=1)
    moving = speed > MOTION_M_S
    dt = np.gradient(t)
    out = (t < clock.source[0]) | (t > clock.source[-1])  # type: ignore[attr-defined]
    for a, b_ in clock.pauses:  # type: ignore[attr-defined]
        out |= (t > a) & (t < b_)
    return float(dt[moving & out].sum()), float(dt[moving].sum())


def teachers(tmp: Path) -> None:
    from studio.core.pipeline import demo_from_recording
    from studio.teacher import recording_from_plan, teach

    print(f"{'teacher':<18}{'takes (s)':>20}{'as taught':>11}{'skill':>8}{'ratio':>7}{'kept':>8}{'ratio':>7}"
          f"{'hesitation left out':>21}{'motion as pause':>17}")  # fmt: skip
    for label, tempo, hesitate in TEACHERS:
        ctl = Controller(store=SessionStore(tmp), session="untitled", backend=SimulatedBaxter())
        try:
            ctl.sessions.new(f"t{TEACHERS.index((label, tempo, hesitate))}", scene="empty table")
            wrong = total = 0.0
            for seed in (1, 2, 3):
                plan = teach("pick-place", seed, rate_hz=100.0, once=True, tempo=tempo, hesitate=hesitate)
                rec = recording_from_plan(plan)
                ctl.session.add_recording(rec)
                clock = take_clock([demo_from_recording(rec, "left")])
                w, m = _motion_taken_for_pause(plan, clock)
                wrong, total = wrong + w, total + m
            ctl.demos.changed()
            sums = ctl.demos.summaries()
            takes = [d.duration for d in sums]
            taught = statistics.median(d.clock.duration for d in sums if d.clock is not None)
            left_out = sum(d.clock.removed + d.clock.still_ends for d in sums if d.clock is not None)
            ctl.training.train().result()
            skill = ctl.placed.duration()
            for i in range(len(sums)):
                ctl.demos.set_keep_pauses(i, True)
            ctl.training.train().result()
            kept = ctl.placed.duration()
            share = f"{left_out:.0f} s of {12 * hesitate:.0f} s" if hesitate else f"{left_out:.1f} s"
            print(f"{label:<18}{', '.join(f'{x:.0f}' for x in takes):>20}{taught:>10.1f}s{skill:>7.1f}s"
                  f"{skill / taught:>7.2f}{kept:>7.1f}s{kept / taught:>7.2f}{share:>21}"
                  f"{100 * wrong / total:>15.1f} %")  # fmt: skip
        finally:
            ctl.close()
            ctl.shutdown()


def main() -> None:
    import argparse

    ap = argparse.ArgumentParser()
    ap.add_argument("--part", choices=("examples", "teachers", "all"), default="all")
    part = ap.parse_args().part
    with tempfile.TemporaryDirectory() as d:
        if part in ("examples", "all"):
            for name in ("stack-cup", "pick-place"):
                example(name, Path(d))
        if part in ("teachers", "all"):
            teachers(Path(d))


if __name__ == "__main__":
    main()
