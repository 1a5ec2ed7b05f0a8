"""Only the studio's own page drives the studio (issue 13 §1).

Each test starts a real studio (viser server on a free 127.0.0.1 port) on a copy of the example session and
attacks it the way another program or another web page would: over viser's websocket protocol
(:mod:`tests.viser_client`) and with raw HTTP requests whose headers the test controls.
"""

from __future__ import annotations

import base64
import http.client
import os
import shutil
import socket
import time
from pathlib import Path

import pytest
from websockets.exceptions import ConnectionClosed, InvalidStatus

from studio.app import STOP_S, Studio, build_app
from tests.conftest import end_with_signal, free_port, reap, wait_for
from tests.viser_client import ViserClient

ROOT = Path(__file__).resolve().parent.parent
MiB = 1024 * 1024


@pytest.fixture
def sessions(tmp_path: Path) -> Path:
    d = tmp_path / "sessions"
    d.mkdir()
    shutil.copytree(ROOT / "sessions" / "stack-cup", d / "stack-cup")
    return d


def key_of(app: Studio) -> str:
    return str(app.access.key)


def cookie_of(app: Studio) -> str:
    return f"{app.access.cookie_name}={key_of(app)}"


def page_ws(app: Studio) -> str:
    """The websocket address of the studio's page (the launch's path, where its cookie is valid)."""
    return f"ws://127.0.0.1:{app.port}{app.access.prefix}"


def own_origin(app: Studio) -> str:
    return f"http://127.0.0.1:{app.port}"


def attack(app: Studio, *, origin: str | None, cookie: str | None = None, url: str | None = None) -> dict:
    """What a client with these headers achieves: GUI received, a demo deleted (one Delete press), the
    session zip downloaded. ``refused`` is the HTTP status of a refused handshake (None when accepted)."""
    before = app.controller.demos.names()
    try:
        c = ViserClient(url or f"ws://127.0.0.1:{app.port}", origin=origin, cookie=cookie)
    except InvalidStatus as exc:
        return {"refused": exc.response.status_code, "gui": 0, "deleted": set(), "downloads": {}}
    try:
        c.wait_gui("Demo action")
        c.set_value("Demo", before[0])
        wait_for(lambda: app.panels.demos.demo_pick.value == before[0])
        c.set_value("Demo action", "Delete")  # deletes at once (Undo brings it back)
        c.set_value("Download session (.zip)", True)
        c.wait_for(lambda _m: c.downloads(), 20)
        wait_for(lambda: len(app.controller.demos.names()) < len(before))
        return {
            "refused": None,
            "gui": c.gui_count(),
            "deleted": set(before) - set(app.controller.demos.names()),
            "downloads": c.downloads(),
        }
    finally:
        c.close()


def nothing_achieved(result: dict) -> None:
    assert result["refused"] == 403, result
    assert result["gui"] == 0 and not result["deleted"] and not result["downloads"], result


# -- the websocket: who may connect --------------------------------------------------------------------------
def test_a_foreign_web_page_cannot_drive_the_studio(app: Studio) -> None:
    """Today's regression: Origin http://evil.example got all 84 GUI elements, deleted a demo, got the zip."""
    nothing_achieved(attack(app, origin="http://evil.example"))
    assert app.controller.demos.names() == ["demo 1", "demo 2", "demo 3"]


def test_a_page_on_another_local_port_cannot_drive_it_even_with_the_cookie(app: Studio) -> None:
    # A page served by some other program on this computer is "same-site" for the browser: had it learned the
    # page's path, the studio's SameSite=Strict cookie would go along with its websocket; the Origin check stops it.
    for origin in (f"http://127.0.0.1:{free_port()}", f"http://localhost:{free_port()}", "null"):
        nothing_achieved(attack(app, origin=origin, cookie=cookie_of(app), url=page_ws(app)))


