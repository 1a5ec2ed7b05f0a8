"""Where a fresh clone's first start spends its time: the README's first command, `bash scripts/run-studio.sh`,
from a fresh clone to the printed address with a cold pip cache (PIP_NO_CACHE_DIR=1), its phases read from the
lines it prints; the same at a baseline commit in the same run, for the ratio; then the parts in scratch
environments (venv, pip's self-upgrade, the resolver, downloads, installing, what only the tests need).

    .venv/bin/python bench/bench_install.py [--ref HEAD] [--baseline main] [--no-parts]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ADDRESS = re.compile(r"open (http://\S+) in your browser")
#: Lines of run-studio.sh / bootstrap.sh that start a phase, in order (older commits print fewer of them).
MARKS = (
    ("venv", "==> creating the virtual environment"),
    ("install", "==> installing"),
    ("start", "==> starting the studio"),
)
COLD = {"PIP_NO_CACHE_DIR": "1", "PIP_DISABLE_PIP_VERSION_CHECK": "1"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def clone(ref: str, dest: Path) -> Path:
    subprocess.run(["git", "clone", "-q", str(ROOT), str(dest)], check=True)
    subprocess.run(["git", "-C", str(dest), "checkout", "-q", ref], check=True)
    return dest


def first_start(repo: Path, timeout: float = 900.0) -> dict[str, float]:
    """Run the README's first command until it prints the address; returns the time (s) of each phase's first
    line and of the address ("address"); the studio is stopped afterwards."""
    env = dict(os.environ, **COLD)
    env.pop("PIP_CACHE_DIR", None)
    t0 = time.monotonic()
    proc = subprocess.Popen(
        ["bash", "scripts/run-studio.sh", "--port", str(free_port())],
        cwd=repo,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,  # its own process group: stopped as one below
    )
    marks: dict[str, float] = {}
    assert proc.stdout is not None
    try:
        for line in proc.stdout:
            now = time.monotonic() - t0
            print(f"      {now:6.1f}  {line.rstrip()}", flush=True)
            for name, start in MARKS:
                if line.startswith(start):
                    marks.setdefault(name, now)
            if ADDRESS.search(line):
                marks["address"] = now
                break
            if now > timeout:
                break
    finally:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=30)
        proc.stdout.close()
    if "address" not in marks:
        raise RuntimeError(f"{repo}: no address printed")
    return marks


def phases(marks: dict[str, float]) -> dict[str, float]:
    """Seconds per phase: venv, install (pip, the import check), the studio's own start (when marked)."""
    out = {"venv": marks.get("install", 0.0) - marks.get("venv", 0.0)}
    end = marks.get("start", marks["address"])
    out["install"] = end - marks.get("install", 0.0)
    if "start" in marks:
        out["studio start"] = marks["address"] - marks["start"]
    out["total"] = marks["address"]
    return out


def timed(cmd: list[str], cwd: Path | None = None, env: dict[str, str] | None = None) -> float:
    t0 = time.monotonic()
    subprocess.run(cmd, cwd=cwd, env=dict(os.environ, **(env or {})), check=True, capture_output=True)
    return time.monotonic() - t0


def venv(where: Path) -> tuple[Path, float]:
    t = timed([sys.executable, "-m", "venv", str(where)])
    return where / "bin" / "python", t


def wheels_mb(folder: Path) -> dict[str, float]:
    return {p.name.split("-")[0].lower().replace("_", "-"): p.stat().st_size / 1e6 for p in folder.glob("*.whl")}


