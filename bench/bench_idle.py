"""What a studio costs while nothing happens: the CPU of a `python -m studio serve` process on the stack-cup
example with no page open (its simulated robot streams at 1 kHz, the pose pump ticks the panels at 60 Hz), and,
in-process, what one pose-pump tick's question "which object poses are shown" costs answered from the last
answer (now) against computed again (before: every tick), with the median ratio.

    .venv/bin/python bench/bench_idle.py [--rounds 3] [--seconds 20] [--calls 2000]
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_suite import process_cpu  # noqa: E402

from tests.e2e.conftest import StudioProcess  # noqa: E402


def idle_process(rounds: int, seconds: float, time_scale: float = 1.0) -> list[float]:
    """Cores used by an idle studio process, one figure per round (after it finished starting); its simulated
    robot on a ``time_scale`` clock (tests/e2e/fast_robot.py)."""
    sessions = Path(tempfile.mkdtemp())
    shutil.copytree(ROOT / "sessions" / "stack-cup", sessions / "stack-cup")
    server = StudioProcess(sessions, "stack-cup", time_scale=time_scale).start()
    out = []
    try:
        assert server.proc is not None
        pid = str(server.proc.pid)
        time.sleep(20.0)  # the example's skill is judged on the work thread after the start
        for _ in range(rounds):
            got0, t0 = process_cpu(pid), time.monotonic()
            time.sleep(seconds)
            got1, t1 = process_cpu(pid), time.monotonic()
            assert got0 is not None and got1 is not None
            out.append((got1[1] - got0[1]) / (t1 - t0))
    finally:
        server.stop()
        shutil.rmtree(sessions, ignore_errors=True)
    return out


def shown_per_call(calls: int) -> tuple[float, float]:
    """Median seconds of ``ctl.scene.shown()`` (answered from the last answer) and of computing the live world's
    poses again, as every tick did before, on a controller on the stack-cup example."""
    from studio.controller import Controller
    from studio.robot_backend.simulated import SimulatedBaxter
    from studio.storage import SessionStore
    from tests.conftest import RecordingNotifier

    sessions = Path(tempfile.mkdtemp())
    shutil.copytree(ROOT / "sessions" / "stack-cup", sessions / "stack-cup")
    sim = SimulatedBaxter()
    ctl = Controller(store=SessionStore(sessions), session="stack-cup", backend=sim, notifier=RecordingNotifier())
    ctl.start()
    sim.stop()
    try:
        now, before = [], []
        for _ in range(calls):
            t0 = time.perf_counter()
            ctl.scene.shown()
            t1 = time.perf_counter()
            ctl.scene.live.poses()
            t2 = time.perf_counter()
            now.append(t1 - t0)
            before.append(t2 - t1)
        return statistics.median(now), statistics.median(before)
    finally:
        ctl.close()
        ctl.shutdown()
        shutil.rmtree(sessions, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--time-scale", type=float, default=0.0, help="also an idle studio on this faster clock")
    args = ap.parse_args()
    now, before = shown_per_call(args.calls)
    print(
        f"shown() per pose-pump tick: {now * 1e6:.1f} µs now, {before * 1e6:.1f} µs computed again "
        f"(×{before / now:.1f}); two panels ask at 60 Hz: {2 * 60 * (before - now):.3f} of a core saved"
    )
    cores = idle_process(args.rounds, args.seconds)
    print(
        f"idle studio process: median {statistics.median(cores):.3f} cores "
        f"(rounds: {', '.join(f'{c:.3f}' for c in cores)})"
    )
    if args.time_scale:
        fast = idle_process(args.rounds, args.seconds, args.time_scale)
        ratio = statistics.median(fast) / statistics.median(cores)
        print(
            f"idle studio process, robot on a {args.time_scale:g}x clock: median {statistics.median(fast):.3f} cores "
            f"(rounds: {', '.join(f'{c:.3f}' for c in fast)}), ×{ratio:.2f}"
        )


if __name__ == "__main__":
    main()