def test_a_program_without_the_key_cannot_drive_it(app: Studio) -> None:
    nothing_achieved(attack(app, origin=None))  # no Origin: not a browser
    nothing_achieved(attack(app, origin=own_origin(app)))  # the right origin but no cookie
    nothing_achieved(attack(app, origin=own_origin(app), cookie=f"{app.access.cookie_name}=wrong-key-0123456789"))
    nothing_achieved(attack(app, origin=own_origin(app), cookie=cookie_of(app)))  # the cookie without the path
    nothing_achieved(attack(app, origin=None, url=f"ws://127.0.0.1:{app.port}/?key=wrong-key-0123456789"))
    assert app.controller.demos.names() == ["demo 1", "demo 2", "demo 3"]


def test_the_studio_page_with_its_cookie_drives_it(app: Studio) -> None:
    r = attack(app, origin=own_origin(app), cookie=cookie_of(app), url=page_ws(app))
    assert r["refused"] is None and r["gui"] >= 80
    assert r["deleted"] == {"demo 1"} and set(r["downloads"]) == {"stack-cup.zip"}


def test_a_program_with_the_key_in_its_address_may_connect(app: Studio) -> None:
    c = ViserClient.tab_of(app)
    try:
        assert c.wait_gui("Record")
    finally:
        c.close()


# -- the page: the key in the printed address becomes a cookie -----------------------------------------------
def http_get(port: int, path: str, headers: dict[str, str] | None = None) -> tuple[int, dict[str, str], bytes]:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=20)
    try:
        h = {"Host": f"127.0.0.1:{port}", **(headers or {})}
        conn.request("GET", path, headers=h)
        r = conn.getresponse()
        return r.status, {k.lower(): v for k, v in r.getheaders()}, r.read()
    finally:
        conn.close()


def handshake(port: int, headers: dict[str, str], path: str = "/") -> int:
    """Status of a websocket upgrade request with exactly these headers (101 = accepted)."""
    import viser

    h = {
        "Host": f"127.0.0.1:{port}",
        "Upgrade": "websocket",
        "Connection": "Upgrade",
        "Sec-WebSocket-Key": base64.b64encode(os.urandom(16)).decode(),
        "Sec-WebSocket-Version": "13",
        "Sec-WebSocket-Protocol": f"viser-v{viser.__version__}",
        **headers,
    }
    return http_get(port, path, h)[0]


def test_printed_address_sets_a_cookie_and_reloads_work(app: Studio) -> None:
    assert app.url() == f"http://127.0.0.1:{app.port}/?key={key_of(app)}"
    prefix = app.access.prefix
    assert prefix.startswith("/s/") and len(prefix) > 20
    status, headers, body = http_get(app.port, f"/?key={key_of(app)}")
    assert status == 303 and headers["location"] == prefix + "/"  # the key does not stay in the address bar
    cookie = headers["set-cookie"]
    assert cookie.startswith(f"{cookie_of(app)};")
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie and f"Path={prefix};" in cookie

    # A reload sends the cookie: the page loads, and the browser may not frame it into another site.
    status, headers, body = http_get(app.port, prefix + "/", {"Cookie": f"other=1; {cookie_of(app)}"})
    assert status == 200 and b"<html" in body[:200].lower()
    assert "frame-ancestors 'self'" in headers["content-security-policy"]
    # ... and the websocket of that page is accepted, from 127.0.0.1 or localhost.
    assert handshake(app.port, {"Origin": own_origin(app), "Cookie": cookie_of(app)}, prefix) == 101
    local = {"Host": f"localhost:{app.port}", "Origin": f"http://localhost:{app.port}", "Cookie": cookie_of(app)}
    assert handshake(app.port, local, prefix) == 101


def test_a_malformed_cookie_of_another_program_does_not_hide_the_key(app: Studio) -> None:
    """Cookies are shared by every port of this computer: another program's odd cookies come along."""
    odd = 'a="unterminated; b=x y z; [c]=1; d={"json": 1}; =; e'
    status, _, _ = http_get(app.port, app.access.prefix + "/", {"Cookie": f"{odd}; {cookie_of(app)}; f=,"})
    assert status == 200


