"""Only the studio's own page may drive the studio: origin, host, a per-launch key, and upload limits.

Why: viser serves the page and its websocket on one port and, left alone, accepts any websocket. Any web
page open in the teacher's browser (or any program on the computer) could connect, receive the whole GUI,
press buttons (delete demonstrations, move the robot) and download the session.

What is checked, on every HTTP request and every websocket upgrade, before viser sees it:

* **Host** must name this studio: ``127.0.0.1``, ``localhost`` or ``[::1]`` (or the address given with
  ``--host``) with the studio's port. This stops DNS rebinding (``evil.example`` resolving to 127.0.0.1).
  When listening on every interface (``0.0.0.0``) any name is accepted and the key does the work.
* **Origin**, when present (browsers always send it with a websocket), must be the page's own origin
  ``http://<Host>``. A page served from elsewhere, even from another port of this computer (which the browser
  counts as the same *site* and so sends it the studio's cookie), is refused.
* **The key**: a random secret made at each start (:func:`secrets.token_urlsafe`), in the address the studio
  prints (``http://127.0.0.1:8080/?key=...``). Opening that address answers with a redirect to the same page
  without the key and a cookie ``studio-key-<port>`` (``HttpOnly; SameSite=Strict``), so reloads work and the
  key does not stay in the address bar. A websocket needs the cookie, or ``?key=`` in its own address (for
  programs, which send no Origin). ``--no-key`` turns the key off, on this computer only: listening beyond
  it without the key is refused (:class:`StudioError`).
* **No other server**: a page address with viser's ``websocket=`` or ``playbackPath=`` parameter (the page
  would connect to, or replay from, another server, whose HTML would then run as the studio's page) is
  refused.

A refused request gets HTTP 403 with a short plain-text explanation (what to open instead); nothing of the
studio is sent, no websocket is opened and no callback runs. Accepted pages also carry headers that keep
other sites from framing them (``frame-ancestors 'self'``) or seeing the address (``no-referrer``).

Uploads are capped at the server. viser's browser client sends a file as one ``FileTransferStartUpload``
(declared size) and 512 KiB ``FileTransferPart`` messages; viser buffers every part in memory until the file
is complete, with no limit. Here the declared size is checked first (:data:`MAX_UPLOAD_BYTES` for all
uploads in flight together), so the parts of a refused upload are dropped as they arrive and never
buffered; parts beyond the declared size end the upload. The browser gets a notification in plain words,
its progress notice is closed and its upload button released. A single websocket message may be at most
:data:`MAX_MESSAGE_BYTES` (viser allows 50 MiB): websockets refuses a longer frame from its header, before
reading it, and closes that connection (code 1009).

Where this hooks into viser, and why there (viser 1.1.1 with websockets 16):

* ``viser.infra.WebsockServer._background_worker`` (a thread started by ``ViserServer.__init__``, which
  waits until the port is bound) calls ``websockets.asyncio.server.serve(ws_handler, host, port,
  max_size=50 MiB, process_request=viser_http_server, ...)``. ``process_request`` is called for every
  request on the port: page loads (viser answers them with its bundled client) and websocket upgrades
  (viser returns None: accept). It is the narrowest point that sees the headers of both, before a websocket
  exists, before any GUI is sent and before any callback can run, and where a refusal is a plain HTTP 403.
  :meth:`Access.start_viser` therefore swaps ``websockets.asyncio.server.serve`` for a wrapper *only while
  the studio's ViserServer is being built* (under a lock), and puts the original back as soon as the server
  listens: the wrapper wraps viser's ``process_request`` with :meth:`Access.check` and sets ``max_size``.
  No other websockets server in the process is affected. (viser's own banner, which shows the address
  without the key, is silenced for that moment: the studio prints the address to open.)
* Every incoming websocket message is dispatched by ``WebsockServer._handle_incoming_message(client_id,
  message)``, looked up on the server instance for each message; :class:`UploadLimit` wraps it on this one
  instance to check uploads before viser's ``GuiApi`` buffers them.
* If a viser upgrade moves either point, :meth:`Access.start_viser` stops the server and raises
  :class:`StudioError` (the studio refuses to run unprotected), and
  ``tests/test_security.py::test_the_guard_sits_where_viser_serves`` fails.
"""

