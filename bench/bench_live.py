"""The live loop in a real browser: one ε5 step (ArrowRight on the focused slider) until the new key-points,
centroids and live learned path show.

Headless Debian Chromium (Playwright) drives the studio the way a teacher does: the Key-points tab, the "All
thresholds" folder open, the ε5 slider ("Travel distance") focused, one arrow key press per step (four right,
four left, …), each once the page is idle again (a teacher looks at the result before the next step). The
studio runs in this process (as `studio serve` would: robot streaming at 1 kHz, pose pump, key-point thread),
so the server's side of each step is timed too, on the same clock as the page (epoch milliseconds).

Per step, from the key press (the key event's own time stamp, taken by the browser when the key went down):
  * server got the change — the slider's callback runs in the studio;
  * server queued the markers — key-points and centroids (sent with the live path, one scene batch);
  * page shows the counts — the per-demo key-point counts changed in the page (sent at once, GUI only: viser
    applies a GUI-only batch without drawing the 3-D scene);
  * first frame drawn after the counts — the first WebGL frame that draws after the counts changed has
    completed (every draw call is watched; the animation frame after it starts once that frame's task is
    over). Where the markers travel with the counts (the baselines) it shows them; in the studio it is the
    frame of the batch below unless viser's 1 Hz safety-net frame comes first;
  * live path shown — the live path's figure changed in the page: the batch with the dashed path, its figure
    and the markers arrived (viser applies a batch with scene updates inside its render loop, so this is
    also when the frame that draws it starts, once the page is free);
  * markers and live path drawn — the first frame drawn after that has completed.
Until 2026-11-25 "drawn" was taken two animation frames after the change: one frame too late whenever the change
arrives inside a frame (viser keeps drawing for 250 ms after each scene update), so the 2026-11-23 "drawn"
rows overstate by about one frame (bench/README.md).

Baselines in the same run: the same steps (1) with the key-point markers sent as soon as they are computed,
apart from their live path (two scene updates a step, as first written), and (2) also without the page script
that keeps arrow keys in the focused control (:mod:`studio.panels._page`): the key press then also starts
viser's keyboard camera orbit, as it did before this work.

Sessions: ``example`` — a copy of "stack-cup" (3 demos × ~22,000 samples at 1 kHz); ``3x30k`` — 3 demos ×
30,000 samples (bench_app.py's), for the live path's ≤ 150 ms budget.

Run:  .venv/bin/python bench/bench_live.py [--steps 16] [--session example|3x30k|both] [--no-baseline]
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.conftest import CHROMIUM, CHROMIUM_ARGS, free_port  # noqa: E402  (after the path insert)

EPS5_LABEL = "Travel distance, cm (ε5)"

_INSTALL_JS = """() => {
    const L = window.__live = {press: [], counts: [], countsFrame: [], path: [], pathFrame: [], longEnd: 0};
    const epoch = (t) => performance.timeOrigin + t;
    new PerformanceObserver(list => { for (const e of list.getEntries()) {
        L.longEnd = Math.max(L.longEnd, e.startTime + e.duration); } }).observe({entryTypes: ["longtask"]});
    // Quiet: no long task (a frame of the software renderer) for 500 ms, and this check itself ran
    // every poll without a gap (a blocked page cannot run it), for 500 ms.
    let since = 0, lastPoll = 0;
    window.__quiet = () => {
        const now = performance.now();
        if (now - lastPoll > 100) since = now;
        lastPoll = now;
        return now - since > 500 && now - L.longEnd > 500;
    };
    window.addEventListener("keydown", e => { if (e.key.startsWith("Arrow")) L.press.push(epoch(e.timeStamp)); },
                            true);
    const read = () => [
        [...document.querySelectorAll(".kp-count")].map(e => e.dataset.count).join(","),
        [...document.querySelectorAll(".live-path")].map(e => e.dataset.version).join(","),
    ];
    // "Drawn": the end of the first WebGL frame that draws with the change. Every draw call is seen (the
    // context's prototype methods are wrapped). viser applies a batch with scene updates inside its render
    // loop, before that frame's draw calls, and React writes its GUI part into the page later in the same
    // task: a change made in a task that already drew is in that frame. Otherwise the next frame that draws
    // has it. Either way the animation frame after that drawing starts once its task (and read-back) is over.
    let waiting = [], drewThisTask = false;
    const stamp = (lists) => requestAnimationFrame(() => {
        const t = epoch(performance.now());
        for (const l of lists) l.push(t);
    });
    const onDraw = () => {
        if (!drewThisTask) {
            drewThisTask = true;
            const ch = new MessageChannel();  // a task of its own: runs once this one is over
            ch.port1.onmessage = () => { drewThisTask = false; };
            ch.port2.postMessage(0);
        }
        if (waiting.length) { stamp(waiting); waiting = []; }
    };
    for (const P of [WebGLRenderingContext.prototype, WebGL2RenderingContext.prototype]) {
        for (const m of ["drawElements", "drawArrays", "drawElementsInstanced", "drawArraysInstanced"]) {
            const f = P[m];
            if (!f) continue;
            P[m] = function (...a) { onDraw(); return f.apply(this, a); };
        }
    }
    const drawn = (list) => { if (drewThisTask) stamp([list]); else waiting.push(list); };
    let [lastCounts, lastPath] = read();
    new MutationObserver(() => {
        const [c, p] = read();
        const now = epoch(performance.now());
        if (c !== lastCounts) { lastCounts = c; L.counts.push(now); drawn(L.countsFrame); }
        if (p !== lastPath) { lastPath = p; L.path.push(now); drawn(L.pathFrame); }
    }).observe(document.body, {subtree: true, childList: true, characterData: true, attributes: true});
}"""


def make_sessions(root: Path, which: str) -> str:
    if which == "example":
        shutil.copytree(ROOT / "sessions" / "stack-cup", root / "example")
        return "example"
    from bench.bench_app import make_session

    make_session(root)
    return "bench"


@contextmanager
def studio(root: Path, session: str, guard: bool, batched: bool = True) -> Iterator:
    """The studio in this process; ``guard=False`` leaves out the arrow-key page script, ``batched=False`` sends
    the markers at once instead of with their live path (the baselines)."""
    import studio.app as app_mod
    from studio.app import build_app
    from studio.panels.keypoints import KeypointsPanel

    original, on_view = app_mod.install_page, KeypointsPanel._on_view
    if not guard:
        app_mod.install_page = lambda server: None  # type: ignore[assignment]
    if not batched:

        def apart(self: KeypointsPanel) -> None:
            if self.ctl.keypoints.view is not None:
                self.draw(self.ctl.keypoints.view)

        KeypointsPanel._on_view = apart  # type: ignore[method-assign]
    try:
        app = build_app(port=free_port(), session=session, sessions_dir=root)
    finally:
        app_mod.install_page, KeypointsPanel._on_view = original, on_view  # type: ignore[method-assign]
    stamps: dict[str, list[float]] = {"got": [], "queued": [], "path_queued": []}
    from studio.controller import Topic

    kp, panel = app.controller.keypoints, app.panels.keypoints
    set_param, draw_markers = kp.set_param, panel._draw_markers

    def timed_set(name: str, value: float) -> None:
        stamps["got"].append(1e3 * time.time())
        set_param(name, value)

    def timed_markers(view) -> None:  # type: ignore[no-untyped-def]
        draw_markers(view)
        stamps["queued"].append(1e3 * time.time())  # the atomic batch is sent when its block ends, right after

    kp.set_param = timed_set  # type: ignore[method-assign]
    panel._draw_markers = timed_markers  # type: ignore[method-assign]
    # subscribed after the panel: runs once the panel queued the dashed path and its figure
    app.controller.events.on(Topic.LIVE_PATH, lambda: stamps["path_queued"].append(1e3 * time.time()))
    try:
        yield app, stamps
    finally:
        app.stop()


def _after(xs: list[float], t: float, until: float) -> float | None:
    hit = [x for x in xs if t <= x < until]
    return hit[0] if hit else None


def measure(browser, app, stamps: dict[str, list[float]], steps: int) -> dict[str, list[float]]:
    from playwright.sync_api import expect

    from tests.e2e import ui

    page = ui.open_studio(browser, app.url())
    out: dict[str, list[float]] = {k: [] for k in ("got", "queued", "counts", "frame", "path", "path_frame")}
    out["misses"] = []
    out["live_ms"] = []
    try:
        ui.tab(page, "Key-points")
        ui.open_folder(page, "All thresholds")
        thumb = ui.row(page, EPS5_LABEL).locator("[role=slider]").first
        expect(thumb).to_be_visible()
        page.wait_for_function("() => document.querySelectorAll('.kp-count').length > 0", timeout=60_000)
        thumb.focus()
        page.keyboard.press("ArrowRight")  # the first step opens the Key-points step of the scene; not counted
        time.sleep(3.0)
        page.evaluate(_INSTALL_JS)
        for i in range(steps):
            n = page.evaluate("() => window.__live.counts.length")
            page.keyboard.press("ArrowRight" if (i // 4) % 2 == 0 else "ArrowLeft")  # the focused slider
            try:
                page.wait_for_function(f"() => window.__live.countsFrame.length > {n}", timeout=5000, polling=10)
            except Exception:
                out["misses"].append(float(i))
            # one step at a time: the next key press finds the page idle (the teacher looks at the result)
            try:
                page.wait_for_function("() => window.__quiet()", timeout=10_000, polling=20)
            except Exception:
                pass
            out["live_ms"].append(app.controller.live.computed_ms)
        live = page.evaluate("() => window.__live")
        presses = live["press"] + [float("inf")]
        for j, t0 in enumerate(presses[:-1]):
            t1 = presses[j + 1]
            for key, src in (
                ("got", stamps["got"]),
                ("queued", stamps["queued"]),
                ("counts", live["counts"]),
                ("frame", live["countsFrame"]),
                ("path", live["path"]),
                ("path_frame", live["pathFrame"]),
            ):
                hit = _after(src, t0, t1)
                if hit is not None:
                    out[key].append(hit - t0)
        return out
    finally:
        page.close()


def measure_suggest(browser, app, repeats: int = 2) -> dict[str, list[float]]:
    """Suggest pressed in the page until "Undo suggestion" shows (applied), in the running studio; with the
    studio's helper threads and in the work thread alone, alternately."""
    from playwright.sync_api import expect

    from tests.e2e import ui

    page = ui.open_studio(browser, app.url())
    out: dict[str, list[float]] = {"workers": [], "one process": [], "server": [], "applied": []}
    applied: list[float] = []
    from studio.controller import Topic

    app.controller.events.on(
        Topic.SUGGEST, lambda: applied.append(time.perf_counter()) if app.controller.suggest.state.can_undo else None
    )
    try:
        ui.tab(page, "Key-points")
        page.wait_for_function("() => document.querySelectorAll('.kp-count').length > 0", timeout=60_000)
        for _ in range(repeats):
            for label, workers in (("workers", None), ("one process", 1)):
                app.controller.suggest.workers = workers
                t0 = time.perf_counter()
                page.get_by_role("button", name="Suggest thresholds").click()
                expect(page.get_by_role("button", name="Undo suggestion")).to_be_visible(timeout=120_000)
                out[label].append(1e3 * (time.perf_counter() - t0))
                out["server"].append(1e3 * app.controller.suggest.state.seconds)
                out["applied"].append(1e3 * (applied[-1] - t0))
                page.get_by_role("button", name="Undo suggestion").click()
                expect(page.get_by_role("button", name="Undo suggestion")).to_be_hidden(timeout=30_000)
        return out
    finally:
        page.close()


