"""Take docs/screenshot.png: the studio on a copy of the "stack-cup" example, trained, Train tab open.

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
    shutil.copytree(ROOT / "sessions" / "stack-cup", tmp / "stack-cup")
    app = build_app(port=free_port(), sessions_dir=tmp, session="stack-cup")
    try:
        app.controller.training.train().result()
        with sync_playwright() as p:
            b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            page = ui.open_studio(b, app.url())
            ui.tab(page, "Train")
            for c in app.server.get_clients().values():  # closer than the default view: the workspace
                c.camera.position = (1.75, -0.55, 0.75)
                c.camera.look_at = (0.42, 0.32, 0.1)
            time.sleep(2.0)
            ui.dismiss_notifications(page, only_webgl=False)
            time.sleep(1.0)
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
