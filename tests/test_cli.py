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


def test_sessions_dir_before_the_command(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    seen: dict[str, object] = {}
    monkeypatch.setattr(cli, "_dispatch", lambda args: seen.update(vars(args)) or 0)
    assert cli.main(["--sessions-dir", str(tmp_path), "learn", "stack-cup"]) == 0
    assert seen["command"] == "learn" and seen["session"] == "stack-cup" and seen["sessions_dir"] == tmp_path
    assert cli.main(["--sessions-dir", str(tmp_path)]) == 0
    assert seen["command"] == "serve" and seen["sessions_dir"] == tmp_path