def measure_server(app, repeats: int = 30) -> dict[str, list[float]]:
    """One ε5 step on the server (re-extract, re-cluster, draw; then the live path), timed in the running studio
    (1 kHz stream, pose pump, viser) and again with the robot stream and the pose pump stopped: what the GIL
    contention with them costs. Also the messages one step sends to the browsers."""

    from studio.controller import Step

    ctl, panel = app.controller, app.panels.keypoints
    ctl.view.set_step(Step.KEYPOINTS)
    kp, live = ctl.keypoints, ctl.live
    base = kp.params().eps5
    out: dict[str, list[float]] = {}

    def steps(label: str) -> None:
        view_ms, path_ms = [], []
        for i in range(repeats):
            kp.set_param("eps5", base * (1.0 + 0.1 * (i % 5)))
            t0 = time.perf_counter()
            view = kp.compute()
            panel.draw(view)
            t1 = time.perf_counter()
            live.follow(view, lambda: False)
            t2 = time.perf_counter()
            view_ms.append(1e3 * (t1 - t0))
            path_ms.append(1e3 * (t2 - t1))
        out[f"view {label}"], out[f"path {label}"] = view_ms, path_ms

    kp.close()  # the key-point thread would compete: the steps here are run by hand
    time.sleep(1.0)
    steps("running")
    app._pump.stop()
    ctl.teaching.stop_robot()
    time.sleep(1.0)
    steps("quiet")
    # messages and bytes one step queues for the browsers (viser's message buffer)
    import msgspec

    buf = app.server._websock_server._broadcast_buffer
    counts, sizes = [], []
    for i in range(10):
        kp.set_param("eps5", base * (1.0 + 0.1 * (i % 5)))
        view = kp.compute()
        n0 = buf.message_counter
        panel.draw(view)
        live.follow(view, lambda: False)
        ids = range(n0, buf.message_counter)
        msgs = [buf.message_from_id[j] for j in ids if j in buf.message_from_id]
        counts.append(float(buf.message_counter - n0))
        sizes.append(sum(len(msgspec.msgpack.encode(m.as_serializable_dict())) for m in msgs) / 1024.0)
    out["messages"], out["kib"] = counts, sizes
    return out


