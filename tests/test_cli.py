"""The command line: help lists every command; the default command is `serve`."""

from __future__ import annotations

import subprocess
import sys

import pytest

from studio import cli


def test_help_lists_commands() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "studio", "--help"], capture_output=True, text=True, timeout=60, check=True
    ).stdout
    for command in cli.COMMANDS:
        assert command in out


def test_default_command_is_serve(monkeypatch: pytest.MonkeyPatch) -> None:
    seen = {}

    def fake_dispatch(args):
        seen.update(vars(args))
        return 0

    monkeypatch.setattr(cli, "_dispatch", fake_dispatch)
    assert cli.main(["--port", "9123"]) == 0
    assert seen["command"] == "serve" and seen["port"] == 9123 and seen["host"] == "127.0.0.1"
    assert seen["session"] == "stack-cup"
    seen.clear()
    assert cli.main([]) == 0
    assert seen["command"] == "serve" and seen["port"] == 8080


def test_unknown_option_is_rejected() -> None:
    with pytest.raises(SystemExit) as info:
        cli.main(["serve", "--no-such-option"])
    assert info.value.code == 2
