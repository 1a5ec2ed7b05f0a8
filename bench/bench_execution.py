"""Benchmark of execution: whole-path IK + timing within the limits, against the tracker it replaced.

    .venv/bin/python bench/bench_execution.py [--quick] [--legacy N] [--only-30s] [--hard N]

1. **200 learned trajectories from perturbed demonstrations**, each solved twice: IK seeded from the reference
   demonstration's first joints (what the studio does) and from Baxter's neutral pose (demos without joint
   data, issue 12). Three families of demonstration sets (3 demos each):
     * the scripted teacher's pick-and-place and stack-cup (left arm), shifted as a whole by up to ±6 cm and
       played 0.7–1.6× as fast (the faster ones exceed the joint limits at the taught pace);
     * pick-and-place through random key postures spread over 25–45 % of each joint's range around
       mid-range (wrist turned, elbow high or low) — the family of tests/core/execution_demos.py;
     * the same with the key postures' Cartesian poses only (seeded from the neutral pose).
   Per trajectory: the share of the skill's samples the joint trajectory executes within 1 mm and 0.01 rad;
   the samples missed are checked for reachability by multi-start IK (30 seeds × 150 damped least-squares
   iterations; reached = within 1 mm and 0.01 rad, the same bar): each run of missed samples is walked from
   both edges inward (exact there) and its interior estimated from 10 probes, so the figure is
   "tracked / reachable".
   Duration: where the taught pace is within the limits (every sample of the joint path at ṡ = 1, by finite
   differences at 1 kHz), the joint trajectory's duration minus the skill's, minus the time to get from
   rest to the path's speed at its two ends (|q̇|/a at the start and end).
2. **Joint trajectory of a 30 s skill** (3 × 30,000-sample scripted demos chained, as bench_pipeline): median
   time of the new implementation and of the old one, same run, both seeds.
4. **Issue 19's hidden case** (``--hard N``, alone): Cartesian-only pick-and-place through key postures over
   80–95 % of each joint's range, IK from the neutral pose: tracked ÷ reachable samples.
3. **The old tracker on a subset** (``--legacy N`` trajectories of part 1, each seed; a 20 s deadline each,
   since it doubles its IK rate while the path is lost): tracked share, duration ratio, time.

The old implementation is generalize.joint_trajectory at commit f060aaf, copied below with a deadline.
Medians of repeated runs; the machine is shared (2 cores), so compare the ratios of the same run.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.ndimage import maximum_filter1d, uniform_filter1d

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studio.core.execution import joint_trajectory
from studio.core.ik_solver import ACCEPT_ORIENTATION_RAD, ACCEPT_POSITION_M, PathSolver, pose_reachable, rotation_angle
from studio.core.kinematics import Baxter, matrix_from_quat_wxyz
from studio.core.pipeline import demo_from_recording, learn_skill
from studio.core.types import Demo, JointTrajectory
from studio.teacher import recording_from_plan, teach
from tests.core.execution_demos import joint_space_pick_place

# -- the implementation this replaced (generalize.py at f060aaf), with a deadline -----------------------------


class Timeout(Exception):
    pass


def legacy_joint_trajectory(
    trajectory: Demo, arm: str, q_seed: np.ndarray, b: Baxter, *, ik_rate_hz=50.0, deadline=None
):
    n = len(trajectory)
    t = trajectory.t
    step = max(1, round((1.0 / ik_rate_hz) / max(float(np.median(np.diff(t))) if n > 1 else 1.0, 1e-9)))
    knots = np.unique(np.concatenate([np.arange(0, n, step), [n - 1]]))
    P, O = trajectory.position, trajectory.orientation
    res = b.ik(
        arm,
        P[0],
        O[0],
        np.asarray(q_seed, dtype=float),
        max_iterations=500,
        position_tolerance=2e-5,
        orientation_tolerance=2e-4,
    )
    qk = np.empty((knots.shape[0], 7))
    q = res.q
    for j, i in enumerate(knots):
        if deadline is not None and time.perf_counter() > deadline:
            raise Timeout
        q = b.ik(arm, P[i], O[i], q, max_iterations=100, position_tolerance=2e-5, orientation_tolerance=2e-4).q
        qk[j] = q
    lo, hi = b.lower_limits(arm), b.upper_limits(arm)
    Q = np.clip(CubicSpline(t[knots], qk, axis=0)(t) if knots.shape[0] > 1 else np.repeat(qk, n, 0), lo, hi)
    pos, ori = b.fk_batch(arm, Q)
    perr = np.linalg.norm(pos - P, axis=1)
    oerr = 2.0 * np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", ori, O)), 0.0, 1.0))
    if (perr.max() > 5e-4 or oerr.max() > 5e-3) and ik_rate_hz < 400.0 and step > 1:
        return legacy_joint_trajectory(trajectory, arm, q_seed, b, ik_rate_hz=ik_rate_hz * 2, deadline=deadline)
    conv = (perr <= 1e-3) & (oerr <= 1e-2)
    vmax = b.velocity_limits(arm)
    if n > 2:
        v = np.abs(np.gradient(Q, t, axis=0)) / vmax
        ratio = v.max(axis=1)
        if ratio.max() > 1.0:
            w = max(1, round(0.2 * n / max(t[-1] - t[0], 1e-9)))
            stretch = np.maximum(1.0, uniform_filter1d(maximum_filter1d(ratio, 2 * w + 1), w) * 1.05)
            dt = np.diff(t) * stretch[1:]
            tn = np.concatenate([[t[0]], t[0] + np.cumsum(dt)])
            rate = 1.0 / float(np.median(np.diff(t)))
            grid = t[0] + np.arange(math.floor((tn[-1] - t[0]) * rate) + 1) / rate
            conv = np.interp(grid, tn, conv.astype(float)) > 0.5
            return grid, conv
    return t, conv


# -- demonstration families --------------------------------------------------------------------------------


def _shifted(demos: list[Demo], shift: np.ndarray, tempo: float) -> list[Demo]:
    """The demos moved by ``shift`` (m) and played ``tempo`` times as fast; joint angles kept only unshifted."""
    out = []
    for d in demos:
        keep_q = d.q if not np.any(shift) else None
        t = (d.t - d.t[0]) / tempo
        out.append(Demo(t, d.position + shift, d.orientation, d.gripper, keep_q, name=d.name))
    return out


def demo_sets(count: int, rng: np.random.Generator) -> list[tuple[str, list[Demo], list[Demo] | None]]:
    """(family, demos, demos with joints for the reference seed or None) × count."""
    b = Baxter.load()
    sets = []
    k = 0
    while len(sets) < count:
        fam = k % 3
        if fam == 0:
            task = ("pick-place", "stack-cup")[(k // 3) % 2]
            seeds = [100 + k, 200 + k, 300 + k]
            base = [demo_from_recording(recording_from_plan(teach(task, s)), "left", b) for s in seeds]
            shift = rng.uniform(-0.06, 0.06, 3) if rng.random() < 0.5 else np.zeros(3)
            tempo = float(rng.uniform(0.7, 1.6))
            ds = _shifted(base, shift, tempo)
            withq = ds if ds[0].q is not None else _shifted(base, np.zeros(3), tempo)
            sets.append((f"teacher {task}", ds, withq))
        else:
            js = joint_space_pick_place(1000 + k, spread=float(rng.uniform(0.25, 0.45)))
            if fam == 1:
                sets.append(("key postures", js, js))
            else:
                cart = [Demo(d.t, d.position, d.orientation, d.gripper, name=d.name) for d in js]
                sets.append(("key postures, Cartesian only", cart, js))
        k += 1
    return sets


# -- measures ----------------------------------------------------------------------------------------------


def per_sample_errors(b: Baxter, tr: Demo, jt: JointTrajectory) -> tuple[np.ndarray, np.ndarray]:
    """Position and orientation error at each skill sample: the joints executing that moment of the skill.

    The joint trajectory is interpolated to the skill sample's own time (its samples execute the skill at
    their own, generally fractional, skill times: at 2–3 m/s the nearest one is up to 1.3 mm along the path).
    """
    s = jt.skill_time if jt.skill_time is not None else jt.t
    j = np.clip(np.searchsorted(s, tr.t), 0, len(jt) - 1)
    jm = np.clip(j - 1, 0, len(jt) - 1)
    j = np.where(np.abs(s[jm] - tr.t) < np.abs(s[j] - tr.t), jm, j)
    keep = np.concatenate([[True], np.diff(s) > 1e-12])  # one sample per skill time (not the posture changes)
    q = np.column_stack([np.interp(tr.t, s[keep], jt.q[keep, k]) for k in range(jt.q.shape[1])])
    rot, pos = b.rotations_batch(jt.arm, q)
    pe = np.linalg.norm(pos - tr.position, axis=1)
    oe = rotation_angle(rot, matrix_from_quat_wxyz(tr.orientation))
    # a skill sample executed during a posture change or skipped is not tracked
    far = np.abs(s[j] - tr.t) > 1.5e-3
    pe[far] = np.maximum(pe[far], 1.0)
    return pe, oe


def reachable_missed(b: Baxter, tr: Demo, missed: np.ndarray, rng: np.random.Generator) -> float:
    """How many of the missed samples some posture reaches within 1 mm and 0.01 rad (multi-start IK).

    Missed samples come in runs (stretches out of reach); a run's reachable samples, if any, sit at its
    edges (reachable only with the arm in another posture), so each run is walked from both edges inward
    sample by sample until a sample is out of reach (exact there), and its interior is estimated from up to
    10 evenly spaced probes.
    """
    if missed.shape[0] == 0:
        return 0.0
    S = PathSolver(b, "left", tr.t, tr.position, matrix_from_quat_wxyz(tr.orientation))
    S.rng = rng
    runs = np.split(missed, np.flatnonzero(np.diff(missed) > 1) + 1)
    total = 0.0
    for run in runs:
        a, z = int(run[0]), int(run[-1])
        left = 0
        while a + left <= z and pose_reachable(S, a + left, seeds=30):
            left += 1
        right = 0
        while z - right > a + left and pose_reachable(S, z - right, seeds=30):
            right += 1
        inner = np.arange(a + left + 1, z - right)
        share = 0.0
        if inner.shape[0]:
            probes = inner[np.linspace(0, inner.shape[0] - 1, min(10, inner.shape[0])).astype(int)]
            share = float(np.mean([pose_reachable(S, int(i), seeds=30) for i in probes]))
        total += left + right + share * inner.shape[0]
    return total


def pace_excess(b: Baxter, tr: Demo, jt: JointTrajectory) -> float | None:
    """Duration beyond the skill's and the ramps from/to rest, when the taught pace is within the limits."""
    s = jt.skill_time
    if s is None or jt.converged.mean() < 1.0:  # a stretch out of reach: the timing is not the pace's alone
        return None
    # the joint path as a function of the skill time, at the skill's samples (ṡ = 1)
    keep = np.concatenate([[True], np.diff(s) > 1e-12])
    q = np.column_stack([np.interp(tr.t, s[keep], jt.q[keep, j]) for j in range(7)])
    dt = float(np.median(np.diff(tr.t)))
    v = np.abs(np.diff(q, axis=0)) / dt
    a = np.abs(np.diff(q, 2, axis=0)) / dt**2
    vl, al = b.velocity_limits("left"), b.acceleration_limits("left")
    if np.any(v > vl) or np.any(a > al):
        return None
    ramps = float(np.max(v[0] / al) + np.max(v[-1] / al))
    return float(jt.t[-1] - jt.t[0]) - tr.duration - ramps


