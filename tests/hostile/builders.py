"""Hostile inputs for the fuzzing suite: recordings, arrays and zips built byte by byte (big ones streamed, so a
test never holds what it asks the studio to hold), and a Python run under a memory limit for attacks that would
otherwise take the test machine down with them."""

from __future__ import annotations

import io
import json
import os
import re
import resource
import subprocess
import sys
import textwrap
import zipfile
import zlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import BinaryIO

import numpy as np

from studio.core.types import Recording

ROOT = Path(__file__).resolve().parent.parent.parent
MiB = 1024**2
BASE_Q = [0.08, -1.0, -1.19, 1.94, 0.67, 1.03, -0.5]


def make_rec(n: int = 1500, seed: int = 0, name: str = "demo", rate: float = 1000.0) -> Recording:
    """A smooth left-arm demonstration of ``n`` samples at ``rate`` Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    s = np.linspace(0.0, 1.0, n)
    q = np.tile(BASE_Q * 2, (n, 1)).astype(float)
    q[:, :7] += 0.4 * s[:, None] * rng.uniform(0.5, 1, 7)
    g = np.full((n, 2), 100.0)
    g[n // 2 :, 0] = 40.0
    return Recording(t=t, q=q, gripper=g, arms=("left",), name=name)


def npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.asarray(a), allow_pickle=False)
    return buf.getvalue()


def npy_header(shape: tuple[int, ...], descr: str = "<f8") -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": shape})
    return buf.getvalue()


def raw_npy(header_text: bytes) -> bytes:
    """A ``.npy`` whose header dictionary is ``header_text`` verbatim (padded as numpy pads)."""
    magic = b"\x93NUMPY\x01\x00"
    body = header_text + b" " * ((-(len(magic) + 2 + len(header_text) + 1)) % 64) + b"\n"
    return magic + len(body).to_bytes(2, "little") + body


Part = tuple[str, "bytes | int"]  # ("data", bytes) or ("zeros", how many)
_ZERO_CHUNK = 1 << 20
_ZERO_BLOCK: bytes | None = None


def _deflate(data: bytes, level: int = 1) -> bytes:
    c = zlib.compressobj(level, zlib.DEFLATED, -15)
    return c.compress(data) + c.flush(zlib.Z_FULL_FLUSH)


def _deflated_parts(parts: list[Part]) -> Iterator[tuple[bytes, bytes]]:
    """(raw deflate blocks, the bytes they stand for or b"" for zeros) for each piece; zeros cost nothing to make.

    Blocks ended by a full flush reference nothing before them, so the same block for 1 MiB of zeros can be
    repeated: a 2 GB member is written in a second, as an attacker would.
    """
    global _ZERO_BLOCK
    if _ZERO_BLOCK is None:
        _ZERO_BLOCK = _deflate(bytes(_ZERO_CHUNK), 9)
    for kind, value in parts:
        if kind == "data":
            assert isinstance(value, bytes)
            yield _deflate(value), value
        else:
            assert isinstance(value, int)
            k, r = divmod(value, _ZERO_CHUNK)
            for _ in range(k):
                yield _ZERO_BLOCK, b""
            if r:
                yield _deflate(bytes(r)), b""


def _zeros_crc(n: int, crc: int) -> int:
    chunk = bytes(_ZERO_CHUNK)
    k, r = divmod(n, _ZERO_CHUNK)
    for _ in range(k):
        crc = zlib.crc32(chunk, crc)
    return zlib.crc32(bytes(r), crc)


def fast_npz(f: BinaryIO, members: Mapping[str, list[Part]]) -> None:
    """An ``.npz`` (deflated, zip64) whose arrays are made of data pieces and runs of zeros (see :func:`fast_zip`)."""
    fast_zip(f, {f"{k}.npy": v for k, v in members.items()})


def fast_zip(f: BinaryIO, members: Mapping[str, list[Part]]) -> None:
    """A zip (deflated, zip64) whose members are made of data pieces and runs of zeros, written at the speed of
    the disk (see :func:`_deflated_parts`). ``f`` must be seekable."""
    with zipfile.ZipFile(f, "w", allowZip64=True) as zf:
        for name, parts in members.items():
            crc, size = 0, 0
            for kind, value in parts:
                if kind == "data":
                    assert isinstance(value, bytes)
                    crc, size = zlib.crc32(value, crc), size + len(value)
                else:
                    assert isinstance(value, int)
                    crc, size = _zeros_crc(value, crc), size + value
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            info.file_size = size
            info.CRC = crc
            info.compress_size = 0  # set below; the local header carries zip64 placeholders
            start = f.tell()
            info.header_offset = start
            f.write(info.FileHeader(zip64=True))
            body_start = f.tell()
            for block, _ in _deflated_parts(parts):
                f.write(block)
            f.write(b"\x03\x00")  # the final (empty) block
            info.compress_size = f.tell() - body_start
            end = f.tell()
            f.seek(start)
            f.write(info.FileHeader(zip64=True))  # same length: sizes now known
            f.seek(end)
            zf.filelist.append(info)
            zf.NameToInfo[info.filename] = info
            zf.start_dir = end
            zf._didModify = True  # type: ignore[attr-defined]


def big_demo_npz(f: BinaryIO, n: int, rate: float = 1024.0) -> None:
    """A valid demonstration file of ``n`` samples at ``rate`` Hz in which the robot holds still: a few MB that
    hold ``136 n`` bytes of float64 arrays."""
    t = (np.arange(n) / rate).astype("<f8").tobytes()
    fast_npz(
        f,
        {
            "t": [("data", npy_header((n,)) + t)],
            "q": [("data", npy_header((n, 14))), ("zeros", n * 14 * 8)],
            "gripper": [("data", npy_header((n, 2))), ("zeros", n * 2 * 8)],
        },
    )


def manifest(name: str, demos: list[tuple[str, int]], **extra: object) -> bytes:
    """A valid version-1 manifest listing ``demos`` as (file, samples)."""
    from studio.core.types import KeypointParams

    m = {
        "format": "teaching-studio-session",
        "version": 1,
        "name": name,
        "robot": "baxter",
        "arms": ["left"],
        "created": "2026-01-01T00:00:00+00:00",
        "modified": "",
        "notes": "",
        "params": KeypointParams().as_dict(),
        "n_clusters": None,
        "precision": "float64",
        "next_id": len(demos) + 1,
        "demos": [
            {"file": f, "name": f"demo {i + 1}", "arms": ["left"], "samples": n, "duration": n / 1000, "hidden": False}
            for i, (f, n) in enumerate(demos)
        ],
        "skills": {},
        "skills_stale": False,
    }
    m.update(extra)
    return json.dumps(m).encode()


def zip_bytes(entries: Mapping[str, bytes], *, compression: int = zipfile.ZIP_DEFLATED) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=compression) as zf:
        for name, data in entries.items():
            zf.writestr(zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0)), data, compress_type=compression)
    return buf.getvalue()


def tree_bytes(root: Path) -> int:
    """Bytes of every file under ``root`` (links not followed)."""
    return sum(p.lstat().st_size for p in root.rglob("*") if p.is_file() and not p.is_symlink())


def run_limited(code: str, *, memory: int = 1536 * MiB, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    """Run ``code`` in a fresh Python limited to ``memory`` bytes of address space and ``timeout`` seconds.

    Attacks that make today's code allocate tens of gigabytes or read forever end there (MemoryError, or
    the timeout: returncode -9) instead of on the machine the tests run on.
    """

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))

    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    try:
        return subprocess.run(
            [sys.executable, "-c", textwrap.dedent(code)],
            capture_output=True,
            text=True,
            timeout=timeout,
            preexec_fn=limit,
            env=env,
            cwd=ROOT,
        )
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        err = exc.stderr.decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")
        return subprocess.CompletedProcess(exc.cmd, -9, out, err + f"\n(timed out after {timeout} s)")


def studio_cli(*args: str, memory: int = 1536 * MiB, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    """``studio ARGS`` in a fresh process under a memory limit."""
    return run_limited(
        f"import sys\nfrom studio.cli import main\nsys.exit(main({list(args)!r}))", memory=memory, timeout=timeout
    )


def assert_plain(proc: subprocess.CompletedProcess[str]) -> None:
    """The command ended by itself, in plain words: no traceback, no Python exception name."""
    text = proc.stdout + proc.stderr
    assert proc.returncode not in (0, -9), text
    assert "Traceback" not in text and not re.search(r"\b\w+(Error|Exception)\b", text), text
