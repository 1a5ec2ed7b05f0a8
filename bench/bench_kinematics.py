"""Kinematics benchmark: FK per call and per batch, IK per solve, and the studio's IK against pink and pyroki.

    bash scripts/bootstrap.sh "test,mesh,bench"   # pink and its QP solver are the bench extra
    .venv/bin/python bench/bench_kinematics.py [--quick] [--skip-fk] [--poses N] [--paths N]

1. FK per call and per 30,000-configuration batch against pinocchio's own per-call loop (same run).
2. Single poses, the same for every solver: ``Baxter.ik`` (damped least squares) against pink (``solve_ik``
   with a ``FrameTask``, the daqp QP solver, position limits), from a nearby seed (0.1 rad noise) and from the
   neutral pose. Success = within 1 mm and 0.01 rad by FK; errors; time per solve; ratio pink / ours.
3. Paths: skills learned from the execution bench's demonstration families (teacher tasks shifted and sped
   up, random key postures, Cartesian only), at 50 Hz, from the reference demo's first joints and from the
   neutral pose: ``ik_path.solve_path`` against pink and ``Baxter.ik`` tracking pose by pose, each pose
   warm-started from the previous one. Share of samples within 1 mm and 0.01 rad, worst error, largest joint
   step between samples, time per path.
4. pyroki (JAX) if it imports; otherwise the reason.

Medians; the machine is shared, so compare the ratios of the same run. Never asserts on time.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _timer import median_s

from studio.core.kinematics import Baxter, quat_angle
from studio.core.rotations import matrix_from_quat_wxyz

POS_OK = 1e-3
ROT_OK = 0.01


def fk_and_ik(b: Baxter, n: int) -> None:
    """FK per call and per batch against pinocchio's loop; IK from a nearby seed; gizmo-sized moves."""
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
    t_pin = median_s(lambda: pin_loop(n_call), 5) / n_call
    t_call = median_s(lambda: studio_loop(n_call), 5) / n_call
    t_batch = median_s(lambda: b.fk_batch(arm, Q), 15)
    t_pin_30k = t_pin * len(Q)
    print(f"FK per call (studio fk, incl. quaternion):       median {t_call * 1e6:8.1f} us")
    print(f"FK per call (pinocchio, position only; baseline): median {t_pin * 1e6:8.1f} us")
    print(f"FK batch of 30,000 (fk_batch, pose + quaternion): median {t_batch * 1e3:8.1f} ms  (target < 50 ms)")
    print(
        f"  baseline: pinocchio loop over 30,000 would take {t_pin_30k * 1e3:8.1f} ms"
        f" -> speed-up x{t_pin_30k / t_batch:.1f}"
    )

    # IK from a nearby seed over random reachable poses.
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


# -- the studio's IK against pink ------------------------------------------------------------------------------

Solver = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def ours(b: Baxter, arm: str) -> Solver:
    def solve(p: np.ndarray, w: np.ndarray, seed: np.ndarray) -> np.ndarray:
        return b.ik(arm, p, w, seed).q

    return solve


def pink_solver(b: Baxter, arm: str, dt: float = 1.0, lm_damping: float = 1e-3, iterations: int = 100) -> Solver:
    """pink's differential IK iterated to the same tolerances as ``Baxter.ik`` (1e-4 m, 1e-3 rad, at most 100
    steps), on the arm's 7 joints (the rest locked), with the model's position limits. dt = 1 and
    lm_damping = 1e-3 were the best of the settings tried (dt 0.5/1, damping 1e-6…1e-2, gain 0.5/1)."""
    import pink
    from pink.limits import ConfigurationLimit
    from pink.tasks import FrameTask

    full = b.model
    keep = {f"{arm}_{j}" for j in ("s0", "s1", "e0", "e1", "w0", "w1", "w2")}
    lock = [full.getJointId(nm) for nm in list(full.names)[1:] if nm not in keep]
    model = pin.buildReducedModel(full, lock, pin.neutral(full))
    data = model.createData()
    frame = f"{arm}_gripper"
    task = FrameTask(frame, position_cost=1.0, orientation_cost=1.0, lm_damping=lm_damping)
    limits = [ConfigurationLimit(model)]
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit

    def solve(p: np.ndarray, w: np.ndarray, seed: np.ndarray) -> np.ndarray:
        R = matrix_from_quat_wxyz(np.asarray(w) / np.linalg.norm(w))
        conf = pink.Configuration(model, data, np.clip(seed, lo, hi))
        task.set_target(pin.SE3(R, np.asarray(p, dtype=float)))
        for _ in range(iterations):
            T = conf.get_transform_frame_to_world(frame)
            if np.linalg.norm(T.translation - p) < 1e-4 and np.linalg.norm(pin.log3(T.rotation.T @ R)) < 1e-3:
                break
            v = pink.solve_ik(conf, [task], dt, solver="daqp", limits=limits, safety_break=False)
            conf.integrate_inplace(v, dt)
        return conf.q.copy()

    return solve


