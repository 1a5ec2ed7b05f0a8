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
    assert seen["session"] is None  # the session open last time (else stack-cup): decided by the studio
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


def test_an_unexpected_failure_is_told_in_plain_words_and_logged(
    monkeypatch: pytest.MonkeyPatch, tmp_path, capsys: pytest.CaptureFixture[str]
) -> None:
    from studio import commands

    def boom(args):
        raise RuntimeError("the flux capacitor melted")

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    monkeypatch.setattr(commands, "learn", boom)
    assert cli.main(["learn", "stack-cup"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and "something went wrong that the studio did not expect" in err
    log = tmp_path / "state" / "teaching-studio" / "errors.log"
    assert str(log) in err
    text = log.read_text()
    assert "Traceback" in text and "the flux capacitor melted" in text and "learn stack-cup" in text


def test_verbose_shows_the_traceback(monkeypatch: pytest.MonkeyPatch, tmp_path, capsys) -> None:
    from studio import commands

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    monkeypatch.setattr(commands, "learn", lambda args: 1 / 0)
    assert cli.main(["learn", "stack-cup", "--verbose"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and "ZeroDivisionError" in err


@pytest.mark.parametrize(
    ("exc", "words"),
    [
        (MemoryError(), "ran out of memory"),
        (OSError(28, "No space left on device"), "No space left on device"),
        (RecursionError("maximum recursion depth exceeded"), "did not expect"),
    ],
)
def test_resource_failures_are_plain_words(
    monkeypatch: pytest.MonkeyPatch, tmp_path, capsys, exc: BaseException, words: str
) -> None:
    from studio import commands

    def fail(args):
        raise exc

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    monkeypatch.setattr(commands, "export_csv", fail)
    assert cli.main(["export-csv", "stack-cup", "--out", str(tmp_path / "x.csv")]) == 1
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err
