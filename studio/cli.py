"""The ``studio`` command line: start the browser studio, or learn / import / export headless."""

from __future__ import annotations

import argparse
import datetime
import logging
import os
import sys
import tempfile
import traceback
from pathlib import Path
from typing import Literal

from studio.core.errors import StudioError
from studio.storage.format import DEFAULT_ROOT

COMMANDS = ("serve", "learn", "import-csv", "export-csv", "make-examples")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="studio",
        description="Teaching Studio: teach a Baxter robot a skill by showing it a few times, in your browser. "
        "Without a command, `studio` starts the studio (same as `studio serve`).",
    )
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--sessions-dir", type=Path, default=DEFAULT_ROOT, help="folder that holds the sessions")
    common.add_argument(
        "--verbose", action="store_true", help="show the technical details (traceback) when something unexpected fails"
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    s = sub.add_parser("serve", parents=[common], help="start the studio in the browser (the default command)")
    s.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this computer only)")
    s.add_argument(
        "--key-file",
        type=Path,
        default=None,
        help="a file holding the key in the address to open (default: $STUDIO_KEY, or a new random key at each "
        "start); 16-128 letters, digits, - or _",
    )
    s.add_argument("--key", default=None, help=argparse.SUPPRESS)  # refused in words: ps shows it to everyone
    s.add_argument(
        "--no-key",
        action="store_true",
        help="no key in the address (this computer only: refused with a --host other than 127.0.0.1)",
    )
    s.add_argument("--port", type=_port, default=8080, help="port to listen on, 1-65535 (default 8080)")
    s.add_argument(
        "--session",
        default=None,
        help='session to open (default: the one open when the studio last stopped, else "stack-cup")',
    )
    s.add_argument(
        "--robot",
        metavar="ws://HOST:9090",
        default=None,
        help="drive a real Baxter through rosbridge at this address (default: the simulated robot)",
    )
    s.add_argument(
        "--meshes",
        choices=["auto", "light", "full"],
        default="auto",
        help="robot meshes: light (decimated, fast without a GPU), full (original), auto (light)",
    )

    s = sub.add_parser("learn", parents=[common], help="learn a session's skill without the browser, print a report")
    s.add_argument("session", help="session name (a folder under the sessions folder)")
    s.add_argument(
        "--arm", choices=["left", "right", "both"], default=None, help="arm(s) to learn (default: as taught)"
    )
    s.add_argument(
        "--auto",
        action="store_true",
        help="first suggest thresholds and k (searched for the best fit to a demonstration left out), then learn",
    )

    s = sub.add_parser("import-csv", parents=[common], help="import Baxter SDK joint-recorder CSV files as demos")
    s.add_argument("files", nargs="+", type=Path, help="CSV files written by the Baxter SDK joint recorder")
    s.add_argument("--session", required=True, help="session to add them to (created if missing)")
    s.add_argument("--arm", choices=["left", "right", "both"], default="left", help="arm(s) taught in the files")

    s = sub.add_parser("export-csv", parents=[common], help="export a learned joint trajectory as Baxter SDK CSV")
    s.add_argument("session", help="session name")
    s.add_argument("--out", type=Path, required=True, help="CSV file to write")

    s = sub.add_parser("make-examples", parents=[common], help="(re)create the example sessions (scripted teacher)")
    s.add_argument("--only", choices=["stack-cup", "pick-place"], default=None)
    return p


def _port(text: str) -> int:
    """A port number from the command line, or argparse's error in plain words."""
    try:
        port = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f'"{text}" is not a port number (a whole number from 1 to 65535)') from None
    if not 1 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{port} is not a port number: ports go from 1 to 65535")
    return port


