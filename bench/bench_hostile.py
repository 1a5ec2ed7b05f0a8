"""Hostile input, at full size and many times over (issue 13 §2–§4): what each attack costs the studio now.

The fuzzing suite (``tests/hostile/``) keeps every attack as a test at a size a test can afford; this runs the
slow ones at the issue's sizes and counts. Each part runs in a fresh process, so that memory one part freed
does not hide growth in the next.

Parts (``--part NAME`` runs one):

* ``archives``  every hostile archive of the suite plus the issue's full-size ones (1 MB → 1 GiB, 8 × 1 GiB,
  a demo at the 21.6 M-sample limit), imported with ``SessionStore.import_zip``: refused or not, peak memory
  growth (VmHWM after a reset through /proc/self/clear_refs) and bytes written (/proc/self/io ``wchar``), per
  uploaded megabyte. Baseline, same run: an honest archive (the example session) of a similar size.
* ``websocket`` the 21.6 M-sample archive uploaded to a running studio over the websocket, as the browser does.
* ``skill``     a learned skill whose time axis is stretched ×10⁶: ``studio export-csv`` (peak memory of its
  process) and the sampling Preview uses.
* ``kill-save``, ``kill-record``  kill -9 during saves (add, trim, rename, hide, delete) and while recording,
  ``--runs`` times each: does the session open, what did opening clean, how much of the take was lost.
* ``race``      two websocket clients, one opening another session while the other presses Record 0–20 ms
  later, ``--runs`` times: takes saved into a session other than the one they started in.
* ``disk-full`` add, create, import, recover and the CLI on a 3 MB tmpfs (root only).
* ``fuzz``      random array headers and mutated CSV files, ``--runs`` × 50 each: failures that are not the
  studio's own plain-words errors.
* ``memory``    peak memory of importing a 10 M-row CSV and of key-points and training with a noisy 3 M-sample
  demonstration, each in a fresh process (issue 21 §5); baselines: a 100,000-row CSV, the example session.
* ``issue21``   issue 21's attacks §1–§4 and §7 against a running studio (links with encoded parameters, the
  key's cookie, an older ``session.json`` put back, upload parts sent again or out of range, Share, a dropdown
  value outside its options): what the attacker got.
* ``flood``     another tab's checkbox and the Emergency stop, time until acted on, ``--runs`` times each while
  one tab sends 10,000 Rename presses (issue 21 §6); baseline: the same without the flood.

Run:  .venv/bin/python bench/bench_hostile.py   (--runs 40 by default; about 15 minutes on 2 busy cores)
"""

from __future__ import annotations

import argparse
import functools
import io
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
MiB = 1024 * 1024
PARTS = (
    "archives",
    "websocket",
    "skill",
    "kill-save",
    "kill-record",
    "race",
    "disk-full",
    "fuzz",
    "memory",
    "flood",
    "burst",
    "issue21",
)