def restarts(b: Baxter, arm: str, solve: Solver, starts: int = 4) -> Solver:
    """``solve`` from the given seed, then from mid-range and random seeds until one reaches the pose (1 mm,
    0.01 rad): how the studio's path solver starts a path and how its reachability probes work."""
    mid = (b.lower_limits(arm) + b.upper_limits(arm)) / 2.0
    rng = np.random.default_rng(11)

    def solve_many(p: np.ndarray, w: np.ndarray, seed: np.ndarray) -> np.ndarray:
        q = solve(p, w, seed)
        for k in range(1, starts):
            p2, w2 = b.fk(arm, q)
            if np.linalg.norm(p2 - p) < POS_OK and quat_angle(w2, w) < ROT_OK:
                break
            nxt = mid if k == 1 else b.random_configuration(arm, rng)
            q = solve(p, w, nxt)
        return q

    return solve_many


def _errors(b: Baxter, arm: str, Q: np.ndarray, P: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pos, wxyz = b.fk_batch(arm, Q)
    pe = np.linalg.norm(pos - P, axis=1)
    oe = np.array([quat_angle(a, c) for a, c in zip(wxyz, W, strict=True)])
    return pe, oe


def single_poses(b: Baxter, n: int, solvers: dict[str, Solver]) -> None:
    arm = "left"
    rng = np.random.default_rng(7)
    Qt = b.random_configuration(arm, rng, n)
    P, W = b.fk_batch(arm, Qt)
    seeds = {
        "nearby seed (0.1 rad)": np.array([b.clamp(arm, q + rng.normal(0.0, 0.1, 7)) for q in Qt]),
        "from the neutral pose": np.tile(b.neutral(arm), (n, 1)),
    }
    print(f"\n== single poses: {n} random reachable poses of the left gripper, the same for every solver ==")
    print(
        f"{'seed':<24}{'solver':<16}{'success':>9}{'pos err median':>16}{'rot err median':>16}"
        f"{'time median':>13}{'p95':>9}{'ratio':>8}"
    )
    for seed_name, S in seeds.items():
        base = None
        cold = {f"{k}, 4 starts": restarts(b, arm, f) for k, f in solvers.items()} if "neutral" in seed_name else {}
        for name, solve in {**solvers, **cold}.items():
            Q = np.empty((n, 7))
            times = []
            for i in range(n):
                t0 = time.perf_counter()
                Q[i] = solve(P[i], W[i], S[i])
                times.append(time.perf_counter() - t0)
            pe, oe = _errors(b, arm, Q, P, W)
            ok = float(np.mean((pe < POS_OK) & (oe < ROT_OK)))
            med = statistics.median(times)
            base = base or med
            print(
                f"{seed_name:<24}{name:<16}{100 * ok:8.1f}%{np.median(pe) * 1e3:13.4f} mm{np.median(oe):12.5f} rad"
                f"{med * 1e3:10.3f} ms{np.percentile(times, 95) * 1e3:7.2f}{med / base:8.2f}"
            )


def _paths(count: int) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]]:
    """(family, t, position, wxyz at 50 Hz, reference demo's first joints or None) per learned skill."""
    from bench_execution import demo_sets

    from studio.core.pipeline import learn_skill

    out = []
    for family, demos, withq in demo_sets(count, np.random.default_rng(3)):
        sk = learn_skill(demos)
        tr = sk.trajectory
        step = max(1, round(0.02 / float(np.median(np.diff(tr.t)))))
        q0 = None if withq is None or withq[sk.reference].q is None else withq[sk.reference].q[0, :7]
        out.append((family, tr.t[::step], tr.position[::step], tr.orientation[::step], q0))
    return out