from __future__ import annotations

import hmac
import http
import inspect
import logging
import re
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from studio.core.errors import StudioError

if TYPE_CHECKING:
    import viser
    from websockets.asyncio.server import ServerConnection
    from websockets.datastructures import Headers
    from websockets.http11 import Request, Response

log = logging.getLogger("studio.security")

#: All uploads in flight together may declare at most this many bytes (viser holds a file in memory).
MAX_UPLOAD_BYTES = 512 * 1024**2
#: One websocket message from a browser (viser's client sends uploads in 512 KiB parts).
MAX_MESSAGE_BYTES = 4 * 1024**2
#: An upload that received nothing for this long no longer counts against the limit.
UPLOAD_IDLE_S = 60.0

LOOPBACK_HOSTS = frozenset({"127.0.0.1", "localhost", "::1"})
WILDCARD_HOSTS = frozenset({"0.0.0.0", "::", ""})
KEY_PARAM = "key"
#: Address parameters of viser's page that make it connect to, or load a recording from, another server:
#: a page driven by someone else's server would run their HTML inside the studio's origin.
FOREIGN_SOURCE_PARAMS = frozenset({"websocket", "playbackPath"})
_KEY_RE = re.compile(r"[A-Za-z0-9_-]{16,128}")
_SERVE_LOCK = threading.Lock()

NEEDS_KEY_TEXT = (
    "Teaching Studio: this address needs its key.\n\n"
    "Open the full address the studio printed when it started, for example\n"
    "    http://127.0.0.1:{port}/?key=...\n"
    "The key changes each time the studio starts; if you restarted it, use the new address.\n"
    "(The key keeps other web pages and other people from controlling the robot. "
    "If you did open that address, allow cookies for it.)\n"
)
REFUSED_TEXT = (
    "Teaching Studio: this connection is refused.\n\n"
    "Only the studio's own page may control it. Open the address the studio printed when it started\n"
    "(http://127.0.0.1:{port}/?key=...) directly in your browser.\n"
)


def is_loopback(host: str) -> bool:
    """True when ``host`` is reachable from this computer only."""
    return host in LOOPBACK_HOSTS or host.startswith("127.")


def new_key() -> str:
    return secrets.token_urlsafe(24)


def _split_host(value: str) -> tuple[str, int] | None:
    """``name:port`` / ``[v6]:port`` / ``name`` → (lower-case name, port); None when malformed."""
    value = value.strip().lower()
    if value.startswith("["):
        name, sep, rest = value[1:].partition("]")
        if not sep:
            return None
        port_s = rest[1:] if rest.startswith(":") else ("" if not rest else None)
    else:
        name, sep, port_s = value.partition(":")
        if ":" in port_s:
            return None
    if port_s is None or not name:
        return None
    if not port_s:
        return name, 80
    if not port_s.isdigit():
        return None
    return name, int(port_s)


def _cookie(headers: Headers, name: str) -> str | None:
    for line in headers.get_all("Cookie"):
        for part in line.split(";"):
            k, sep, v = part.strip().partition("=")
            if sep and k.strip() == name:
                return v.strip().strip('"')
    return None


def _query_key(path: str) -> tuple[str | None, str]:
    """(the ``key`` parameter of a request target, the target without it)."""
    base, sep, query = path.partition("?")
    if not sep:
        return None, path
    key = None
    keep = []
    for part in query.split("&"):
        k, _, v = part.partition("=")
        if k == KEY_PARAM:
            key = v
        elif part:
            keep.append(part)
    return key, base + ("?" + "&".join(keep) if keep else "")


@dataclass
class Verdict:
    """What :meth:`Access.decide` concluded about one request."""

    action: Literal["pass", "refuse", "redirect"]
    reason: str = ""
    location: str = ""  # for "redirect"