def _load() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3]) if Path("/proc/loadavg").exists() else "?"


def bench_30s(b: Baxter, quick: bool) -> None:
    """Part 2: the joint trajectory of a 30 s skill, new against old, both seeds, same run."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_pipeline import _demo_of_length

    demos3 = [_demo_of_length([s, s + 10], 30_000, f"demo {s}") for s in range(3)]
    sk30 = learn_skill(demos3)
    tr30 = sk30.trajectory
    joint_trajectory(tr30, "left", b.neutral("left"), b)  # warm-up: toppra's first import
    rep = 3 if quick else 7
    print(f"\n30 s skill ({tr30.duration:.1f} s, {len(tr30)} samples), median of {rep}:")
    q_ref = demos3[sk30.reference].q
    assert q_ref is not None
    for name, qs in (("reference demo", q_ref[0]), ("neutral pose", b.neutral("left"))):
        new, old = [], []
        for _ in range(rep):
            t0 = time.perf_counter()
            jt = joint_trajectory(tr30, "left", qs, b)
            new.append(time.perf_counter() - t0)
        for _ in range(max(2, rep // 2)):
            t0 = time.perf_counter()
            legacy_joint_trajectory(tr30, "left", qs, b)
            old.append(time.perf_counter() - t0)
        mn, mo = statistics.median(new) * 1e3, statistics.median(old) * 1e3
        print(
            f"  seeded from the {name:15s} new {mn:6.0f} ms (range {min(new) * 1e3:.0f}–{max(new) * 1e3:.0f})   "
            f"old {mo:6.0f} ms   ×{mo / mn:.1f} faster   tracked {jt.converged.mean() * 100:.2f} %"
        )


def _measure(b: Baxter, family: str, seed_name: str, tr: Demo, qs: np.ndarray, rng: np.random.Generator) -> dict:
    """One joint trajectory of part 1: tracked and reachable samples, time, duration ratio, pace excess."""
    t0 = time.perf_counter()
    try:
        jt = joint_trajectory(tr, "left", qs, b)
    except Exception as exc:  # IkFailed: the start is out of reach
        return dict(family=family, seed=seed_name, failed=str(exc), duration=tr.duration)
    el = time.perf_counter() - t0
    pe, oe = per_sample_errors(b, tr, jt)
    ok = (pe <= ACCEPT_POSITION_M) & (oe <= ACCEPT_ORIENTATION_RAD)
    reachable = ok.sum() + reachable_missed(b, tr, np.flatnonzero(~ok), rng)
    return dict(
        family=family,
        seed=seed_name,
        samples=len(tr),
        tracked=int(ok.sum()),
        reachable=float(reachable),
        time=el,
        duration=tr.duration,
        ratio=(jt.t[-1] - jt.t[0]) / tr.duration,
        excess=pace_excess(b, tr, jt),
    )


def _legacy(b: Baxter, seed_name: str, tr: Demo, qs: np.ndarray, new: dict) -> dict:
    """Part 3: the old tracker on the same trajectory and seed (20 s deadline), beside the new one's figures."""
    t0 = time.perf_counter()
    row = dict(
        seed=seed_name,
        new_tracked=new["tracked"] / new["samples"],
        new_ratio=new["ratio"],
        new_time=new["time"],
    )
    try:
        lt, lconv = legacy_joint_trajectory(tr, "left", qs, b, deadline=time.perf_counter() + 20.0)
    except Timeout:
        return dict(row, tracked=float("nan"), ratio=float("nan"), time=20.0)
    return dict(row, tracked=float(np.mean(lconv)), ratio=(lt[-1] - lt[0]) / tr.duration, time=time.perf_counter() - t0)


