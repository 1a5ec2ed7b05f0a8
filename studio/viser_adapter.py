"""The one place the studio reaches into viser's private internals (decision 098): sending a page script, the
table of GUI controls and their state, the websocket server's handler, connections and thread pools, upload
states, each tab's reader and sender, and the frames a ``ViserUrdf`` built. :func:`check` runs at server start
and refuses, in one line naming the viser version and what is missing, when an upgrade moved any of them."""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from studio.core.errors import StudioError

if TYPE_CHECKING:
    import viser
    from viser.extras import ViserUrdf

#: The viser version the studio was made for (pyproject.toml pins ``>=1.1.1,<1.2``).
MADE_FOR = "1.1.1"
#: viser's message classes the studio sends or recognises.
MESSAGES = (
    "RunJavascriptMessage",
    "GuiUpdateMessage",
    "ShareUrlRequest",
    "ShareUrlDisconnect",
    "FileTransferStartUpload",
    "FileTransferPart",
    "FileTransferPartAck",
    "RemoveNotificationMessage",
)
#: What viser's per-tab reader and sender take (the studio's hooks take the same).
READER_ARGS = ["websocket", "handle_message", "message_class"]
SENDER_ARGS = ["websocket", "buffer", "client_id", "backlog_done_message"]


def version() -> str:
    """The installed viser's version."""
    import viser

    return str(viser.__version__)


# -- the self-check -------------------------------------------------------------------------------------------


def _sets(cls: type, *names: str) -> bool:
    """Whether ``cls.__init__`` assigns (or reads) every attribute in ``names``."""
    code = getattr(getattr(cls, "__init__", None), "__code__", None)
    return code is not None and all(n in code.co_names for n in names)


def _takes(fn: Any, args: list[str]) -> bool:
    return inspect.iscoroutinefunction(fn) and list(inspect.signature(fn).parameters) == args


def _classes() -> list[tuple[str, bool]]:
    """What the classes must show, with or without a server: (the piece, whether this viser has it)."""
    from viser import _gui_handles, _messages, _scene_handles
    from viser._viser import ClientHandle
    from viser.extras import ViserUrdf
    from viser.infra import WebsockServer, _infra

    out = [(f"viser._messages.{n}", isinstance(getattr(_messages, n, None), type)) for n in MESSAGES]
    js = getattr(_messages, "RunJavascriptMessage", None)
    out.append(("RunJavascriptMessage(source=…)", js is not None and "source" in inspect.signature(js).parameters))
    state = getattr(_gui_handles, "_GuiHandleState", None)
    fields = {f.name for f in dataclasses.fields(state)} if dataclasses.is_dataclass(state) else set()
    out.append(("_GuiHandleState.value and .is_button", {"value", "is_button"} <= fields))
    out.append(
        ("WebsockServer._handle_incoming_message", callable(getattr(WebsockServer, "_handle_incoming_message", None)))
    )
    node = getattr(_scene_handles, "_SceneNodeHandleState", None)
    fields = {f.name for f in dataclasses.fields(node)} if dataclasses.is_dataclass(node) else set()
    out.append(("_SceneNodeHandleState.wxyz and .position", {"wxyz", "position"} <= fields))
    out.append(("ClientHandle._websock_connection", _sets(ClientHandle, "_websock_connection")))
    out.append(("ViserUrdf._urdf and ._joint_frames", _sets(ViserUrdf, "_urdf", "_joint_frames")))
    reader, sender = getattr(_infra, "_message_consumer", None), getattr(_infra, "_message_producer", None)
    out.append((f"viser.infra._infra._message_consumer({', '.join(READER_ARGS)})", _takes(reader, READER_ARGS)))
    out.append((f"viser.infra._infra._message_producer({', '.join(SENDER_ARGS)})", _takes(sender, SENDER_ARGS)))
    return out


def _instances(server: viser.ViserServer) -> list[tuple[str, bool]]:
    """What a running server must hold."""
    from viser.infra import WebsockServer

    ws = getattr(server, "_websock_server", None)
    gui, scene = server.gui, server.scene
    queue = getattr(getattr(gui, "_websock_interface", None), "queue_message", None)
    return [
        ("ViserServer._websock_server", isinstance(ws, WebsockServer)),
        ("WebsockServer._live_connections", isinstance(getattr(ws, "_live_connections", None), dict)),
        ("WebsockServer._http_server_root", hasattr(ws, "_http_server_root")),
        ("GuiApi._websock_interface.queue_message", callable(queue)),
        ("GuiApi._gui_input_handle_from_uuid", isinstance(getattr(gui, "_gui_input_handle_from_uuid", None), dict)),
        ("GuiApi._current_file_upload_states", isinstance(getattr(gui, "_current_file_upload_states", None), dict)),
        ("GuiApi._thread_executor", callable(getattr(getattr(gui, "_thread_executor", None), "submit", None))),
        ("SceneApi._thread_executor", callable(getattr(getattr(scene, "_thread_executor", None), "submit", None))),
    ]


def missing(server: viser.ViserServer | None = None) -> list[str]:
    """Every private piece this module relies on that the installed viser lacks or shapes otherwise ([] when
    all are there); without ``server``, only what viser's classes show."""
    try:
        found = _classes() + (_instances(server) if server is not None else [])
    except (ImportError, AttributeError) as exc:  # a module moved
        return [f"{type(exc).__name__}: {exc}"]
    return [piece for piece, ok in found if not ok]