class Access:
    """Who may use the studio's server: its host, its key, its upload limits.

    Args:
        host: the address the server listens on (as given with ``--host``).
        key: None for a new random key; a string for a chosen key (16-128 letters, digits, ``-`` or ``_``);
            False for no key, allowed only on this computer (loopback).
    """

    def __init__(self, host: str, key: str | Literal[False] | None = None) -> None:
        self.host = host.strip().lower()
        if key is False:
            if not is_loopback(self.host):
                raise StudioError(
                    f"Listening on {host} without the key would let anyone who can reach this computer control "
                    "the robot and change your sessions. Remove --no-key (the studio then prints an address "
                    "with a key to open), or use --host 127.0.0.1."
                )
            self.key: str | None = None
        elif key is None:
            self.key = new_key()
        elif isinstance(key, str) and _KEY_RE.fullmatch(key):
            self.key = key
        else:
            raise StudioError("The key must be 16 to 128 characters long, made of letters, digits, '-' and '_' only.")
        #: the viser function the guard wraps (its qualified name) once the server listens; None before.
        self.hooked: str | None = None
        self.uploads: UploadLimit | None = None
        self._last_log: dict[str, float] = {}

    # -- addresses ---------------------------------------------------------------------------------------
    def cookie_name(self, port: int) -> str:
        return f"studio-key-{port}"

    def url(self, port: int) -> str:
        """The address to open in the browser (with the key)."""
        host = "127.0.0.1" if self.host in WILDCARD_HOSTS else self.host
        if ":" in host:
            host = f"[{host}]"
        base = f"http://{host}:{port}"
        return f"{base}/?{KEY_PARAM}={self.key}" if self.key else base

    # -- the decision ------------------------------------------------------------------------------------
    def _key_ok(self, candidate: str | None) -> bool:
        return bool(
            self.key is not None
            and candidate is not None
            and hmac.compare_digest(candidate.encode("utf-8", "replace"), self.key.encode())
        )

    def _host_ok(self, name: str, port: int, local_port: int) -> bool:
        if port != local_port:
            return False
        if self.host in WILDCARD_HOSTS:
            return True
        return name in LOOPBACK_HOSTS or name == self.host

    def decide(self, path: str, headers: Headers, local_port: int) -> Verdict:
        """Pass, refuse or redirect (key in the address → cookie) one request, from its target and headers."""
        hosts = headers.get_all("Host")
        parsed = _split_host(hosts[0]) if len(hosts) == 1 else None
        if parsed is None or not self._host_ok(*parsed, local_port):
            return Verdict("refuse", f"unknown host {hosts!r}")
        origins = headers.get_all("Origin")
        if len(origins) > 1:
            return Verdict("refuse", "several Origin headers")
        if origins:
            origin = origins[0].strip().lower().rstrip("/")
            host = hosts[0].strip().lower()
            if origin not in (f"http://{host}", f"https://{host}"):
                return Verdict("refuse", f"foreign origin {origins[0]!r}")
        upgrade = any("websocket" in v.lower() for v in headers.get_all("Upgrade"))
        if not upgrade:
            names = {part.partition("=")[0] for part in path.partition("?")[2].split("&")}
            if names & FOREIGN_SOURCE_PARAMS:
                return Verdict("refuse", "the address asks the page to use another server")
        if self.key is None:
            return Verdict("pass")
        query_key, without_key = _query_key(path)
        if query_key is not None:
            if not self._key_ok(query_key):
                return Verdict("refuse", "wrong key in the address")
            if upgrade:
                return Verdict("pass")
            location = "/" + without_key.lstrip("/")  # never "//host": a redirect stays on this server
            return Verdict("redirect", location=location)
        if self._key_ok(_cookie(headers, self.cookie_name(local_port))):
            return Verdict("pass")
        return Verdict("refuse", "no key")

    def check(
        self, inner: Callable[[ServerConnection, Request], Any] | None
    ) -> Callable[[ServerConnection, Request], Any]:
        """A websockets ``process_request`` hook: :meth:`decide` first, then viser's own (``inner``)."""
        from websockets.datastructures import Headers
        from websockets.http11 import Response

        async def process_request(connection: ServerConnection, request: Request) -> Response | None:
            local_port = int(connection.local_address[1])
            verdict = self.decide(request.path, request.headers, local_port)
            if verdict.action == "refuse":
                self._log_refusal(verdict.reason, request)
                page = not any("websocket" in v.lower() for v in request.headers.get_all("Upgrade"))
                needs_key = page and verdict.reason in ("no key", "wrong key in the address")
                text = (NEEDS_KEY_TEXT if needs_key else REFUSED_TEXT).format(port=local_port)
                response = connection.respond(http.HTTPStatus.FORBIDDEN, text)
                _protect(response.headers)
                return response
            if verdict.action == "redirect":
                assert self.key is not None
                headers = Headers()
                headers["Location"] = verdict.location
                headers["Set-Cookie"] = f"{self.cookie_name(local_port)}={self.key}; Path=/; HttpOnly; SameSite=Strict"
                headers["Cache-Control"] = "no-store"
                headers["Content-Length"] = "0"
                _protect(headers)
                return Response(http.HTTPStatus.SEE_OTHER.value, "See Other", headers, b"")
            result = inner(connection, request) if inner is not None else None
            if inspect.isawaitable(result):
                result = await result
            if result is not None:
                _protect(result.headers)
            return result

        return process_request

    def _log_refusal(self, reason: str, request: Request) -> None:
        now = time.monotonic()
        if now - self._last_log.get(reason, -1e9) < 10.0:
            return
        self._last_log[reason] = now
        origin = request.headers.get("Origin")
        where = f", from a page at {origin}" if origin and "origin" not in reason else ""
        log.warning("refused a connection to the studio (%s%s)", reason, where)

    # -- hooking into viser ------------------------------------------------------------------------------
    def start_viser(self, **kwargs: Any) -> viser.ViserServer:
        """``viser.ViserServer(**kwargs)`` with every request checked and uploads capped (see the module doc)."""
        import rich
        import viser
        import websockets.asyncio.server as wss

        access = self
        console = rich.get_console()

        with _SERVE_LOCK:
            real_serve = wss.serve

            def guarded_serve(handler: Any, *args: Any, process_request: Any = None, **kw: Any) -> Any:
                access.hooked = getattr(process_request, "__qualname__", repr(process_request))
                kw["max_size"] = MAX_MESSAGE_BYTES
                return real_serve(handler, *args, process_request=access.check(process_request), **kw)

            setattr(wss, "serve", guarded_serve)  # noqa: B010 (mypy: `serve` is a class)
            # viser prints a box with its address *without* the key; the studio prints the one to open.
            quiet, console.quiet = console.quiet, True
            try:
                server = viser.ViserServer(**kwargs)
            finally:
                setattr(wss, "serve", real_serve)  # noqa: B010
                console.quiet = quiet
        try:
            if self.hooked is None:
                raise StudioError("its web server no longer starts where the studio checks who connects")
            self.uploads = UploadLimit(server)
        except Exception as exc:
            server.stop()
            detail = str(exc) if isinstance(exc, StudioError) else f"{type(exc).__name__}: {exc}"
            raise StudioError(
                f"The studio could not protect its connection with viser {viser.__version__} ({detail}), so it "
                "did not start. Install the viser version it was made for: pip install 'viser==1.1.1'."
            ) from exc
        return server


