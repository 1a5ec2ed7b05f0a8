"""What an open studio page costs headless Chromium (software WebGL) at several window sizes: the CPU of every
Chromium process while the page stands still (viser's client still draws a frame a second), per size, in
alternating rounds of one run, with medians and ratios against the test suite's 1280 × 800.

    .venv/bin/python bench/bench_page.py [--rounds 3] [--seconds 15]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_suite import process_cpu  # noqa: E402
from playwright.sync_api import sync_playwright  # noqa: E402

from tests.conftest import CHROMIUM, CHROMIUM_ARGS  # noqa: E402
from tests.e2e import ui  # noqa: E402
from tests.e2e.conftest import StudioProcess  # noqa: E402

SIZES = ((1280, 800), (1024, 640), (800, 500))


def chromium_cpu() -> float:
    """CPU seconds of every running Chromium process."""
    return sum(got[1] for pid in os.listdir("/proc") if (got := process_cpu(pid)) and got[0].startswith("chromium"))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=15.0, help="how long each page is watched")
    args = ap.parse_args()
    sessions = Path(tempfile.mkdtemp())
    shutil.copytree(ROOT / "sessions" / "stack-cup", sessions / "stack-cup")
    server = StudioProcess(sessions, "stack-cup").start()
    cores: dict[tuple[int, int], list[float]] = {s: [] for s in SIZES}
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            for _ in range(args.rounds):
                for w, h in SIZES:
                    page = browser.new_page(viewport={"width": w, "height": h})
                    page.goto(server.url)
                    ui.wait_ready(page)
                    time.sleep(2.0)  # the first frames after loading are not the standing page's
                    c0, t0 = chromium_cpu(), time.monotonic()
                    time.sleep(args.seconds)
                    cores[(w, h)].append((chromium_cpu() - c0) / (time.monotonic() - t0))
                    page.close()
            browser.close()
    finally:
        server.stop()
        shutil.rmtree(sessions, ignore_errors=True)
    base = statistics.median(cores[SIZES[0]])
    print(f"an open, still studio page, Chromium's CPU (median of {args.rounds} rounds of {args.seconds:.0f} s):")
    for (w, h), v in cores.items():
        m = statistics.median(v)
        print(f"  {w:>5} × {h:<4} ({w * h / 1e6:4.2f} Mpx): {m:5.2f} cores  ×{m / base:4.2f} of 1280 × 800")
    print(f"load {os.getloadavg()[0]:.1f} (2 cores shared)")


if __name__ == "__main__":
    main()