def run_sets(
    b: Baxter, sets: list[tuple[str, list[Demo], list[Demo] | None]], legacy: int, rng: np.random.Generator
) -> tuple[list[dict], list[dict]]:
    """Part 1 (and 3 on the first ``legacy`` sets): rows of figures per joint trajectory."""
    rows: list[dict] = []
    legacy_rows: list[dict] = []
    t_start = time.perf_counter()
    for n, (family, ds, withq) in enumerate(sets):
        try:
            sk = learn_skill(ds)
        except Exception as exc:  # a perturbed set the pipeline refuses (too few key-points): skip, say so
            print(f"  set {n} ({family}) not learned: {exc}")
            continue
        tr = sk.trajectory
        seeds = [("neutral", b.neutral("left"))]
        q_ref = withq[sk.reference].q if withq is not None else None
        if q_ref is not None:
            seeds.insert(0, ("reference", q_ref[0]))
        for seed_name, qs in seeds:
            rows.append(_measure(b, family, seed_name, tr, qs, rng))
            if n < legacy and "failed" not in rows[-1]:
                legacy_rows.append(_legacy(b, seed_name, tr, qs, rows[-1]))
        if (n + 1) % 20 == 0:
            print(f"  … {n + 1} sets in {time.perf_counter() - t_start:.0f} s")
    return rows, legacy_rows


