"""What each test costs the machine, not only how long it takes: runs pytest with a small plugin (this file) that
reads, around each test, the worker's own CPU time, the CPU time of the worker's live descendants (Chromium, the
Playwright driver, studios started as subprocesses) from /proc, and the CPU of children that ended during the test;
then prints wall test-seconds against CPU core-seconds for the browser tests and the others, and the tests and
files that cost the most CPU.

    .venv/bin/python bench/bench_test_cpu.py                        # the whole suite, as the test command runs it
    .venv/bin/python bench/bench_test_cpu.py -- tests/e2e -n 2      # any pytest arguments after --

A child that ends is counted where it is reaped, which can be a later test (a studio subprocess reaped by the
garbage collector): per test the figures are approximate, the totals are not.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from bench_suite import Sampler

ROOT = Path(__file__).resolve().parents[1]
OUT_ENV = "STUDIO_TEST_CPU_OUT"


# -- the plugin (loaded in each pytest worker with ``-p bench_test_cpu``) ---------------------------------------
def _descendants_cpu() -> dict[str, float]:
    """CPU seconds of every live descendant of this process, by pid (read as ``bench_suite.Sampler`` reads them)."""
    sampler = Sampler()
    sampler.root = str(os.getpid())
    sampler.sweep()
    return {pid: cpu for pid, (_, cpu) in sampler.last.items() if pid != sampler.root}


def _ended_children_cpu() -> float:
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """Around each test (setup, call and teardown): wall, own CPU, descendants' CPU, ended children's CPU."""
    out = os.environ.get(OUT_ENV)
    if not out:
        yield
        return
    w0, c0, e0, d0 = time.monotonic(), time.process_time(), _ended_children_cpu(), _descendants_cpu()
    yield
    d1 = _descendants_cpu()
    row = {
        "id": item.nodeid,
        "wall": time.monotonic() - w0,
        "own": time.process_time() - c0,
        "descendants": sum(v - d0.get(pid, 0.0) for pid, v in d1.items()),
        "ended": _ended_children_cpu() - e0,
    }
    with open(Path(out) / f"{os.getpid()}.jsonl", "a") as f:
        f.write(json.dumps(row) + "\n")


# -- the bench --------------------------------------------------------------------------------------------------
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pytest_args", nargs="*", help="pytest arguments (default: the test command's)")
    args = ap.parse_args()
    pytest_args = args.pytest_args or ["-n", "2", "--dist", "loadgroup", "-q"]
    with tempfile.TemporaryDirectory() as out:
        env = dict(os.environ, PYTHONPATH=f"{ROOT / 'bench'}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
        env[OUT_ENV] = out
        t0 = time.monotonic()
        rc = subprocess.call([sys.executable, "-m", "pytest", "-p", "bench_test_cpu", *pytest_args], cwd=ROOT, env=env)
        wall = time.monotonic() - t0
        rows = [json.loads(line) for p in Path(out).glob("*.jsonl") for line in p.read_text().splitlines()]
    for r in rows:
        r["cpu"] = r["own"] + r["descendants"] + r["ended"]
    print(f"\npytest exit {rc}, {wall:.0f} s wall, {len(rows)} tests, load {os.getloadavg()[0]:.1f} at the end")
    browser = [r for r in rows if "/e2e/" in r["id"]]
    for name, part in (("browser tests", browser), ("other tests", [r for r in rows if r not in browser])):
        w, c = sum(r["wall"] for r in part), sum(r["cpu"] for r in part)
        rate = c / max(w, 1e-9)
        print(f"  {name:14} {len(part):4d} tests: {w:7.0f} test-s wall, {c:7.0f} core-s CPU ({rate:.2f} cores)")
    print("\nthe 15 tests that cost the most CPU (core-s: own, descendants, ended children; wall s):")
    for r in sorted(rows, key=lambda r: -r["cpu"])[:15]:
        parts = f"({r['own']:5.1f} {r['descendants']:5.1f} {r['ended']:5.1f})"
        print(f"  {r['cpu']:6.1f} {parts} {r['wall']:6.1f} s  {r['id']}")
    files: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0.0, 0.0])
    for r in rows:
        f = files[r["id"].split("::")[0]]
        f[0] += r["cpu"]
        f[1] += r["wall"]
        f[2] += 1
    print("\nthe 15 files that cost the most CPU (core-s, wall test-s, tests):")
    for name, (c, w, n) in sorted(files.items(), key=lambda kv: -kv[1][0])[:15]:
        print(f"  {c:6.1f} {w:7.1f} {int(n):4d}  {name}")


if __name__ == "__main__":
    main()
