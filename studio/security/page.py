"""The Content-Security-Policy of the studio's page: it may connect only to the studio's own server, and run
only the scripts viser's page is made of (by their hashes), never a script inside HTML it is shown."""

from __future__ import annotations

import base64
import hashlib
import logging
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

log = logging.getLogger("studio.security")

#: The alphabet of viser's page loader (a base-88 encoding of its zstd-compressed style and code).
_ALPHABET = "!#$%()*+,-./0123456789:;=?@ABCDEFGHIJKLMNOPQRSTUVWXYZ[\\]^_abcdefghijklmnopqrstuvwxyz{|}~"
_SCRIPT = re.compile(rb"<script\b([^>]*)>(.*?)</script>", re.DOTALL)
_ATTR = re.compile(rb'\bdata-(p|ss|cs)="([^"]*)"')


@dataclass(frozen=True)
class PageScripts:
    """The ``'sha256-…'`` sources of every script viser's page runs (None: the page could not be read, and the
    policy falls back to allowing inline scripts; the connection limits still hold)."""

    hashes: tuple[str, ...] | None


def _sha(data: bytes) -> str:
    return "'sha256-" + base64.b64encode(hashlib.sha256(data).digest()).decode() + "'"


def _decode(text: bytes) -> bytes:
    """viser's loader decoding (``de`` in its page): 5 characters → 4 bytes, base 88, big-endian."""
    table = np.full(256, -1, np.int64)
    table[np.frombuffer(_ALPHABET.encode(), np.uint8)] = np.arange(len(_ALPHABET))
    digits = table[np.frombuffer(text, np.uint8)]
    if (digits < 0).any():
        raise ValueError("not viser's encoding")
    n, r = divmod(len(digits), 5)
    whole = digits[: n * 5].reshape(n, 5) @ (88 ** np.arange(4, -1, -1, dtype=np.int64))
    out = whole.astype(">u4").tobytes()
    if r:
        v = 0
        for d in digits[n * 5 :]:
            v = v * 88 + int(d)
        out += v.to_bytes(r - 1, "big")
    return out


def page_scripts(html: bytes) -> PageScripts:
    """The hashes of the inline scripts of viser's page ``html``: its loader, and the module the loader unpacks
    and inserts (read the way the loader does it)."""
    try:
        import zstandard

        hashes: list[str] = []
        for attrs, body in _SCRIPT.findall(html):
            hashes.append(_sha(body))
            data = dict(_ATTR.findall(attrs))
            if b"p" in data:
                ss, cs = int(data[b"ss"]), int(data[b"cs"])
                unpacked = zstandard.ZstdDecompressor().decompress(_decode(data[b"p"]), max_output_size=ss + cs)
                if len(unpacked) != ss + cs:
                    raise ValueError("unexpected size")
                hashes.append(_sha(unpacked[ss:].decode("utf-8").encode("utf-8")))
        if len(hashes) < 2:
            raise ValueError("no packed module")
        return PageScripts(tuple(hashes))
    except Exception as exc:  # a viser whose page is built differently
        log.warning("the page's scripts could not be listed (%s): inline scripts stay allowed", exc)
        return PageScripts(None)


def read_page_scripts(root: Path | None) -> PageScripts:
    try:
        html = (Path(root) / "index.html").read_bytes() if root is not None else b""
    except OSError:
        html = b""
    return page_scripts(html)


def policy(scripts: PageScripts, websocket: str) -> str:
    """The page's Content-Security-Policy; ``websocket`` is the studio's own websocket address (``ws://host/path``).

    viser's page needs: its inline loader and module (hashes), WebAssembly (its zstd decoder, one more fetched
    from a ``data:`` address), ``new Function`` for the scripts the studio's server sends (``RunJavascriptMessage``),
    blob workers (its websocket client), inline styles, and data/blob images and fonts."""
    inline = " ".join(scripts.hashes) if scripts.hashes is not None else "'unsafe-inline'"
    return "; ".join(
        [
            "default-src 'self'",
            f"script-src 'self' {inline} 'unsafe-eval' 'wasm-unsafe-eval'",
            "style-src 'self' 'unsafe-inline'",
            "img-src 'self' data: blob:",
            "font-src 'self' data:",
            "media-src 'self' data: blob:",
            "worker-src 'self' blob:",
            f"connect-src 'self' data: {websocket}",
            "object-src 'none'",
            "base-uri 'none'",
            "form-action 'none'",
            "frame-ancestors 'self'",
        ]
    )
