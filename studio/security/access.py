"""Who may use the studio's server: :class:`Access` decides on every request (host, origin, the page's address,
key and path) and hooks that decision, the page's policy and the upload caps into viser's server
(why there: docs/decisions/016; the page's address, key and path: 050)."""

from __future__ import annotations

import hmac
import http
import inspect
import logging
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from studio import viser_adapter
from studio.core.errors import StudioError
from studio.security import wire
from studio.security.addresses import (
    KEY_PARAM,
    KEY_RE,
    WEBSOCKET_PARAM,
    WILDCARD_HOSTS,
    cookies,
    host_name,
    is_loopback,
    new_key,
    read_target,
    split_host,
)
from studio.security.heads import MAX_LINE_BYTES, TOO_MANY_COOKIES_TEXT, connection_class
from studio.security.page import PageScripts, policy, read_page_scripts
from studio.security.presses import Presses
from studio.security.uploads import MAX_MESSAGE_BYTES, UploadLimit

if TYPE_CHECKING:
    import viser
    from websockets.asyncio.server import ServerConnection
    from websockets.datastructures import Headers
    from websockets.http11 import Request, Response

log = logging.getLogger("studio.security")

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
ODD_ADDRESS_TEXT = (
    "Teaching Studio: this address is refused.\n\n"
    "It asks the studio's page for something the studio does not use (another server, a recording to play, or an\n"
    "unknown setting). A link made by someone else can do that to take control of the studio, so nothing was\n"
    "opened. Open the address the studio printed when it started (http://127.0.0.1:{port}/?key=...) exactly as\n"
    "printed.\n"
)
#: Refusal reasons that mean "open the printed address" (the page then says so).
_NEEDS_KEY = ("no key", "wrong key in the address")
_ODD = "the address has parameters the studio's page does not use"


@dataclass
class Verdict:
    """What :meth:`Access.decide` concluded about one request."""

    action: Literal["pass", "refuse", "redirect"]
    reason: str = ""
    location: str = ""  # for "redirect"
    #: for "pass": the request target viser gets (the launch's path and the checked query removed)
    forward: str = "/"


