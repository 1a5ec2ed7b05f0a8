"""What the browser tests' page script (tests/conftest.py ``page_js``) costs headless Chromium per frame asked for,
per click on the panel and while the arm moves: Chromium's CPU seconds (this bench's own processes) for ten frames
(``drawn``), ten clicks on the panel's gripper buttons and ten seconds of the left arm sent back and forth, with the
script as it is, with multisampling asked for again, with a click anywhere drawing frames freely again, and with
every frame painted and one a second (as before decision 099's last paragraph), in alternating rounds of one run,
with medians and ratios against the script as it is.

    .venv/bin/python bench/bench_test_page.py [--rounds 3]
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

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_page import chromium_cpu  # noqa: E402
from bench_suite import Sampler  # noqa: E402
from playwright.sync_api import sync_playwright  # noqa: E402

from studio.panels.move import CLOSE, OPEN  # noqa: E402
from tests.conftest import CHROMIUM, CHROMIUM_ARGS, drawn, free_port, page_js  # noqa: E402
from tests.e2e import ui  # noqa: E402

#: Added before the page script, whose own wrapper then calls this one: WebGL with multisampling again.
MULTISAMPLING = """(() => {
    const g = HTMLCanvasElement.prototype.getContext;
    HTMLCanvasElement.prototype.getContext = function (type, attrs) {
        if (type === "webgl2" || type === "webgl") attrs = Object.assign({}, attrs || {}, { antialias: true });
        return g.call(this, type, attrs);
    };
})();"""
CANVAS_ONLY = "if (!(e.target instanceof HTMLCanvasElement)) return;"
#: The draws on the canvas are skipped between looks; replaced, every frame is painted.
LOOKS_ONLY = "if (!look) return undefined;"
SETTINGS = (
    "the page script as it is",
    "with multisampling",
    "a click anywhere draws freely",
    "every frame painted, 1 a second",
)


def main() -> None:
    from studio.app import build_app

    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    script = page_js()
    assert CANVAS_ONLY in script and LOOKS_ONLY in script, "the page script changed: update this bench"
    painted = page_js(frame_ms=1000).replace(LOOKS_ONLY, "")
    sessions = Path(tempfile.mkdtemp())
    shutil.copytree(ROOT / "sessions" / "stack-cup", sessions / "stack-cup")
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    sampler = Sampler()
    sampler.root = str(os.getpid())
    frames: dict[str, list[float]] = {s: [] for s in SETTINGS}
    clicks: dict[str, list[float]] = {s: [] for s in SETTINGS}
    moving: dict[str, list[float]] = {s: [] for s in SETTINGS}
    guide = app.controller.guide
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            for _ in range(args.rounds):
                for setting in SETTINGS:
                    page = browser.new_page(viewport=ui.VIEWPORT)
                    if setting == "with multisampling":
                        page.add_init_script(MULTISAMPLING)
                    if setting.startswith("a click"):
                        page.add_init_script(script.replace(CANVAS_ONLY, ""))
                    else:
                        page.add_init_script(painted if setting.startswith("every frame") else script)
                    page.goto(app.url())
                    ui.wait_ready(page)
                    time.sleep(3.0)  # the first frames after loading are not the standing page's
                    c0 = chromium_cpu(sampler)
                    for _ in range(10):
                        drawn(page)
                    frames[setting].append((chromium_cpu(sampler) - c0) / 10)
                    row = ui.row(page, "Gripper")
                    c0 = chromium_cpu(sampler)
                    for i in range(10):
                        row.get_by_role("button", name=(CLOSE, OPEN)[i % 2], exact=True).click()
                        ui.wait_status(page, ("s.open < 1", "s.open > 99")[i % 2])
                        time.sleep(1.0)
                    clicks[setting].append((chromium_cpu(sampler) - c0) / 10)
                    c0 = chromium_cpu(sampler)
                    for i in range(4):  # 15 cm to the side and back, twice: about 10 s of a moving arm
                        guide.move("left", guide.pose("left")[0] + np.array([0.0, 0.15 * (-1) ** i, 0.0]))
                        time.sleep(2.5)
                    moving[setting].append(chromium_cpu(sampler) - c0)
                    page.close()
            browser.close()
    finally:
        app.stop()
        shutil.rmtree(sessions, ignore_errors=True)
    print(f"the browser tests' page script, Chromium's CPU seconds (median of {args.rounds} rounds):")
    for name, table in (
        ("a frame asked for", frames),
        ("a click on a gripper button", clicks),
        ("10 s of the arm moving", moving),
    ):
        base = statistics.median(table[SETTINGS[0]])
        for setting, v in table.items():
            med = statistics.median(v)
            print(f"  {name:28} {setting:32}: {med:5.3f} s  ×{med / base:4.2f}")
    print(f"load {os.getloadavg()[0]:.1f} (2 cores shared)")


if __name__ == "__main__":
    main()
