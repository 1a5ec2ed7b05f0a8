"""Teaching by hand: does the handle's IK trap the arm, and how many user actions does teaching stack-cup take?

* ``ik``: the trap of issue 18. Carrying the stack-cup cup, the handle is dragged out of reach in 40 random
  directions (40 steps out, 40 back to where the example releases the cup); counted: the drags after which that
  place is not reached or a joint rests within 1° of a limit. Then every 250th pose of the bundled examples'
  demonstrations, solved from the home posture and from two trapped postures. Both for the studio's handle IK
  (``posture_ik.reach_pose``) against the plain warm-started IK it replaced (``Baxter.ik``, the baseline), with
  the median and 95th-percentile time of one solve.
* ``keys``: a held key in headless Chromium, as a keyboard repeats it (a press, 0.5 s, then 30 a second): how far
  the gripper's goal moved after 1, 2 and 3 s held, and a Shift press; this commit against a baseline commit
  (``--baseline``, default main) in the same run.
* ``actions``: the browser flow of ``tests/e2e/test_teach_mouse.py`` (a new session, the handle out of reach and
  back, three demonstrations, Train, Preview) in headless Chromium, with every click, drag, key press and typed
  word counted; the teaching part (new session, demonstrations, train and preview) has a target of 60.

Run: ``.venv/bin/python bench/bench_teaching.py [--part ik|keys|actions] [--baseline main]``. Prints figures;
never asserts on time.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from studio.core.kinematics import Baxter  # noqa: E402
from studio.core.posture_ik import reach_pose  # noqa: E402
from studio.storage import SessionStore  # noqa: E402

TRAPPED = (
    np.radians([-55.4, -0.5, -172.6, -2.9, 175.3, 92.4, -13.5]),
    np.radians([97.5, -123.0, -150.3, 82.9, -13.7, 67.5, -10.2]),
)


def _solvers(b: Baxter) -> dict[str, object]:
    return {
        "handle IK (posture_ik.reach_pose)": lambda arm, p, w, q: reach_pose(b, arm, p, w, q).result,
        "baseline: plain IK (Baxter.ik, 60 iterations)": lambda arm, p, w, q: b.ik(arm, p, w, q, max_iterations=60),
    }


def part_ik() -> None:
    b = Baxter.load()
    store = SessionStore(ROOT / "sessions")
    rec = store.open("stack-cup").recordings[0]
    Q, g = rec.arm_q("left"), rec.arm_gripper("left")
    P, W = b.fk_batch("left", Q)
    grasp = int(np.argmax(g < 50))
    release = int(len(g) - 1 - np.argmax(g[::-1] < 50))
    lo, hi = b.lower_limits("left"), b.upper_limits("left")
    reach_pose(b, "left", P[0], W[0], Q[0])  # builds the solver once
    print("Out of reach and back while carrying the cup (40 drags, stack-cup demo 1):")
    for name, solve in _solvers(b).items():
        rng = np.random.default_rng(0)
        trapped, times = 0, []
        for _ in range(40):
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            far = P[grasp] + d * rng.uniform(0.6, 1.5)
            q = Q[grasp].copy()
            for p in [*np.linspace(P[grasp], far, 40), *np.linspace(far, P[release], 40)]:
                t0 = time.perf_counter()
                r = solve("left", p, W[grasp], q)  # type: ignore[operator]
                times.append(time.perf_counter() - t0)
                q = np.asarray(r.q)
            pinned = np.minimum(q - lo, hi - q) < math.radians(1.0)
            pinned[3] = False  # a straight elbow is not a trap
            trapped += int((not r.converged) or bool(pinned.any()))
        t = np.array(times) * 1000
        print(
            f"  {name}: trapped after {trapped}/40 drags; one solve median {np.median(t):.2f} ms, "
            f"p95 {np.percentile(t, 95):.2f} ms"
        )
    print("Every 250th pose of the bundled examples' demonstrations, from home and two trapped postures:")
    poses = []
    for session in ("stack-cup", "pick-place"):
        for r in store.open(session).recordings:
            for arm in r.arms:
                Pa, Wa = b.fk_batch(arm, r.arm_q(arm)[::250])
                poses += [(arm, p, w) for p, w in zip(Pa, Wa, strict=True)]
    for name, solve in _solvers(b).items():
        fails, times = 0, []
        for seed in (b.neutral("left"), *TRAPPED):
            for arm, p, w in poses:
                s = seed if arm == "left" else seed * np.array([-1, 1, -1, 1, -1, 1, -1])
                t0 = time.perf_counter()
                r = solve(arm, p, w, s)  # type: ignore[operator]
                times.append(time.perf_counter() - t0)
                fails += int(not r.converged)
        print(
            f"  {name}: {fails}/{3 * len(poses)} not reached; one solve median "
            f"{statistics.median(times) * 1000:.2f} ms, p95 {np.percentile(np.array(times) * 1000, 95):.2f} ms"
        )


def part_actions() -> None:
    from playwright.sync_api import sync_playwright

    from tests.conftest import CHROMIUM, CHROMIUM_ARGS
    from tests.e2e import ui
    from tests.e2e.conftest import StudioProcess
    from tests.e2e.mouse_flow import (
        TEACHING_PARTS,
        Teacher,
        finish_excursion,
        look,
        new_session,
        out_of_reach_and_back,
        teach_train_preview,
    )

    with tempfile.TemporaryDirectory() as tmp:
        sessions = Path(tmp) / "sessions"
        sessions.mkdir()
        shutil.copytree(ROOT / "sessions" / "stack-cup", sessions / "stack-cup")
        studio = StudioProcess(sessions, "stack-cup").start()
        t0 = time.monotonic()
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
                page = ui.open_studio(browser, studio.url)
                t = Teacher(page)
                new_session(t)
                t.part("views")
                look(t, "Front")
                look(t, "Top")
                out_of_reach_and_back(t)
                finish_excursion(t)
                words = teach_train_preview(t)
                browser.close()
        finally:
            studio.stop()
    teaching = sum(sum(t.parts[name].values()) for name in TEACHING_PARTS)
    print(f"Teaching stack-cup in a new session with the mouse and keys ({time.monotonic() - t0:.0f} s wall):")
    for name, c in t.parts.items():
        print(f"  {name}: {sum(c.values())} ({', '.join(f'{k} {v}' for k, v in sorted(c.items()))})")
    print(f"  all: {t.total} actions ({', '.join(f'{k} {v}' for k, v in sorted(t.counts.items()))})")
    print(f"  teaching (new session, three demonstrations, train, preview): {teaching} actions (target <= 60)")
    print(f"  the preview said: {words.strip()}")


def _serve(src: Path, sessions: Path) -> tuple[subprocess.Popen[str], str]:
    """`python -m studio serve` of the checkout ``src`` (its folder first on the import path); its address."""
    import re

    from tests.conftest import free_port

    cmd = [sys.executable, "-m", "studio", "serve", "--port", str(free_port()), "--session", "stack-cup"]
    cmd += ["--sessions-dir", str(sessions), "--meshes", "light"]
    proc = subprocess.Popen(cmd, cwd=src, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    for line in proc.stdout:
        m = re.search(r"open (http://\S+) in your browser", line)
        if m:
            return proc, m.group(1)
    raise RuntimeError(f"the studio of {src} did not start")


def _hold(page: object, key: str, seconds: float) -> int:
    """Hold ``key`` as a keyboard does: one press, 0.5 s, then a repeat every 1/30 s; then let go. Returns the
    key events sent (on a busy machine Playwright delivers fewer than a keyboard would)."""
    kb = page.keyboard  # type: ignore[attr-defined]
    kb.down(key)
    t0 = time.monotonic()
    time.sleep(0.5)
    sent = 1
    while time.monotonic() - t0 < seconds:
        kb.down(key)  # Playwright marks a second keydown without a keyup as a repeat
        sent += 1
        time.sleep(1 / 30)
    kb.up(key)
    return sent


def part_keys(baseline: str) -> None:
    from playwright.sync_api import sync_playwright

    from tests.conftest import CHROMIUM, CHROMIUM_ARGS
    from tests.e2e import ui

    def goal_x(page: object) -> float:
        """Where the gripper is going along x, cm (the Move panel's data)."""
        return float(page.locator(".gripper-goal").first.get_attribute("data-x"))  # type: ignore[attr-defined]

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        base = work / "baseline"
        subprocess.run(["git", "clone", "-q", str(ROOT), str(base)], check=True)
        subprocess.run(["git", "-C", str(base), "checkout", "-q", baseline], check=True)
        print(f"A held key (S: away from the robot): how far the gripper's goal moved; baseline {baseline}:")
        print(f"  load average at the start: {os.getloadavg()[0]:.2f}")
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            for label, src in (("this commit", ROOT), ("baseline", base)):
                sessions = work / f"sessions-{label.replace(' ', '-')}"
                sessions.mkdir()
                shutil.copytree(ROOT / "sessions" / "stack-cup", sessions / "stack-cup")
                proc, url = _serve(src, sessions)
                try:
                    page = ui.open_studio(browser, url)
                    page.mouse.click(20, ui.VIEWPORT["height"] - 20)  # the focus on the page, not in a box
                    got = []
                    for seconds in (1.0, 2.0, 3.0):
                        page.keyboard.press("KeyH")
                        ui.wait_arm_settled(page)
                        x0 = goal_x(page)
                        sent = _hold(page, "KeyS", seconds)
                        time.sleep(1.0)  # the last presses reach the studio
                        got.append(f"{seconds:.0f} s held: {goal_x(page) - x0:4.1f} cm ({sent} key events)")
                    page.keyboard.press("KeyH")
                    ui.wait_arm_settled(page)
                    x0 = goal_x(page)
                    page.keyboard.press("Shift+KeyS")
                    time.sleep(1.0)
                    got.append(f"one Shift+S: {goal_x(page) - x0:4.1f} cm")
                    print(f"  {label}: " + "; ".join(got))
                    page.close()
                finally:
                    proc.terminate()
                    proc.wait(timeout=30)
                    if proc.stdout is not None:
                        proc.stdout.close()
            browser.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--part", choices=("ik", "keys", "actions"), default=None)
    ap.add_argument("--baseline", default="main", help="the commit the keys are compared with")
    args = ap.parse_args()
    if args.part in (None, "ik"):
        part_ik()
    if args.part in (None, "keys"):
        part_keys(args.baseline)
    if args.part in (None, "actions"):
        part_actions()


if __name__ == "__main__":
    main()
