"""A minimal client of viser's websocket protocol, for tests that act as another program (or an attacker).

It speaks what viser's browser client speaks: subprotocol ``viser-v<version>``; messages to the server are
msgpack dicts with a ``type``; frames from the server are zstd-compressed msgpack followed by raw binary
buffers (see ``viser.infra._infra._message_producer``). It collects every message it receives, finds GUI
elements by their label, presses buttons, and reassembles file downloads.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import msgspec
import numpy as np
import viser
import zstandard
from websockets.sync.client import ClientConnection, connect


def decode_frame(frame: bytes) -> list[dict[str, Any]]:
    """The messages of one frame; numpy arrays (sent as raw buffers after the msgpack) as flat numpy arrays."""
    n_inner = int.from_bytes(frame[0:8], "little")
    n_comp = int.from_bytes(frame[8:16], "little")
    inner = msgspec.msgpack.decode(
        zstandard.ZstdDecompressor().decompress(frame[16 : 16 + n_comp], max_output_size=n_inner)
    )
    buffers: list[bytes] = []
    offset = 16 + n_comp
    for n in inner.get("binaryBufferLengths", ()):
        offset += (8 - offset % 8) % 8
        buffers.append(frame[offset : offset + n])
        offset += n

    def fill(v: Any) -> Any:
        if isinstance(v, dict):
            if "__binary_index" in v:
                return np.frombuffer(buffers[v["__binary_index"]], dtype=v["dtype"])
            return {k: fill(x) for k, x in v.items()}
        if isinstance(v, list):
            return [fill(x) for x in v]
        return v

    return [fill(m) for m in inner.get("messages", ())]


class ViserClient:
    """Connect to ``url`` (``ws://...``) with optional ``Origin`` and ``Cookie`` headers.

    Raises ``websockets.exceptions.InvalidStatus`` when the server refuses the handshake.
    """

    def __init__(self, url: str, *, origin: str | None = None, cookie: str | None = None) -> None:
        headers: dict[str, str] = {}
        if origin is not None:
            headers["Origin"] = origin
        if cookie is not None:
            headers["Cookie"] = cookie
        self.ws: ClientConnection = connect(
            url,
            subprotocols=[f"viser-v{viser.__version__}"],  # type: ignore[list-item]
            additional_headers=headers,
            max_size=None,
            open_timeout=20,
        )
        self.messages: list[dict[str, Any]] = []
        #: called on the reading thread with each frame's messages as they arrive (benches time arrivals here)
        self.watchers: list[Callable[[list[dict[str, Any]]], None]] = []
        self.closed = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()
        # viser counts a client as connected (its button presses reach callbacks) after its first camera.
        self.send(
            {
                "type": "ViewerCameraMessage",
                "wxyz": (1.0, 0.0, 0.0, 0.0),
                "position": (2.5, -0.95, 1.05),
                "fov": 0.96,
                "near": 0.01,
                "far": 100.0,
                "image_height": 800,
                "image_width": 1280,
                "look_at": (0.3, 0.12, 0.12),
                "up_direction": (0.0, 0.0, 1.0),
            }
        )

    @classmethod
    def tab_of(cls, app: Any) -> ViserClient:
        """A new tab of the running studio ``app`` (its own key in the address, as the printed link has it)."""
        return cls(f"ws://127.0.0.1:{app.port}/?key={app.access.key}")

    def _read(self) -> None:
        try:
            while True:
                data = self.ws.recv()
                if isinstance(data, bytes):
                    msgs = decode_frame(data)
                    with self._lock:
                        self.messages.extend(msgs)
                    for watch in list(self.watchers):
                        watch(msgs)
        except Exception:
            self.closed.set()

    def snapshot(self) -> list[dict[str, Any]]:
        with self._lock:
            return list(self.messages)

    def wait_for(self, pred: Callable[[list[dict[str, Any]]], Any], timeout: float = 20.0) -> Any:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            out = pred(self.snapshot())
            if out:
                return out
            time.sleep(0.05)
        return pred(self.snapshot())

    def gui(self) -> dict[str, dict[str, Any]]:
        """GUI elements received so far, by label (the last one added wins)."""
        out: dict[str, dict[str, Any]] = {}
        for m in self.snapshot():
            if m["type"].startswith("Gui") and isinstance(m.get("props"), dict) and m["props"].get("label"):
                out[m["props"]["label"]] = m
        return out

    def gui_count(self) -> int:
        """How many GUI elements (folders, buttons, sliders, ...) were received."""
        return len({m["uuid"] for m in self.snapshot() if m["type"].startswith("Gui") and "props" in m})

    def wait_gui(self, label: str, timeout: float = 30.0) -> dict[str, Any]:
        el = self.wait_for(lambda _m: self.gui().get(label), timeout)
        assert el, f'no GUI element "{label}" received'
        return el

    def send(self, message: dict[str, Any]) -> None:
        self.ws.send(msgspec.msgpack.encode(message))

    def set_value(self, label: str, value: Any) -> None:
        """Change an input or press a button (buttons: value True; button groups: the option)."""
        uuid = self.wait_gui(label)["uuid"]
        self.send({"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": value}})

    def scene(self) -> dict[str, dict[str, Any]]:
        """The scene as this page has it: node name → {"type", "props", "visible", "position", "wxyz"}."""
        nodes: dict[str, dict[str, Any]] = {}
        for m in self.snapshot():
            t, name = m["type"], m.get("name")
            if name is None or t.startswith("Gui"):
                continue
            if isinstance(m.get("props"), dict) and t.endswith("Message") and "virtual" in m:
                nodes[name] = {"type": t, "props": dict(m["props"]), "visible": True, "position": None, "wxyz": None}
            elif name not in nodes:
                continue
            elif t == "RemoveSceneNodeMessage":
                del nodes[name]
            elif t == "SetSceneNodeVisibilityMessage":
                nodes[name]["visible"] = bool(m["visible"])
            elif t == "SetPositionMessage":
                nodes[name]["position"] = tuple(m["position"])
            elif t == "SetOrientationMessage":
                nodes[name]["wxyz"] = tuple(m["wxyz"])
            elif t == "SceneNodeUpdateMessage":
                nodes[name]["props"].update(m["updates"])
        return nodes

    def shown(self, prefix: str) -> dict[str, dict[str, Any]]:
        """The nodes under ``prefix`` the page draws (a node is drawn when it and every parent are visible)."""
        nodes = self.scene()

        def drawn(name: str) -> bool:
            parts = name.split("/")
            return all(nodes.get("/".join(parts[:i]), {"visible": True})["visible"] for i in range(2, len(parts) + 1))

        return {n: v for n, v in nodes.items() if n.startswith(prefix) and drawn(n)}

    def drawn_position(self, prefix: str) -> np.ndarray | None:
        """Where this page draws the first node whose name starts with ``prefix`` (None until it has one)."""
        node = next((v for n, v in self.scene().items() if n.startswith(prefix)), None)
        return None if node is None or node["position"] is None else np.array(node["position"], dtype=np.float64)

    def wait_drawn_at(self, prefix: str, where: Any = None, atol: float = 1e-6, timeout: float = 20.0) -> np.ndarray:
        """Wait until this page draws the first node named ``prefix``… within ``atol`` of ``where`` (or at all,
        without ``where``); return where it is drawn (the last place within ``timeout``, NaN if nowhere)."""

        def placed() -> np.ndarray | None:
            p = self.drawn_position(prefix)
            return p if p is not None and (where is None or np.allclose(p, where, atol=atol)) else None

        found = self.wait_for(lambda _m: placed() is not None, timeout)
        p = placed() if found else self.drawn_position(prefix)
        return np.full(3, np.nan) if p is None else p

    def layer(self, prefix: str) -> dict[str, bool]:
        """The nodes right under ``prefix`` (e.g. "/demos"), each with whether the page draws it."""
        nodes, shown = self.scene(), self.shown(prefix + "/")
        depth = prefix.count("/") + 1
        return {n: n in shown for n in nodes if n.startswith(prefix + "/") and n.count("/") == depth}

    def drag(
        self, name: str, position: tuple[float, float, float], wxyz=(1.0, 0.0, 0.0, 0.0), end: bool = True
    ) -> None:
        """What a page sends when the transform handle ``name`` is dragged to ``position`` (and let go)."""
        self.send({"type": "TransformControlsDragStartMessage", "name": name, "owner": ""})
        self.send(
            {"type": "TransformControlsUpdateMessage", "name": name, "wxyz": wxyz, "position": position, "owner": ""}
        )
        if end:
            self.send({"type": "TransformControlsDragEndMessage", "name": name, "owner": ""})

    def notifications(self) -> list[dict[str, Any]]:
        return [m for m in self.snapshot() if m["type"] in ("NotificationShowMessage", "NotificationUpdateMessage")]

    def downloads(self) -> dict[str, bytes]:
        """Files fully received, by name."""
        starts: dict[str, dict[str, Any]] = {}
        parts: dict[str, dict[int, bytes]] = {}
        for m in self.snapshot():
            if m["type"] == "FileTransferStartDownload":
                starts[m["transfer_uuid"]] = m
            elif m["type"] == "FileTransferPart" and m.get("source_component_uuid") is None:
                parts.setdefault(m["transfer_uuid"], {})[m["part_index"]] = bytes(m["content"])
        out: dict[str, bytes] = {}
        for tid, s in starts.items():
            got = parts.get(tid, {})
            if len(got) == s["part_count"]:
                out[s["filename"]] = b"".join(got[i] for i in range(s["part_count"]))
        return out

    def __enter__(self) -> ViserClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        try:
            self.ws.close()
        finally:
            self._thread.join(timeout=5)


def drawn_at(app: Any, prefix: str, where: Any = None, atol: float = 1e-6, timeout: float = 20.0) -> np.ndarray:
    """Where a new tab of the running studio ``app`` draws the first node named ``prefix``… (see
    :meth:`ViserClient.wait_drawn_at`)."""
    with ViserClient.tab_of(app) as tab:
        return tab.wait_drawn_at(prefix, where, atol, timeout)
