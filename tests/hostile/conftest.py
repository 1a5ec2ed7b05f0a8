"""The hostile tests' running studio (in-process, on the example session) and a tab connected to it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from studio.app import Studio, build_app
from tests.conftest import free_port
from tests.viser_client import ViserClient


@pytest.fixture
def app(sessions: Path) -> Iterator[Studio]:
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    yield a
    a.stop()


def tab(app: Studio) -> ViserClient:
    """A tab of ``app`` whose panel has arrived."""
    c = ViserClient.tab_of(app)
    c.wait_gui("Demo action")
    return c