def _fmt(xs: list[float]) -> str:
    if not xs:
        return "n/a"
    return f"median {statistics.median(xs):5.0f} ms (range {min(xs):.0f}–{max(xs):.0f}, n = {len(xs)})"


def report(name: str, r: dict[str, list[float]], batched: bool = True) -> None:
    """``batched``: the markers travel with the live path (the studio), else with the counts (baselines)."""
    print(f"  server got the change:                 {_fmt(r['got'])}")
    print(f"  server queued key-points + centroids:  {_fmt(r['queued'])}")
    print(f"  page shows the new key-point counts:   {_fmt(r['counts'])}")
    after = "first frame drawn after the counts" if batched else "new markers drawn"
    print(f"  {after + ':':39s}{_fmt(r['frame'])}")
    print(f"  page shows the live path's figure:     {_fmt(r['path'])}")
    both = "markers + live path drawn" if batched else "new live path drawn"
    print(f"  {both + ':':39s}{_fmt(r['path_frame'])}")
    live = [x for x in r["live_ms"] if x == x]
    if live:
        print(f"  (live path computed in {statistics.median(live):.0f} ms median on the server)")
    if r["misses"]:
        print(f"  steps after which no count changed: {len(r['misses'])}")


def main() -> int:
    from playwright.sync_api import sync_playwright

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=16)
    ap.add_argument("--session", choices=("example", "3x30k", "both"), default="both")
    ap.add_argument("--no-baseline", action="store_true", help="skip the run without the page script")
    ap.add_argument("--suggest", action="store_true", help="also time Suggest in the browser on 3 × 30,000")
    ap.add_argument("--server", action="store_true", help="also time one step on the server, stream on and off")
    args = ap.parse_args()
    which = ("example", "3x30k") if args.session == "both" else (args.session,)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        variants = [("the studio", True, True)]
        if not args.no_baseline:
            variants += [
                ("baseline: markers sent apart from their live path (two scene updates a step)", True, False),
                ("baseline: as before, arrow keys also orbit the camera, markers apart", False, False),
            ]
        for which_one in which:
            for label, guard, batched in variants:
                tmp = Path(tempfile.mkdtemp(prefix="bench-live-"))
                try:
                    session = make_sessions(tmp, which_one)
                    with studio(tmp, session, guard, batched) as (app, stamps):
                        r = measure(browser, app, stamps, args.steps)
                    print(f"[{which_one}] {label}, ε5 one step, from the key press:")
                    report(which_one, r, batched)
                finally:
                    shutil.rmtree(tmp, ignore_errors=True)
        if args.server:
            for which_one in which:
                tmp = Path(tempfile.mkdtemp(prefix="bench-live-"))
                try:
                    with studio(tmp, make_sessions(tmp, which_one), True) as (app, _):
                        r = measure_server(app)
                    print(f"[{which_one}] one ε5 step on the server (no browser connected):")
                    for key in ("view running", "view quiet", "path running", "path quiet"):
                        what = "key-points + k-means + drawing" if key.startswith("view") else "live path"
                        where = "studio running" if key.endswith("running") else "stream and pose pump stopped"
                        print(f"  {what}, {where}: {_fmt(r[key])}")
                    m, kib = r["messages"], r["kib"]
                    print(
                        f"  sent to the browsers per step: {statistics.median(m):.0f} messages, "
                        f"{statistics.median(kib):.1f} KiB (median)"
                    )
                finally:
                    shutil.rmtree(tmp, ignore_errors=True)
        if args.suggest:
            tmp = Path(tempfile.mkdtemp(prefix="bench-live-"))
            try:
                session = make_sessions(tmp, "3x30k")
                with studio(tmp, session, True) as (app, _):
                    r = measure_suggest(browser, app)
                print("[3x30k] Suggest thresholds pressed → applied (Undo shown), in the running studio:")
                print(f"  helper threads:           {_fmt(r['workers'])}")
                print(f"  one process:              {_fmt(r['one process'])}")
                print(f"  applied in the studio:    {_fmt(r['applied'])}")
                print(f"  (the search itself:       {_fmt(r['server'])})")
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
        browser.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