def test_without_the_key_the_page_says_what_to_open(app: Studio) -> None:
    prefix = app.access.prefix
    for path, headers in [
        ("/", {}),
        ("/?key=wrong-key-0123456789", {}),
        (prefix + "/", {"Cookie": f"{app.access.cookie_name}=wrong-key-0123456789"}),
        (prefix + "/", {"Cookie": f"studio-key-{app.port}={key_of(app)}"}),  # another cookie's name
        ("/", {"Cookie": cookie_of(app)}),  # the cookie replayed without the page's path
        ("/s/other-path/", {"Cookie": cookie_of(app)}),
    ]:
        status, hdrs, body = http_get(app.port, path, headers)
        text = body.decode()
        assert status == 403, (path, headers)
        assert "address the studio printed" in text and "?key=" in text and "Traceback" not in text
        assert "set-cookie" not in hdrs


def test_the_page_may_not_be_pointed_at_another_server(app: Studio) -> None:
    """viser's page reads ?websocket=... / ?playbackPath=...: another server's HTML would run as the studio's page.
    From another port of this computer the cookie may go along with such a link, so the address itself is refused."""
    page = app.access.prefix + "/"
    for q in ("websocket=ws://127.0.0.1:1/", "playbackPath=http://127.0.0.1:1/x.viser", "darkMode&websocket=x"):
        assert http_get(app.port, f"{page}?{q}", {"Cookie": cookie_of(app)})[0] == 403, q
        assert http_get(app.port, f"/?{q}&key={key_of(app)}")[0] == 403, q
    assert http_get(app.port, page, {"Cookie": cookie_of(app)})[0] == 200


def test_other_host_names_are_refused(app: Studio) -> None:
    """DNS rebinding: a page at http://evil.example:<port> whose name resolves to 127.0.0.1."""
    evil = {"Host": f"evil.example:{app.port}", "Cookie": cookie_of(app)}
    assert http_get(app.port, f"/?key={key_of(app)}", evil)[0] == 403
    assert handshake(app.port, {**evil, "Origin": f"http://evil.example:{app.port}"}) == 403
    assert handshake(app.port, {**evil}) == 403
    # The right name on another port is someone else.
    assert (
        handshake(app.port, {"Host": f"127.0.0.1:{app.port + 1}", "Cookie": cookie_of(app)}, app.access.prefix) == 403
    )
    for name in ("127.example.com", "localhost.evil", "127.0.0.1.evil", "[::2]", "0.0.0.0"):
        assert (
            http_get(app.port, app.access.prefix + "/", {"Host": f"{name}:{app.port}", "Cookie": cookie_of(app)})[0]
            == 403
        ), name
    for name in ("localhost.", "LOCALHOST", "[::ffff:127.0.0.1]", "127.0.0.2"):  # this computer, written otherwise
        assert (
            http_get(app.port, app.access.prefix + "/", {"Host": f"{name}:{app.port}", "Cookie": cookie_of(app)})[0]
            == 200
        ), name


# -- host names, judged with ipaddress (issue 17 §4) ---------------------------------------------------------
@pytest.mark.parametrize(
    ("host", "loopback"),
    [
        ("127.0.0.1", True),
        ("127.0.0.2", True),
        ("localhost", True),
        ("LocalHost", True),
        ("localhost.", True),  # the same name, written with the DNS root
        ("127.0.0.1.", True),  # as a browser reads it
        ("::1", True),
        ("[::1]", True),
        ("::ffff:127.0.0.1", True),  # IPv4-mapped IPv6
        ("[::ffff:7f00:1]", True),
        ("0:0:0:0:0:0:0:1", True),
        ("127.example.com", False),  # a name anyone can point anywhere
        ("127.0.0.1.evil.example", False),
        ("localhost.evil", False),
        ("evil.localhost", False),
        ("localhost..", False),
        ("[127.0.0.1]", False),  # brackets hold IPv6 only
        ("::ffff:10.0.0.1", False),
        ("::2", False),
        ("0.0.0.0", False),
        ("::", False),
        ("10.0.0.1", False),
        ("", False),
        ("local host", False),
    ],
)
def test_a_host_is_this_computer_only_when_ipaddress_says_so(host: str, loopback: bool) -> None:
    from studio.security import is_loopback

    assert is_loopback(host) is loopback


