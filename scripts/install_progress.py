"""A progress line for `pip install`, read from pip's output on stdin: packages fetched of how many, then
installing, with the time so far and the usual time; pip's errors are printed in full at the end.

Usage: pip install ... 2>&1 | python scripts/install_progress.py --packages N --about SECONDS
Standard library only (it runs before anything is installed)."""

from __future__ import annotations

import argparse
import os
import re
import sys
import threading
import time
from collections import deque

FETCHED = re.compile(r"^\s*(Downloading|Processing|Using cached|File was already downloaded)\s+(\S+)(.*)$")
SIZE = re.compile(r"\(([\d.]+\s*[kMG]B)\)")


class Progress:
    """What pip has done so far, from its lines."""

    def __init__(self, packages: int) -> None:
        self.packages = packages
        self.fetched = 0
        self.last = ""
        self.installing = False
        self.done = False
        self.errors: list[str] = []
        self.tail: deque[str] = deque(maxlen=30)
        self.lock = threading.Lock()

    def feed(self, line: str) -> None:
        line = line.rstrip("\n")
        with self.lock:
            self.tail.append(line)
            m = FETCHED.match(line)
            if m and not line.lstrip().startswith("Processing ./"):
                self.fetched += 1
                path = m.group(2)
                name = path.rsplit("/", 1)[-1].split("-")[0]
                size = SIZE.search(m.group(3))
                if size:
                    self.last = f"{name}, {size.group(1)}"
                else:
                    self.last = f"{name}, {os.path.getsize(path) / 1e6:.1f} MB" if os.path.isfile(path) else name
            elif line.startswith("Installing collected packages"):
                self.installing = True
            elif line.startswith("ERROR:") or line.lstrip().startswith("error:"):
                self.errors.append(line)

    def line(self, elapsed: float, about: float) -> str:
        with self.lock:
            if self.installing:
                what = f"installing {self.packages} packages (unpacking the robot model's libraries takes longest)"
            else:
                what = f"{min(self.fetched, self.packages)} of {self.packages} packages fetched"
                what += f" ({self.last})" if self.last else ""
        late = " — slower than usual (network or a busy computer), still working" if elapsed > about else ""
        return f"    {elapsed:4.0f} s of about {about:.0f} s: {what}{late}"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--packages", type=int, required=True, help="how many packages pip installs")
    p.add_argument("--about", type=float, required=True, help="how long it usually takes, s")
    p.add_argument("--every", type=float, default=5.0, help="seconds between lines when not on a terminal")
    args = p.parse_args()
    progress = Progress(args.packages)
    tty = sys.stdout.isatty()
    t0 = time.monotonic()

    def read() -> None:
        for line in sys.stdin:
            progress.feed(line)
        progress.done = True

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    shown = ""
    last = 0.0
    while not progress.done:
        reader.join(timeout=1.0 if tty else 0.5)
        now = time.monotonic() - t0
        text = progress.line(now, args.about)
        if tty:
            sys.stdout.write("\r" + text.ljust(len(shown)))
            shown = text
        elif now - last >= args.every and not progress.done:
            print(text, flush=True)
            last = now
        sys.stdout.flush()
    if tty:
        sys.stdout.write("\n")
    if progress.errors:
        print("pip said:", *progress.tail, sep="\n    ", file=sys.stderr)
        return 1
    print(f"    {time.monotonic() - t0:4.0f} s: done", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
