"""viser's websocket reader and sender of each tab, hooked (docs/decisions/089): every message a tab sends is read,
decoded and judged by the gate (:class:`~studio.security.presses.Presses`) before viser queues work for it, so a
burst from one tab never stands in front of another tab's Emergency stop, and a malformed message costs one log
line; a frame that cannot be encoded for a tab is mended and sent, never ending that tab's connection."""

from __future__ import annotations

import asyncio
import contextvars
import dataclasses
import functools
import logging
import threading
from collections.abc import Callable
from typing import Any

from studio import viser_adapter
from studio.core.text import sendable

log = logging.getLogger("studio.security")

#: Messages the reader decodes in a row before it lets the event loop serve the other tabs.
YIELD_EVERY = 16
#: Bytes read from a tab's socket at once (asyncio reads 256 KiB: thousands of small messages parsed in one go,
#: with every other tab waiting).
READ_BYTES = 16 * 1024
#: The gate of the server whose connection a task serves (a callable: the gate is built after viser starts).
_GATE: contextvars.ContextVar[Callable[[], Any] | None] = contextvars.ContextVar("studio_gate", default=None)
_LOCK = threading.Lock()


def install() -> None:
    """Hook viser's reader and sender of each connection, once per process (connections of a server the studio
    did not start keep viser's own). Refused when viser moved them or changed what they take."""
    with _LOCK:
        reader, sender = viser_adapter.reader_and_sender()
        if getattr(reader, "studio_hook", False):
            return
        viser_adapter.check()  # the reader and sender take what the hooks hand on

        async def consumer(websocket: Any, handle_message: Callable[[Any], None], message_class: Any) -> None:
            gate = _gate()
            if gate is None:
                await reader(websocket, handle_message, message_class)
            else:
                await read(gate, websocket, handle_message, message_class)

        async def producer(websocket: Any, buffer: Any, client_id: int, backlog_done_message: Any = None) -> None:
            if _GATE.get() is None:
                await sender(websocket, buffer, client_id, backlog_done_message)
            else:
                await send(sender, websocket, buffer, client_id, backlog_done_message)

        consumer.studio_hook = True  # type: ignore[attr-defined]
        viser_adapter.set_reader_and_sender(consumer, producer)


def hooked() -> bool:
    """Whether viser's reader and sender are the studio's (:func:`install`)."""
    return bool(getattr(viser_adapter.reader_and_sender()[0], "studio_hook", False))


def serving(handler: Callable[[Any], Any], gate: Callable[[], Any]) -> Callable[[Any], Any]:
    """viser's connection ``handler``, run so that the reader and sender of its connections find ``gate`` (a
    callable returning the server's :class:`~studio.security.presses.Presses`, or None before it exists)."""

    async def studio_connection(connection: Any) -> None:
        _GATE.set(gate)  # this connection's task and the tasks it starts (reader, senders) see it
        transport: Any = getattr(connection, "transport", None)
        if isinstance(getattr(transport, "max_size", None), int):
            transport.max_size = min(transport.max_size, READ_BYTES)
        await handler(connection)

    return studio_connection


def _gate() -> Any:
    gate = _GATE.get()
    return gate() if gate is not None else None


async def read(gate: Any, websocket: Any, handle_message: Callable[[Any], None], message_class: Any) -> None:
    """Read one tab's messages: each unpacked and handed to the gate at once (viser's message object is made
    only for what the gate lets through), the event loop let go every :data:`YIELD_EVERY` messages; a message
    that cannot be unpacked is ignored with a log line."""
    import msgspec

    client_id = gate.client_of(websocket)
    gate.greet(client_id, websocket)
    n = 0
    while True:
        raw = await websocket.recv()
        n += 1
        if n % YIELD_EVERY == 0:
            await asyncio.sleep(0)  # another tab's message (an Emergency stop) is read between a burst's
        if not isinstance(raw, (bytes, bytearray)):
            gate.malformed(client_id, "a text frame; the studio's page sends binary ones")
            continue
        try:
            fields = msgspec.msgpack.decode(raw)
            if not isinstance(fields, dict) or not isinstance(fields.get("type"), str):
                raise ValueError("not a message")
        except Exception as exc:  # not a message of viser's protocol
            gate.malformed(client_id, f"{type(exc).__name__}: {str(exc)[:80]}")
            continue
        gate.receive(client_id, fields, functools.partial(message_class.deserialize, bytes(raw)), handle_message)


class _Windows:
    """Stands in for viser's message buffer in its sender: the same windows, and one mended window again."""

    def __init__(self, buffer: Any) -> None:
        self.buffer = buffer
        self.inner: Any = None
        #: the window the sender took last and has not sent yet (None once it asks for the next)
        self.last: list[Any] | None = None
        self.again: list[Any] | None = None

    @property
    def done(self) -> bool:
        return bool(self.buffer.done)

    def window_generator(self, client_id: int, backlog_done_message: Any = None) -> _Windows:
        if self.inner is None:
            self.inner = self.buffer.window_generator(client_id, backlog_done_message=backlog_done_message)
        return self

    def __aiter__(self) -> _Windows:
        return self

    async def __anext__(self) -> list[Any]:
        self.last = None  # asking for the next: the one before was sent
        if self.again is not None:
            window, self.again = self.again, None
        else:
            window = await self.inner.__anext__()
        self.last = window
        return window

    async def aclose(self) -> None:
        """The sender closes its windows when it ends; the real generator is closed once, by :func:`send`."""


async def send(sender: Callable[..., Any], websocket: Any, buffer: Any, client_id: int, backlog: Any) -> None:
    """viser's sender for one tab; a window it cannot encode is mended (:func:`mended`) and sent again."""
    from websockets.exceptions import ConnectionClosed

    windows = _Windows(buffer)
    try:
        while True:
            try:
                await sender(websocket, windows, client_id, backlog)
                return
            except ConnectionClosed:
                raise
            except Exception as exc:
                if windows.last is None:
                    raise
                windows.again, windows.last = mended(windows.last, exc), None
    finally:
        if windows.inner is not None:
            await windows.inner.aclose()


def mended(window: list[Any], exc: Exception) -> list[Any]:
    """The messages of ``window`` with every text made sendable; a message that still cannot be encoded is
    left out. One log line."""
    import msgspec

    out, left = [], []
    for message in window:
        _clean(message)
        try:
            msgspec.msgpack.encode(message.as_serializable_dict([]))
        except Exception:
            left.append(type(message).__name__)
            continue
        out.append(message)
    log.warning(
        "a message to a tab could not be encoded (%s: %s); its text was mended%s",
        type(exc).__name__,
        str(exc)[:120],
        f" and {', '.join(left)} left out" if left else "",
    )
    return out


def _clean(value: Any) -> Any:
    """``value`` with its texts made sendable (a message or its properties are mended in place)."""
    if isinstance(value, str):
        return sendable(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            old = getattr(value, f.name, None)
            new = _clean(old)
            if new is not old:
                object.__setattr__(value, f.name, new)  # viser's properties are frozen dataclasses
        return value
    if isinstance(value, dict):
        return {_clean(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        items = [_clean(v) for v in value]
        if all(a is b for a, b in zip(items, value, strict=True)):
            return value
        return items if isinstance(value, list) else tuple(items)
    return value
