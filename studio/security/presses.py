"""Every message a browser tab sends passes :class:`Presses` as it is read from the socket (:mod:`.wire`): the
Share relay is never asked; values are checked against their control (:mod:`.values`), a control's newer value
joining the one not yet handled; presses are limited per tab; and each tab's callbacks run one at a time, a
repeated press or value joining the one still waiting (docs/decisions/052, 089)."""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from studio import viser_adapter
from studio.security.addresses import split_host
from studio.security.heads import MAX_LINE_BYTES, TOO_MANY_COOKIES_NOTE
from studio.security.values import refusal, value_refusal

if TYPE_CHECKING:
    import viser

log = logging.getLogger("studio.security")

#: Button presses one tab may make in a burst, and per second after it.
PRESS_BURST = 30
PRESS_RATE = 10.0
#: Callbacks one tab may have waiting (each control and callback at most once).
MAX_WAITING = 64
#: Seconds between two "too many presses" notices to the same tab.
TELL_EVERY_S = 10.0
#: Malformed messages of one tab logged one line each within 10 s; beyond, they are counted in one line.
MALFORMED_LINES = 10
TOO_FAST = (
    "The studio ignored some presses: they came faster than it can act on them. What you pressed before is done "
    "or under way; wait a moment before pressing again."
)


@dataclass
class _Job:
    key: tuple[int, int, Any]
    fn: Callable[..., Any]
    args: tuple[Any, ...]
    kwargs: dict[str, Any]
    future: Future[Any]
    #: the control (viser's handle) and the value its tab sent (the newest, when presses joined)
    target: Any = None
    value: Any = None
    #: a transform handle's orientation and position as its tab sent them (the newest, when steps joined)
    pose: tuple[tuple[float, ...], tuple[float, ...]] | None = None


@dataclass
class _Tab:
    """One browser tab's presses and waiting callbacks."""

    tokens: float = float(PRESS_BURST)
    stamp: float = field(default_factory=time.monotonic)
    told: float = -1e9
    running: bool = False
    waiting: deque[_Job] = field(default_factory=deque)
    keys: dict[tuple[int, int, Any], _Job] = field(default_factory=dict)
    #: buttons whose (coroutine) callback is being awaited
    pressing: set[str] = field(default_factory=set)
    gone: bool = False
    #: values read from the socket and not yet handed to viser (control → the newest message), in order
    held: dict[str, Any] = field(default_factory=dict)
    #: what the tab is to be told once viser counts it as connected ("" when nothing)
    note: str = ""
    #: malformed messages: when the current 10 s began, and how many in them
    malformed_since: float = -1e9
    malformed: int = 0


@dataclass
class Counts:
    """What the gate did so far (for tests, the bench and logs)."""

    refused: int = 0
    joined: int = 0
    too_fast: int = 0
    share: int = 0
    ran: int = 0
    malformed: int = 0