def parts(new: Path, base: Path, work: Path) -> None:
    """The parts of an install, each in a scratch environment, cold cache."""
    lock = new / "scripts" / "runtime-requirements.txt"
    py, t_venv = venv(work / "v1")
    print(f"  venv creation: {t_venv:.1f} s")
    t = timed([str(py), "-m", "pip", "install", "--upgrade", "pip"], env=COLD)
    print(f"  pip self-upgrade (the baseline's bootstrap did it): {t:.1f} s")
    py, _ = venv(work / "v2")
    report = work / "report.json"
    t = timed(
        [str(py), "-m", "pip", "install", "--dry-run", "--ignore-installed", "--report", str(report), str(base)],
        env=COLD,
    )
    n_base = len(json.loads(report.read_text())["install"])
    print(f"  resolver, baseline's dependencies (metadata only, nothing installed): {t:.1f} s, {n_base} packages")
    t = timed(
        [
            str(py),
            "-m",
            "pip",
            "install",
            "--dry-run",
            "--ignore-installed",
            "--report",
            str(report),
            f"{new}[test,mesh]",
        ],
        env=COLD,
    )
    n_test = len(json.loads(report.read_text())["install"])
    n_lock = sum(1 for line in lock.read_text().splitlines() if line and not line.startswith("#"))
    print(f"  resolver, this commit with the test and mesh extras: {t:.1f} s, {n_test} packages (the studio: {n_lock})")
    wb, wn = work / "wheels-base", work / "wheels-new"
    t_b = timed([str(py), "-m", "pip", "download", "-q", "-d", str(wb), str(base)], env=COLD)
    t_n = timed([str(py), "-m", "pip", "download", "-q", "--no-deps", "-d", str(wn), "-r", str(lock)], env=COLD)
    mb_b, mb_n = wheels_mb(wb), wheels_mb(wn)
    print(f"  download, baseline (resolver + wheels): {t_b:.1f} s, {len(mb_b)} wheels, {sum(mb_b.values()):.0f} MB")
    print(f"  download, this commit (pinned, --no-deps): {t_n:.1f} s, {len(mb_n)} wheels, {sum(mb_n.values()):.0f} MB")
    left = sorted(((mb, n) for n, mb in mb_b.items() if n not in mb_n), reverse=True)
    print(
        f"  left out of the first start: {len(left)} wheels, {sum(mb for mb, _ in left):.0f} MB; the largest: "
        + ", ".join(f"{n} {mb:.1f} MB" for mb, n in left[:8])
    )
    for name, folder, flags in (
        ("baseline", wb, []),
        ("this commit, byte-compiled", wn, []),
        ("this commit, --no-compile", wn, ["--no-compile"]),
    ):
        py, _ = venv(work / f"install-{len(flags)}-{folder.name}")
        files = [str(p) for p in folder.glob("*.whl")]
        t = timed([str(py), "-m", "pip", "install", "-q", "--no-index", "--no-deps", *flags, *files])
        print(f"  installing the downloaded wheels only, {name}: {t:.1f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--ref", default="HEAD", help="the commit measured (default HEAD)")
    ap.add_argument("--baseline", default="main", help='the commit compared with in the same run ("" for none)')
    ap.add_argument("--no-parts", action="store_true", help="only the two first starts")
    args = ap.parse_args()
    print(f"load average at the start: {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory(prefix="bench-install-") as tmp:
        work = Path(tmp)
        refs = [("this commit", args.ref)] + ([("baseline", args.baseline)] if args.baseline else [])
        repos, results = {}, {}
        for label, ref in refs:
            repos[label] = clone(ref, work / label.replace(" ", "-"))
            print(f"{label} ({ref}): first start from a fresh clone, cold pip cache")
            results[label] = phases(first_start(repos[label]))
            again = first_start(repos[label])
            results[label]["second start (installed)"] = again["address"]
        print(f"\nload average now: {os.getloadavg()[0]:.2f}")
        print("| phase | " + " | ".join(results) + " |")
        print("|---|" + "---|" * len(results))
        for key in ("venv", "install", "studio start", "total", "second start (installed)"):
            print(f"| {key} | " + " | ".join(f"{r[key]:.1f} s" if key in r else "—" for r in results.values()) + " |")
        if "baseline" in results:
            ratio = results["this commit"]["total"] / results["baseline"]["total"]
            print(f"first start to the address: ×{ratio:.2f} of the baseline's")
        if not args.no_parts and "baseline" in repos:
            print("\nparts (scratch environments, cold cache):")
            parts(repos["this commit"], repos["baseline"], work)


if __name__ == "__main__":
    main()
