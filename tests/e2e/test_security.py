"""Browser tests: only the studio's own page drives it (issues 13 §1 and 21 §1–§2), in real Chromium.

* the printed address (with its key) opens the studio, the key leaves the address bar, reloads work, and
  the address without the key shows what to open instead;
* a page served from another port of this computer, in the same browser, never receives the studio's key and
  cannot open the studio's websocket, while the studio's own page can;
* a link with an encoded parameter that would point the page at another server gets a refusal page, and the
  page's Content-Security-Policy keeps it to the studio's own server while the studio renders and works;
* an upload above the limit is refused at once with a plain message, and the upload button works again.
"""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest
import viser
from playwright.sync_api import Page, expect

from tests.conftest import wait_for
from tests.e2e import ui
from tests.e2e.conftest import free_port

pytestmark = pytest.mark.e2e

#: Opens a websocket to the studio the way viser's client does and reports what happened.
PROBE_JS = """
async ([url, protocol]) => await new Promise((resolve) => {
  let ws;
  try { ws = new WebSocket(url, [protocol]); } catch (e) { resolve("error " + e); return; }
  ws.onopen = () => { resolve("open"); ws.close(); };
  ws.onclose = (e) => resolve("closed " + e.code);
  setTimeout(() => resolve("timeout"), 15000);
})
"""


def probe(page: Page, url: str) -> str:
    return str(page.evaluate(PROBE_JS, [url, f"viser-v{viser.__version__}"]))


def own_websocket(page: Page) -> str:
    """The websocket address of the studio's page (its launch's path), as viser's client makes it."""
    return page.url.split("?")[0].replace("http://", "ws://").rstrip("/")


#: Every cookie header the other site received.
OTHER_SITE_COOKIES: list[str] = []


@pytest.fixture
def other_site() -> Iterator[str]:
    """A tiny web server on another port of this computer: the page an attacker would serve."""
    OTHER_SITE_COOKIES.clear()

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            OTHER_SITE_COOKIES.append(self.headers.get("Cookie", ""))
            body = b"<!doctype html><html><head><title>Another site</title></head><body><h1>Another site</h1></body>"
            self.send_response(200)
            self.send_header("Content-Type", "text/html; charset=utf-8")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", free_port()), Handler)
    t = threading.Thread(target=server.serve_forever, daemon=True)
    t.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()
        t.join(timeout=5)


def test_the_printed_address_opens_the_studio_and_reloads_work(browser, studio_factory, shots, tmp_path) -> None:
    server = studio_factory("fresh", sessions_dir=tmp_path / "sessions")
    page = ui.open_studio(browser, server.url)
    assert "key=" not in page.url and page.url.startswith(server.base)
    shots(page, "opened with the key")
    page.reload()
    ui.wait_ready(page)
    expect(page.get_by_role("button", name="Record")).to_be_enabled()
    assert probe(page, own_websocket(page)) == "open"  # the studio's own page may open its websocket
    shots(page, "after reload")

    # The same address without the key, in another browser: a plain explanation, nothing of the studio.
    other = browser.new_page(viewport=ui.VIEWPORT)
    response = other.goto(server.base)
    assert response is not None and response.status == 403
    expect(other.get_by_text("this address needs its key")).to_be_visible()
    assert "?key=" in other.content()
    shots(other, "without the key")
    other.close()
    page.close()


def test_a_page_at_another_origin_cannot_connect(browser, studio_factory, shots, other_site, tmp_path) -> None:
    server = studio_factory("fresh", sessions_dir=tmp_path / "sessions")
    context = browser.new_context(viewport=ui.VIEWPORT)
    page = context.new_page()
    page.goto(server.url)
    ui.wait_ready(page)
    key = server.url.split("key=")[1]
    assert any(c["value"] == key for c in context.cookies())  # the browser holds the key
    evil = context.new_page()
    for path in ("", "s/", "index.html"):
        evil.goto(other_site + path)
    expect(evil.get_by_text("Another site")).to_be_visible()
    assert len(OTHER_SITE_COOKIES) >= 3 and not any(key in c for c in OTHER_SITE_COOKIES), OTHER_SITE_COOKIES
    for url in (f"ws://127.0.0.1:{server.port}", own_websocket(page)):  # even had it learned the page's path
        result = probe(evil, url)
        assert result.startswith("closed") and result != "closed 1000", result  # refused during the handshake
    shots(evil, "another site refused")
    # The studio is untouched and its own page still works.
    assert probe(page, own_websocket(page)) == "open"
    ui.click_in_row(page, "Left gripper", "Close")
    expect(page.locator('.gripper-status[data-arm="left"][data-open="0"]')).to_have_count(1, timeout=30_000)
    assert "refused a connection to the studio (foreign origin" in server.read_output()
    context.close()


@pytest.fixture
def listener() -> Iterator[tuple[int, list[int]]]:
    """A port where "another server" listens; counts the connections it gets."""
    accepted: list[int] = []
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(8)
    sock.settimeout(0.2)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = sock.accept()
            except OSError:
                continue
            accepted.append(1)
            conn.close()

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        yield int(sock.getsockname()[1]), accepted
    finally:
        stop.set()
        t.join(timeout=5)
        sock.close()