class Presses:
    """The gate between viser's websocket and the studio's GUI callbacks on one server.

    Installed once at start (:meth:`Access.start_viser <studio.security.Access.start_viser>`): the socket reader
    of each tab hands it every message as it is read (:meth:`receive`, before viser queues any work for it); it
    wraps the server's message handler and stands in for the thread pool viser's GUI and scene submit callbacks
    to (so no tab holds more than one of its threads).
    """

    def __init__(self, server: viser.ViserServer) -> None:
        viser_adapter.check(server)
        self._msgs = viser_adapter.messages()
        self._server = server
        self._handles = viser_adapter.controls(server)
        self._pool = viser_adapter.thread_pool(server)
        self._inner = viser_adapter.message_handler(server)
        self._tabs: dict[int, _Tab] = {}
        self._lock = threading.Lock()
        self._closed = False
        self._last_log: dict[str, float] = {}
        self.counts = Counts()
        viser_adapter.set_message_handler(server, self.handle)
        viser_adapter.set_thread_pool(server, self)
        viser_adapter.on_disconnect(server, self._on_disconnect)
        server.on_client_connect(lambda client: self._told(client.client_id))

    # -- messages as they are read from a tab's socket, on viser's event loop ------------------------------
    def client_of(self, websocket: Any) -> int | None:
        """The tab (viser's client id) whose connection is ``websocket``."""
        live = viser_adapter.connections(self._server)
        return next((cid for cid, conn in list(live.items()) if conn is websocket), None)

    def greet(self, client_id: Any, websocket: Any) -> None:
        """A tab just connected: told when its browser sent a cookie bomb (:mod:`.heads`) with its request."""
        n = int(getattr(websocket, "cookie_bytes", 0))
        if n <= MAX_LINE_BYTES:
            return
        request = getattr(websocket, "request", None)
        host = split_host(request.headers.get("Host", "")) if request is not None else None
        text = TOO_MANY_COOKIES_NOTE.format(kb=round(n / 1000), host=host[0] if host else "this address")
        with self._lock:
            self._tabs.setdefault(client_id, _Tab()).note = text  # told once viser counts the tab as connected

    def _told(self, client_id: Any) -> None:
        tab = self._tabs.get(client_id)
        if tab is not None and tab.note and client_id in self._server.get_clients():
            note, tab.note = tab.note, ""
            self._tell(client_id, "Too many cookies for this address", note, "yellow")

    def receive(
        self, client_id: Any, fields: dict[str, Any], message: Callable[[], Any], handle: Callable[[Any], None]
    ) -> None:
        """One message just read from tab ``client_id``'s socket (``fields`` unpacked; ``message()`` makes viser's
        object of it): dropped (Share, a refused value, a press beyond the tab's rate), held (a value: a newer one
        of the same control replaces it until the event loop gets to it), or handed to viser at once
        (``handle``, after the values held before it)."""
        m = self._msgs
        kind = fields["type"]
        if kind in (m.ShareUrlRequest.__name__, m.ShareUrlDisconnect.__name__):
            self.counts.share += 1
            self._log("share", "ignored a request for a public share link (the studio never shares itself)")
            return
        if kind == m.GuiUpdateMessage.__name__:
            uuid = fields.get("uuid")
            if not isinstance(uuid, str):
                self.malformed(client_id, "a value for no control")
                return
            control = self._handles.get(uuid)
            if control is None:
                return  # a control removed since (viser ignores it too)
            why = refusal(control, fields.get("updates"))
            if why is not None:
                self.counts.refused += 1
                label = str(getattr(control, "label", "?"))[:60]
                self._log(f"value {label}", f'ignored a value a tab sent to "{label}": {why}')
                return
            if not viser_adapter.is_button(control):
                self._hold(client_id, uuid, message, handle)
                return
            if not self._may_press(client_id, uuid):
                return
        self._release(client_id, handle)
        self._pass(client_id, message, handle)

    def _pass(self, client_id: Any, message: Callable[[], Any], handle: Callable[[Any], None]) -> None:
        try:
            made = message()
        except Exception as exc:  # unpacked, but not a message of viser's protocol
            self.malformed(client_id, f"{type(exc).__name__}: {str(exc)[:80]}")
            return
        handle(made)

    def _hold(self, client_id: Any, uuid: str, message: Callable[[], Any], handle: Callable[[Any], None]) -> None:
        with self._lock:
            tab = self._tabs.setdefault(client_id, _Tab())
        if uuid in tab.held:
            self.counts.joined += 1
        elif not tab.held:
            asyncio.get_running_loop().call_soon(self._release, client_id, handle)
        tab.held[uuid] = message

    def _release(self, client_id: Any, handle: Callable[[Any], None]) -> None:
        """Hand the values held for a tab to viser, in the order they first came."""
        tab = self._tabs.get(client_id)
        if tab is None or not tab.held:
            return
        held, tab.held = tab.held, {}
        for message in held.values():
            self._pass(client_id, message, handle)

    def malformed(self, client_id: Any, why: str) -> None:
        """A message of tab ``client_id`` that is not one of viser's: ignored, one log line (at most
        :data:`MALFORMED_LINES` a tab in 10 s; the rest are counted in one line)."""
        self.counts.malformed += 1
        now = time.monotonic()
        with self._lock:
            tab = self._tabs.setdefault(client_id, _Tab())
            if now - tab.malformed_since >= TELL_EVERY_S:
                earlier, tab.malformed_since, tab.malformed = tab.malformed - MALFORMED_LINES, now, 0
            else:
                earlier = 0
            tab.malformed += 1
            n = tab.malformed
        if earlier > 0:
            log.warning("ignored %d more malformed messages from a tab, not logged one by one", earlier)
        if n <= MALFORMED_LINES:
            log.warning("ignored a malformed message from a tab (%s)", why)

    async def handle(self, client_id: Any, message: Any) -> None:
        """viser's message handler, wrapped: a button's coroutine callback (Stop, Emergency stop) is awaited
        here; the same button of the same tab is joined until it ends (:meth:`_may_press`)."""
        uuid = getattr(message, "uuid", None) if isinstance(message, self._msgs.GuiUpdateMessage) else None
        try:
            await self._inner(client_id, message)
        finally:
            if uuid is not None:
                with self._lock:
                    tab = self._tabs.get(client_id)
                    if tab is not None:
                        tab.pressing.discard(uuid)

    def _may_press(self, client_id: int, uuid: str) -> bool:
        """A press counts against its tab's rate; the same button again while its coroutine runs is joined."""
        now = time.monotonic()
        with self._lock:
            if self._closed:
                return False
            tab = self._tabs.setdefault(client_id, _Tab())
            if uuid in tab.pressing:
                self.counts.joined += 1
                return False
            tab.tokens = min(float(PRESS_BURST), tab.tokens + (now - tab.stamp) * PRESS_RATE)
            tab.stamp = now
            if tab.tokens < 1.0:
                self.counts.too_fast += 1
                tell = now - tab.told >= TELL_EVERY_S
                if tell:
                    tab.told = now
            else:
                tab.tokens -= 1.0
                tab.pressing.add(uuid)
                return True
        self._log("too fast", "ignored presses of a tab that came faster than the studio acts on them")
        if tell:
            self._tell(client_id, "Too many presses", TOO_FAST, "yellow", 8.0)
        return False

    # -- callbacks: viser submits them here (it takes this for its thread pool) ----------------------------
    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]:
        """Run ``fn(*args)`` for the tab of the event in ``args[0]``, after that tab's earlier callbacks; not again
        when the same control's callback already waits for that tab (that one runs with this newest value)."""
        event = args[0] if args else None
        client_id = getattr(event, "client_id", None)
        if not isinstance(client_id, int):  # not a tab's event: as viser would
            return self._pool.submit(fn, *args, **kwargs)
        future: Future[Any] = Future()
        target = getattr(event, "target", None)
        impl = viser_adapter.state(target)
        # The value this tab sent (viser stored it just now, on its event loop). A button group's options are
        # different presses, and a handle's drag start, moves and end different steps; any other control's newer
        # value replaces the one still waiting, unless another of its presses or steps came after it. A handle's
        # pose is kept as its tab sent it with this step of the drag.
        value = getattr(impl, "value", None)
        pose = viser_adapter.pose_sent(target)
        button = bool(getattr(impl, "is_button", False))
        kind = value if button and isinstance(value, str) else getattr(event, "phase", None)
        key = (id(target), id(fn), kind)
        with self._lock:
            tab = self._tabs.setdefault(client_id, _Tab())
            waiting = tab.keys.get(key)
            if waiting is not None and next(j for j in reversed(tab.waiting) if j.key[0] == key[0]) is not waiting:
                waiting = None  # another press or step of the same control came after it: this one runs after that
            if waiting is not None:
                waiting.value, waiting.pose = value, pose
            if self._closed or waiting is not None or len(tab.waiting) >= MAX_WAITING:
                self.counts.joined += 1
                future.set_result(None)
                return future
            job = _Job(key, fn, args, kwargs, future, target if impl is not None else None, value, pose)
            tab.keys[key] = job
            tab.waiting.append(job)
            start = not tab.running
            tab.running = True
        if start:
            self._pool.submit(self._drain, client_id)
        return future

    def _drain(self, client_id: int) -> None:
        """Run one tab's waiting callbacks in order, on one of viser's threads."""
        while True:
            with self._lock:
                tab = self._tabs.get(client_id)
                if tab is None or not tab.waiting or self._closed:
                    if tab is not None:
                        tab.running = False
                        for job in tab.waiting:
                            job.future.set_result(None)
                        tab.waiting.clear()
                        tab.keys.clear()
                        if tab.gone:
                            del self._tabs[client_id]
                    return
                job = tab.waiting.popleft()
                if tab.keys.get(job.key) is job:  # a later job of the same key may wait too
                    del tab.keys[job.key]
            if not self._as_sent(job):
                job.future.set_result(None)
                continue
            self.counts.ran += 1
            try:
                job.future.set_result(job.fn(*job.args, **job.kwargs))
            except BaseException as exc:  # viser prints it (print_threadpool_errors), as before
                job.future.set_exception(exc)

    def _as_sent(self, job: _Job) -> bool:
        """Give the control back the value its tab sent before its callback reads it: the studio may have
        redrawn the control since (another tab's action), and the callback acts on what this tab asked for.
        False when that value no longer fits the control (its options changed meanwhile)."""
        if job.pose is not None:
            viser_adapter.set_pose_quietly(job.target, job.pose)
            return True
        impl = viser_adapter.state(job.target)
        if impl is None or getattr(impl, "value", None) == job.value:
            return True
        judged = isinstance(job.value, (str, bool, int, float, tuple, list))  # not an uploaded file
        if judged and value_refusal(job.target, job.value) is not None:
            self._log("stale", "ignored a value that no longer fits its control")
            return False
        viser_adapter.set_value_quietly(job.target, job.value)
        return True

    def close(self) -> None:
        """Stop: waiting callbacks are dropped and no new one is taken (the studio is stopping)."""
        with self._lock:
            self._closed = True

    def _on_disconnect(self, conn: Any) -> None:
        with self._lock:
            tab = self._tabs.get(conn.client_id)
            if tab is not None and not tab.running:
                del self._tabs[conn.client_id]
            elif tab is not None:
                tab.gone = True  # forgotten once its last callback ran

    # -- words ---------------------------------------------------------------------------------------------
    def _log(self, what: str, text: str) -> None:
        now = time.monotonic()
        if now - self._last_log.get(what, -1e9) < 10.0:
            return
        self._last_log[what] = now
        log.warning("%s", text)

    def _tell(
        self, client_id: int, title: str, body: str, color: Any = "yellow", close_after: float | None = None
    ) -> None:
        client = self._server.get_clients().get(client_id)
        if client is None:
            return
        try:
            client.add_notification(title, body, color=color, auto_close_seconds=close_after)
        except Exception:  # a tab that just closed
            log.debug("notice to a closed tab", exc_info=True)
