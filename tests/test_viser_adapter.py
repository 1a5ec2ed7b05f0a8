"""The start-up self-check of viser's private internals (decision 098): every piece the adapter reaches for is
there in the installed viser, and a missing one stops the start in one line naming the version and the piece."""

from __future__ import annotations

import socket

import pytest

from studio import viser_adapter
from studio.security import Access
from tests.conftest import free_port


def _listening(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex(("127.0.0.1", port)) == 0


def test_the_installed_viser_has_every_piece_the_studio_relies_on() -> None:
    assert viser_adapter.missing() == []
    port = free_port()
    server = Access("127.0.0.1", False).start_viser(host="127.0.0.1", port=port)
    try:
        assert viser_adapter.missing(server) == []
        viser_adapter.check(server)
        assert viser_adapter.version() == viser_adapter.MADE_FOR
    finally:
        server.stop()


def test_a_missing_message_class_is_named_in_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    from viser import _messages

    monkeypatch.setattr(viser_adapter, "version", lambda: "1.9.0")
    monkeypatch.delattr(_messages, "FileTransferPartAck")
    with pytest.raises(viser_adapter.ViserChanged) as told:
        viser_adapter.check()
    said = str(told.value)
    assert "\n" not in said
    assert said == (
        "The studio cannot start with viser 1.9.0: it relies on viser._messages.FileTransferPartAck, which this "
        "viser does not have. Install the viser version it was made for: pip install 'viser==1.1.1'."
    )


def test_a_server_without_a_piece_does_not_start(monkeypatch: pytest.MonkeyPatch) -> None:
    import viser._gui_api as gui_api

    real = gui_api.GuiApi.__init__

    def without_uploads(self: gui_api.GuiApi, *args: object, **kwargs: object) -> None:
        real(self, *args, **kwargs)  # type: ignore[arg-type]
        del self._current_file_upload_states  # as if an upgrade had renamed it

    monkeypatch.setattr(gui_api.GuiApi, "__init__", without_uploads)
    port = free_port()
    with pytest.raises(viser_adapter.ViserChanged, match=r"relies on GuiApi\._current_file_upload_states, which"):
        Access("127.0.0.1", False).start_viser(host="127.0.0.1", port=port)
    assert not _listening(port)  # stopped, not left serving unprotected
