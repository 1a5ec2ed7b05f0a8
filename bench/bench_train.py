"""CPU seconds of one Train (as the Train button does: learn, then judge) on each example session, in this
checkout and, as a baseline measured in the same run, at another commit (checked out in a temporary git worktree).
Each train runs in a process of its own kind, the two kinds taking turns; medians.

    .venv/bin/python bench/bench_train.py --baseline eafa334 [--rounds 3] [--trains 3]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ("stack-cup", "pick-place")

#: Run in the checkout measured (its ``studio`` first on the path): one warm-up train, then ``trains`` more, each
#: on a fresh controller (nothing learned is kept between them); prints the CPU seconds of each, as JSON.
CHILD = """
import json, shutil, sys, tempfile, time
from pathlib import Path
from studio.commands import headless, train
from studio.storage import SessionStore
src, trains = Path(sys.argv[1]), int(sys.argv[2])
out = {}
with tempfile.TemporaryDirectory() as d:
    shutil.copytree(src, Path(d) / "sessions")
    store = SessionStore(Path(d) / "sessions")
    for name in sys.argv[3:]:
        out[name] = []
        for i in range(trains + 1):
            t0 = time.process_time()
            with headless(store, store.open(name)) as ctl:
                train(ctl)
            if i:
                out[name].append(time.process_time() - t0)
print(json.dumps(out))
"""


def run(checkout: Path, trains: int) -> dict[str, list[float]]:
    env = dict(os.environ, PYTHONPATH=str(checkout), PYTHONDONTWRITEBYTECODE="")
    done = subprocess.run(
        [sys.executable, "-c", CHILD, str(ROOT / "sessions"), str(trains), *EXAMPLES],
        cwd=checkout,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", required=True, help="the commit to compare with (e.g. the last stop's)")
    ap.add_argument("--rounds", type=int, default=3, help="processes of each kind, taking turns")
    ap.add_argument("--trains", type=int, default=3, help="trains per example in each process (after a warm-up)")
    args = ap.parse_args()
    base = Path(tempfile.mkdtemp()) / "baseline"
    subprocess.run(["git", "worktree", "add", "--detach", str(base), args.baseline], cwd=ROOT, check=True)
    try:
        cpu: dict[str, dict[str, list[float]]] = {"baseline": {}, "this": {}}
        for _ in range(args.rounds):
            for kind, checkout in (("baseline", base), ("this", ROOT)):
                for name, values in run(checkout, args.trains).items():
                    cpu[kind].setdefault(name, []).extend(values)
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(base)], cwd=ROOT, check=False)
        shutil.rmtree(base.parent, ignore_errors=True)
    n = args.rounds * args.trains
    print(f"load average {os.getloadavg()[0]:.1f} at the end; CPU s of one Train, median of {n}")
    print(f"{'example':12} {'baseline ' + args.baseline:>20} {'this checkout':>14} {'ratio':>6}")
    for name in EXAMPLES:
        b, t = statistics.median(cpu["baseline"][name]), statistics.median(cpu["this"][name])
        print(f"{name:12} {b:20.2f} {t:14.2f} {t / b:6.2f}")


if __name__ == "__main__":
    main()