def report_sets(rows: list[dict], n_sets: int) -> None:
    """Part 1's figures: tracked/reachable per seed and per family, time, duration beyond the taught pace."""
    good = [r for r in rows if "failed" not in r]
    refused = len(rows) - len(good)
    print(f"\n{n_sets} demonstration sets → {len(good)} joint trajectories ({refused} start out of reach)")
    for seed_name in ("reference", "neutral"):
        rs = [r for r in good if r["seed"] == seed_name]
        if not rs:
            continue
        tracked = sum(r["tracked"] for r in rs)
        reach = sum(r["reachable"] for r in rs)
        per = [r["tracked"] / max(r["reachable"], 1) for r in rs]
        full = sum(1 for r in rs if r["tracked"] >= r["samples"])
        print(
            f"  seeded from {seed_name:9s}: {len(rs):3d} trajectories, tracked/reachable "
            f"{tracked / reach * 100:.3f} % of samples (worst trajectory {min(per) * 100:.2f} %), "
            f"{full} with every sample tracked; median time {statistics.median(r['time'] for r in rs) * 1e3:.0f} ms "
            f"for a median {statistics.median(r['duration'] for r in rs):.1f} s skill"
        )
        ex = [r["excess"] for r in rs if r["excess"] is not None]
        slow = [r["ratio"] for r in rs if r["excess"] is None]
        if ex:
            print(
                f"    taught pace within the limits ({len(ex)}): duration beyond skill + ramps from rest: "
                f"median {statistics.median(ex) * 1e3:.1f} ms, max {max(ex) * 1e3:.1f} ms"
            )
        if slow:
            med = statistics.median(slow)
            print(
                f"    taught pace beyond the limits ({len(slow)}): duration ratio median {med:.3f}, max {max(slow):.3f}"
            )
    for fam in sorted({r["family"] for r in good}):
        rs = [r for r in good if r["family"] == fam]
        print(
            f"  {fam:30s}: {sum(r['tracked'] for r in rs) / sum(r['reachable'] for r in rs) * 100:.3f} % "
            f"of reachable samples tracked, {len(rs)} trajectories"
        )