VIOLATIONS_JS = """
() => { window.__violations = [];
  document.addEventListener('securitypolicyviolation', (e) => window.__violations.push(e.effectiveDirective)); }
"""


def test_one_link_cannot_point_the_page_elsewhere_and_the_policy_holds(
    browser, studio_factory, shots, listener, tmp_path
) -> None:
    server = studio_factory("fresh", sessions_dir=tmp_path / "sessions")
    port, accepted = listener
    context = browser.new_context(viewport=ui.VIEWPORT)
    page = context.new_page()
    page.set_default_timeout(30_000)
    console: list[str] = []
    page.on("console", lambda m: console.append(m.text))
    page.goto(server.url)
    ui.wait_ready(page)
    # The studio renders and works under its policy: nothing of viser's page was refused.
    refused = [m[:300] for m in console if "Content Security Policy" in m]
    assert not refused, refused
    ui.click_in_row(page, "Left gripper", "Close")
    expect(page.locator('.gripper-status[data-arm="left"][data-open="0"]')).to_have_count(1, timeout=30_000)
    shots(page, "the studio under its policy")

    # Today's attack: the page's address with viser's websocket parameter, its name percent-encoded.
    link = page.url.split("?")[0] + f"?%77ebsocket=ws://127.0.0.1:{port}/"
    other = context.new_page()
    response = other.goto(link)
    assert response is not None and response.status == 403
    expect(other.get_by_text("this address is refused")).to_be_visible()
    shots(other, "the link is refused")
    other.close()

    # Inside the studio's page: no connection to another server, no script from HTML it is shown.
    page.evaluate(VIOLATIONS_JS)
    result = probe(page, f"ws://127.0.0.1:{port}")
    assert not result.startswith("open"), result
    page.evaluate(
        "() => { const d = document.createElement('div');"
        ' d.innerHTML = \'<img src="data:,x" onerror="window.__ran = 1">\'; document.body.appendChild(d); }'
    )
    page.wait_for_function("() => window.__violations.includes('script-src-attr')")
    assert page.evaluate("() => window.__ran") is None
    assert "connect-src" in page.evaluate("() => window.__violations")
    assert not accepted  # the other server was never reached
    context.close()


def test_an_oversize_upload_is_refused_in_plain_words(browser, shots, tmp_path, monkeypatch) -> None:
    from studio import security
    from studio.app import build_app

    monkeypatch.setattr(security.uploads, "MAX_UPLOAD_BYTES", 1024 * 1024)
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    app = build_app(port=free_port(), session="fresh", sessions_dir=sessions)
    try:
        page = ui.open_studio(browser, app.url())
        ui.tab(page, "Sessions")
        big = tmp_path / "big-session.zip"
        big.write_bytes(b"PK\x03\x04" + bytes(3 * 1024 * 1024))
        page.locator("input[type=file]").first.set_input_files(str(big))
        note = page.locator(".mantine-Notification-root").filter(has_text="too large")
        expect(note.first).to_be_visible(timeout=30_000)
        text = note.first.inner_text()
        assert '"big-session.zip" is too large (3 MB)' in text and "up to 1 MB" in text, text
        assert "Nothing was imported" in text
        shots(page, "oversize upload refused")
        expect(page.get_by_text("File uploaded successfully")).to_have_count(0)
        expect(page.get_by_role("button", name="Upload session (.zip)")).to_be_enabled()
        assert app.controller.sessions.names() == ["fresh"]
        assert not app.server.gui._current_file_upload_states
        page.close()
    finally:
        app.stop()


def test_a_cookie_bomb_from_another_port_gets_words_and_the_studio_keeps_working(
    browser, studio_factory, shots, other_site, tmp_path
) -> None:
    """Issue 31 §4, today: 30 cookies of 3.5 KB on ``path=/``, set by a page of another port of 127.0.0.1, and
    Chromium got no answer at all from the studio (ERR_EMPTY_RESPONSE) until the cookies were cleared."""
    server = studio_factory("fresh", sessions_dir=tmp_path / "sessions")
    context = browser.new_context(viewport=ui.VIEWPORT)
    evil = context.new_page()
    evil.goto(other_site)
    evil.evaluate("() => { for (let i = 0; i < 30; i++) document.cookie = `junk${i}=${'x'.repeat(3500)}; path=/`; }")
    # the page hands its cookies to the browser's cookie store, which keeps them a moment later
    assert wait_for(lambda: len([c for c in context.cookies() if c["name"].startswith("junk")]) == 30)
    # Without the key the page says what happened and how to clear the cookies.
    response = evil.goto(server.base)
    assert response is not None and response.status == 431
    expect(evil.get_by_text("KB of cookies with this request")).to_be_visible()
    assert "Cookies and site data" in evil.content()
    shots(evil, "the cookie bomb told")
    # The printed address still opens the studio, which works and tells the tab.
    page = context.new_page()
    page.goto(server.url)
    ui.wait_ready(page)
    expect(page.get_by_text("Too many cookies for this address")).to_be_visible(timeout=30_000)
    shots(page, "the studio with the cookie bomb")
    ui.click_in_row(page, "Left gripper", "Close")
    expect(page.locator('.gripper-status[data-arm="left"][data-open="0"]')).to_have_count(1, timeout=30_000)
    context.close()
