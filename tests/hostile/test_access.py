"""Issue 21 §1–§2: one link must not take the studio over, and the key must not leak to another local server.

The studio is opened the way a browser does it (:class:`Browser`: follows the printed address's redirect, keeps
cookies by the browser's rules, among them that a cookie is sent to every port of the same host), then attacked
with links and with what another program on this computer receives.
"""

from __future__ import annotations

import http.cookiejar
import threading
import urllib.error
import urllib.request
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest
from websockets.exceptions import InvalidStatus

from studio.app import Studio
from tests.conftest import free_port
from tests.viser_client import ViserClient


class _NoRedirect(urllib.request.HTTPRedirectHandler):
    def redirect_request(self, *args: object, **kwargs: object) -> None:
        return None


class Browser:
    """A cookie-keeping HTTP client (Python's cookie jar: Netscape rules, ports ignored as browsers do)."""

    def __init__(self) -> None:
        self.jar = http.cookiejar.CookieJar()
        self.follow = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(self.jar))
        self.stay = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(self.jar), _NoRedirect())

    def get(self, url: str, *, follow: bool = True) -> tuple[int, str, str]:
        """(status, final address, body)."""
        try:
            with (self.follow if follow else self.stay).open(url, timeout=20) as r:
                return r.status, r.geturl(), r.read().decode("utf-8", "replace")
        except urllib.error.HTTPError as exc:
            return exc.code, url, exc.read().decode("utf-8", "replace")

    def cookie_header(self, url: str) -> str:
        """The Cookie header this browser would send with a request to ``url``."""
        req = urllib.request.Request(url)
        self.jar.add_cookie_header(req)
        return str(req.get_header("Cookie") or "")


@pytest.fixture
def opened(app: Studio) -> tuple[Browser, str]:
    """A browser that opened the printed address, and the address of the page it was led to."""
    b = Browser()
    status, page, body = b.get(app.url())
    assert status == 200 and "<html" in body[:300].lower(), (status, body[:300])
    assert "key=" not in page
    return b, page


def _with_query(page: str, query: str) -> str:
    return page.split("?")[0] + "?" + query


# -- §1: one link takes the studio over ------------------------------------------------------------------------
ATTACKS = [
    "websocket=ws://127.0.0.1:1/",
    "%77ebsocket=ws://127.0.0.1:1/",  # the name percent-encoded: viser's page decodes it
    "web%73ocket=ws%3A%2F%2F127.0.0.1%3A1",
    "playbackPath=http://127.0.0.1:1/x.viser",
    "playback%50ath=http://127.0.0.1:1/x.viser",
    "darkMode&%77ebsocket=ws://127.0.0.1:1/",
    "initialCameraPosition=1,2,3",  # any parameter the studio does not use
    "unknown",
    "key=&websocket=ws://127.0.0.1:1/",
]


@pytest.mark.parametrize("query", ATTACKS)
def test_a_link_with_an_encoded_or_unknown_parameter_gets_a_refusal_page(
    app: Studio, opened: tuple[Browser, str], query: str
) -> None:
    """Today's regression: with the key cookie set, ``/?%77ebsocket=ws://ATTACKER`` was served (200) and the page
    connected to the attacker's viser server, whose HTML then drove the studio."""
    browser, page = opened
    status, _, body = browser.get(_with_query(page, query))
    assert status == 403, (query, body[:200])
    assert "<html" not in body.lower() and "Teaching Studio" in body and "refused" in body
    assert "printed" in body  # says what to open instead
    # The same link with the key in it (pasted from the printed address) is refused as well.
    status, _, _ = browser.get(f"{app.url()}&{query}")
    assert status == 403, query


def test_the_page_itself_still_opens_and_may_name_its_own_websocket(app: Studio, opened: tuple[Browser, str]) -> None:
    browser, page = opened
    assert browser.get(page)[0] == 200
    # viser's page writes its own websocket address into the address bar when it is not the page's root.
    own = page.replace("http://", "ws://").rstrip("/")
    assert browser.get(_with_query(page, f"websocket={own}"))[0] == 200
    assert browser.get(_with_query(page, f"websocket={own}x"))[0] == 403


def test_the_page_carries_a_policy_that_keeps_it_to_the_studio(app: Studio, opened: tuple[Browser, str]) -> None:
    browser, page = opened
    with browser.follow.open(page, timeout=20) as r:
        csp = r.headers["Content-Security-Policy"]
    rules = dict(part.strip().split(" ", 1) for part in csp.split(";"))
    own = page.replace("http://", "ws://").rstrip("/")
    assert rules["connect-src"].split() == ["'self'", "data:", own]
    assert "'unsafe-inline'" not in rules["script-src"] and "'sha256-" in rules["script-src"]
    assert rules["frame-ancestors"] == "'self'" and rules["object-src"] == "'none'"


# -- §2: the key must not leak to other local servers ---------------------------------------------------------
@pytest.fixture
def other_server() -> Iterator[tuple[int, list[str]]]:
    """Another program's web server on this computer; it keeps every Cookie header it receives."""
    seen: list[str] = []

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            seen.append(self.headers.get("Cookie", ""))
            self.send_response(200)
            self.send_header("Content-Length", "2")
            self.end_headers()
            self.wfile.write(b"ok")

        def log_message(self, *args: object) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", free_port()), Handler)
    t = threading.Thread(target=server.serve_forever, daemon=True)
    t.start()
    try:
        yield int(server.server_address[1]), seen
    finally:
        server.shutdown()
        server.server_close()
        t.join(timeout=5)


