"""Kinematics benchmark: FK per call and per 30,000-configuration batch, IK per solve and success rate.

Prints medians and ratios against a baseline measured in the same run (pinocchio's own per-call FK loop).
Never asserts on time. Run: ``.venv/bin/python bench/bench_kinematics.py``.
"""

from __future__ import annotations

import statistics
import time

import numpy as np
import pinocchio as pin

from studio.core.kinematics import Baxter, quat_angle


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    b = Baxter.load()
    rng = np.random.default_rng(0)
    arm = "left"
    Q = b.random_configuration(arm, rng, 30_000)

    # Per-call FK (studio) vs pinocchio per call on the full model (baseline).
    model = b.model
    data = model.createData()
    fid = model.getFrameId("left_gripper")
    idx = [model.joints[model.getJointId(f"left_{s}")].idx_q for s in ("s0", "s1", "e0", "e1", "w0", "w1", "w2")]
    full = pin.neutral(model)

    def pin_loop(n: int) -> None:
        for q in Q[:n]:
            full[idx] = q
            pin.forwardKinematics(model, data, full)
            pin.updateFramePlacement(model, data, fid)

    def studio_loop(n: int) -> None:
        for q in Q[:n]:
            b.fk(arm, q)

    n_call = 2000
    t_pin = _median_time(lambda: pin_loop(n_call), 5) / n_call
    t_call = _median_time(lambda: studio_loop(n_call), 5) / n_call
    t_batch = _median_time(lambda: b.fk_batch(arm, Q), 15)
    t_pin_30k = t_pin * len(Q)
    print(f"FK per call (studio fk, incl. quaternion):       median {t_call * 1e6:8.1f} us")
    print(f"FK per call (pinocchio, position only; baseline): median {t_pin * 1e6:8.1f} us")
    print(f"FK batch of 30,000 (fk_batch, pose + quaternion): median {t_batch * 1e3:8.1f} ms  (target < 50 ms)")
    print(
        f"  baseline: pinocchio loop over 30,000 would take {t_pin_30k * 1e3:8.1f} ms"
        f" -> speed-up x{t_pin_30k / t_batch:.1f}"
    )

    # IK from a nearby seed over 1,000 random reachable poses.
    n = 1000
    times, ok, iters = [], 0, []
    for _ in range(n):
        q_true = b.random_configuration(arm, rng)
        pos, quat = b.fk(arm, q_true)
        seed = b.clamp(arm, q_true + rng.normal(0.0, 0.1, 7))
        t0 = time.perf_counter()
        res = b.ik(arm, pos, quat, seed)
        times.append(time.perf_counter() - t0)
        p2, w2 = b.fk(arm, res.q)
        ok += bool(res.converged and np.linalg.norm(p2 - pos) < 1e-3 and quat_angle(w2, quat) < 0.01)
        iters.append(res.iterations)
    print(
        f"IK from a nearby seed (0.1 rad noise), {n} poses: median {statistics.median(times) * 1e3:.2f} ms, "
        f"p95 {np.percentile(times, 95) * 1e3:.2f} ms, success {100.0 * ok / n:.1f} %, "
        f"median iterations {statistics.median(iters):.0f}  (target < 2 ms, >= 99 %)"
    )

    # Gizmo-sized moves: 2 cm steps from the current pose (how the teach panel uses IK).
    times, ok = [], 0
    q = b.neutral(arm)
    home, _ = b.fk(arm, q)
    for _ in range(n):
        pos, quat = b.fk(arm, q)
        # A random walk that stays within 20 cm of the start pose, as a teacher's hand would.
        step = rng.normal(0.0, 0.02, 3)
        if np.linalg.norm(pos - home) > 0.2:
            step = 0.02 * (home - pos) / np.linalg.norm(home - pos)
        target = pos + step
        t0 = time.perf_counter()
        res = b.ik(arm, target, quat, q)
        times.append(time.perf_counter() - t0)
        ok += res.converged
        if res.converged:
            q = res.q
    print(
        f"IK gizmo-sized moves (2 cm), {n}: median {statistics.median(times) * 1e3:.2f} ms,"
        f" converged {100.0 * ok / n:.1f} %"
    )


if __name__ == "__main__":
    main()