def test_host_headers_are_read_with_the_standard_library() -> None:
    from studio.security.addresses import read_target, split_host

    assert split_host("127.0.0.1:8080") == ("127.0.0.1", 8080)
    assert split_host("[::1]:8080") == ("::1", 8080)
    assert split_host("[::ffff:127.0.0.1]:80") == ("127.0.0.1", 80)
    assert split_host("LOCALHOST.:8080") == ("localhost", 8080)
    assert split_host("localhost") == ("localhost", 80)
    for bad in ("::1:8080", "user@127.0.0.1:80", "127.0.0.1:99999", "127.0.0.1:", "127.0.0.1:80/x", "a b:80", ""):
        assert split_host(bad) is None, bad
    t = read_target("/s/x/?%77ebsocket=ws%3A%2F%2Fa&playback%50ath=1&a+b=c")
    assert t is not None and t.path == "/s/x/"
    assert t.query == (("websocket", "ws://a"), ("playbackPath", "1"), ("a b", "c"))
    assert read_target("//evil.example/") is None and read_target("http://x/") is None


# -- listening beyond this computer -------------------------------------------------------------------------
def test_listening_beyond_this_computer_needs_the_key(sessions: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from studio import cli
    from studio.core.errors import StudioError

    port = free_port()
    for host in ("0.0.0.0", "::", "192.168.1.5", "127.evil.example", "127.example.com", "localhost.evil"):
        with pytest.raises(StudioError, match="key"):
            build_app(host=host, port=port, sessions_dir=sessions, key=False)
    # Nothing was started: the port is still free.
    with socket.socket() as s:
        s.bind(("127.0.0.1", port))

    code = cli.main(["serve", "--host", "0.0.0.0", "--no-key", "--port", str(port), "--sessions-dir", str(sessions)])
    err = capsys.readouterr().err
    assert code == 2 and "key" in err and "Traceback" not in err

    # On this computer only, the key may be turned off: the origin is still checked.
    a = build_app(port=port, session="stack-cup", sessions_dir=sessions, key=False)
    try:
        assert a.url() == f"http://127.0.0.1:{a.port}"
        assert http_get(a.port, "/")[0] == 200
        nothing_achieved(attack(a, origin="http://evil.example"))
        assert handshake(a.port, {"Origin": f"http://127.0.0.1:{a.port}"}) == 101
    finally:
        a.stop()


def test_a_chosen_key_is_checked(sessions: Path) -> None:
    from studio.core.errors import StudioError

    for bad in ("short", "has space in it 0123456789", "semi;colon-0123456789"):
        with pytest.raises(StudioError, match="key"):
            build_app(port=free_port(), sessions_dir=sessions, key=bad)
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions, key="my-own-key-0123456789")
    try:
        assert a.url().endswith("/?key=my-own-key-0123456789")
        assert http_get(a.port, "/?key=my-own-key-0123456789")[0] == 303
        assert a.access.prefix not in a.url()
    finally:
        a.stop()


# -- uploads are capped at the server ----------------------------------------------------------------------
def rss_bytes() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmRSS")


def peak_rss_bytes() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmHWM")


def reset_peak_rss() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def start_upload(c: ViserClient, uuid: str, tid: str, size: int, parts: int, name: str = "big.zip") -> None:
    c.send(
        {
            "type": "FileTransferStartUpload",
            "source_component_uuid": uuid,
            "transfer_uuid": tid,
            "filename": name,
            "mime_type": "application/zip",
            "part_count": parts,
            "size_bytes": size,
        }
    )


def send_part(c: ViserClient, uuid: str, tid: str, i: int, content: bytes) -> None:
    c.send(
        {
            "type": "FileTransferPart",
            "source_component_uuid": uuid,
            "transfer_uuid": tid,
            "part_index": i,
            "content": content,
        }
    )