def _protect(headers: Headers) -> None:
    """Headers for every answer: no framing by other sites, no address in Referer, no type sniffing."""
    headers["Content-Security-Policy"] = "frame-ancestors 'self'"
    headers["X-Frame-Options"] = "SAMEORIGIN"
    headers["Referrer-Policy"] = "no-referrer"
    headers["X-Content-Type-Options"] = "nosniff"


@dataclass
class _Transfer:
    client_id: int
    declared: int
    parts: int
    seen: int = 0
    received: int = 0
    last: float = 0.0


class UploadLimit:
    """Checks viser's upload messages on one server before its GuiApi buffers them (see the module doc)."""

    def __init__(self, server: viser.ViserServer) -> None:
        from viser import _messages
        from viser.infra import WebsockServer

        ws = server._websock_server
        inner = ws._handle_incoming_message
        if not (
            isinstance(ws, WebsockServer)
            and callable(inner)
            and isinstance(getattr(server.gui, "_current_file_upload_states", None), dict)
            and hasattr(_messages, "FileTransferStartUpload")
            and hasattr(_messages, "FileTransferPart")
        ):
            raise StudioError("its upload messages are no longer where the studio checks their size")
        self._server = server
        self._msgs = _messages
        self._inner = inner
        self._transfers: dict[str, _Transfer] = {}
        self._lock = threading.Lock()
        #: uploads refused so far (for tests and logs)
        self.refused = 0
        ws._handle_incoming_message = self.handle  # type: ignore[method-assign]
        ws.on_client_disconnect(self._on_disconnect)

    async def handle(self, client_id: Any, message: Any) -> None:
        m = self._msgs
        if isinstance(message, m.FileTransferStartUpload):
            if not self._start(client_id, message):
                return
        elif isinstance(message, m.FileTransferPart):
            if not self._part(client_id, message):
                return
        await self._inner(client_id, message)

    def _start(self, client_id: int, msg: Any) -> bool:
        size, parts, tid = msg.size_bytes, msg.part_count, msg.transfer_uuid
        if not (
            isinstance(size, int)
            and isinstance(parts, int)
            and isinstance(tid, str)
            and 0 <= parts <= size
            and (parts > 0 or size == 0)
        ):
            return False  # not what viser's client sends: drop silently
        now = time.monotonic()
        with self._lock:
            if tid in self._transfers:
                return False  # the same upload announced twice
            for k in [k for k, t in self._transfers.items() if now - t.last > UPLOAD_IDLE_S]:
                self._forget(k)
            busy = sum(t.declared for t in self._transfers.values())
            cap = MAX_UPLOAD_BYTES
            if size > cap:
                reason = f"is too large ({_mb(size)}); the studio accepts files up to {_mb(cap)}"
            elif busy + size > cap:
                reason = (
                    f"({_mb(size)}) is too large to upload while another upload of {_mb(busy)} is still running; "
                    "try again when it has finished"
                )
            else:
                if size > 0:
                    self._transfers[tid] = _Transfer(client_id, size, parts, last=now)
                return True
        self._refuse(client_id, msg, size, f'"{_short(msg.filename)}" {reason}. Nothing was imported.')
        return False

    def _part(self, client_id: int, msg: Any) -> bool:
        content = msg.content
        with self._lock:
            t = self._transfers.get(msg.transfer_uuid)
            if t is None or t.client_id != client_id or not isinstance(content, (bytes, bytearray, memoryview)):
                return False  # a refused, finished or unknown upload: never buffered
            t.received += len(content)
            t.seen += 1
            t.last = time.monotonic()
            over = t.received > t.declared
            if over:
                self._forget(msg.transfer_uuid)
            elif t.seen >= t.parts:  # viser completes (or drops) the file with this part
                del self._transfers[msg.transfer_uuid]
        if over:
            self._refuse(
                client_id,
                msg,
                t.declared,
                "The file is too large: more arrived than the browser announced, so the upload was stopped. "
                "Nothing was imported.",
            )
            return False
        return True

    def _forget(self, tid: str) -> None:
        self._transfers.pop(tid, None)
        self._server.gui._current_file_upload_states.pop(tid, None)

    def _on_disconnect(self, conn: Any) -> None:
        with self._lock:
            for k in [k for k, t in self._transfers.items() if t.client_id == conn.client_id]:
                self._forget(k)

    def _refuse(self, client_id: int, msg: Any, size: int, body: str) -> None:
        self.refused += 1
        log.warning("refused an upload: %s", body)
        client = self._server.get_clients().get(client_id)
        if client is None:
            return
        m = self._msgs
        try:
            conn = client._websock_connection
            # Close the browser's progress notice first, then release its upload button (an acknowledgement
            # of every byte): the order keeps the notice from turning into "File uploaded successfully".
            conn.queue_message(m.RemoveNotificationMessage(f"upload-{msg.transfer_uuid}"))
            conn.queue_message(
                m.FileTransferPartAck(
                    source_component_uuid=msg.source_component_uuid,
                    transfer_uuid=msg.transfer_uuid,
                    transferred_bytes=size,
                    total_bytes=size,
                )
            )
            client.add_notification("The upload did not work", body, color="red", auto_close_seconds=None)
        except Exception:  # a tab that just closed
            log.debug("upload refusal to a closed tab", exc_info=True)


def _mb(n: int) -> str:
    return f"{n / 1024**2:,.0f} MB" if n >= 1024**2 else f"{n / 1024:,.0f} KB"


def _short(name: Any) -> str:
    s = str(name)
    return s if len(s) <= 80 else s[:77] + "..."


__all__ = [
    "MAX_MESSAGE_BYTES",
    "MAX_UPLOAD_BYTES",
    "Access",
    "UploadLimit",
    "Verdict",
    "is_loopback",
    "new_key",
]
