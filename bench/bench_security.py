"""What refusing costs the studio (issue 13 §1): memory per uploaded megabyte, refused handshakes.

Each part runs in a fresh process (memory freed by an earlier part would hide growth in a later one).

1. An upload over the limit, sent in full the way viser's browser client sends it (512 KiB parts over the
   websocket), to the studio (refused at the announced size) and, as the baseline measured in the same run, to
   a plain viser server with an upload button (how the studio behaved before: every part buffered). Peak
   resident memory (VmHWM, reset through /proc/self/clear_refs) growth per megabyte sent.
2. An upload within the limit to the studio: the memory it costs (viser holds the file, then joins it).
3. Handshakes from a foreign page (Origin http://evil.example), refused with 403: time per refusal, memory.

Run:  .venv/bin/python bench/bench_security.py   (--upload-mb N, default 600, above the 512 MB limit)
"""

from __future__ import annotations

import argparse
import base64
import http.client
import os
import shutil
import socket
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
MiB = 1024 * 1024
CHUNK = 512 * 1024


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _status(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    raise RuntimeError(field)


def reset_peak() -> None:
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


def upload(url: str, label: str, size: int, name: str = "big.zip", wait=None) -> dict[str, float]:
    """Send ``size`` bytes as an upload on the button ``label``; peak memory growth while it is handled."""
    from tests.viser_client import ViserClient

    c = ViserClient(url)
    try:
        uuid = c.wait_gui(label)["uuid"]
        time.sleep(1.0)
        part = os.urandom(CHUNK)
        n = -(-size // CHUNK)
        reset_peak()
        rss0 = _status("VmRSS")
        t0 = time.perf_counter()
        c.send(
            {
                "type": "FileTransferStartUpload",
                "source_component_uuid": uuid,
                "transfer_uuid": "bench",
                "filename": name,
                "mime_type": "application/zip",
                "part_count": n,
                "size_bytes": size,
            }
        )
        for i in range(n):
            content = part if i < n - 1 else part[: size - CHUNK * (n - 1)]
            c.send(
                {
                    "type": "FileTransferPart",
                    "source_component_uuid": uuid,
                    "transfer_uuid": "bench",
                    "part_index": i,
                    "content": content,
                }
            )
        assert wait is not None
        wait(c)
        t1 = time.perf_counter()
        return {"peak": (_status("VmHWM") - rss0) / MiB, "after": (_status("VmRSS") - rss0) / MiB, "s": t1 - t0}
    finally:
        c.close()


def bench_baseline(size_mb: int) -> None:
    """A plain viser server with an upload button (no guard): how the studio behaved before."""
    import threading

    import viser

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    done = threading.Event()
    button = server.gui.add_upload_button("Upload")
    button.on_upload(lambda _event: done.set())
    try:
        r = upload(f"ws://127.0.0.1:{server.get_port()}", "Upload", size_mb * MiB, wait=lambda c: done.wait(300))
        print(
            f"plain viser server, {size_mb} MB upload (baseline): peak +{r['peak']:.0f} MB = "
            f"{r['peak'] / size_mb:.2f} MB per MB sent, {r['s']:.1f} s"
        )
    finally:
        server.stop()


def _studio():
    from studio.app import build_app

    tmp = Path(tempfile.mkdtemp(prefix="bench-security-"))
    shutil.copytree(ROOT / "sessions" / "stack-cup", tmp / "stack-cup")
    return build_app(port=free_port(), session="stack-cup", sessions_dir=tmp), tmp


def bench_refused(size_mb: int) -> None:
    from studio import security

    app, tmp = _studio()
    try:

        def refused(c) -> None:  # a second refused announcement: every part before it was handled
            c.send(
                {
                    "type": "FileTransferStartUpload",
                    "source_component_uuid": c.gui()["Upload session (.zip)"]["uuid"],
                    "transfer_uuid": "marker",
                    "filename": "marker.zip",
                    "mime_type": "application/zip",
                    "part_count": 1,
                    "size_bytes": 10 * 1024**3,
                }
            )
            c.wait_for(lambda _m: sum("too large" in str(m) for m in c.notifications()) >= 2, 300)

        r = upload(app.url().replace("http://", "ws://"), "Upload session (.zip)", size_mb * MiB, wait=refused)
        print(
            f"the studio, {size_mb} MB upload (limit {security.MAX_UPLOAD_BYTES / MiB:.0f} MB, refused): "
            f"peak +{r['peak']:.1f} MB = {r['peak'] / size_mb:.3f} MB per MB sent, {r['s']:.1f} s"
        )
    finally:
        app.stop()
        shutil.rmtree(tmp, ignore_errors=True)


def bench_within(size_mb: int) -> None:
    app, tmp = _studio()
    try:

        def arrived(c) -> None:  # the importer answers (not a session archive) once the file has arrived
            t0 = time.monotonic()
            while time.monotonic() - t0 < 120 and not [m for m in c.notifications() if "upload" in str(m).lower()]:
                time.sleep(0.05)

        r = upload(app.url().replace("http://", "ws://"), "Upload session (.zip)", size_mb * MiB, wait=arrived)
        print(
            f"the studio, {size_mb} MB upload within the limit (arrives, then the importer refuses it): "
            f"peak +{r['peak']:.0f} MB = {r['peak'] / size_mb:.2f} MB per MB, held afterwards +{r['after']:.0f} MB"
        )
    finally:
        app.stop()
        shutil.rmtree(tmp, ignore_errors=True)


def bench_handshakes(n: int = 1000) -> None:
    import viser

    app, tmp = _studio()
    try:
        headers = {
            "Host": f"127.0.0.1:{app.port}",
            "Origin": "http://evil.example",
            "Upgrade": "websocket",
            "Connection": "Upgrade",
            "Sec-WebSocket-Version": "13",
            "Sec-WebSocket-Protocol": f"viser-v{viser.__version__}",
        }
        times = []
        rss0 = _status("VmRSS")
        for _ in range(n):
            headers["Sec-WebSocket-Key"] = base64.b64encode(os.urandom(16)).decode()
            t0 = time.perf_counter()
            conn = http.client.HTTPConnection("127.0.0.1", app.port, timeout=20)
            conn.request("GET", "/", headers=headers)
            status = conn.getresponse().status
            conn.close()
            times.append(time.perf_counter() - t0)
            assert status == 403, status
        print(
            f"{n} handshakes from a foreign page, all 403: median {statistics.median(times) * 1e3:.2f} ms each "
            f"(p90 {sorted(times)[int(0.9 * n)] * 1e3:.2f} ms), memory +{(_status('VmRSS') - rss0) / MiB:.1f} MB"
        )
    finally:
        app.stop()
        shutil.rmtree(tmp, ignore_errors=True)


PARTS = ("baseline", "refused", "within", "handshakes")


def main() -> int:
    import subprocess

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--upload-mb", type=int, default=600, help="size of the refused upload (default 600 MB)")
    p.add_argument("--within-mb", type=int, default=64, help="size of the upload within the limit (default 64 MB)")
    p.add_argument("--part", choices=PARTS, help="run one part here (default: each in a fresh process)")
    args = p.parse_args()
    if args.part is None:
        # One process per part: memory freed by an earlier part stays in the allocator and would hide growth.
        for part in PARTS:
            out = subprocess.run(
                [
                    sys.executable,
                    __file__,
                    "--part",
                    part,
                    "--upload-mb",
                    str(args.upload_mb),
                    "--within-mb",
                    str(args.within_mb),
                ],
                capture_output=True,
                text=True,
                check=False,
            )
            lines = [ln for ln in out.stdout.splitlines() if ln.startswith(("plain", "the studio", str(1000)))]
            print("\n".join(lines) or out.stdout + out.stderr, flush=True)
        return 0
    if args.part == "baseline":
        bench_baseline(args.upload_mb)
    elif args.part == "refused":
        bench_refused(args.upload_mb)
    elif args.part == "within":
        bench_within(args.within_mb)
    else:
        bench_handshakes()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