def serve_key(args: argparse.Namespace) -> str | Literal[False] | None:
    """The key ``studio serve`` uses: none (``--no-key``), read from ``--key-file`` or ``$STUDIO_KEY``, or None
    (a new random one). A key on the command line is refused: every user of the computer sees it in ``ps``."""
    if args.key is not None:
        raise StudioError(
            "--key would show the key to every user of this computer (in the list of running programs). Put the "
            "key in a file and use --key-file FILE, or set the environment variable STUDIO_KEY."
        )
    if args.no_key:
        return False
    if args.key_file is not None:
        path = Path(args.key_file)
        try:
            if not path.is_file() or path.stat().st_size > 4096:
                raise StudioError(f'The key file "{path}" is not a small text file holding the key.')
            return path.read_text("utf-8", "replace").strip()
        except OSError as exc:
            raise StudioError(f'The key file "{path}" cannot be read ({exc.strerror}).') from exc
    return os.environ.get("STUDIO_KEY") or None


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    # `studio --sessions-dir D learn X` works like `studio learn X --sessions-dir D`.
    lead: list[str] = []
    while argv and argv[0] in ("--sessions-dir", "--verbose"):
        n = 2 if argv[0] == "--sessions-dir" else 1
        lead, argv = [*lead, *argv[:n]], argv[n:]
    if not (argv and (argv[0] in COMMANDS or argv[0] in ("-h", "--help"))):
        argv = ["serve", *argv]  # `studio` alone, or `studio --port 9000`, starts the studio
    argv = [argv[0], *lead, *argv[1:]]
    args = build_parser().parse_args(argv)
    args.command_line = " ".join(argv)  # for the error log
    return _dispatch(args)


def _dispatch(args: argparse.Namespace) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    for library in ("hmmlearn", "toppra"):  # their notes on convergence and solvers are not for the person
        logging.getLogger(library).setLevel(logging.ERROR)
    try:
        if args.command == "serve":
            from studio.security import Access

            key = serve_key(args)
            Access(args.host, key)  # a host or key it refuses is said before the studio's slower imports
            from studio.app import robot_backend, serve

            backend = robot_backend(args.robot)  # the app knows the backends; the CLI only parses
            serve(
                host=args.host,
                port=args.port,
                session=args.session,
                sessions_dir=args.sessions_dir,
                meshes=args.meshes,
                key=key,
                backend=backend,
            )
            return 0
        from studio import commands

        return int(getattr(commands, args.command.replace("-", "_"))(args))
    except StudioError as exc:
        print(f"studio: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except Exception as exc:  # never a traceback for the person: plain words, the details in a file
        verbose = bool(getattr(args, "verbose", False))
        print(f"studio: {_unexpected(exc, getattr(args, 'command_line', ''), verbose=verbose)}", file=sys.stderr)
        return 1


def _unexpected(exc: BaseException, command_line: str, *, verbose: bool) -> str:
    """Plain words for a failure the studio did not expect; the traceback goes to the error log (and, with
    ``--verbose``, to the terminal)."""
    details = "".join(traceback.format_exception(exc))
    if verbose:
        print(details, file=sys.stderr, end="")
    where = _log_error(details, command_line)
    see = f" The details were written to {where}." if where else ""
    if isinstance(exc, MemoryError):
        return f"the computer ran out of memory; close other programs and try again.{see}"
    if isinstance(exc, OSError) and exc.strerror:
        name = f' "{exc.filename}"' if exc.filename else ""
        return f"a file{name} could not be used: {exc.strerror}.{see}"
    return (
        f"something went wrong that the studio did not expect ({type(exc).__name__}: {exc}).{see} "
        "Your sessions are kept; please send that file with a note of what you did."
    )


def error_log() -> Path:
    """The file unexpected failures are written to: ``$XDG_STATE_HOME/teaching-studio/errors.log``."""
    state = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(state) / "teaching-studio" / "errors.log"


def _log_error(details: str, command_line: str) -> Path | None:
    stamp = datetime.datetime.now().isoformat(timespec="seconds")
    entry = f"--- {stamp}  studio {command_line}\n{details}\n"
    for path in (error_log(), Path(tempfile.gettempdir()) / "teaching-studio-errors.log"):
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(path, "a", encoding="utf-8") as f:
                f.write(entry)
            return path
        except OSError:
            continue
    return None


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
