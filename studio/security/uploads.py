"""Upload and message size caps at viser's server: :class:`UploadLimit` checks viser's upload messages on one
server before its ``GuiApi`` buffers them (the protocol and the hook: docs/decisions/016)."""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from studio import viser_adapter

if TYPE_CHECKING:
    import viser

log = logging.getLogger("studio.security")

#: All uploads in flight together may declare at most this many bytes (viser holds a file in memory).
MAX_UPLOAD_BYTES = 512 * 1024**2
#: One websocket message from a browser (viser's client sends uploads in 512 KiB parts).
MAX_MESSAGE_BYTES = 4 * 1024**2
#: An upload that received nothing for this long no longer counts against the limit.
UPLOAD_IDLE_S = 60.0


@dataclass
class _Transfer:
    client_id: int
    declared: int
    parts: int
    #: indices of the parts viser kept (in range, each once): only those count
    kept: set[int] = field(default_factory=set)
    received: int = 0
    last: float = 0.0


class UploadLimit:
    """Checks viser's upload messages on one server before its GuiApi buffers them (docs/decisions/016)."""

    def __init__(self, server: viser.ViserServer) -> None:
        viser_adapter.check(server)
        self._server = server
        self._msgs = viser_adapter.messages()
        self._inner = viser_adapter.message_handler(server)
        self._transfers: dict[str, _Transfer] = {}
        self._lock = threading.Lock()
        #: uploads refused so far (for tests and logs)
        self.refused = 0
        viser_adapter.set_message_handler(server, self.handle)
        viser_adapter.on_disconnect(server, self._on_disconnect)

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
        content, index = msg.content, msg.part_index
        with self._lock:
            t = self._transfers.get(msg.transfer_uuid)
            if t is None or t.client_id != client_id or not isinstance(content, (bytes, bytearray, memoryview)):
                return False  # a refused, finished or unknown upload: never buffered
            if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < t.parts or index in t.kept:
                return False  # viser would drop it (out of range, or again): it neither counts nor reaches viser
            t.kept.add(index)
            t.received += len(content)
            t.last = time.monotonic()
            over = t.received > t.declared
            if over:
                self._forget(msg.transfer_uuid)
            elif len(t.kept) == t.parts:  # viser completes the file with this part
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
        viser_adapter.upload_states(self._server).pop(tid, None)

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
            # Close the browser's progress notice first, then release its upload button (an acknowledgement
            # of every byte): the order keeps the notice from turning into "File uploaded successfully".
            viser_adapter.send_to(client, m.RemoveNotificationMessage(f"upload-{msg.transfer_uuid}"))
            viser_adapter.send_to(
                client,
                m.FileTransferPartAck(
                    source_component_uuid=msg.source_component_uuid,
                    transfer_uuid=msg.transfer_uuid,
                    transferred_bytes=size,
                    total_bytes=size,
                ),
            )
            client.add_notification("The upload did not work", body, color="red", auto_close_seconds=None)
        except Exception:  # a tab that just closed
            log.debug("upload refusal to a closed tab", exc_info=True)


def _mb(n: int) -> str:
    return f"{n / 1024**2:,.0f} MB" if n >= 1024**2 else f"{n / 1024:,.0f} KB"


def _short(name: Any) -> str:
    s = str(name)
    return s if len(s) <= 80 else s[:77] + "..."
