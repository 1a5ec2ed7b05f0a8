"""What a Python process of the studio costs to start with and without compiled modules: the CPU seconds of
``import studio.app`` (every studio, `studio learn`) and of a pytest worker's imports, each compiled from source as
in a fresh clone whose environment says PYTHONDONTWRITEBYTECODE (an empty PYTHONPYCACHEPREFIX: nothing found,
nothing written), against reading the compiled files the bootstrap and the test command now leave.

    .venv/bin/python bench/bench_bytecode.py [--rounds 5]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: (what, the code a process runs)
IMPORTS = (
    ("a studio: import studio.app", "import studio.app"),
    (
        "a test worker: the studio, pytest, playwright, hypothesis",
        "import studio.app, pytest, playwright.sync_api, hypothesis, xdist, tests.conftest",
    ),
)


def cpu_of(code: str, env: dict[str, str]) -> float:
    """CPU seconds (user + system) of a new interpreter running ``code``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    base = {k: v for k, v in os.environ.items() if k not in ("PYTHONPYCACHEPREFIX", "PYTHONDONTWRITEBYTECODE")}
    with tempfile.TemporaryDirectory() as empty:
        source = dict(base, PYTHONDONTWRITEBYTECODE="1", PYTHONPYCACHEPREFIX=empty)
        compiled = dict(base, PYTHONDONTWRITEBYTECODE="1")
        for _, code in IMPORTS:  # write what is missing, as scripts/bootstrap.sh and scripts/run-tests.sh do
            cpu_of(code, base)
        print(f"CPU seconds to start, median of {args.rounds} rounds (alternating)")
        print(f"{'':58} {'from source':>12} {'compiled':>10} {'ratio':>7}")
        for what, code in IMPORTS:
            a: list[float] = []
            b: list[float] = []
            for _ in range(args.rounds):
                a.append(cpu_of(code, source))
                b.append(cpu_of(code, compiled))
            ma, mb = statistics.median(a), statistics.median(b)
            print(f"{what:58} {ma:10.2f} s {mb:8.2f} s {mb / ma:7.2f}")


if __name__ == "__main__":
    main()