# -- measuring -----------------------------------------------------------------------------------------------
def _status(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    raise RuntimeError(field)


def _written() -> int:
    with open("/proc/self/io") as f:
        for line in f:
            if line.startswith("wchar:"):
                return int(line.split()[1])
    raise RuntimeError("wchar")


def measured(fn: Callable[[], Any]) -> dict[str, Any]:
    """Run ``fn``: its outcome, seconds, peak memory growth and bytes written."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    rss0, w0, t0 = _status("VmRSS"), _written(), time.perf_counter()
    try:
        fn()
        outcome = "accepted"
    except Exception as exc:  # the studio's own errors are the expected outcome
        from studio.core.errors import StudioError

        outcome = ("refused: " if isinstance(exc, StudioError) else f"CRASH {type(exc).__name__}: ") + str(exc)
    return {
        "outcome": outcome,
        "seconds": time.perf_counter() - t0,
        "peak_mb": (_status("VmHWM") - rss0) / MiB,
        "written_mb": (_written() - w0) / MiB,
    }


# -- parts ----------------------------------------------------------------------------------------------------
def part_archives(args: argparse.Namespace) -> list[dict[str, Any]]:
    from studio.storage import SessionStore
    from tests.hostile import test_archives as ta
    from tests.hostile.builders import big_demo_npz, fast_zip, manifest, zip_bytes

    def bombs(n: int, each: int) -> bytes:
        buf = io.BytesIO()
        demos = [(f"demos/d{i + 1:04d}.npz", 1500) for i in range(n)]
        parts: dict[str, Any] = {"b/session.json": [("data", manifest("b", demos))]}
        parts.update({f"b/{f}": [("zeros", each)] for f, _ in demos})
        fast_zip(buf, parts)
        return buf.getvalue()

    def sample_limit() -> bytes:
        n = 21_600_000
        npz = io.BytesIO()
        big_demo_npz(npz, n)
        return zip_bytes(
            {"l/session.json": manifest("l", [("demos/d0001.npz", n)]), "l/demos/d0001.npz": npz.getvalue()},
            compression=zipfile.ZIP_STORED,
        )

    def still(n: int) -> bytes:
        npz = io.BytesIO()
        big_demo_npz(npz, n)
        return zip_bytes(
            {"s/session.json": manifest("s", [("demos/d0001.npz", n)]), "s/demos/d0001.npz": npz.getvalue()},
            compression=zipfile.ZIP_STORED,
        )

    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-"))
    try:
        store = SessionStore(tmp / "sessions")
        shutil.copytree(ROOT / "sessions" / "stack-cup", store.root / "stack-cup")
        honest = store.export_zip("stack-cup")
        shutil.rmtree(store.root)
        cases: list[tuple[str, Callable[[], bytes]]] = [
            ("honest archive: the stack-cup example (baseline)", lambda: honest),
            ("bomb: 1 MB unpacking to 1 GiB (issue)", lambda: bombs(1, 1024 * MiB)),
            ("bomb: 8 entries of 1 GiB (issue: 8.3 MB → 8.55 GB)", lambda: bombs(8, 1024 * MiB + 80 * MiB)),
            ("demo at the 21.6 M-sample limit (issue: 2.9 MB → 3.2 GB)", sample_limit),
            ("still robot, 2.5 M samples (340 MB of arrays)", lambda: still(2_500_000)),
            ("still robot, 480 k samples (65 MB, under the 64 MiB floor: accepted)", lambda: still(480_000)),
            ("still robot, 500 k samples (68 MB, over the floor and 32 x the upload)", lambda: still(500_000)),
        ]
        for name, data in sorted(ta.CORPUS.items()):
            cases.append((f"suite: {name}", functools.partial(bytes, data)))
        rows = []
        for i, (name, build) in enumerate(cases):
            f = tmp / f"case{i}.zip"
            f.write_bytes(build())
            # Each import in a fresh process: memory freed by building the attack would hide its cost.
            proc = subprocess.run(
                [sys.executable, __file__, "--part", "import-one", "--file", str(f), "--json"],
                capture_output=True,
                text=True,
                timeout=1200,
                cwd=ROOT,
            )
            row = json.loads(proc.stdout.strip().splitlines()[-1]) if proc.returncode == 0 else {}
            row = row or {"outcome": f"CRASH (exit {proc.returncode}): {proc.stderr[-300:]}", "peak_mb": 0.0}
            row.update(case=name, upload_mb=f.stat().st_size / MiB)
            row.setdefault("seconds", 0.0)
            row.setdefault("written_mb", 0.0)
            rows.append(row)
            f.unlink()
        return rows
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def part_import_one(args: argparse.Namespace) -> dict[str, Any]:
    """Import the archive ``--file`` into an empty sessions folder (one case of ``archives``)."""
    from studio.storage import SessionStore

    data = Path(args.file).read_bytes()
    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-one-"))
    try:
        return measured(lambda: SessionStore(tmp).import_zip(data, archive="upload.zip"))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def part_websocket(args: argparse.Namespace) -> list[dict[str, Any]]:
    from studio.app import build_app
    from tests.conftest import free_port
    from tests.hostile.builders import big_demo_npz, manifest, zip_bytes
    from tests.viser_client import ViserClient

    n = 21_600_000
    npz = io.BytesIO()
    big_demo_npz(npz, n)
    data = zip_bytes(
        {"l/session.json": manifest("l", [("demos/d0001.npz", n)]), "l/demos/d0001.npz": npz.getvalue()},
        compression=zipfile.ZIP_STORED,
    )
    del npz
    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-ws-"))
    shutil.copytree(ROOT / "sessions" / "stack-cup", tmp / "stack-cup")
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=tmp)
    c = ViserClient(f"ws://127.0.0.1:{app.port}/?key={app.access.key}")
    try:
        uuid = c.wait_gui("Upload session (.zip)")["uuid"]
        time.sleep(2.0)
        chunk = 512 * 1024
        parts = -(-len(data) // chunk)

        def send() -> None:
            c.send(
                {
                    "type": "FileTransferStartUpload",
                    "source_component_uuid": uuid,
                    "transfer_uuid": "bench",
                    "filename": "limit.zip",
                    "mime_type": "application/zip",
                    "part_count": parts,
                    "size_bytes": len(data),
                }
            )
            for i in range(parts):
                c.send(
                    {
                        "type": "FileTransferPart",
                        "source_component_uuid": uuid,
                        "transfer_uuid": "bench",
                        "part_index": i,
                        "content": data[i * chunk : (i + 1) * chunk],
                    }
                )
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline:
                if any("limit.zip" in str(m) for m in c.notifications() if "did not work" in str(m)):
                    return
                time.sleep(0.1)
            raise RuntimeError("no answer to the upload")

        rss0 = _status("VmRSS")
        r = measured(send)
        notes = [str(m.get("props", m).get("body", "")) for m in c.notifications() if "limit.zip" in str(m)]
        r.update(
            case="21.6 M-sample archive over the websocket",
            upload_mb=len(data) / MiB,
            rss_before_mb=rss0 / MiB,
            rss_after_mb=_status("VmRSS") / MiB,
            said=notes[-1] if notes else "",
            sessions=app.controller.sessions.names(),
        )
        return [r]
    finally:
        c.close()
        app.stop()
        shutil.rmtree(tmp, ignore_errors=True)


def part_skill(args: argparse.Namespace) -> list[dict[str, Any]]:
    import numpy as np

    from studio.core import sampling
    from studio.core.learn import learn
    from studio.core.learn_settings import LearnSettings
    from studio.core.pipeline import demo_from_recording
    from studio.storage import SessionStore

    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-skill-"))
    try:
        shutil.copytree(ROOT / "sessions" / "stack-cup", tmp / "stack-cup")
        store = SessionStore(tmp)
        s = store.open("stack-cup")
        demos = [demo_from_recording(r, "left") for r in s.recordings if "left" in r.arms]
        skills = {"left": learn(demos, None, LearnSettings(params=s.params), arm="left").skill}
        s.set_skills(skills)
        sk = skills["left"]
        jt = sk.joint_trajectory
        assert jt is not None
        p = s.path / "skills" / "left.npz"

        def export(what: str) -> dict[str, Any]:
            """``studio export-csv`` in its own process; its own peak memory (VmHWM, kB)."""
            argv = ["export-csv", "stack-cup", "--out", str(tmp / "x.csv"), "--sessions-dir", str(tmp)]
            # VmHWM of the new process (ru_maxrss would carry this process's peak across fork and exec)
            code = (
                "import sys\nfrom studio.cli import main\n"
                f"rc = main({argv!r})\n"
                "hwm = [ln.split()[1] for ln in open('/proc/self/status') if ln.startswith('VmHWM:')][0]\n"
                "print('MAXRSS', hwm, file=sys.stderr)\n"
                "sys.exit(rc)\n"
            )
            t0 = time.perf_counter()
            proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, cwd=ROOT)
            peak = next((int(ln.split()[1]) / 1024 for ln in proc.stderr.splitlines() if ln.startswith("MAXRSS")), -1)
            said = [ln for ln in proc.stderr.splitlines() if not ln.startswith("MAXRSS")]
            return {
                "case": what,
                "seconds": time.perf_counter() - t0,
                "exit": proc.returncode,
                "process_peak_mb": peak,
                "said": (said[-1] if said else proc.stdout.strip())[-300:],
            }

        baseline = export("studio export-csv of the learned skill (baseline, same run)")
        with np.load(p) as z:
            arrays = {k: z[k] for k in z.files}
        for k in ("trajectory_t", "joint_t", "centroid_times", "path_times"):
            arrays[k] = arrays[k] * 1e6
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        p.write_bytes(buf.getvalue())
        stretched_run = export("studio export-csv of the same skill stretched ×10⁶")
        stretched = type(jt)(**{**jt.__dict__, "t": np.asarray(jt.t) * 1e6})
        fake = type(sk)(**{**sk.__dict__, "joint_trajectory": stretched})
        preview = measured(lambda: sampling.duration({"left": fake}))
        preview["case"] = "the sampling Preview uses, same skill"
        return [baseline, stretched_run, preview]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _kill_loop(code: str, ready: str, runs: int, seconds: Callable[[random.Random], float]) -> list[dict[str, Any]]:
    from studio.storage import SessionStore
    from tests.hostile.builders import make_rec

    rng = random.Random(13)
    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-kill-"))
    store = SessionStore(tmp / "sessions")
    s = store.create("victim")
    s.add_recording(make_rec(seed=1))
    out = []
    try:
        for _ in range(runs):
            proc = subprocess.Popen(
                [sys.executable, "-c", code.format(root=str(ROOT), sessions=str(store.root))],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            assert proc.stdout is not None
            line = proc.stdout.readline()
            assert ready in line, proc.stderr.read() if proc.stderr else line
            t0 = time.monotonic()
            time.sleep(seconds(rng))
            os.kill(proc.pid, 9)
            alive = time.monotonic() - t0
            proc.communicate(timeout=10)
            path = store.root / "victim"
            tmp_files = len(list(path.rglob(".tmp-*")))
            row: dict[str, Any] = {"alive": alive, "tmp_before": tmp_files}
            try:
                opened = store.open("victim")
                row["opened"] = True
                row["demos"] = len(opened.recordings)
                row["recovered"] = opened.recordings[-1].duration if "recovered" in opened.recovery_message else None
                listed = set(opened.demo_files)
                row["tmp_after"] = len(list(path.rglob(".tmp-*")))
                row["orphans_after"] = len(
                    [p for p in (path / "demos").glob("*.npz") if f"demos/{p.name}" not in listed]
                )
            except Exception as exc:
                row["opened"] = False
                row["error"] = f"{type(exc).__name__}: {exc}"
            out.append(row)
        return out
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def part_kill_save(args: argparse.Namespace) -> list[dict[str, Any]]:
    from tests.hostile.test_kill import SAVER

    return _kill_loop(SAVER, "ready", args.runs, lambda r: r.uniform(0.1, 1.5))


def part_kill_record(args: argparse.Namespace) -> list[dict[str, Any]]:
    from tests.hostile.test_kill import RECORDER

    return _kill_loop(RECORDER, "recording", args.runs, lambda r: r.uniform(0.5, 2.5))


def part_race(args: argparse.Namespace) -> list[dict[str, Any]]:
    from studio.app import build_app
    from studio.controller import Topic
    from studio.storage import SessionStore
    from tests.conftest import free_port, wait_for
    from tests.viser_client import ViserClient

    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-race-"))
    for name in ("stack-cup", "pick-place"):
        shutil.copytree(ROOT / "sessions" / name, tmp / name)
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=tmp)
    ctl = app.controller
    started: list[str] = []
    ctl.events.on(Topic.RECORDING, lambda: started.append(ctl.session.name) if ctl.teaching.recording else None)
    url = f"ws://127.0.0.1:{app.port}/?key={app.access.key}"
    a, b = ViserClient(url), ViserClient(url)
    rng = random.Random(5)
    rows = []

    def counts() -> dict[str, int]:
        st = SessionStore(tmp)
        return {n: len(st.open(n, recover=False).recordings) for n in ("stack-cup", "pick-place")}

    try:
        for c in (a, b):
            c.wait_gui("Record")
        for _ in range(args.runs):
            before = counts()
            other = "pick-place" if ctl.session.name == "stack-cup" else "stack-cup"
            started.clear()
            b.set_value("Open session", other)
            time.sleep(0.3)
            delay = rng.uniform(0.0, 0.02)
            b.set_value("Session action", "Open")
            time.sleep(delay)
            a.set_value("Record", True)
            ok = wait_for(lambda: bool(started), 15)
            time.sleep(0.3)
            a.set_value("Stop", True)
            wait_for(lambda: not ctl.teaching.recording, 15)
            time.sleep(0.4)
            after = counts()
            where = started[0] if ok else "?"
            landed = [n for n in after if after[n] != before[n]]
            rows.append(
                {"delay_ms": delay * 1000, "started_in": where, "landed_in": landed, "open_now": ctl.session.name}
            )
        return rows
    finally:
        a.close()
        b.close()
        app.stop()
        shutil.rmtree(tmp, ignore_errors=True)


def part_disk_full(args: argparse.Namespace) -> list[dict[str, Any]]:
    if os.geteuid() != 0:
        return [{"case": "disk full", "outcome": "skipped: mounting a tmpfs needs root"}]
    from studio.storage import SessionStore
    from tests.hostile.builders import make_rec
    from tests.hostile.test_disk_full import fill

    mnt = Path(tempfile.mkdtemp(prefix="bench-hostile-disk-"))
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(mnt)], check=True)
    rows = []
    try:
        store = SessionStore(mnt / "sessions")
        s = store.create("s")

        def add_until_full() -> None:
            for i in range(500):
                s.add_recording(make_rec(n=5000, seed=i, name=f"d{i}"))

        r = measured(add_until_full)
        r.update(case=f"add demos until the disk is full ({len(s.recordings)} kept)")
        rows.append(r)
        again = store.open("s")
        rows.append(
            {"case": "reopen after that", "outcome": f"{len(again.recordings)} demos, problems {again.problems}"}
        )
        filler = fill(mnt)
        r = measured(lambda: store.create("new"))
        r.update(case="create a session on the full disk", left=sorted(p.name for p in store.root.iterdir()))
        rows.append(r)
        r = measured(lambda: store.import_zip(SessionStore(ROOT / "sessions").export_zip("stack-cup"), archive="s.zip"))
        r.update(case="import the example on the full disk")
        rows.append(r)
        filler.unlink()
        return rows
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)
        shutil.rmtree(mnt, ignore_errors=True)


def part_fuzz(args: argparse.Namespace) -> list[dict[str, Any]]:
    from studio.core.errors import StudioError
    from studio.csv_io import import_csv
    from studio.storage import SessionStore
    from tests.hostile.builders import make_rec, npy, raw_npy

    rng = random.Random(3)
    n = args.runs * 50
    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-fuzz-"))
    try:
        store = SessionStore(tmp / "s")
        s = store.create("f")
        for i in range(2):
            s.add_recording(make_rec(seed=i))
        p = s.path / s.demo_files[1]
        r = s.recordings[1]
        alphabet = b"(){}[]'\":,0123456789.-e <>fiuOSUVbcx_ descrshapefortran_orderTrueFalse"
        crashes: dict[str, int] = {}
        t0 = time.perf_counter()
        for _ in range(n):
            k = rng.randrange(3)
            if k == 0:
                header = bytes(rng.choice(alphabet) for _ in range(rng.randrange(0, 200)))
            elif k == 1:
                header = rng.randbytes(rng.randrange(0, 200))
            else:
                good = bytearray(npy(r.q)[10:128])
                for _ in range(rng.randrange(1, 6)):
                    good[rng.randrange(len(good))] = rng.choice(alphabet)
                header = bytes(good)
            with zipfile.ZipFile(p, "w") as zf:
                zf.writestr("t.npy", npy(r.t))
                zf.writestr("q.npy", raw_npy(header))
                zf.writestr("gripper.npy", npy(r.gripper))
            try:
                store.open("f", recover=False)
            except StudioError:
                pass
            except Exception as exc:
                crashes[type(exc).__name__] = crashes.get(type(exc).__name__, 0) + 1
        headers = {"case": f"{n} fuzzed array headers", "crashes": crashes, "seconds": time.perf_counter() - t0}
        from tests.hostile.test_csv_fuzz import NUMBERS, _valid_text  # noqa: F401  (the same seed text)

        values = ["1e-300", "1e300", "-1e300", "nan", "inf", "-0", "0x10", "1_0", "١", "1e", "", " ", "9" * 400]
        lines0 = _valid_text().splitlines()
        crashes = {}
        refused = accepted = 0
        t0 = time.perf_counter()
        for i in range(n):
            lines = list(lines0)
            for _ in range(rng.randrange(1, 6)):
                row = rng.randrange(len(lines))
                parts = lines[row].split(",")
                parts[rng.randrange(len(parts))] = rng.choice([*values, rng.randbytes(4).decode("latin-1")])
                lines[row] = ",".join(parts)
            f = tmp / f"c{i % 7}.csv"
            f.write_text("\n".join(lines) + "\n")
            try:
                rec = import_csv(f)
                s.add_recording(rec)
                accepted += 1
            except StudioError:
                refused += 1
            except Exception as exc:
                crashes[type(exc).__name__] = crashes.get(type(exc).__name__, 0) + 1
        csv = {
            "case": f"{n} mutated CSV files",
            "crashes": crashes,
            "refused": refused,
            "accepted": accepted,
            "seconds": time.perf_counter() - t0,
        }
        return [headers, csv]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# -- issue 21 §5-§6: memory of what is derived, and a flood of presses -----------------------------------------
def _answer(press: Callable[[], None], done: Callable[[], bool], timeout: float = 60.0) -> float:
    """Seconds from ``press()`` until ``done()`` holds (polled every millisecond; ``timeout`` when never)."""
    t0 = time.perf_counter()
    press()
    while not done():
        if time.perf_counter() - t0 > timeout:
            return timeout
        time.sleep(0.001)
    return time.perf_counter() - t0


def part_flood(args: argparse.Namespace) -> list[dict[str, Any]]:
    """Another tab's checkbox and the Emergency stop, answered (the controller's state changed) while one tab
    sends 10,000 presses of Rename; the same without the flood first (the baseline of this run)."""
    import threading

    from studio.app import build_app
    from tests.conftest import free_port
    from tests.viser_client import ViserClient

    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-flood-"))
    shutil.copytree(ROOT / "sessions" / "stack-cup", tmp / "stack-cup")
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=tmp)
    ctl = app.controller
    url = f"ws://127.0.0.1:{app.port}/?key={app.access.key}"
    flood, other = ViserClient(url), ViserClient(url)

    def uuid(c: ViserClient, label: str, kind: str) -> str:
        found = c.wait_for(lambda ms: [m["uuid"] for m in ms if m["type"] == kind and m["props"].get("label") == label])
        return str(found[-1])

    def send(c: ViserClient, u: str, value: Any) -> None:
        c.send({"type": "GuiUpdateMessage", "uuid": u, "updates": {"value": value}})

    try:
        rename = uuid(flood, "Demo action", "GuiButtonGroupMessage")
        show = uuid(other, "Show in the scene", "GuiCheckboxMessage")
        estop = uuid(other, "Emergency stop", "GuiButtonMessage")
        name = ctl.demos.names()[-1]
        time.sleep(2.0)

        def sample(n: int) -> dict[str, list[float]]:
            out: dict[str, list[float]] = {"tab": [], "estop": []}
            for i in range(n):
                hide = i % 2 == 0
                out["tab"].append(
                    _answer(lambda h=hide: send(other, show, not h), lambda h=hide: (name in ctl.demos.hidden) == h)
                )
                out["estop"].append(_answer(lambda: send(other, estop, True), lambda: ctl.execution.status.estop))
                ctl.execution.release_emergency_stop()
                time.sleep(0.05)
            return out

        base = sample(args.runs)
        sent = [0]

        def pour() -> None:
            for _ in range(10_000):
                send(flood, rename, "Rename")
                sent[0] += 1
                if sent[0] % 500 == 0:
                    time.sleep(0.05)  # 10,000 presses spread over the samples, as a script would send them

        t = threading.Thread(target=pour, daemon=True)
        t.start()
        during = sample(args.runs)
        t.join()
        counts = app.access.presses.counts if app.access.presses is not None else None
        # The hardest case: 10,000 presses sent at once (Rename, then the flooding tab's own Emergency stop),
        # the other tab's checkbox right behind them, waiting for viser's event loop to read through them.
        flood_estop = uuid(flood, "Emergency stop", "GuiButtonMessage")
        burst: dict[str, list[float]] = {"Rename": [], "Emergency stop": []}
        for _ in range(max(2, args.runs // 4)):
            for button, u, value in (("Rename", rename, "Rename"), ("Emergency stop", flood_estop, True)):
                for _ in range(10_000):
                    send(flood, u, value)
                hide = name not in ctl.demos.hidden
                burst[button].append(
                    _answer(lambda h=hide: send(other, show, not h), lambda h=hide: (name in ctl.demos.hidden) == h)
                )
                ctl.execution.release_emergency_stop()
                time.sleep(1.0)  # the loop has read the burst; the next starts from quiet
        rows: list[dict[str, Any]] = []
        for what, label in (("tab", "another tab's checkbox"), ("estop", "Emergency stop (another tab)")):
            rows.append({"case": label, "baseline": base[what], "flood": during[what]})
        for button, times in burst.items():
            rows.append({"case": f"checkbox behind {button} x10,000 at once", "baseline": base["tab"], "flood": times})
        rows.append({"case": "gate", "sent": sent[0], "counts": str(counts)})
        return rows
    finally:
        flood.close()
        other.close()
        app.stop()
        shutil.rmtree(tmp, ignore_errors=True)


#: The tabs of ``--part burst``, in two processes as a browser's tabs are: ``press`` floods from one tab and then
#: presses the Emergency stop in another ("go KIND" on stdin → the times, time.monotonic, as JSON); ``watch`` is a
#: third tab ("arm" → the time its status next says e-stopped). Separate, so that the watcher's reading never
#: waits for the flooder's sending.
BURST_TABS = """
import json, sys, threading, time
sys.path.insert(0, {root!r})
import msgspec
from tests.viser_client import ViserClient
url, role = sys.argv[1], sys.argv[2]

