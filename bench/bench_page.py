"""What an open studio page costs headless Chromium (software WebGL): the CPU of the Chromium processes this
bench started, while the page stands still (viser's client still draws a frame a second) and while the robot
moves (a demonstration replayed), at several window sizes and with the tests' frame cap (tests/conftest.py
``FRAME_CAP_JS``: at most one animation frame per so many ms), in alternating rounds of one run, with medians
and ratios against the first setting.

    .venv/bin/python bench/bench_page.py [--rounds 3] [--seconds 15] [--caps 0,250,500] [--sizes 1280x800]
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

from bench_suite import Sampler  # noqa: E402
from playwright.sync_api import sync_playwright  # noqa: E402

from tests.conftest import CHROMIUM, CHROMIUM_ARGS, free_port, page_js  # noqa: E402
from tests.e2e import ui  # noqa: E402


def chromium_cpu(sampler: Sampler) -> float:
    """CPU seconds of the Chromium processes started by this process (not other people's)."""
    sampler.sweep()
    return sum(c for k, c in sampler.last.values() if k.startswith("chromium"))


def main() -> None:
    from studio.app import build_app

    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=15.0, help="how long each page is watched")
    ap.add_argument(
        "--caps", default="0,250/10000,500/10000", help="frame cap/heartbeat in ms (0: neither), comma-separated"
    )
    ap.add_argument("--sizes", default="1280x800", help="window sizes, e.g. 1280x800,800x500")
    ap.add_argument("--modes", default="still,moving")
    args = ap.parse_args()
    caps = args.caps.split(",")
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]
    modes = args.modes.split(",")
    sessions = Path(tempfile.mkdtemp())
    shutil.copytree(ROOT / "sessions" / "stack-cup", sessions / "stack-cup")
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions, meshes="light")
    sampler = Sampler()
    sampler.root = str(os.getpid())
    settings = [(m, s, c) for m in modes for s in sizes for c in caps]
    cores: dict[tuple, list[float]] = {k: [] for k in settings}
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            for _ in range(args.rounds):
                for mode, (w, h), cap in settings:
                    page = browser.new_page(viewport={"width": w, "height": h})
                    if cap != "0":
                        frame, heartbeat = (int(v) for v in cap.split("/"))
                        page.add_init_script(page_js(frame, heartbeat))
                    page.goto(app.url())
                    ui.wait_ready(page)
                    time.sleep(2.0)  # the first frames after loading are not the standing page's
                    if mode == "moving":
                        app.controller.playback.play_demo(0)
                    c0, t0 = chromium_cpu(sampler), time.monotonic()
                    while time.monotonic() - t0 < args.seconds:
                        time.sleep(0.5)
                        pb = app.controller.playback.loaded
                        if mode == "moving" and (pb is None or not pb.playing):
                            app.controller.playback.play_demo(0)  # again from the start: keep it moving
                    cores[(mode, (w, h), cap)].append((chromium_cpu(sampler) - c0) / (time.monotonic() - t0))
                    if mode == "moving":
                        app.controller.playback.stop(app.controller.playback.kind or "replay")
                    page.close()
            browser.close()
    finally:
        app.stop()
        shutil.rmtree(sessions, ignore_errors=True)
    print(f"an open studio page, Chromium's CPU (median of {args.rounds} rounds of {args.seconds:.0f} s):")
    for mode in modes:
        base = statistics.median(cores[(mode, sizes[0], caps[0])])
        for (m, (w, h), cap), v in cores.items():
            if m != mode:
                continue
            med = statistics.median(v)
            shown = "none" if cap == "0" else cap
            what = f"{mode:6} {w:>5} × {h:<4} ({w * h / 1e6:4.2f} Mpx), frame cap/heartbeat {shown:>10} ms"
            print(f"  {what}: {med:5.2f} cores  ×{med / base:4.2f}")
    print(f"load {os.getloadavg()[0]:.1f} (2 cores shared)")


if __name__ == "__main__":
    main()
