"""Where the test suite's time goes: runs a command (by default the test command, ``scripts/run-tests.sh``) and
reads the CPU time of every process it starts (its descendants only: the machine may be shared) from /proc once a
second, then prints the CPU seconds per kind of process (Chromium's GPU process and renderers, the pytest workers
with their in-process studios, the studios started as subprocesses, pip, lint) beside the wall time.

    .venv/bin/python bench/bench_suite.py                     # the whole test command
    .venv/bin/python bench/bench_suite.py -- .venv/bin/python -m pytest -n 2 tests/e2e   # any command
"""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TICK = os.sysconf("SC_CLK_TCK")

#: (kind, words in the command line that make it so), first match wins.
KINDS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("chromium GPU process (software WebGL)", ("chromium", "gpu-process")),
    ("chromium renderers", ("chromium", "type=renderer")),
    ("chromium, other", ("chromium",)),
    ("studio servers started as subprocesses", ("studio serve",)),
    ("studio servers started as subprocesses", ("fast_robot", "serve")),
    ("playwright driver", ("playwright/driver",)),
    ("pytest workers, with their in-process studios", ("pytest",)),
    ("pytest workers, with their in-process studios", ("exec(eval(sys.stdin",)),
    ("lint and types", ("mypy",)),
    ("lint and types", ("ruff",)),
    ("pip", ("pip",)),
)


def kind(cmdline: str) -> str:
    for name, words in KINDS:
        if all(w in cmdline for w in words):
            return name
    return "other"


def command(pid: str) -> str:
    return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")


def process_cpu(pid: str) -> tuple[str, float] | None:
    """The kind of process ``pid`` and its CPU seconds so far (None once it has ended)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        cmd = command(pid)
    except OSError:
        return None
    return kind(cmd), (int(stat[11]) + int(stat[12])) / TICK


def _idle() -> float:
    return float(Path("/proc/stat").read_text().split("\n", 1)[0].split()[4]) / TICK


def _parent(pid: str) -> str | None:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1]
    except OSError:
        return None


class Sampler:
    """CPU seconds per kind of process among the descendants of ``root`` (each process's last reading before it
    ended): other people's processes on a shared machine are not counted."""

    def __init__(self) -> None:
        self.root = ""
        self.last: dict[str, tuple[str, float]] = {}
        self.commands: dict[str, str] = {}  # of the processes of no known kind
        self.idle0 = _idle()
        self.stop = threading.Event()

    def _tree(self) -> set[str]:
        children: dict[str, list[str]] = {}
        for pid in os.listdir("/proc"):
            if pid.isdigit() and (parent := _parent(pid)) is not None:
                children.setdefault(parent, []).append(pid)
        tree, todo = set(), [self.root]
        while todo:
            pid = todo.pop()
            tree.add(pid)
            todo.extend(children.get(pid, ()))
        return tree

    def run(self) -> None:
        while not self.stop.wait(1.0):
            self.sweep()

    def sweep(self) -> None:
        for pid in self._tree():
            if (got := process_cpu(pid)) is not None:
                # an ended process (a zombie) has no command line any more: it keeps the kind it had
                self.last[pid] = (self.last[pid][0] if got[0] == "other" and pid in self.last else got[0], got[1])
                if got[0] == "other" and pid not in self.commands:
                    with contextlib.suppress(OSError):
                        self.commands[pid] = command(pid)[:100]

    def totals(self) -> dict[str, float]:
        tot: dict[str, float] = {}
        for k, c in self.last.values():
            tot[k] = tot.get(k, 0.0) + c
        return tot


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("command", nargs="*", help="the command to run (default: bash scripts/run-tests.sh)")
    args = ap.parse_args()
    cmd = args.command or ["bash", "scripts/run-tests.sh"]
    sampler = Sampler()
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, cwd=ROOT)
    sampler.root = str(proc.pid)
    th = threading.Thread(target=sampler.run, daemon=True)
    th.start()
    rc = proc.wait()
    wall = time.monotonic() - t0
    sampler.stop.set()
    th.join()
    idle = _idle() - sampler.idle0
    cores = os.cpu_count() or 1
    tot = sampler.totals()
    print(f"\n# {' '.join(cmd)}: exit {rc}, {wall:.0f} s wall on {cores} cores")
    print(f"idle: {idle:.0f} core-s of {wall * cores:.0f} ({100 * idle / (wall * cores):.0f} %)")
    for k, v in sorted(tot.items(), key=lambda kv: -kv[1]):
        print(f"{v:7.0f} s  {100 * v / max(sum(tot.values()), 1e-9):4.0f} %  {k}")
    others = sorted(((c, sampler.commands.get(p, "?")) for p, (k, c) in sampler.last.items() if k == "other"))
    for c, cmd in others[::-1][:5]:
        print(f"        {c:7.1f} s  other: {cmd}")
    return rc


if __name__ == "__main__":
    sys.exit(main())