def uuid(c, label, kind):
    found = c.wait_for(lambda ms: [m["uuid"] for m in ms if m["type"] == kind and m["props"].get("label") == label], 60)
    return str(found[-1])

def press(u, value):
    return msgspec.msgpack.encode({{"type": "GuiUpdateMessage", "uuid": u, "updates": {{"value": value}}}})

if role == "watch":
    watcher = ViserClient(url)
    uuid(watcher, "Emergency stop", "GuiButtonMessage")
    shown, armed, seen = threading.Event(), [False], {{}}

    def watch(msgs):
        if not armed[0]:
            return
        if any('data-estop="true"' in str(m) for m in msgs):
            seen["status"] = time.monotonic()
            armed[0] = False
            shown.set()

    watcher.watchers.append(watch)
    print("ready", flush=True)
    for line in sys.stdin:
        shown.clear()
        seen.clear()
        armed[0] = True
        print("armed", flush=True)
        shown.wait(30)
        print(json.dumps(seen), flush=True)
else:
    flood, presser = ViserClient(url), ViserClient(url)
    floods = {{
        "nothing": [],
        "Rename": [press(uuid(flood, "Demo action", "GuiButtonGroupMessage"), "Rename")] * 10_000,
        "Detail slider": [press(uuid(flood, "Detail: fewer \u2194 more key-points", "GuiSliderMessage"), v)
                          for v in (0.5 + (i % 2) * 0.5 for i in range(10_000))],
    }}
    estop = press(uuid(presser, "Emergency stop", "GuiButtonMessage"), True)
    print("ready", flush=True)
    for line in sys.stdin:
        kind = line.split(" ", 1)[1].strip()
        t0 = time.monotonic()
        for raw in floods[kind]:
            flood.ws.send(raw)
        sent = time.monotonic()
        presser.ws.send(estop)
        print(json.dumps({{"flood_s": sent - t0, "press": sent}}), flush=True)
