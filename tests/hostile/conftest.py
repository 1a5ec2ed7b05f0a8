"""A tab connected to the hostile tests' running studio (the ``app`` fixture of tests/conftest.py)."""

from __future__ import annotations

from studio.app import Studio
from tests.viser_client import ViserClient


def tab(app: Studio) -> ViserClient:
    """A tab of ``app`` whose panel has arrived."""
    c = ViserClient.tab_of(app)
    c.wait_gui("Demo action")
    return c
