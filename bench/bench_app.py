"""Benchmarks of the browser studio (figures only; never asserts on time).

1. ε slider → scene update: 3 demonstrations × 30,000 samples (30 s at 1 kHz each); time from a threshold
   change to the key-point and centroid markers queued for the browsers (re-extraction, k-means, drawing).
2. Robot pose updates reaching a connected browser while the arm moves: headless Chromium (Playwright)
   connected to the studio; every websocket frame the page receives is decoded (viser's wire format:
   zstd-compressed msgpack) and frames carrying a new robot joint pose are counted per second.
3. Frames per second drawn by software WebGL in headless Chromium at 1280×800 **while the arm moves** (viser
   draws on demand: a frame is drawn only when something changed, so animation frames counted while nothing
   moves are not drawings; that idle count is printed too, labelled, because it is what this bench reported
   before 2026-11-23): with the task scene (a table, the pick-place block and pad and two cups) and, in the
   same run, without any table or object, and two floors: a plain viser page with one moving box, and a plain
   viser page with only the same Baxter (light meshes) moving, the studio's camera and lights.

Run:  .venv/bin/python bench/bench_app.py            (add --skip-browser to run only part 1)
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.conftest import CHROMIUM, CHROMIUM_ARGS, free_port  # noqa: E402  (after the path insert)


def make_session(root: Path, n_samples: int = 30_000, name: str = "bench", objects: bool = True) -> str:
    """A session with three 30,000-sample left-arm demos from the scripted teacher (time-stretched), on the task
    scene (a table, a block, a pad and two cups) or, without ``objects``, on nothing at all."""
    from studio.core.types import Recording
    from studio.storage import SessionStore
    from studio.teacher import recording_from_plan, teach
    from studio.world import Scene, preset

    store = SessionStore(root)
    s = store.create(name, arms=("left",))
    scene = preset("pick-place").add("cup", (0.6, -0.3, -0.07)).add("cup", (0.75, -0.45, -0.07))
    s.set_scene(scene if objects else Scene(preset="", table=None))
    for seed in range(3):
        rec = recording_from_plan(teach("stack-cup", seed=seed))
        t = np.arange(n_samples) / 1000.0
        src = np.linspace(0.0, rec.t[-1], n_samples)
        q = np.column_stack([np.interp(src, rec.t, rec.q[:, j]) for j in range(14)])
        g = np.column_stack([np.interp(src, rec.t, rec.gripper[:, j]) for j in range(2)])
        s.add_recording(Recording(t=t, q=q, gripper=g, arms=("left",), name=f"demo {seed + 1}"))
    return name


def bench_slider(root: Path, repeats: int = 40) -> dict[str, float]:
    from studio.app import build_app

    app = build_app(port=free_port(), session="bench", sessions_dir=root)
    try:
        panel, kp = app.panels.keypoints, app.controller.keypoints
        time.sleep(1.0)
        panel.draw(kp.refresh())  # warm: forward kinematics and the per-demo derived series are cached once
        # The same work as the studio's key-point thread (compute, then draw), done here in this thread so that
        # it can be timed: the thread itself is not woken (it would compute every view a second time at once).
        kp.request = lambda: None  # type: ignore[method-assign]
        total, compute, draw, counts = [], [], [], []
        values = [0.03, 0.12, 0.05, 0.2, 0.08]
        for i in range(repeats):
            t0 = time.perf_counter()
            kp.set_param("eps5", values[i % len(values)])  # what the ε5 slider's callback does
            view = kp.compute()  # what the key-point thread then does
            t1 = time.perf_counter()
            panel.draw(view)  # markers + labels + counts, one atomic batch for the browsers
            t2 = time.perf_counter()
            total.append(t2 - t0)
            compute.append(t1 - t0)
            draw.append(t2 - t1)
            counts.append(sum(d.count for d in view.demos))
        n = [len(app.controller.demos.demo(i, "left")) for i in range(3)]
        return {
            "samples_per_demo": float(min(n)),
            "median_ms": 1e3 * statistics.median(total),
            "p90_ms": 1e3 * float(np.percentile(total, 90)),
            "compute_median_ms": 1e3 * statistics.median(compute),
            "draw_median_ms": 1e3 * statistics.median(draw),
            "keypoints_min": float(min(counts)),
            "keypoints_max": float(max(counts)),
        }
    finally:
        app.stop()


def _decode(frame: bytes) -> list[dict]:
    import msgspec
    import zstandard

    n_inner = int.from_bytes(frame[0:8], "little")
    n_comp = int.from_bytes(frame[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(frame[16 : 16 + n_comp], max_output_size=n_inner)
    return list(msgspec.msgpack.decode(inner).get("messages", ()))


#: Animation frames per second over ``ms`` milliseconds, counted in the page.
_FPS_JS = """(ms) => new Promise(r => { let n = 0; const t0 = performance.now();
   function f() { n++; if (performance.now() - t0 < ms) requestAnimationFrame(f);
                  else r(n * 1000 / (performance.now() - t0)); }
   requestAnimationFrame(f); })"""


def _moving(step: Callable[[int], None], rate_hz: float = 50.0) -> tuple[threading.Thread, threading.Event]:
    """Call ``step(k)`` at ``rate_hz`` on a thread until the returned event is set (something keeps moving)."""
    stop = threading.Event()

    def run() -> None:
        k = 0
        while not stop.is_set():
            step(k)
            k += 1
            time.sleep(1.0 / rate_hz)

    th = threading.Thread(target=run, daemon=True)
    th.start()
    return th, stop


def bench_floor(what: str, seconds: float = 4.0) -> float:
    """Frames per second a plain viser page draws at 1280x800 while ``what`` moves: "box" (one small box, the
    floor of this renderer) or "baxter" (the studio's light Baxter alone, the studio's camera and lights)."""
    import viser
    from playwright.sync_api import sync_playwright
    from viser.extras import ViserUrdf

    from studio.app import configure_scene, robot_urdf_path

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        configure_scene(server)
        if what == "box":
            box = server.scene.add_box("/box", dimensions=(0.05, 0.05, 0.05), color=(200, 30, 40))

            def step(k: int) -> None:
                box.position = (0.6 + 0.2 * np.sin(k * 0.05), 0.0, 0.0)
        else:
            urdf = ViserUrdf(server, urdf_or_path=robot_urdf_path(), root_node_name="/robot")
            q0 = np.zeros(len(urdf.get_actuated_joint_limits()))

            def step(k: int) -> None:
                q = q0.copy()
                q[0] = 0.6 * np.sin(k * 0.05)
                urdf.update_cfg(q)

        with sync_playwright() as p:
            b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            page = b.new_page(viewport={"width": 1280, "height": 800})
            page.goto(f"http://127.0.0.1:{server.get_port()}")
            time.sleep(8.0)  # the meshes arrive and are drawn once
            th, stop = _moving(step)
            fps = float(page.evaluate(_FPS_JS, seconds * 1000))
            stop.set()
            th.join()
            b.close()
        return fps
    finally:
        server.stop()


def bench_browser(root: Path, seconds: float = 5.0, session: str = "bench") -> dict[str, float]:
    """Pose updates per second reaching connected clients while the arm moves, and the browser's frame rate.

    Headless Chromium is connected (it receives and draws every update); next to it a plain websocket client
    speaking viser's protocol receives the same broadcast and decodes each frame, so the count is of frames
    that really carried a new robot pose (viser's client reads its websocket inside a web worker, which
    Playwright cannot observe).
    """
    import viser
    from playwright.sync_api import sync_playwright
    from websockets.sync.client import connect

    from studio.app import build_app

    out: dict[str, float] = {}
    app = build_app(port=free_port(), session=session, sessions_dir=root)
    try:
        with sync_playwright() as p:
            b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            page = b.new_page(viewport={"width": 1280, "height": 800})
            page.goto(app.url())
            page.get_by_role("button", name="Record").wait_for(timeout=60_000)
            time.sleep(3.0)

            frames: list[tuple[float, bytes]] = []
            ws = connect(
                app.url().replace("http://", "ws://"),  # a program, not a page: the key in its address
                subprotocols=[f"viser-v{viser.__version__}"],
                max_size=None,
                open_timeout=30,
            )
            done = threading.Event()

            def reader() -> None:
                while not done.is_set():
                    try:
                        data = ws.recv(timeout=0.5)
                    except TimeoutError:
                        continue
                    except Exception:
                        return
                    if isinstance(data, bytes):
                        frames.append((time.perf_counter(), data))

            rt = threading.Thread(target=reader, daemon=True)
            rt.start()
            time.sleep(3.0)  # the initial scene (meshes) arrives first

            # Move the left arm back and forth continuously.
            q0 = app.controller.teaching.arm_q("left")

            def step(k: int) -> None:
                q = q0.copy()
                q[0] += 0.6 * np.sin(k * 0.05)
                q[3] += 0.4 * np.sin(k * 0.03)
                app.controller.teaching.command_arm("left", q)

            pushes0 = app.panels.robot.updates
            t_start = time.perf_counter()
            th, stop = _moving(step, rate_hz=100.0)
            out["render_fps_moving"] = float(page.evaluate(_FPS_JS, 0.8 * seconds * 1000))  # drawn frames
            time.sleep(max(0.0, seconds - (time.perf_counter() - t_start)))
            stop.set()
            th.join()
            t_end = time.perf_counter()
            pushes = app.panels.robot.updates - pushes0
            done.set()
            rt.join(timeout=2)
            ws.close()
            got = [f for f in frames if t_start <= f[0] <= t_end]
            pose_frames = 0
            for _, data in got:
                msgs = _decode(data)
                if any(
                    m.get("type") == "SetOrientationMessage" and str(m.get("name", "")).startswith("/robot/")
                    for m in msgs
                ):
                    pose_frames += 1
            out["pose_updates_per_s"] = pose_frames / (t_end - t_start)
            out["frames_per_s"] = len(got) / (t_end - t_start)
            out["server_pose_pushes_per_s"] = pushes / (t_end - t_start)

            out["raf_idle"] = float(page.evaluate(_FPS_JS, 4000))  # nothing moves: nothing is drawn
            b.close()
    finally:
        app.stop()
    return out


def bench_full_meshes(root: Path) -> float:
    from playwright.sync_api import sync_playwright

    from studio.app import build_app

    app = build_app(port=free_port(), session="bench", sessions_dir=root, meshes="full")
    try:
        with sync_playwright() as p:
            b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            page = b.new_page(viewport={"width": 1280, "height": 800})
            page.set_default_timeout(180_000)
            page.goto(app.url())
            page.get_by_role("button", name="Record").wait_for()
            time.sleep(15.0)
            q0 = app.controller.teaching.arm_q("left")

            def step(k: int) -> None:
                q = q0.copy()
                q[0] += 0.6 * np.sin(k * 0.05)
                app.controller.teaching.command_arm("left", q)

            th, stop = _moving(step)
            fps = page.evaluate(_FPS_JS, 6000)
            stop.set()
            th.join()
            b.close()
            return float(fps)
    finally:
        app.stop()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-browser", action="store_true")
    ap.add_argument("--full-meshes", action="store_true", help="also measure the full meshes (slow)")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench-app-"))
    try:
        make_session(tmp)
        make_session(tmp, name="bare", objects=False)
        r = bench_slider(tmp)
        print(
            f"eps slider -> scene update, 3 demos x {r['samples_per_demo']:.0f} samples: "
            f"median {r['median_ms']:.1f} ms, p90 {r['p90_ms']:.1f} ms "
            f"(key-points + clustering {r['compute_median_ms']:.1f} ms, drawing {r['draw_median_ms']:.1f} ms; "
            f"{r['keypoints_min']:.0f}-{r['keypoints_max']:.0f} key-points)"
        )
        if not args.skip_browser:
            r2 = bench_browser(tmp)
            print(
                f"robot pose updates reaching a connected client while the arm moves: "
                f"{r2['pose_updates_per_s']:.1f}/s ({r2['frames_per_s']:.1f} websocket frames/s; "
                f"the studio pushed {r2['server_pose_pushes_per_s']:.1f} poses/s)"
            )
            print(
                f"software WebGL, light meshes, 1280x800, arm moving, with the task scene: "
                f"{r2['render_fps_moving']:.1f} frames/s drawn "
                f"(idle page, nothing drawn: {r2['raf_idle']:.1f} animation frames/s)"
            )
            bare = bench_browser(tmp, session="bare")
            print(
                f"software WebGL, light meshes, 1280x800, arm moving, no table or objects (same run): "
                f"{bare['render_fps_moving']:.1f} frames/s drawn (idle {bare['raf_idle']:.1f}; "
                f"pose updates {bare['pose_updates_per_s']:.1f}/s)"
            )
            print(f"floor, plain viser page, one box moving (same run): {bench_floor('box'):.1f} frames/s")
            print(f"floor, plain viser page, Baxter alone moving (same run): {bench_floor('baxter'):.1f} frames/s")
            if args.full_meshes:
                print(f"software WebGL, full meshes, 1280x800: {bench_full_meshes(tmp):.1f} frames/s")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