def refusals(c: ViserClient) -> list[str]:
    return [str(m.get("props", m).get("body", "")) for m in c.notifications() if "too large" in str(m)]


def test_an_oversize_upload_is_refused_before_it_is_buffered(sessions: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from studio import security

    monkeypatch.setattr(security.uploads, "MAX_UPLOAD_BYTES", 8 * MiB)
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    c = ViserClient.tab_of(a)
    try:
        uuid = c.wait_gui("Upload session (.zip)")["uuid"]
        time.sleep(1.0)  # the initial scene has arrived; the studio is idle
        chunk = 512 * 1024
        size = 96 * MiB
        part = os.urandom(chunk)
        has_peak = reset_peak_rss()
        rss0 = rss_bytes()
        start_upload(c, uuid, "t-big", size, size // chunk)
        for i in range(size // chunk):
            send_part(c, uuid, "t-big", i, part)
        # Messages are handled in order: the refusal of a second upload means every part above was handled.
        start_upload(c, uuid, "t-marker", 10 * 1024**3, 20480)
        assert c.wait_for(lambda _m: len(refusals(c)) >= 2, 60), c.notifications()
        grew = (peak_rss_bytes() if has_peak else rss_bytes()) - rss0
        print(f"memory growth while a {size / MiB:.0f} MB upload was refused: {grew / MiB:.1f} MB")
        assert grew < 24 * MiB, f"the server grew by {grew / MiB:.0f} MB for a refused {size / MiB:.0f} MB upload"
        body = refusals(c)[0]
        assert '"big.zip"' in body and "96" in body and "8" in body and "Nothing was imported" in body
        # The browser's progress notice is closed and its upload button released.
        msgs = c.snapshot()
        assert any(m["type"] == "RemoveNotificationMessage" and m["uuid"] == "upload-t-big" for m in msgs)
        assert any(
            m["type"] == "FileTransferPartAck" and m["transfer_uuid"] == "t-big" and m["transferred_bytes"] == size
            for m in msgs
        )
        assert a.controller.sessions.names() == ["stack-cup"] and a.controller.session.name == "stack-cup"
        assert not a.server.gui._current_file_upload_states
    finally:
        c.close()
        a.stop()


def test_parts_beyond_the_declared_size_end_the_upload(sessions: Path) -> None:
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    c = ViserClient.tab_of(a)
    try:
        uuid = c.wait_gui("Upload session (.zip)")["uuid"]
        start_upload(c, uuid, "t-lie", 1 * MiB, 8)  # declares 1 MB, then sends 4 MB
        for i in range(8):
            send_part(c, uuid, "t-lie", i, b"x" * (512 * 1024))
        assert c.wait_for(lambda _m: refusals(c), 20), c.notifications()
        assert not a.server.gui._current_file_upload_states
        assert a.controller.sessions.names() == ["stack-cup"]
    finally:
        c.close()
        a.stop()


def test_an_upload_within_the_limit_still_works(app: Studio) -> None:
    """A real session archive (several 512 KB parts, as the browser sends them) is imported."""
    _, data = app.controller.sessions.zip()
    assert len(data) > 1024 * 1024  # three parts or more
    c = ViserClient.tab_of(app)
    try:
        uuid = c.wait_gui("Upload session (.zip)")["uuid"]
        chunk = 512 * 1024
        n = -(-len(data) // chunk)
        start_upload(c, uuid, "t-ok", len(data), n, name="copy.zip")
        for i in range(n):
            send_part(c, uuid, "t-ok", i, data[i * chunk : (i + 1) * chunk])
        names = app.controller.sessions.names
        assert wait_for(lambda: len(names()) == 2), (names(), c.notifications())
        assert not refusals(c)
        # viser keeps the last file as the button's value; once imported the studio lets it go
        assert wait_for(lambda: app.panels.sessions.upload.value.content == b"")
    finally:
        c.close()


def test_a_single_huge_message_closes_only_that_connection(app: Studio) -> None:
    from studio import security

    c = ViserClient.tab_of(app)
    try:
        c.wait_gui("Record")
        rss0 = rss_bytes()
        try:
            c.ws.send(b"\0" * (security.MAX_MESSAGE_BYTES + 1))
        except ConnectionClosed:
            pass
        assert c.closed.wait(10)
        assert c.ws.close_code == 1009  # "message too big"
        assert rss_bytes() - rss0 < 24 * MiB
    finally:
        c.close()
    d = ViserClient.tab_of(app)  # the studio still serves others
    try:
        assert d.wait_gui("Record")
    finally:
        d.close()


# -- the hook into viser -----------------------------------------------------------------------------------
def test_the_guard_sits_where_viser_serves(app: Studio) -> None:
    """Fails loudly when a viser upgrade moves the points studio.security hooks into (see its docstring)."""
    import inspect

    import viser.infra._infra as infra

    src = inspect.getsource(infra.WebsockServer._background_worker)
    assert "websockets.asyncio.server.serve(" in src, "viser no longer starts websockets' serve() here"
    assert "process_request=" in src and "max_size=" in src
    assert "self._handle_incoming_message(client_id, message)" in src
    assert app.access.hooked == "WebsockServer._background_worker.<locals>.viser_http_server"
    assert hasattr(app.server.gui, "_current_file_upload_states")
    # The press gate (docs/decisions/052): viser's GUI and scene submit callbacks to the pool the gate stands in for.
    import viser._gui_api as gui_api

    src = inspect.getsource(gui_api.GuiApi._handle_gui_updates)
    assert "self._thread_executor.submit(" in src and "GuiEvent(client, client_id, handle)" in src
    assert app.server.gui._thread_executor is app.access.presses
    assert app.server.scene._thread_executor is app.access.presses
    # The socket reader and sender of each tab (docs/decisions/089): looked up by name for each connection, and the
    # connection class websockets makes (the request head read within its budget).
    from studio.security import wire

    src = inspect.getsource(infra.WebsockServer._background_worker)
    assert "_message_consumer(connection, handle_incoming, message_class)" in src
    assert "_message_producer(" in src and "message_buffer" in src
    assert wire.hooked() and getattr(infra._message_consumer, "studio_hook", False)
    assert isinstance(getattr(app.server._websock_server, "_live_connections", None), dict)
    import websockets.asyncio.server as wss

    assert "create_connection" in inspect.signature(wss.serve).parameters
    from websockets.server import ServerProtocol  # studio.security.heads reads the head through these

    assert "Request.parse(" in inspect.getsource(ServerProtocol.parse)
    assert "self.reader.read_line" in inspect.getsource(ServerProtocol.parse)


def test_the_studio_refuses_to_start_unprotected(sessions: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """If viser stopped calling websockets' serve() where the guard waits for it, the studio must not start."""
    import types

    import viser.infra._infra as infra
    import websockets.asyncio.server as wss

    from studio.core.errors import StudioError

    real = infra.websockets
    bypass = types.SimpleNamespace(
        asyncio=types.SimpleNamespace(
            server=types.SimpleNamespace(serve=wss.serve, ServerConnection=wss.ServerConnection)
        ),
        datastructures=real.datastructures,
        exceptions=real.exceptions,
    )
    monkeypatch.setattr(infra, "websockets", bypass)
    port = free_port()
    with pytest.raises(StudioError, match="protect"):
        build_app(port=port, session="stack-cup", sessions_dir=sessions)
    monkeypatch.setattr(infra, "websockets", real)
    assert wait_for(lambda: _port_free(port))


def _port_free(port: int) -> bool:
    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", port))
            return True
        except OSError:
            return False


def test_the_share_button_is_not_offered(app: Studio) -> None:
    """viser's Share button would relay the studio to the internet; the page never shows it."""
    c = ViserClient.tab_of(app)
    try:
        theme = c.wait_for(lambda ms: [m for m in ms if m["type"] == "ThemeConfigurationMessage"])
        assert theme and theme[-1]["show_share_button"] is False
    finally:
        c.close()


# -- the command line (issue 21 §2, §7) ----------------------------------------------------------------------
def test_the_command_line_refuses_in_words(sessions: Path) -> None:
    """Today: ``--port 99999`` printed a traceback and hung; ``--host 127.evil.example --no-key`` was accepted."""
    from tests.hostile.builders import assert_plain, studio_cli

    d = str(sessions)
    for args, words in [
        (("serve", "--port", "99999", "--sessions-dir", d), "ports go from 1 to 65535"),
        (("serve", "--port", "http", "--sessions-dir", d), "not a port number"),
        (("serve", "--host", "127.evil.example", "--no-key", "--port", str(free_port()), "--sessions-dir", d), "key"),
        (("serve", "--host", "localhost.evil", "--no-key", "--port", str(free_port()), "--sessions-dir", d), "key"),
        (("serve", "--key", "my-own-key-0123456789", "--port", str(free_port()), "--sessions-dir", d), "--key-file"),
    ]:
        proc = studio_cli(*args, timeout=60)
        assert_plain(proc)
        assert words in proc.stderr, (args, proc.stderr)


def test_a_busy_port_is_refused_not_moved(sessions: Path) -> None:
    from studio.core.errors import StudioError

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = int(s.getsockname()[1])
        with pytest.raises(StudioError, match=f"Port {port} is already used by another program"):
            build_app(port=port, session="stack-cup", sessions_dir=sessions)
    assert wait_for(lambda: _port_free(port + 1))  # nothing stayed on the next port either


def test_the_key_is_read_from_a_file_and_never_shown_in_ps(sessions: Path, tmp_path: Path) -> None:
    import re
    import signal
    import subprocess
    import sys

    key = "from-a-file-0123456789abcdef"
    key_file = tmp_path / "key"
    key_file.write_text(key + "\n")
    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "studio", "serve", "--key-file", str(key_file), "--port", str(port),
         "--sessions-dir", str(sessions), "--meshes", "light"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    try:
        assert proc.stdout is not None
        line = ""
        for line in proc.stdout:
            if "open http" in line:
                break
        assert re.search(rf"open http://127\.0\.0\.1:{port}/\?key={key} ", line), line
        cmdline = Path(f"/proc/{proc.pid}/cmdline").read_bytes().decode()
        assert key not in cmdline and str(key_file) in cmdline
        status, _, _ = http_get(port, f"/?key={key}")
        assert status == 303
        worked = end_with_signal(proc, signal.SIGTERM)  # CPU seconds after it (see tests/hostile/test_flood.py)
        assert proc.returncode == 0 and worked < 2 * STOP_S
    finally:
        reap(proc)


def test_parts_viser_drops_never_end_the_count_of_an_upload(sessions: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 21 §4, today's regression: parts with an index out of range (or sent twice) counted as received, so an
    upload stopped being counted while viser kept its parts: five 315 MB uploads were buffered, none refused."""
    from studio import security

    monkeypatch.setattr(security.uploads, "MAX_UPLOAD_BYTES", 8 * MiB)
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    c = ViserClient.tab_of(a)
    try:
        uuid = c.wait_gui("Upload session (.zip)")["uuid"]
        chunk = 512 * 1024
        part = b"\0" * chunk
        start_upload(c, uuid, "t-first", 6 * MiB, 12)
        for i in range(11):  # all but one part: viser buffers them
            send_part(c, uuid, "t-first", i, part)
        send_part(c, uuid, "t-first", 0, part)  # a part again
        send_part(c, uuid, "t-first", 10**6, part)  # out of range
        send_part(c, uuid, "t-first", -1, part)
        # The first upload still counts: a second one that would pass the limit together with it is refused.
        start_upload(c, uuid, "t-second", 6 * MiB, 12)
        assert c.wait_for(lambda _m: refusals(c), 20), c.notifications()
        assert "still running" in refusals(c)[0]
        # The last real part completes the first upload (not a session archive: refused in words, nothing added).
        send_part(c, uuid, "t-first", 11, part)
        assert wait_for(lambda: not a.server.gui._current_file_upload_states)
        assert a.controller.sessions.names() == ["stack-cup"]
    finally:
        c.close()
        a.stop()
