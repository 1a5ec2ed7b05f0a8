"""The request head of each connection, read within a byte budget (docs/decisions/089): a Cookie header longer than a
web server takes (another page on this computer can set cookies for every port of its address) is kept to the
studio's own cookie, and its size is remembered, so the studio still answers and can say what happened."""

from __future__ import annotations

from collections.abc import Callable, Generator
from typing import Any

#: Longest header line websockets reads (its own limit), and the longest Cookie header taken as it is.
MAX_LINE_BYTES = 8192
#: Most bytes of one request head (websockets' own worst case: 128 lines of 8 KiB); a Cookie line may use them.
MAX_HEAD_BYTES = 128 * 8192

TOO_MANY_COOKIES_TEXT = (
    "Teaching Studio: your browser sent {kb:,} KB of cookies with this request.\n\n"
    "A web server takes about 8 KB. Cookies do not tell ports apart, so a page of another program on this\n"
    "computer can set them for every address of {host}; the studio ignores them, and answers the address it\n"
    "printed when it started (http://{host}:{port}/?key=...). Open that address again.\n\n"
    "To clear those cookies (other programs at this address may not answer until you do):\n"
    "  Chrome, Chromium, Edge: click the icon left of the address, then 'Cookies and site data', and delete\n"
    "    the data of {host}; or Settings > Privacy > Third-party cookies > See all site data > {host} > Delete.\n"
    "  Firefox: click the lock left of the address, then 'Clear cookies and site data'.\n"
)
TOO_MANY_COOKIES_NOTE = (
    "Your browser sends this studio {kb:,} KB of cookies that another program's page set for {host}. The studio "
    "ignores them; other programs at this address may stop answering. To clear them, click the icon left of the "
    "address, then 'Cookies and site data', and delete the data of {host}."
)


def own_cookie_line(line: bytes, name: str) -> bytes:
    """A ``Cookie:`` header line kept to the cookies called ``name`` (the rest dropped unread)."""
    _, _, value = line.rstrip(b"\r\n").partition(b":")
    want = name.encode("ascii")
    kept = [p.strip() for p in value.split(b";") if p.strip().partition(b"=")[0] == want]
    return b"Cookie: " + b"; ".join(kept) + b"\r\n"


def connection_class(cookie_name: Callable[[], str]) -> type:
    """websockets' server connection, reading its request head within :data:`MAX_HEAD_BYTES`: a Cookie line over
    :data:`MAX_LINE_BYTES` is kept to the cookie ``cookie_name()`` names, its size in ``cookie_bytes``."""
    from websockets.asyncio.server import ServerConnection

    class StudioConnection(ServerConnection):
        #: bytes of the Cookie header lines that were too long to take as they were (0: none)
        cookie_bytes = 0

        def __init__(self, protocol: Any, *args: Any, **kwargs: Any) -> None:
            super().__init__(protocol, *args, **kwargs)
            read = protocol.reader.read_line
            left = [MAX_HEAD_BYTES]
            conn = self

            def read_line(m: int) -> Generator[None, None, bytes | bytearray]:
                line = yield from read(max(m, left[0]))
                left[0] -= len(line)
                if len(line) > m:
                    if bytes(line[:7]).lower() != b"cookie:":
                        raise RuntimeError(f"a header line of {len(line)} bytes")
                    conn.cookie_bytes += len(line)
                    line = own_cookie_line(bytes(line), cookie_name())
                return line

            protocol.reader.read_line = read_line
            # Nothing was received yet: websockets' own request parser starts again, reading with read_line.
            protocol.parser = protocol.parse()
            next(protocol.parser)

    return StudioConnection
