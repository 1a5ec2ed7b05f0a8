"""The parts of a request the studio checks, read with the standard library: host names (:mod:`ipaddress`),
the request target and its query (:mod:`urllib.parse`, names decoded as a browser decodes them) and cookies
(:mod:`http.cookies`)."""

from __future__ import annotations

import ipaddress
import re
import secrets
from dataclasses import dataclass
from http.cookies import CookieError, SimpleCookie
from typing import TYPE_CHECKING
from urllib.parse import parse_qsl, unquote, urlsplit

if TYPE_CHECKING:
    from websockets.datastructures import Headers

#: Host names that always mean this computer (RFC 6761); IP literals are judged with :mod:`ipaddress`.
LOOPBACK_NAMES = frozenset({"localhost"})
WILDCARD_HOSTS = frozenset({"0.0.0.0", "::", ""})
KEY_PARAM = "key"
#: viser's page parameter that names the server its page connects to (allowed only naming the studio itself).
WEBSOCKET_PARAM = "websocket"
KEY_RE = re.compile(r"[A-Za-z0-9_-]{16,128}")
#: Most query fields read from one request target (a longer query is refused, not parsed).
MAX_QUERY_FIELDS = 16

IP = ipaddress.IPv4Address | ipaddress.IPv6Address


def host_name(host: str) -> str | None:
    """``host`` as one comparable name: lower case, brackets and one trailing dot removed, IP literals in their
    canonical form (an IPv4-mapped IPv6 address as IPv4); None when it is not a valid host name or address."""
    h = host.strip().lower()
    if h.startswith("[") and h.endswith("]"):
        h = h[1:-1]
        ip = _ip(h)
        return None if ip is None or ip.version != 6 else _canonical(ip)
    if h.endswith(".") and not h.endswith(".."):
        h = h[:-1]  # "localhost." is the same name as "localhost" (the DNS root); "127.0.0.1." as browsers read it
    ip = _ip(h)
    if ip is not None:
        return _canonical(ip)
    labels = h.split(".")
    if not h or len(h) > 253 or not all(_LABEL.fullmatch(label) for label in labels):
        return None
    return h


def is_loopback(host: str) -> bool:
    """True when ``host`` (a name or an address, as given with ``--host`` or in a Host header) reaches this
    computer only: ``localhost`` or a loopback address (127.0.0.0/8, ::1, ::ffff:127.x.y.z)."""
    name = host_name(host)
    if name is None:
        return False
    ip = _ip(name)
    return ip.is_loopback if ip is not None else name in LOOPBACK_NAMES


def new_key() -> str:
    return secrets.token_urlsafe(24)


def split_host(value: str) -> tuple[str, int] | None:
    """A Host header ``name:port`` / ``[v6]:port`` / ``name`` → (:func:`host_name`, port); None when malformed."""
    try:
        parts = urlsplit("//" + value.strip())
        port = parts.port
        raw = parts.netloc.rpartition(":")[0] if port is not None else parts.netloc
    except ValueError:
        return None
    if parts.username is not None or parts.path or parts.query or parts.fragment or not raw:
        return None
    if ":" in raw and not raw.startswith("["):  # an IPv6 address must be in brackets: "::1:80" is ambiguous
        return None
    if value.strip().endswith(":") or (port is not None and not 0 < port < 65536):
        return None
    name = host_name(raw)
    return None if name is None else (name, 80 if port is None else port)


def cookies(headers: Headers) -> dict[str, str]:
    """Every cookie the request carries (name → value). Each ``name=value`` pair is read on its own, so a
    malformed cookie some other program set for this computer never hides the others."""
    out: dict[str, str] = {}
    for line in headers.get_all("Cookie"):
        for pair in line.split(";"):
            jar: SimpleCookie = SimpleCookie()
            try:
                jar.load(pair.strip())
            except CookieError:
                continue
            for name, morsel in jar.items():
                out.setdefault(name, morsel.value)
    return out


@dataclass(frozen=True)
class Target:
    """A request target read as the page's browser reads it: the decoded path and (name, value) query pairs."""

    path: str
    query: tuple[tuple[str, str], ...]

    def names(self) -> set[str]:
        return {k for k, _ in self.query}

    def values(self, name: str) -> list[str]:
        return [v for k, v in self.query if k == name]


def read_target(target: str) -> Target | None:
    """The path and query of a request target (``/p?a=1``), names and values percent-decoded (``%77ebsocket`` is
    ``websocket``, ``+`` a space, as ``URLSearchParams`` reads them); None when it cannot be read."""
    if not target.startswith("/") or target.startswith("//"):
        return None
    try:
        parts = urlsplit(target)
        query = parse_qsl(parts.query, keep_blank_values=True, max_num_fields=MAX_QUERY_FIELDS)
    except ValueError:
        return None
    return Target(unquote(parts.path), tuple(query))


_LABEL = re.compile(r"[a-z0-9_]([a-z0-9_-]{0,61}[a-z0-9_])?")


def _ip(text: str) -> IP | None:
    try:
        return ipaddress.ip_address(text)
    except ValueError:
        return None


def _canonical(ip: IP) -> str:
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        return str(ip.ipv4_mapped)
    return str(ip)