def test_another_local_server_never_receives_a_usable_key(
    app: Studio, opened: tuple[Browser, str], other_server: tuple[int, list[str]]
) -> None:
    """Today's regression: a server on another port of 127.0.0.1 received ``studio-key-<port>=<key>`` (cookies do
    not separate ports), and with it a program got the full GUI."""
    browser, page = opened
    port, seen = other_server
    for path in ("/", "/s/", "/index.html", "/?websocket=x"):
        assert browser.get(f"http://127.0.0.1:{port}{path}")[0] == 200
    key = str(app.access.key)
    assert len(seen) == 4 and not any(key in c for c in seen), seen

    # Even with the cookie stolen some other way, it is useless without the page's path.
    stolen = browser.cookie_header(page)
    assert key in stolen
    for url in (f"ws://127.0.0.1:{app.port}", f"ws://127.0.0.1:{app.port}/index.html"):
        with pytest.raises(InvalidStatus) as refused:
            ViserClient(url, origin=f"http://127.0.0.1:{app.port}", cookie=stolen)
        assert refused.value.response.status_code == 403


def test_the_page_and_its_websocket_work_with_the_cookie_under_its_path(
    app: Studio, opened: tuple[Browser, str]
) -> None:
    browser, page = opened
    c = ViserClient(
        page.replace("http://", "ws://").rstrip("/"),
        origin=f"http://127.0.0.1:{app.port}",
        cookie=browser.cookie_header(page),
    )
    try:
        assert c.wait_gui("Record")
    finally:
        c.close()


# -- issue 31 §4-§5: a cookie bomb from any other local port, a doubled Origin ------------------------------------
def _raw_get(app: Studio, path: str, headers: list[tuple[str, str]]) -> tuple[int, str]:
    """(status, body) of a GET sent with exactly ``headers`` (repeats kept, as a browser or a program sends them)."""
    import http.client

    conn = http.client.HTTPConnection("127.0.0.1", app.port, timeout=20)
    try:
        conn.putrequest("GET", path, skip_host=True)
        for name, value in [("Host", f"127.0.0.1:{app.port}"), *headers]:
            conn.putheader(name, value)
        conn.endheaders()
        r = conn.getresponse()
        return r.status, r.read().decode("utf-8", "replace")
    finally:
        conn.close()


#: What a page of another program on 127.0.0.1 can set for every port: 30 cookies of 3.5 KB on ``path=/``.
BOMB = "; ".join(f"junk{i}={'x' * 3500}" for i in range(30))


def test_a_cookie_bomb_gets_words_and_the_studios_own_cookie_keeps_working(
    app: Studio, opened: tuple[Browser, str]
) -> None:
    """Today: a Cookie header over ~8.1 KB got no answer at all (ERR_EMPTY_RESPONSE in the browser), until the
    cookies were cleared."""
    browser, page = opened
    assert len(BOMB) > 100_000
    path = page.split(f":{app.port}", 1)[1]
    status, body = _raw_get(app, "/", [("Cookie", BOMB)])
    assert status == 431 and "105 KB of cookies" in body and "Cookies and site data" in body, (status, body[:300])
    assert "127.0.0.1" in body and "printed" in body and "<html" not in body.lower()
    own = browser.cookie_header(page)
    assert str(app.access.key) in own
    for cookie in (f"{BOMB}; {own}", f"{own}; {BOMB}"):
        status, body = _raw_get(app, path, [("Cookie", cookie)])
        assert status == 200 and "<html" in body[:300].lower(), status
    c = ViserClient(page.replace("http://", "ws://").rstrip("/"), origin=f"http://127.0.0.1:{app.port}",
                    cookie=f"{BOMB}; {own}")  # fmt: skip
    try:
        assert c.wait_gui("Record")
        told = c.wait_for(lambda _m: [n for n in c.notifications() if "Too many cookies" in str(n)])
        assert told and "Cookies and site data" in str(told[0]), c.notifications()
    finally:
        c.close()
    status, _ = _raw_get(app, path, [("Cookie", BOMB)])  # the bomb alone still has no key
    assert status == 431
    import http.client

    with pytest.raises(http.client.RemoteDisconnected):  # only a Cookie line may be long: others as websockets did
        _raw_get(app, path, [("X-Long", "y" * 20_000), ("Cookie", own)])


def test_two_origin_headers_are_refused_with_403(app: Studio, opened: tuple[Browser, str]) -> None:
    """Today: 500 (the refusal's log line read the Origin header with a lookup that raises on two)."""
    browser, page = opened
    path = page.split(f":{app.port}", 1)[1]
    origin = f"http://127.0.0.1:{app.port}"
    headers = [("Cookie", browser.cookie_header(page)), ("Origin", origin), ("Origin", "http://evil.example")]
    assert _raw_get(app, path, headers)[0] == 403
    assert _raw_get(app, path, headers[:2])[0] == 200