def report_legacy(legacy_rows: list[dict], legacy: int) -> None:
    """Part 3's figures: the old tracker against the new on the same trajectories and seeds."""
    if not legacy_rows:
        return
    print(f"\nold tracker on the first {legacy} sets (same trajectories, same seeds):")
    nan = float("nan")
    for seed_name in ("reference", "neutral"):
        ls = [r for r in legacy_rows if r["seed"] == seed_name]
        if not ls:
            continue
        done = [r for r in ls if not math.isnan(r["tracked"])]
        tr_med = statistics.median([r["tracked"] for r in done]) * 100 if done else nan
        tr_min = min(r["tracked"] for r in done) * 100 if done else nan
        ra_med = statistics.median([r["ratio"] for r in done]) if done else nan
        ra_max = max(r["ratio"] for r in done) if done else nan
        print(
            f"  {seed_name:9s}: {len(ls)} runs, {len(ls) - len(done)} past the 20 s deadline; tracked median "
            f"{tr_med:.1f} % (min {tr_min:.1f} %), duration ratio median {ra_med:.2f} (max {ra_max:.2f}), time "
            f"median {statistics.median([r['time'] for r in ls]) * 1e3:.0f} ms | new: tracked min "
            f"{min(r['new_tracked'] for r in ls) * 100:.1f} %, ratio max {max(r['new_ratio'] for r in ls):.2f}, "
            f"time median {statistics.median([r['new_time'] for r in ls]) * 1e3:.0f} ms"
        )


def bench_hard(b: Baxter, count: int) -> None:
    """Part 4 (issue 19's hidden case): Cartesian-only pick-and-place through key postures over 80–95 % of each
    joint's range (wrist rolled, elbow and shoulder near their limits), IK from the neutral pose; tracked ÷
    reachable samples (multi-start IK on probes of each missed stretch), per set and over all."""
    from tests.core.execution_demos import hard_cartesian_pick_place, tracked_of_reachable

    print(f"\nhard Cartesian-only sets ({count}), IK from the neutral pose; load {_load()}")
    tracked = reachable = 0.0
    worst: list[tuple[float, str]] = []
    for k in range(count):
        spread = (0.8, 0.9, 0.95)[k % 3]
        t0 = time.perf_counter()
        sk = learn_skill(list(hard_cartesian_pick_place(k, spread)), arm="left")
        el = time.perf_counter() - t0
        assert sk.joint_trajectory is not None
        tr_, re_ = tracked_of_reachable(b, sk.trajectory, sk.joint_trajectory)
        tracked, reachable = tracked + tr_, reachable + re_
        worst.append((tr_ / re_, f"seed {k} spread {spread}"))
        print(f"  seed {k:3d} spread {spread}: {tr_ / re_ * 100:7.3f} % of reachable tracked, learned in {el:.1f} s")
    worst.sort()
    print(f"all: {tracked / reachable * 100:.3f} % of {reachable:.0f} reachable samples tracked; worst: {worst[:3]}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="30 trajectories instead of 200, fewer repetitions")
    ap.add_argument("--legacy", type=int, default=12, help="trajectories the old tracker is run on (each seed)")
    ap.add_argument("--only-30s", action="store_true", help="only part 2 (the 30 s skill timing)")
    ap.add_argument("--hard", type=int, default=0, help="only part 4: N hard Cartesian-only sets (issue 19)")
    args = ap.parse_args()
    b = Baxter.load()
    if args.hard:
        bench_hard(b, args.hard)
        return
    rng = np.random.default_rng(12)
    print(f"machine: load average {_load()} at start (2 cores shared)")
    bench_30s(b, args.quick)  # the 30 s skill first (quietest moment of the run)
    if args.only_30s:
        return
    sets = demo_sets(30 if args.quick else 200, rng)
    rows, legacy_rows = run_sets(b, sets, args.legacy, rng)
    report_sets(rows, len(sets))
    report_legacy(legacy_rows, args.legacy)
    print(f"\nmachine: load average {_load()} at the end")


if __name__ == "__main__":
    main()
