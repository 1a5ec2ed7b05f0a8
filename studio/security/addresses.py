"""The parts of a request the studio checks: host names, the key in an address, the key in a cookie."""

from __future__ import annotations

import re
import secrets
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from websockets.datastructures import Headers

LOOPBACK_HOSTS = frozenset({"127.0.0.1", "localhost", "::1"})
WILDCARD_HOSTS = frozenset({"0.0.0.0", "::", ""})
KEY_PARAM = "key"
#: Address parameters of viser's page that make it connect to, or load a recording from, another server:
#: a page driven by someone else's server would run their HTML inside the studio's origin.
FOREIGN_SOURCE_PARAMS = frozenset({"websocket", "playbackPath"})
KEY_RE = re.compile(r"[A-Za-z0-9_-]{16,128}")


def is_loopback(host: str) -> bool:
    """True when ``host`` is reachable from this computer only."""
    return host in LOOPBACK_HOSTS or host.startswith("127.")


def new_key() -> str:
    return secrets.token_urlsafe(24)


def split_host(value: str) -> tuple[str, int] | None:
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


def cookie(headers: Headers, name: str) -> str | None:
    for line in headers.get_all("Cookie"):
        for part in line.split(";"):
            k, sep, v = part.strip().partition("=")
            if sep and k.strip() == name:
                return v.strip().strip('"')
    return None


def query_key(path: str) -> tuple[str | None, str]:
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
