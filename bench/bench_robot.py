"""Benchmark of the real-robot backend against the Baxter test bed (tests/baxter_bed.py, a rosbridge server
in a process of its own, so that what loads the studio's process does not slow the robot's clock).

    .venv/bin/python bench/bench_robot.py [--seconds 8] [--trials 10]

1. **Commands while a plan runs** (the left arm swings for ``--seconds``): the rate the robot receives joint
   commands (median over whole seconds of the count received) and the longest gap, on a quiet machine and
   with two threads keeping the interpreter busy (a loaded machine).
2. **Plan clock vs wall clock** over the same runs: the plan time reached per wall second; beside it, in the
   same run, what the earlier clock (advanced one command period per tick) would have reached.
3. **The robot's e-stop to the studio's "failed" run**: the bed's button pressed during a run, the time until
   ``progress()`` says so (median, max of ``--trials``); the bed publishes /robot/state at 20 Hz.
4. **Socket loss to "connection lost"**: the bed closes the socket, or goes silent (the studio must notice
   the stale stream), the time until ``health()`` says disconnected (median, max).
"""

from __future__ import annotations

import argparse
import multiprocessing
import statistics
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studio.robot_backend.rosbridge import RosbridgeBaxter
from tests.baxter_bed import BaxterBed
from tests.test_rosbridge_safety import plan_for

LEFT_CMD = "/robot/limb/left/joint_command"


class BedProcess:
    """The test bed in a child process; ``call(name, *args)`` runs ``BaxterBed.name(*args)`` there."""

    def __init__(self, **kw: object) -> None:
        self.conn, child = multiprocessing.Pipe()
        self.proc = multiprocessing.get_context("spawn").Process(target=_serve, args=(child, kw), daemon=True)
        self.proc.start()
        self.url = self.conn.recv()

    def call(self, name: str, *args: object) -> Any:
        self.conn.send((name, args))
        ok, value = self.conn.recv()
        if not ok:
            raise RuntimeError(value)
        return value

    def close(self) -> None:
        self.call("close")
        self.proc.join(timeout=10)


def _serve(conn: Any, kw: dict[str, Any]) -> None:
    bed = BaxterBed(**kw)
    conn.send(bed.url)
    while True:
        name, args = conn.recv()
        try:
            value = getattr(bed, name)(*args) if name != "attr" else getattr(bed, args[0])
            conn.send((True, value))
        except Exception as exc:
            conn.send((False, repr(exc)))
        if name == "close":
            return


@contextmanager
def loaded(threads: int) -> Iterator[None]:
    """``threads`` Python threads spinning (they hold the interpreter lock as a busy studio would)."""
    stop = threading.Event()

    def spin() -> None:
        x = 0
        while not stop.is_set():
            x = (x * 31 + 7) % 1_000_003

    ts = [threading.Thread(target=spin, daemon=True) for _ in range(threads)]
    for t in ts:
        t.start()
    try:
        yield
    finally:
        stop.set()
        for t in ts:
            t.join()


def ready(bed: BedProcess) -> RosbridgeBaxter:
    r = RosbridgeBaxter(bed.url, connect_timeout=10.0)
    r.start()
    deadline = time.monotonic() + 20
    while not r.health().ready:
        if time.monotonic() > deadline:
            raise SystemExit(f"the test bed's robot is not ready: {r.health().message}")
        time.sleep(0.01)
    return r


def run_once(bed: BedProcess, robot: RosbridgeBaxter, seconds: float) -> dict[str, float]:
    plan = plan_for(robot, seconds=seconds)
    n0 = len(bed.call("by_op", "publish", LEFT_CMD))
    sent0 = robot.commands_sent
    wall0 = time.monotonic()
    robot.execute(plan)
    samples = []
    while robot.progress().state == "running":
        samples.append((time.monotonic() - wall0, robot.progress().t, robot.commands_sent - sent0))
        time.sleep(0.05)
    wall, reached, ticks = samples[-1]
    times = np.array([t for t, _ in bed.call("by_op", "publish", LEFT_CMD)[n0:]])
    times = times[times < wall0 + wall]
    gaps = np.diff(times)
    per_second = np.bincount(((times - times[0]) // 1.0).astype(int))[:-1]  # whole seconds only
    return {
        "rate": float(np.median(per_second)),
        "longest_gap_ms": float(gaps.max() * 1000),
        "clock_ratio": reached / wall,
        # the earlier clock advanced one command period per tick (one left-arm command per tick)
        "tick_clock_ratio": ticks / robot.command_rate_hz / wall,
    }


def estop_latency(bed: BedProcess, robot: RosbridgeBaxter) -> float:
    robot.execute(plan_for(robot, seconds=6.0))
    time.sleep(0.5)
    t0 = bed.call("press_estop")
    while robot.progress().state != "failed":
        time.sleep(0.001)
    dt = time.monotonic() - t0
    bed.call("release_estop")
    robot.enable()
    return dt


def loss_latency(bed: BedProcess, robot: RosbridgeBaxter, silent: bool) -> float:
    t0 = bed.call("drop", 1.0, silent)
    while robot.health().connected:
        time.sleep(0.001)
    dt = time.monotonic() - t0
    deadline = time.monotonic() + 30
    while not robot.health().ready and time.monotonic() < deadline:
        time.sleep(0.01)
    return dt


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--trials", type=int, default=10)
    args = ap.parse_args()
    bed = BedProcess(gripper_calibrated=True)
    robot = ready(bed)
    try:
        print(f"1-2. commands during a {args.seconds:.0f} s run (100 Hz command thread)")
        for name, threads in (("quiet", 0), ("loaded (2 busy threads)", 2)):
            with loaded(threads):
                r = run_once(bed, robot, args.seconds)
            print(
                f"  {name:24s} rate {r['rate']:6.1f}/s  longest gap {r['longest_gap_ms']:6.1f} ms  "
                f"plan clock / wall {r['clock_ratio']:.3f}  (tick-counting clock: {r['tick_clock_ratio']:.3f})"
            )
        print(f"3. robot e-stop -> run 'failed' ({args.trials} trials)")
        lat = [estop_latency(bed, robot) for _ in range(args.trials)]
        print(f"  median {statistics.median(lat) * 1000:.0f} ms, max {max(lat) * 1000:.0f} ms")
        for silent in (False, True):
            lat = [loss_latency(bed, robot, silent) for _ in range(max(3, args.trials // 2))]
            how = "silent link" if silent else "socket closed"
            print(
                f"4. {how} -> 'connection lost': median {statistics.median(lat) * 1000:.0f} ms, "
                f"max {max(lat) * 1000:.0f} ms"
            )
    finally:
        robot.stop()
        bed.close()


if __name__ == "__main__":
    main()