class Access:
    """Who may use the studio's server: its host, its key, its upload limits.

    With a key, the printed address ``/?key=K`` answers with a redirect to ``/s/<path>/`` and a cookie named for
    this launch, valid only under that path: the page and its websocket need both, and the browser never sends
    the cookie to another server of this computer, which cannot guess the path (docs/decisions/050).

    Args:
        host: the address the server listens on (as given with ``--host``).
        key: None for a new random key; a string for a chosen key (16-128 letters, digits, ``-`` or ``_``);
            False for no key, allowed only on this computer (loopback).
    """

    def __init__(self, host: str, key: str | Literal[False] | None = None) -> None:
        raw = host.strip().lower()
        name = raw if raw in WILDCARD_HOSTS else host_name(raw)
        if name is None:
            raise StudioError(f'"{host}" is not a computer name or address to listen on; use --host 127.0.0.1.')
        self.host = name
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
        elif isinstance(key, str) and KEY_RE.fullmatch(key):
            self.key = key
        else:
            raise StudioError("The key must be 16 to 128 characters long, made of letters, digits, '-' and '_' only.")
        #: the page's path for this launch ("" without a key) and the cookie that holds the key under it
        self.prefix = f"/s/{secrets.token_urlsafe(18)}" if self.key else ""
        self.cookie_name = f"studio-{secrets.token_hex(6)}"
        #: the viser function the guard wraps (its qualified name) once the server listens; None before.
        self.hooked: str | None = None
        self.uploads: UploadLimit | None = None
        #: the gate every GUI message of a tab passes (values checked, presses limited); None before start
        self.presses: Presses | None = None
        self.scripts = PageScripts(None)
        self._last_log: dict[str, float] = {}

    # -- addresses ---------------------------------------------------------------------------------------
    def url(self, port: int) -> str:
        """The address to open in the browser (with the key)."""
        host = "127.0.0.1" if self.host in WILDCARD_HOSTS else self.host
        if ":" in host:
            host = f"[{host}]"
        base = f"http://{host}:{port}"
        return f"{base}/?{KEY_PARAM}={self.key}" if self.key else base

    def own_websocket(self, host_header: str) -> str:
        """The websocket address the studio's page connects to, as its browser writes it."""
        return f"ws://{host_header.strip()}{self.prefix}"

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
        return name == self.host or is_loopback(name)

    def _under_prefix(self, path: str) -> str | None:
        """The part of ``path`` after this launch's path ("/" for the page), or None when it is not under it."""
        if path == self.prefix or path.startswith(self.prefix + "/"):
            return path[len(self.prefix) :] or "/"
        return None

    def decide(self, path: str, headers: Headers, local_port: int) -> Verdict:
        """Pass, refuse or redirect (key in the address → cookie) one request, from its target and headers."""
        hosts = headers.get_all("Host")
        parsed = split_host(hosts[0]) if len(hosts) == 1 else None
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
        target = read_target(path)
        if target is None:
            return Verdict("refuse", "an unreadable address")
        names = target.names()
        allowed = {KEY_PARAM} if upgrade else {KEY_PARAM, WEBSOCKET_PARAM}
        if self.key is None:
            allowed.discard(KEY_PARAM)
        if names - allowed or len(target.values(KEY_PARAM)) > 1:
            return Verdict("refuse", _ODD)
        if any(v != self.own_websocket(hosts[0]) for v in target.values(WEBSOCKET_PARAM)):
            return Verdict("refuse", "the address asks the page to use another server")
        if self.key is None:
            return Verdict("pass", forward=target.path)
        in_address = target.values(KEY_PARAM)
        if in_address:
            if not self._key_ok(in_address[0]):
                return Verdict("refuse", "wrong key in the address")
            if upgrade:  # a program (no browser, so no Origin and no cookie): the key in its own address
                return Verdict("pass", forward="/")
            return Verdict("redirect", location=self.prefix + "/")
        rest = self._under_prefix(target.path)
        if rest is not None and self._key_ok(cookies(headers).get(self.cookie_name)):
            return Verdict("pass", forward=rest)
        return Verdict("refuse", "no key")

    def check(
        self, inner: Callable[[ServerConnection, Request], Any] | None
    ) -> Callable[[ServerConnection, Request], Any]:
        """A websockets ``process_request`` hook: :meth:`decide` first, then viser's own (``inner``)."""
        from websockets.datastructures import Headers
        from websockets.http11 import Request, Response

        async def process_request(connection: ServerConnection, request: Request) -> Response | None:
            local_port = int(connection.local_address[1])
            verdict = self.decide(request.path, request.headers, local_port)
            cookie_bytes = int(getattr(connection, "cookie_bytes", 0))
            if cookie_bytes > MAX_LINE_BYTES:
                self._log_cookies(cookie_bytes)
            if verdict.action == "refuse":
                self._log_refusal(verdict.reason, request)
                page = not any("websocket" in v.lower() for v in request.headers.get_all("Upgrade"))
                text, status = REFUSED_TEXT, http.HTTPStatus.FORBIDDEN
                if page and cookie_bytes > MAX_LINE_BYTES:  # the cookies another page set: say so, and how to clear
                    hosts = request.headers.get_all("Host")
                    named = split_host(hosts[0]) if len(hosts) == 1 else None
                    host = named[0] if named else "127.0.0.1"
                    text = TOO_MANY_COOKIES_TEXT.format(kb=round(cookie_bytes / 1000), host=host, port=local_port)
                    status = http.HTTPStatus.REQUEST_HEADER_FIELDS_TOO_LARGE
                elif page and verdict.reason in _NEEDS_KEY:
                    text = NEEDS_KEY_TEXT
                elif page and verdict.reason in (_ODD, "the address asks the page to use another server"):
                    text = ODD_ADDRESS_TEXT
                response = connection.respond(status, text.format(port=local_port))
                _protect(response.headers)
                return response
            if verdict.action == "redirect":
                assert self.key is not None
                headers = Headers()
                headers["Location"] = verdict.location
                headers["Set-Cookie"] = f"{self.cookie_name}={self.key}; Path={self.prefix}; HttpOnly; SameSite=Strict"
                headers["Cache-Control"] = "no-store"
                headers["Content-Length"] = "0"
                _protect(headers)
                return Response(http.HTTPStatus.SEE_OTHER.value, "See Other", headers, b"")
            forwarded = Request(verdict.forward, request.headers)
            result = inner(connection, forwarded) if inner is not None else None
            if inspect.isawaitable(result):
                result = await result
            if result is not None:
                csp = None
                if result.headers.get("Content-Type", "").startswith("text/html"):
                    csp = policy(self.scripts, self.own_websocket(request.headers.get("Host", "")))
                    result.headers["Cache-Control"] = "no-store"
                _protect(result.headers, csp)
            return result

        return process_request

    def _log_cookies(self, n: int) -> None:
        now = time.monotonic()
        if now - self._last_log.get("cookies", -1e9) >= 10.0:
            self._last_log["cookies"] = now
            log.warning("a request carried %d bytes of cookies (another page's?); only the studio's own was read", n)

    def _log_refusal(self, reason: str, request: Request) -> None:
        now = time.monotonic()
        if now - self._last_log.get(reason, -1e9) < 10.0:
            return
        self._last_log[reason] = now
        origins = request.headers.get_all("Origin")  # two of them: .get would raise
        origin = origins[0] if len(origins) == 1 else None
        where = f", from a page at {origin}" if origin and "origin" not in reason.lower() else ""
        log.warning("refused a connection to the studio (%s%s)", reason, where)

    # -- hooking into viser ------------------------------------------------------------------------------
    def start_viser(self, **kwargs: Any) -> viser.ViserServer:
        """``viser.ViserServer(**kwargs)`` with every request checked and uploads capped, on the port asked for."""
        import rich
        import viser
        import websockets.asyncio.server as wss

        access = self
        console = rich.get_console()
        port = kwargs.get("port", 8080)
        if not isinstance(port, int) or isinstance(port, bool) or not 0 <= port <= 65535:
            raise StudioError(f"{port} is not a port number: ports go from 1 to 65535.")

        with _SERVE_LOCK:
            real_serve = wss.serve

            def guarded_serve(handler: Any, *args: Any, process_request: Any = None, **kw: Any) -> Any:
                access.hooked = getattr(process_request, "__qualname__", repr(process_request))
                kw["max_size"] = MAX_MESSAGE_BYTES
                kw["create_connection"] = connection_class(lambda: access.cookie_name)  # a cookie bomb is read
                handler = wire.serving(handler, lambda: access.presses)  # its reader and sender find the gate
                return real_serve(handler, *args, process_request=access.check(process_request), **kw)

            setattr(wss, "serve", guarded_serve)  # noqa: B010 (mypy: `serve` is a class)
            # viser prints a box with its address *without* the key; the studio prints the one to open.
            quiet, console.quiet = console.quiet, True
            try:
                server = viser.ViserServer(**kwargs)
            finally:
                setattr(wss, "serve", real_serve)  # noqa: B010
                console.quiet = quiet
        if port and server.get_port() != port:  # viser moves on to the next free port; the studio does not
            server.stop()
            raise StudioError(
                f"Port {port} is already used by another program (perhaps another studio). Stop that program, or "
                "choose another port with --port."
            )
        try:
            if self.hooked is None:
                raise StudioError("its web server no longer starts where the studio checks who connects")
            viser_adapter.check(server)  # every private piece of viser the studio relies on, or one line why not
            wire.install()  # each tab's messages reach the gate as they are read; a frame that fails is mended
            self.uploads = UploadLimit(server)
            self.presses = Presses(server)  # sees each message first, then hands it to the upload limit
            self.scripts = read_page_scripts(viser_adapter.http_root(server))
        except viser_adapter.ViserChanged:
            server.stop()
            raise
        except Exception as exc:
            server.stop()
            detail = str(exc) if isinstance(exc, StudioError) else f"{type(exc).__name__}: {exc}"
            raise StudioError(
                f"The studio could not protect its connection with viser {viser.__version__} ({detail}), so it "
                "did not start. Install the viser version it was made for: pip install 'viser==1.1.1'."
            ) from exc
        return server


def _protect(headers: Headers, csp: str | None = None) -> None:
    """Headers for every answer: no framing by other sites, no address in Referer, no type sniffing; the page's
    own policy (``csp``) on the studio's page."""
    for name in ("Content-Security-Policy", "X-Frame-Options", "Referrer-Policy", "X-Content-Type-Options"):
        if name in headers:
            del headers[name]
    headers["Content-Security-Policy"] = csp or "frame-ancestors 'self'"
    headers["X-Frame-Options"] = "SAMEORIGIN"
    headers["Referrer-Policy"] = "no-referrer"
    headers["X-Content-Type-Options"] = "nosniff"
