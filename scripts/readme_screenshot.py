"""Take docs/screenshot.png: the studio on a copy of the "pick-place" example, trained, in the Preview step
halfway through the learned skill (the block in the gripper above the table, the learned path, the task result).

Usage: .venv/bin/python scripts/readme_screenshot.py [out.png]   (needs Debian's chromium at /usr/bin/chromium)
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def main() -> int:
    from playwright.sync_api import sync_playwright

    from studio.app import build_app
    from tests.conftest import CHROMIUM, CHROMIUM_ARGS, free_port
    from tests.e2e import ui

    out = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "screenshot.png"
    tmp = Path(tempfile.mkdtemp(prefix="studio-shot-"))
    shutil.copytree(ROOT / "sessions" / "pick-place", tmp / "pick-place")
    app = build_app(port=free_port(), sessions_dir=tmp, session="pick-place")
    try:
        ctl = app.controller
        ctl.training.train().result()
        with sync_playwright() as p:
            b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            page = ui.open_studio(b, app.url())
            ui.tab(page, "Preview")
            ui.set_number(page, "Time (s)", round(0.34 * ctl.playback.preview_duration(), 1))  # carrying the block
            for c in app.server.get_clients().values():  # closer than the default view: the workspace
                c.camera.position = (1.95, -0.35, 0.75)
                c.camera.look_at = (0.55, 0.42, -0.02)
            time.sleep(2.0)
            for _ in range(10):  # the browser's notices can come late: close them until none is left
                ui.dismiss_notifications(page, only_webgl=False)
                time.sleep(0.7)
                if not page.locator(".mantine-Notification-root").count():
                    break
            out.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(out))
            b.close()
    finally:
        app.stop()
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