"""


def part_burst(args: argparse.Namespace) -> list[dict[str, Any]]:
    """The Emergency stop of one tab right behind 10,000 presses (Rename) or values (a slider) another tab sent at
    once: time to the robot (the backend's ``emergency_stop`` called) and to a third tab's display (the run
    panel's status says e-stopped); at the machine's own load, then with two CPU-bound processes started, in the
    same run."""
    from studio.app import build_app
    from tests.conftest import free_port, reap

    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-burst-"))
    shutil.copytree(ROOT / "sessions" / "stack-cup", tmp / "stack-cup")
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=tmp)
    backend = app.controller.execution.backend
    stopped: list[float] = []
    real_stop = backend.emergency_stop

    def timed_stop() -> Any:
        stopped.append(time.monotonic())
        return real_stop()

    backend.emergency_stop = timed_stop  # type: ignore[method-assign]
    url = f"ws://127.0.0.1:{app.port}/?key={app.access.key}"
    code = BURST_TABS.format(root=str(ROOT))
    tabs, watch = (
        subprocess.Popen(
            [sys.executable, "-c", code, url, role], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=ROOT
        )
        for role in ("press", "watch")
    )
    busy: list[subprocess.Popen] = []
    rows: list[dict[str, Any]] = []
    try:
        assert tabs.stdin and tabs.stdout and watch.stdin and watch.stdout
        if tabs.stdout.readline().strip() != "ready" or watch.stdout.readline().strip() != "ready":
            raise RuntimeError("the tabs did not start")
        time.sleep(2.0)
        for load in ("own load", "two CPU-bound processes"):
            if load != "own load":
                busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
                time.sleep(5.0)
            for kind in ("nothing", "Rename", "Detail slider"):
                robot, status, flood_s, loads = [], [], [], []
                for _ in range(max(3, args.runs // 4)):
                    stopped.clear()
                    watch.stdin.write("arm\n")
                    watch.stdin.flush()
                    watch.stdout.readline()  # armed
                    tabs.stdin.write(f"go {kind}\n")
                    tabs.stdin.flush()
                    got = json.loads(tabs.stdout.readline())
                    got.update(json.loads(watch.stdout.readline()))
                    deadline = time.monotonic() + 30
                    while not stopped and time.monotonic() < deadline:
                        time.sleep(0.001)
                    robot.append(stopped[0] - got["press"] if stopped else 30.0)
                    status.append(got["status"] - got["press"] if "status" in got else 30.0)
                    flood_s.append(got["flood_s"])
                    loads.append(os.getloadavg()[0])
                    app.controller.execution.release_emergency_stop()
                    time.sleep(3.0)  # the loop has read the burst and the gate's rate refilled: the next from quiet
                what = "quiet (baseline)" if kind == "nothing" else f"{kind} x10,000 at once"
                rows.append({"case": f"{what}, {load}", "robot": robot, "status": status,
                             "flood_s": flood_s, "load": loads})  # fmt: skip
        rows.append({"case": "studio peak memory", "peak_mb": _status("VmHWM") / MiB})
        return rows
    finally:
        for b in busy:
            b.kill()
            b.wait()
        for proc in (tabs, watch):
            if proc.stdin is not None:
                proc.stdin.close()
            reap(proc)
        app.stop()
        shutil.rmtree(tmp, ignore_errors=True)


def part_issue21(args: argparse.Namespace) -> list[dict[str, Any]]:
    """Issue 21's attacks §1-§4 and §7 against a running studio, one row each: what the attacker got."""
    import http.client

    import studio.security.uploads as uploads
    from studio.app import build_app
    from studio.storage import SessionStore
    from tests.conftest import free_port
    from tests.hostile.builders import make_rec
    from tests.viser_client import ViserClient

    uploads.MAX_UPLOAD_BYTES = 8 * MiB
    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-21-"))
    shutil.copytree(ROOT / "sessions" / "stack-cup", tmp / "stack-cup")
    app = build_app(port=free_port(), session="stack-cup", sessions_dir=tmp)
    ac = app.access
    rows: list[dict[str, Any]] = []

    def get(path: str) -> tuple[int, str]:
        conn = http.client.HTTPConnection("127.0.0.1", app.port, timeout=20)
        try:
            cookie = f"{ac.cookie_name}={ac.key}"
            conn.request("GET", path, headers={"Host": f"127.0.0.1:{app.port}", "Cookie": cookie})
            r = conn.getresponse()
            r.read()
            return r.status, r.getheader("Set-Cookie") or ""
        finally:
            conn.close()

    try:
        links = ("/ (the page itself: the baseline)", "/?%77ebsocket=ws://127.0.0.1:1", "/?playback%50ath=/x")
        for link in (*links, "/?websocket=ws://evil", "/?x=1"):
            status, _ = get(ac.prefix + link.split(" ")[0])
            rows.append({"case": f"§1 link {link} (with the cookie)", "got": f"HTTP {status}"})
        status, cookie = get(f"/?key={ac.key}")
        path = cookie.split("Path=")[1].split(";")[0] if "Path=" in cookie else "(none)"
        rows.append({"case": "§2 the key's cookie", "got": f"HTTP {status}, valid only under {path[:4]}… (per launch)"})

        store = SessionStore(tmp / "restore")
        s = store.create("three")
        for i in range(3):
            s.add_recording(make_rec(seed=i, name=f"demo {i + 1}"))
        backup = (s.path / "session.json").read_bytes()
        s.add_recording(make_rec(seed=9, name="newest"))
        (s.path / "session.json").write_bytes(backup)
        before = len(list(s.path.rglob("d*.npz")))
        store.open("three")
        after = len(list(s.path.rglob("d*.npz")))
        recovered = len(list((s.path / "recovered").glob("d*.npz")))
        rows.append({"case": "§3 an older session.json put back, then opened",
                     "got": f"{before - after} demo files deleted, {recovered} moved to recovered/"})  # fmt: skip

        c = ViserClient(f"ws://127.0.0.1:{app.port}/?key={ac.key}")
        try:
            up = c.wait_gui("Upload session (.zip)")["uuid"]
            part = b"\0" * (512 * 1024)

            def start(tid: str) -> None:
                c.send({"type": "FileTransferStartUpload", "source_component_uuid": up, "transfer_uuid": tid,
                        "filename": "big.zip", "mime_type": "application/zip", "part_count": 12,
                        "size_bytes": 6 * MiB})  # fmt: skip

            def send_part(i: int) -> None:
                c.send({"type": "FileTransferPart", "source_component_uuid": up, "transfer_uuid": "a",
                        "part_index": i, "content": part})  # fmt: skip

            start("a")
            for i in [*range(11), 0, 10**6, -1]:
                send_part(i)
            start("b")
            refused = c.wait_for(lambda _m: [m for m in c.notifications() if "still running" in str(m)], 20)
            rows.append({"case": "§4 parts sent again or out of range, then a second upload over the limit",
                         "got": "second upload refused" if refused else "second upload NOT refused"})  # fmt: skip
            send_part(11)

            def asked() -> None:
                raise RuntimeError("the share relay was asked")

            app.server.request_share_url = asked  # type: ignore[method-assign]
            c.send({"type": "ShareUrlRequest"})
            demo = [
                m["uuid"] for m in c.snapshot() if m["type"] == "GuiDropdownMessage" and m["props"]["label"] == "Demo"
            ]
            c.send({"type": "GuiUpdateMessage", "uuid": demo[-1], "updates": {"value": "no such demo"}})
            time.sleep(1.0)
            counts = ac.presses.counts if ac.presses is not None else None
            unexpected = [m for m in c.notifications() if "unexpected" in str(m)]
            rows.append({"case": "§7 a Share request and a dropdown value outside its options",
                         "got": f"{counts}, 'unexpected' notices: {len(unexpected)}"})  # fmt: skip
        finally:
            c.close()
        return rows
    finally:
        app.stop()
        shutil.rmtree(tmp, ignore_errors=True)


def _rows_csv(path: Path, rows: int) -> None:
    """A Baxter SDK CSV of ``rows`` rows (time, both arms, grippers), written in chunks."""
    from studio.csv_io import CSV_COLUMNS

    q = ",".join(["0.100000,-0.500000,0.000000,1.000000,0.000000,0.500000,0.000000,100.0"] * 2)
    with open(path, "w") as f:
        f.write(",".join(CSV_COLUMNS) + "\n")
        for s in range(0, rows, 100_000):
            f.write("".join(f"{i / 1000:.3f},{q}\n" for i in range(s, min(rows, s + 100_000))))


MEMORY_CODE = """
import sys, time
sys.path.insert(0, {root!r})
def hwm():
    return int([l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1]) * 1024
from studio.core.kinematics import Baxter
Baxter.load()
import numpy as np
open('/proc/self/clear_refs', 'w').write('5')
before, t0 = hwm(), time.perf_counter()
{body}
print('PEAK', hwm() - before, 'TOTAL', hwm(), 'SECONDS', time.perf_counter() - t0)
"""

CSV_BODY = """
from studio.csv_io import import_csv
try:
    r = import_csv({path!r})
    print('OUTCOME imported', len(r), 'samples')
except Exception as exc:
    print('OUTCOME', type(exc).__name__, str(exc)[:200])
"""

DEMO_BODY = """
from studio.controller import Controller
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore
from tests.conftest import RecordingNotifier
told = RecordingNotifier()
ctl = Controller(store=SessionStore({root_s!r}), session='long', backend=SimulatedBaxter(), notifier=told)
try:
    view = ctl.keypoints.refresh()
    print('OUTCOME key-points', dict(view.k), list(view.messages)[:2])
    try:
        ctl.training.train().result()
        print('OUTCOME trained', sorted(ctl.session.skills))
    except Exception as exc:
        print('OUTCOME training:', type(exc).__name__, str(exc)[:200])
    print('OUTCOME told', [(t, b[:160]) for _, t, b in told.notes][:4])
finally:
    ctl.shutdown()
"""


def _peak(code: str) -> dict[str, Any]:
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=3600)
    out = proc.stdout
    row: dict[str, Any] = {"outcome": " | ".join(l[8:] for l in out.splitlines() if l.startswith("OUTCOME "))}
    if "PEAK" in out:
        words = out.split("PEAK", 1)[1].split()
        row.update(peak_mb=int(words[0]) / MiB, total_mb=int(words[2]) / MiB, seconds=float(words[4]))
    else:
        row["outcome"] += f" CRASH (exit {proc.returncode}): {proc.stderr[-400:]}"
    return row


def part_memory(args: argparse.Namespace) -> list[dict[str, Any]]:
    """Peak memory of importing a 10 M-row CSV and of working on a 3 M-sample noisy demonstration (key-points,
    then training), each in a fresh process; baseline: the same for a 100,000-row CSV and the example session;
    also the longest CSV accepted (3.6 M rows)."""
    import numpy as np

    from studio.core.types import Recording
    from studio.storage import SessionStore
    from tests.hostile.builders import make_rec

    tmp = Path(tempfile.mkdtemp(prefix="bench-hostile-mem-"))
    rows: list[dict[str, Any]] = []
    try:
        for n in (100_000, 3_600_000, 10_000_000):  # the largest CSV accepted, and the issue's
            p = tmp / f"rows-{n}.csv"
            _rows_csv(p, n)
            r = _peak(MEMORY_CODE.format(root=str(ROOT), body=CSV_BODY.format(path=str(p))))
            r.update(case=f"import a {n:,}-row CSV ({p.stat().st_size / MiB:,.0f} MB)")
            rows.append(r)
            p.unlink()
        sessions = tmp / "sessions"
        shutil.copytree(ROOT / "sessions" / "stack-cup", sessions / "long")
        r = _peak(MEMORY_CODE.format(root=str(ROOT), body=DEMO_BODY.format(root_s=str(sessions))))
        r.update(case="the example session: key-points, then training (baseline)")
        rows.append(r)
        s = SessionStore(sessions).open("long")
        rng = np.random.default_rng(0)
        base = make_rec(n=3_000_000, seed=1, name="three million")
        noisy = Recording(t=base.t, q=base.q + rng.normal(0, 0.01, base.q.shape), gripper=base.gripper,
                          arms=base.arms, name=base.name)  # fmt: skip
        s.add_recording(noisy)
        del base, noisy, s
        r = _peak(MEMORY_CODE.format(root=str(ROOT), body=DEMO_BODY.format(root_s=str(sessions))))
        r.update(case="+ a noisy 3 M-sample demonstration: key-points, then training")
        rows.append(r)
        return rows
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# -- running and reporting ----------------------------------------------------------------------------------
def run_part(name: str, runs: int) -> list[dict[str, Any]]:
    """One part in a fresh process; its rows."""
    proc = subprocess.run(
        [sys.executable, __file__, "--part", name, "--runs", str(runs), "--json"],
        capture_output=True,
        text=True,
        timeout=3600,
        cwd=ROOT,
    )
    if proc.returncode != 0:
        return [{"case": name, "outcome": f"CRASH (exit {proc.returncode}): {proc.stderr[-800:]}"}]
    return list(json.loads(proc.stdout.strip().splitlines()[-1]))


def report_flood(rows: list[dict[str, Any]]) -> None:
    for r in rows:
        if "baseline" not in r:
            print(f"  {r}")
            continue
        b, f = sorted(r["baseline"]), sorted(r["flood"])
        mb, mf = b[len(b) // 2], f[len(f) // 2]
        print(
            f"{r['case']:<40} answered: quiet median {mb * 1000:7.1f} ms worst {b[-1] * 1000:7.1f} ms | during "
            f"10,000 presses median {mf * 1000:7.1f} ms worst {f[-1] * 1000:7.1f} ms (x{mf / max(mb, 1e-9):.1f})"
        )


def report_burst(rows: list[dict[str, Any]]) -> None:
    for r in rows:
        if "robot" not in r:
            print(f"  {r}")
            continue
        line = f"{r['case']:<52}"
        for what in ("robot", "status"):
            v = sorted(r[what])
            line += f" {what} {v[len(v) // 2] * 1000:5.1f} / {v[-1] * 1000:6.1f} ms |"
        loads, sent = sorted(r["load"]), sorted(r["flood_s"])
        print(f"{line} sent in {sent[len(sent) // 2]:.2f} s, load {loads[0]:.1f}–{loads[-1]:.1f}")


def report_memory(rows: list[dict[str, Any]]) -> None:
    nan = float("nan")
    for r in rows:
        print(
            f"{r['case']:<66} peak +{r.get('peak_mb', nan):8.1f} MB (process {r.get('total_mb', nan):7.1f} MB) "
            f"{r.get('seconds', nan):6.1f} s  {r['outcome'][:300]}"
        )


def report(name: str, rows: list[dict[str, Any]]) -> None:
    print(f"\n== {name}")
    if name == "archives":
        print(
            f"{'attack':<58}{'upload':>9}{'peak mem':>10}{'written':>10}{'mem/MB':>8}{'disk/MB':>8}{'time':>7}  outcome"
        )
        for r in rows:
            up = max(r["upload_mb"], 1e-6)
            print(
                f"{r['case'][:57]:<58}{r['upload_mb']:>7.2f}MB{r['peak_mb']:>8.1f}MB{r['written_mb']:>8.2f}MB"
                f"{r['peak_mb'] / up:>8.1f}{r['written_mb'] / up:>8.2f}{r['seconds']:>6.2f}s  {r['outcome'][:90]}"
            )
        hostile = [r for r in rows if "baseline" not in r["case"] and not r["outcome"].startswith("accepted")]
        crash = [r for r in rows if r["outcome"].startswith("CRASH")]
        big = [r for r in hostile if r["upload_mb"] >= 0.5]
        print(f"attacks refused: {len(hostile)} of {len(rows) - 1}; crashes: {len(crash)}")
        if big:
            wm = max(big, key=lambda r: r["peak_mb"] / r["upload_mb"])
            wd = max(big, key=lambda r: r["written_mb"] / r["upload_mb"])
            print(
                f"worst refused upload of ≥ 0.5 MB: memory {wm['peak_mb'] / wm['upload_mb']:.2f} MB per uploaded MB "
                f"({wm['case']}), disk {wd['written_mb'] / wd['upload_mb']:.3f} MB per uploaded MB ({wd['case']})"
            )
        print(
            f"largest absolute cost of any attack: memory +{max(r['peak_mb'] for r in hostile):.1f} MB, "
            f"written {max(r['written_mb'] for r in hostile):.2f} MB"
        )
        return
    if name in ("kill-save", "kill-record"):
        opened = sum(r.get("opened", False) for r in rows)
        print(f"runs {len(rows)}; session opened {opened}/{len(rows)}")
        print(
            f"temporary files found before opening in {sum(r['tmp_before'] > 0 for r in rows)} runs; "
            f"after opening: .tmp {sum(r.get('tmp_after', 0) for r in rows)}, "
            f"unlisted demo files {sum(r.get('orphans_after', 0) for r in rows)}"
        )
        if name == "kill-record":
            lost = [r["alive"] - r["recovered"] for r in rows if r.get("recovered") is not None]
            print(
                f"takes recovered {len(lost)}/{len(rows)}; lost at most {max(lost, default=float('nan')):.2f} s "
                f"(median {sorted(lost)[len(lost) // 2] if lost else float('nan'):.2f} s) of each take"
            )
        for r in rows:
            if not r.get("opened", False):
                print("  did not open:", r.get("error"))
        return
    if name == "race":
        wrong = [r for r in rows if r["landed_in"] != [r["started_in"]]]
        print(
            f"tries {len(rows)} (Record 0–20 ms after Open); takes saved into another session than the one "
            f"they started in: {len(wrong)}"
        )
        for r in wrong:
            print("  ", r)
        return
    if name in ("flood", "memory", "burst"):
        {"flood": report_flood, "memory": report_memory, "burst": report_burst}[name](rows)
        return
    for r in rows:
        print("  " + json.dumps(r, ensure_ascii=False)[:400])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--part", choices=(*PARTS, "import-one"))
    ap.add_argument("--runs", type=int, default=40)
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--file", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.part and args.json:
        rows = globals()[f"part_{args.part.replace('-', '_')}"](args)
        print(json.dumps(rows, default=str))
        return
    for name in [args.part] if args.part else PARTS:
        t0 = time.perf_counter()
        rows = run_part(name, args.runs)
        report(name, rows)
        print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
