"""The live loop in a real browser: an ε slider step until the key-points (and the live learned path) show.

Measured in headless Debian Chromium (Playwright) against a `studio serve` subprocess, the way a teacher
works: the Key-points tab is open, the ε5 slider ("Travel distance") has the keyboard focus, and each step is
one ArrowRight key press. In the page, a key-down listener stamps the press (``performance.now()``), a
MutationObserver stamps the moment the per-demo key-point counts change in the side panel (they arrive in the
same atomic batch as the key-point and centroid markers) and the first animation frame after it (the frame
that draws the new markers); the live path's figure (and its dashed path, one batch) is stamped the same way.

Baseline in the same run: the round trip of a GUI change that does no work (the "Choose the number of
clusters automatically" box is ticked twice; its callback only stores k and requests the key-point view),
measured from the click to the first frame after the studio's answer (the k slider's enabled state).

Sessions:
* ``example``: a copy of the example session "stack-cup" (3 demos × ~22,000 samples at 1 kHz);
* ``3x30k``: 3 demos × 30,000 samples (bench_app.py's), for the live path's ≤ 150 ms budget.

Run:  .venv/bin/python bench/bench_live.py [--steps 15] [--session example|3x30k|both]
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.conftest import CHROMIUM, CHROMIUM_ARGS  # noqa: E402  (after the path insert)
from tests.e2e.conftest import StudioProcess  # noqa: E402

EPS5_LABEL = "Travel distance (ε5)"

_INSTALL_JS = """() => {
    window.__live = {press: [], counts: [], countsFrame: [], path: [], pathFrame: [], click: []};
    const L = window.__live;
    document.addEventListener("pointerdown", () => L.click.push(performance.now()), true);
    document.addEventListener("keydown", e => { if (e.key.startsWith("Arrow")) {L.press.push(performance.now()); console.log("TRACE press " + (performance.timeOrigin + performance.now()).toFixed(1));} },
                              true);
    let lastCounts = null, lastPath = null;
    const read = () => {
        const c = [...document.querySelectorAll(".kp-count")].map(e => e.dataset.count).join(",");
        const p = [...document.querySelectorAll(".live-path")].map(e => e.dataset.version).join(",");
        return [c, p];
    };
    [lastCounts, lastPath] = read();
    new MutationObserver(() => {
        const [c, p] = read();
        const now = performance.now();
        if (c !== lastCounts) {
            lastCounts = c; L.counts.push(now); console.log("TRACE counts " + (performance.timeOrigin + now).toFixed(1));
            requestAnimationFrame(() => L.countsFrame.push(performance.now()));
        }
        if (p !== lastPath) {
            lastPath = p; L.path.push(now);
            requestAnimationFrame(() => L.pathFrame.push(performance.now()));
        }
    }).observe(document.body, {subtree: true, childList: true, characterData: true, attributes: true});
}"""


def make_sessions(root: Path, which: str) -> None:
    if which == "example":
        shutil.copytree(ROOT / "sessions" / "stack-cup", root / "example")
    else:
        from bench.bench_app import make_session

        make_session(root)
        (root / "bench").rename(root / "3x30k")


def _slider_thumb(page, label: str):
    from tests.e2e import ui

    return ui.row(page, label).locator("[role=slider]").first


def measure(browser, url: str, steps: int, has_path: bool) -> dict[str, list[float]]:
    from playwright.sync_api import expect

    from tests.e2e import ui

    page = ui.open_studio(browser, url)
    page.on("console", lambda m: print(m.text, flush=True) if m.text.startswith("TRACE") else None)
    try:
        ui.tab(page, "Key-points")
        thumb = _slider_thumb(page, EPS5_LABEL)
        expect(thumb).to_be_visible()
        page.wait_for_function("() => document.querySelectorAll('.kp-count').length > 0", timeout=60_000)
        time.sleep(2.0)  # let the first view and live path settle
        page.evaluate(_INSTALL_JS)
        out: dict[str, list[float]] = {"counts": [], "frame": [], "path": [], "path_frame": [], "misses": []}
        thumb.focus()
        for i in range(steps):
            n_press = page.evaluate("() => window.__live.press.length")
            n_counts = page.evaluate("() => window.__live.counts.length")
            n_path = page.evaluate("() => window.__live.path.length")
            key = "ArrowRight" if (i // 4) % 2 == 0 else "ArrowLeft"  # wander up and back
            thumb.press(key)
            try:
                page.wait_for_function(
                    f"() => window.__live.counts.length > {n_counts} && window.__live.countsFrame.length > {n_counts}",
                    timeout=3000,
                    polling=20,
                )
            except Exception:
                out["misses"].append(float(i))  # this step did not change any count
                time.sleep(0.3)
                continue
            if has_path:
                try:
                    page.wait_for_function(f"() => window.__live.pathFrame.length > {n_path}", timeout=5000, polling=20)
                except Exception:
                    pass
            time.sleep(0.25)  # the teacher looks before the next step
            live = page.evaluate("() => window.__live")
            t0 = live["press"][n_press]
            out["counts"].append(live["counts"][n_counts] - t0)
            out["frame"].append(live["countsFrame"][n_counts] - t0)
            if has_path and len(live["pathFrame"]) > n_path:
                out["path"].append(live["path"][n_path] - t0)
                out["path_frame"].append(live["pathFrame"][n_path] - t0)
        # Baseline: a GUI change that does no work, click → the studio's answer drawn.
        base: list[float] = []
        box = ui.row(page, "Choose the number of clusters automatically").locator("input").first
        k_input = ui.row(page, "Clusters (k)").locator("[role=slider]").first
        for _ in range(6):
            was_disabled = k_input.get_attribute("data-disabled") == "true"
            n_click = page.evaluate("() => window.__live.click.length")
            box.click()
            page.wait_for_function(
                """(was) => {
                    const rows = [...document.querySelectorAll('label')].filter(l => l.textContent.trim() === 'Clusters (k)');
                    if (!rows.length) return false;
                    const row = rows[0].closest('.mantine-Flex-root');
                    const s = row && row.querySelector('[role=slider]');
                    return s && ((s.getAttribute('data-disabled') === 'true') !== was);
                }""",
                arg=was_disabled,
                timeout=5000,
                polling=10,
            )
            t1 = page.evaluate("() => new Promise(r => requestAnimationFrame(() => r(performance.now())))")
            base.append(t1 - page.evaluate(f"() => window.__live.click[{n_click}]"))
            time.sleep(0.3)
        out["baseline"] = base
        return out
    finally:
        page.close()


def _fmt(xs: list[float]) -> str:
    if not xs:
        return "n/a"
    return f"median {statistics.median(xs):.0f} ms (range {min(xs):.0f}–{max(xs):.0f}, n = {len(xs)})"


def main() -> int:
    from playwright.sync_api import sync_playwright

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=15)
    ap.add_argument("--session", choices=("example", "3x30k", "both"), default="both")
    args = ap.parse_args()
    which = ("example", "3x30k") if args.session == "both" else (args.session,)
    tmp = Path(tempfile.mkdtemp(prefix="bench-live-"))
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            for name in which:
                make_sessions(tmp, name)
                studio = StudioProcess(tmp, name).start(timeout=120)
                try:
                    r = measure(browser, studio.url, args.steps, has_path=True)
                finally:
                    studio.stop()
                print(f"[{name}] ε5 ArrowRight → key-point counts changed in the page: {_fmt(r['counts'])}")
                print(f"[{name}] ε5 ArrowRight → first frame with the new key-points: {_fmt(r['frame'])}")
                print(f"[{name}] ε5 ArrowRight → live path figure changed: {_fmt(r['path'])}")
                print(f"[{name}] ε5 ArrowRight → first frame with the new live path: {_fmt(r['path_frame'])}")
                print(f"[{name}] baseline, a GUI change that does no work → answer drawn: {_fmt(r['baseline'])}")
                if r["misses"]:
                    print(f"[{name}] steps that changed no count: {len(r['misses'])}")
            browser.close()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