def paths(b: Baxter, count: int, solvers: dict[str, Solver]) -> None:
    from studio.core.ik_path import solve_path

    arm = "left"
    vmax = b.velocity_limits(arm)
    print(f"\n== paths: {count} learned skills at 50 Hz (bench_execution's families), pose by pose vs whole path ==")
    rows: dict[tuple[str, str], list[tuple[float, float, float, float]]] = {}
    for _family, t, P, W, q_ref in _paths(count):
        for seed_name, seed in (("reference", q_ref), ("neutral", b.neutral(arm))):
            if seed is None:
                continue
            t0 = time.perf_counter()
            sol = solve_path(t, P, W, arm, seed, b)
            Q = sol.spline()(t)
            took = time.perf_counter() - t0
            results = {"ik_path": (Q, took)}
            for name, solve in solvers.items():
                Q = np.empty((len(t), 7))
                q = seed
                t0 = time.perf_counter()
                for i in range(len(t)):
                    q = Q[i] = solve(P[i], W[i], q)
                results[f"{name} pose by pose"] = (Q, time.perf_counter() - t0)
            for name, (Q, took) in results.items():
                pe, oe = _errors(b, arm, Q, P, W)
                ok = float(np.mean((pe < POS_OK) & (oe < ROT_OK)))
                dq = np.abs(np.diff(Q, axis=0))
                jump = float(dq.max()) if len(Q) > 1 else 0.0
                # steps faster than the joints' velocity limits: the timing must slow the skill down there
                fast = int(np.count_nonzero(np.any(dq / np.diff(t)[:, None] > vmax, axis=1)))
                rows.setdefault((seed_name, name), []).append((ok, float(pe.max()), jump, took / len(t), fast))
    print(
        f"{'seed':<11}{'solver':<22}{'paths':>6}{'within 1 mm (median, worst)':>30}{'worst pos err':>15}"
        f"{'largest joint step':>20}{'steps over the velocity limit':>32}{'time per pose':>15}"
    )
    for (seed_name, name), r in rows.items():
        a = np.array(r)
        over = f"{int(a[:, 4].sum())} in {int((a[:, 4] > 0).sum())} paths"
        print(
            f"{seed_name:<11}{name:<22}{len(r):6d}{100 * np.median(a[:, 0]):15.1f}%{100 * a[:, 0].min():12.1f}%"
            f"{a[:, 1].max() * 1e3:12.1f} mm{a[:, 2].max():15.2f} rad{over:>32}{np.median(a[:, 3]) * 1e3:12.3f} ms"
        )


def pyroki() -> None:
    print("\n== pyroki ==")
    try:
        import pyroki  # type: ignore[import-not-found]  # noqa: F401
    except ImportError as exc:
        print(
            f"not installed ({exc}); `pip install pyroki` finds no such package on the index this machine"
            " reaches (pyroki is installed from its GitHub repository), so it is not compared."
        )
        return
    print("pyroki imports, but no comparison is written yet.")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer poses and paths")
    ap.add_argument("--skip-fk", action="store_true")
    ap.add_argument("--poses", type=int, default=None)
    ap.add_argument("--paths", type=int, default=None)
    args = ap.parse_args()
    b = Baxter.load()
    n = args.poses or (200 if args.quick else 1000)
    if not args.skip_fk:
        fk_and_ik(b, n)
    solvers: dict[str, Solver] = {"ours": ours(b, "left")}
    try:
        solvers["pink"] = pink_solver(b, "left")
    except ImportError as exc:
        print(f"pink is not installed ({exc}): pip install -e '.[test]'")
    single_poses(b, n, solvers)
    paths(b, args.paths or (6 if args.quick else 24), solvers)
    pyroki()


if __name__ == "__main__":
    main()