class ViserChanged(StudioError):
    """The installed viser lacks a private piece the studio relies on (:func:`check`)."""


def check(server: viser.ViserServer | None = None) -> None:
    """The start-up self-check: raise :class:`ViserChanged` (one line: the viser version, what is missing, what to
    install) unless every private piece is where this module reaches for it."""
    gone = missing(server)
    if gone:
        raise ViserChanged(
            f"The studio cannot start with viser {version()}: it relies on {', '.join(gone)}, which this viser "
            f"does not have. Install the viser version it was made for: pip install 'viser=={MADE_FOR}'."
        )


# -- the page and the controls (panels) -----------------------------------------------------------------------


def run_javascript(server: viser.ViserServer, source: str) -> None:
    """Run ``source`` in every tab, now and in tabs that connect later (viser keeps it in the scene state)."""
    from viser import _messages

    server.gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=source))


def controls(server: viser.ViserServer) -> dict[str, Any]:
    """Every GUI input control of ``server`` by its uuid (viser's own table: read it, never change it)."""
    table: dict[str, Any] = server.gui._gui_input_handle_from_uuid
    return table


def state(handle: Any) -> Any | None:
    """A control's state behind its handle (``value``, ``is_button``), or None for what is not a control."""
    return getattr(handle, "_impl", None)


def is_button(handle: Any) -> bool:
    """Whether a control is a button (a press, not a value)."""
    return bool(getattr(state(handle), "is_button", False))


def set_value_quietly(handle: Any, value: Any) -> None:
    """Set a control's value on the server only (no message to the tabs, no callback)."""
    impl = state(handle)
    if impl is not None:
        impl.value = value


def pose_sent(handle: Any) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """A transform handle's orientation (wxyz) and position as its tab last sent them, or None for a control."""
    import viser

    impl = state(handle)
    if impl is None or not isinstance(handle, viser.TransformControlsHandle):
        return None
    return tuple(float(v) for v in impl.wxyz), tuple(float(v) for v in impl.position)


def set_pose_quietly(handle: Any, pose: tuple[tuple[float, ...], tuple[float, ...]]) -> None:
    """Set a transform handle's orientation and position on the server only (no message to the tabs)."""
    impl = state(handle)
    if impl is not None:
        impl.wxyz, impl.position = np.array(pose[0], dtype=np.float64), np.array(pose[1], dtype=np.float64)


def urdf_parts(urdf: ViserUrdf) -> tuple[list[Any], list[Any]]:
    """The joints of a ``ViserUrdf``'s model and the scene frame it built for each, in the same order."""
    return list(urdf._urdf.joint_map.values()), list(urdf._joint_frames)


# -- the websocket server and each tab's connection (security) ----------------------------------------------


def messages() -> ModuleType:
    """viser's message classes (:data:`MESSAGES` are checked)."""
    from viser import _messages

    return _messages


def message_handler(server: viser.ViserServer) -> Callable[[Any, Any], Any]:
    """The server's handler of each message a tab sends (a coroutine function of client id and message)."""
    handler: Callable[[Any, Any], Any] = server._websock_server._handle_incoming_message
    return handler


def set_message_handler(server: viser.ViserServer, handler: Callable[[Any, Any], Any]) -> None:
    """Put ``handler`` in front: it gets every message first (and hands on what it lets through)."""
    server._websock_server._handle_incoming_message = handler  # type: ignore[method-assign,assignment]


def on_disconnect(server: viser.ViserServer, fn: Callable[[Any], None]) -> None:
    """Call ``fn(connection)`` when a tab's connection ends (before viser's own client handle goes)."""
    server._websock_server.on_client_disconnect(fn)


def connections(server: viser.ViserServer) -> dict[int, Any]:
    """The tabs connected now: client id → websocket connection."""
    live: dict[int, Any] = server._websock_server._live_connections
    return live


def http_root(server: viser.ViserServer) -> Path | None:
    """The folder viser serves its page from (its ``index.html``), if any."""
    root = getattr(server._websock_server, "_http_server_root", None)
    return Path(root) if root is not None else None


def thread_pool(server: viser.ViserServer) -> Any:
    """The pool viser runs GUI and scene callbacks on."""
    return server.gui._thread_executor


def set_thread_pool(server: viser.ViserServer, pool: Any) -> None:
    """Have viser submit its GUI and scene callbacks to ``pool`` (anything with ``submit``)."""
    server.gui._thread_executor = pool
    server.scene._thread_executor = pool


def upload_states(server: viser.ViserServer) -> dict[str, Any]:
    """The uploads viser is buffering, by transfer uuid."""
    states: dict[str, Any] = server.gui._current_file_upload_states
    return states


def send_to(client: viser.ClientHandle, message: Any) -> None:
    """Queue one of viser's messages to one tab."""
    client._websock_connection.queue_message(message)


def reader_and_sender() -> tuple[Callable[..., Any], Callable[..., Any]]:
    """viser's reader and sender of each tab's websocket (:data:`READER_ARGS`, :data:`SENDER_ARGS`)."""
    from viser.infra import _infra

    return _infra._message_consumer, _infra._message_producer


def set_reader_and_sender(reader: Callable[..., Any], sender: Callable[..., Any]) -> None:
    """Have every connection viser opens from now on read and send with these."""
    from viser.infra import _infra

    _infra._message_consumer = reader
    _infra._message_producer = sender
