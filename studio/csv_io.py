"""Baxter SDK joint-recorder CSV: import real-robot recordings, export learned joint trajectories.

The SDK's ``joint_recorder.py`` writes a header ``time,left_s0,…,left_w2,left_gripper,right_s0,…,right_gripper``
and one line per sample (seconds, radians, gripper percent 0 = closed … 100 = open); its
``joint_trajectory_file_playback.py`` reads the same format, so an exported skill runs on a real Baxter."""

from __future__ import annotations

import math
import os
import stat
from array import array
from collections.abc import Mapping
from pathlib import Path
from typing import BinaryIO, TextIO

import numpy as np

from studio.core import sampling
from studio.core.arms import normalize_arms
from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.types import ALL_ARM_JOINTS, ARM_JOINTS, ARMS, Arm, Recording, Skill, check_arm
from studio.storage.atomic import atomic_write
from studio.storage.format import DEMO_BYTES_PER_SAMPLE, MAX_DEMO_BYTES, MAX_DURATION_S, MAX_SAMPLES, implausible
from studio.storage.limits import size_text

#: The SDK's column order.
CSV_COLUMNS: tuple[str, ...] = (
    "time",
    *ARM_JOINTS["left"],
    "left_gripper",
    *ARM_JOINTS["right"],
    "right_gripper",
)
#: Largest CSV accepted (bytes): ~4 hours at 1 kHz.
MAX_CSV_BYTES = 2 * 1024**3
#: Most rows an export writes: 6 hours at the SDK's 100 rows a second (checked before anything is sampled).
MAX_EXPORT_ROWS = int(MAX_DURATION_S * 100) + 1
#: Longest line read (characters): a row of 17 numbers is about 200.
MAX_LINE_CHARS = 4096
#: Rows parsed into numbers at once when reading a CSV.
PARSE_CHUNK_ROWS = 65_536
#: The characters a row of decimal numbers is written with (ASCII digits, sign, point, exponent, commas; the
#: letters of nan and inf, which the plausibility checks refuse in their own words).
_NUMBER_CHARS = frozenset("0123456789+-.eE, \tnaNAifINFtyTY")
#: How far beyond Baxter's joint limits (URDF) a recorded angle may be, radians (encoder noise).
JOINT_LIMIT_SLACK = 0.05
#: Rows formatted at once when writing a CSV.
WRITE_CHUNK_ROWS = 20_000
TIME_DECIMALS = 6
JOINT_DECIMALS = 8
GRIPPER_DECIMALS = 4


class CsvFormatError(InvalidInput):
    """A CSV file is not in the Baxter SDK joint-recorder format (the message names the file and line)."""


def import_csv(
    path: str | os.PathLike[str], arms: tuple[str, ...] | str = ("left",), name: str | None = None
) -> Recording:
    """Read a Baxter SDK joint-recorder CSV as a :class:`Recording`.

    Columns are found by header name, in any order; times are made to start at 0. Rows whose time does not
    increase (the SDK sometimes writes the same time stamp twice) are dropped.

    Args:
        path: the CSV file.
        arms: the arm(s) taught in it ("left", "right", "both" or a tuple).
        name: the demonstration name (default: the file name without extension, cut to 100 characters).

    Raises:
        CsvFormatError: missing columns, non-numbers, NaN, too few rows — with file and line number.
    """
    p = Path(path)
    arms = normalize_arms(arms)
    label = p.name
    t, q, g, lines = _read_rows(p, label)
    if t.shape[0] < 2:
        raise NotEnoughData(f'"{label}" holds fewer than two samples; there is nothing to learn from.')
    _check_plausible(t, q, g, lines, label)
    return Recording(t=t - t[0], q=q, gripper=np.clip(g, 0.0, 100.0), arms=tuple(arms), name=name or p.stem[:100])


def _check_plausible(t: np.ndarray, q: np.ndarray, g: np.ndarray, lines: np.ndarray, label: str) -> None:
    """Numbers no robot records (1e-300 s steps, a million years, joints beyond Baxter's limits) are refused,
    naming the line: they pass as numbers but make learning overflow or never end."""
    problem = implausible(t, np.zeros((0, 14)))
    if problem is not None:
        raise CsvFormatError(f'"{label}" {problem}; nothing was imported from it.')
    lo, hi = _joint_limits()
    for c, joint in enumerate(ALL_ARM_JOINTS):
        col = q[:, c]
        bad = (col < lo[c]) | (col > hi[c])
        if bad.any():
            r = int(np.argmax(bad))
            raise CsvFormatError(
                f'"{label}" line {lines[r]}: the joint {joint} is at {col[r]:.3g} rad, beyond what Baxter\'s joint '
                f"can reach ({lo[c] + JOINT_LIMIT_SLACK:.3g} to {hi[c] - JOINT_LIMIT_SLACK:.3g} rad); joint angles "
                "must be in radians, in the Baxter SDK's joint order."
            )
    if np.any(g < -0.5) or np.any(g > 100.5):
        raise CsvFormatError(f'"{label}": gripper positions must be percent 0..100.')


def _joint_limits() -> tuple[np.ndarray, np.ndarray]:
    """(14,) lower and upper joint limits (rad) in :data:`ALL_ARM_JOINTS` order, widened by the slack."""
    from studio.core.kinematics import Baxter  # pinocchio: loaded only when a file is imported

    b = Baxter.load()
    lo = np.concatenate([b.lower_limits(a) for a in ARMS]) - JOINT_LIMIT_SLACK
    hi = np.concatenate([b.upper_limits(a) for a in ARMS]) + JOINT_LIMIT_SLACK
    return lo, hi


def _read_rows(p: Path, label: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """t (n,), q (n, 14), gripper (n, 2) and each row's line number, read in two passes: the rows are counted
    first (refused before anything is parsed when the demonstration could not be kept), then parsed a chunk at
    a time into arrays of their final size. Rows whose time repeats are dropped as they are read."""
    try:
        st = p.stat()
    except OSError as exc:
        raise CsvFormatError(f'The file "{label}" cannot be opened ({exc.strerror}).') from exc
    if not stat.S_ISREG(st.st_mode):  # a FIFO or a device would never end
        raise CsvFormatError(f'"{label}" is not a regular file, so it cannot be a joint recording.')
    if st.st_size > MAX_CSV_BYTES:
        raise CsvFormatError(f'The file "{label}" is too large to be a joint recording ({st.st_size / 1e9:.1f} GB).')
    try:
        rows = _count_rows(p)
        if rows > MAX_SAMPLES or rows * DEMO_BYTES_PER_SAMPLE > MAX_DEMO_BYTES:
            raise CsvFormatError(
                f'"{label}" holds {rows:,} rows: longer than a demonstration the studio keeps ({MAX_SAMPLES:,} '
                f"samples, an hour at 1,000 a second, {size_text(MAX_DEMO_BYTES)} in memory). Nothing was imported; "
                "split the file, or record at a lower rate."
            )
        with open(p, encoding="utf-8-sig", newline="") as f:
            header = _check_header(_line(f, 1, label), label)
            return _parse_rows(f, header, rows, label)
    except UnicodeDecodeError as exc:
        raise CsvFormatError(f'The file "{label}" is not a text (CSV) file.') from exc
    except OSError as exc:
        raise CsvFormatError(f'The file "{label}" cannot be read ({exc.strerror}).') from exc


def _count_rows(p: Path) -> int:
    """Lines after the first (an upper bound on the rows), counted a megabyte at a time; a line ends as the reader
    ends it: LF, CR LF, or CR alone (old Mac and some spreadsheet exports)."""
    lines, last = 0, b"\n"
    with open(p, "rb") as f:
        while chunk := f.read(1 << 20):
            lines += chunk.count(b"\n") + chunk.count(b"\r") - chunk.count(b"\r\n")
            if last == b"\r" and chunk[:1] == b"\n":
                lines -= 1  # a CR LF cut between two chunks
            last = chunk[-1:]
    return max(0, lines + (last not in (b"\n", b"\r")) - 1)


def _line(f: TextIO, number: int, label: str) -> str:
    """Line ``number`` of ``f`` ("" at the end), at most :data:`MAX_LINE_CHARS` long."""
    ln = f.readline(MAX_LINE_CHARS + 1)
    if len(ln) > MAX_LINE_CHARS:
        raise CsvFormatError(f'"{label}" line {number} is too long to be a row of joint values.')
    return ln


def _check_header(header_line: str, label: str) -> list[str]:
    header = [h.strip() for h in header_line.strip().split(",")]
    if not header or header[0] != "time":
        raise CsvFormatError(
            f'"{label}" is not a Baxter joint-recorder file: its first line must start with "time," '
            f"(it starts with {header_line[:40]!r})."
        )
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise CsvFormatError(f'"{label}" lacks the column(s) {", ".join(missing)} of the Baxter joint-recorder format.')
    if len(set(header)) != len(header):
        raise CsvFormatError(f'"{label}" has a column name twice in its first line.')
    return header


class _Rows:
    """The arrays being filled: t, q, gripper and line numbers, ``n`` rows so far (repeated times dropped)."""

    def __init__(self, header: list[str], capacity: int) -> None:
        col = {h: i for i, h in enumerate(header)}
        self.ncol = len(header)
        self.ti = col["time"]
        self.qi = [col[j] for j in ALL_ARM_JOINTS]
        self.gi = [col["left_gripper"], col["right_gripper"]]
        self.t = np.empty(capacity)
        self.q = np.empty((capacity, 14))
        self.g = np.empty((capacity, 2))
        self.lines = np.empty(capacity, np.int64)
        self.n = 0

    def add(self, flat: array, numbers: array, label: str) -> None:
        """Append the rows of ``flat`` (their line numbers in ``numbers``); the time must never go back."""
        rows = np.frombuffer(flat, dtype=np.float64).reshape(-1, self.ncol)
        ok = np.all(np.isfinite(rows), axis=1)
        if not ok.all():
            raise CsvFormatError(
                f'"{label}" line {numbers[int(np.argmin(ok))]} contains a missing or invalid value (NaN or infinity).'
            )
        t = rows[:, self.ti]
        prev = self.t[self.n - 1] if self.n else -np.inf
        step = np.diff(t, prepend=prev)
        if np.any(step < 0):
            i = int(np.argmax(step < 0))
            raise CsvFormatError(f'"{label}" line {numbers[i]}: the time goes backwards.')
        keep = np.flatnonzero(step > 0)  # the first row of the file always (its step is from -inf)
        a, b = self.n, self.n + keep.shape[0]
        if b > self.t.shape[0]:
            raise CsvFormatError(f'"{label}" changed while it was read; import it again once it is complete.')
        self.t[a:b] = t[keep]
        self.q[a:b] = rows[keep][:, self.qi]
        self.g[a:b] = rows[keep][:, self.gi]
        self.lines[a:b] = np.frombuffer(numbers, dtype=np.int64)[keep]
        self.n = b


def _parse_rows(
    f: TextIO, header: list[str], capacity: int, label: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The rows after the header, a chunk at a time, into arrays of ``capacity`` rows (the counted lines); every
    problem names its line (the header is line 1). Numbers are read strictly: decimals in ASCII digits (``1_00.0``
    and ``١٠٠`` are not numbers here)."""
    out = _Rows(header, capacity)
    ncol = len(header)
    flat, numbers = array("d"), array("q")
    blank = 0  # the first blank line seen: fine at the end of the file, not before a row
    number = 1
    while ln := _line(f, number + 1, label):
        number += 1
        text = ln.rstrip("\r\n")
        if not text.strip():
            blank = blank or number
            continue
        if blank:
            raise CsvFormatError(f'"{label}" line {blank} is empty.')
        parts = text.split(",")
        if len(parts) != ncol:
            raise CsvFormatError(f'"{label}" line {number} has {len(parts)} values, expected {ncol}.')
        try:
            if not _NUMBER_CHARS.issuperset(text):  # float() would also read 1_00 and digits of other scripts
                raise ValueError("not a plain decimal number")
            flat.extend([float(x) for x in parts])
        except ValueError as exc:
            raise CsvFormatError(f'"{label}" line {number} contains something that is not a number.') from exc
        numbers.append(number)
        if len(numbers) >= PARSE_CHUNK_ROWS:
            out.add(flat, numbers, label)
            flat, numbers = array("d"), array("q")
    if numbers:
        out.add(flat, numbers, label)
    n = out.n
    return out.t[:n], out.q[:n], out.g[:n], out.lines[:n]


def _fmt_rows(t: np.ndarray, q: np.ndarray, g: np.ndarray) -> str:
    """The rows (no header) of samples t (n,), q (n, 14), g (n, 2) in the SDK's column order."""
    cols = np.column_stack([t, q[:, :7], g[:, 0], q[:, 7:], g[:, 1]])
    fmt = (
        [f"%.{TIME_DECIMALS}f"]
        + [f"%.{JOINT_DECIMALS}f"] * 7
        + [f"%.{GRIPPER_DECIMALS}f"]
        + [f"%.{JOINT_DECIMALS}f"] * 7
        + [f"%.{GRIPPER_DECIMALS}f"]
    )
    line = ",".join(fmt)
    return "".join(line % tuple(r) + "\n" for r in cols)


def _write_rows(f: BinaryIO, t: np.ndarray, q: np.ndarray, g: np.ndarray) -> None:
    """Header and rows, formatted and written a chunk at a time (memory stays a few MB whatever the length)."""
    f.write((",".join(CSV_COLUMNS) + "\n").encode())
    for s in range(0, t.shape[0], WRITE_CHUNK_ROWS):
        e = s + WRITE_CHUNK_ROWS
        f.write(_fmt_rows(t[s:e], q[s:e], g[s:e]).encode())


def write_csv(path: str | os.PathLike[str], t: np.ndarray, q: np.ndarray, gripper: np.ndarray) -> None:
    """Write samples in the SDK format: t (N,) s, q (N, 14) rad in :data:`ALL_ARM_JOINTS` order, gripper (N, 2) %."""
    t = np.asarray(t, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    g = np.asarray(gripper, dtype=np.float64)
    n = t.shape[0]
    if t.ndim != 1 or q.shape != (n, 14) or g.shape != (n, 2):
        raise InvalidInput(f"Expected t (N,), q (N, 14), gripper (N, 2); got {t.shape}, {q.shape}, {g.shape}.")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q)) and np.all(np.isfinite(g))):
        raise InvalidInput("The trajectory contains missing or invalid values (NaN or infinity); nothing was written.")
    atomic_write(Path(path), lambda f: _write_rows(f, t, q, g))


def export_recording_csv(rec: Recording, path: str | os.PathLike[str]) -> None:
    """Write a recorded demonstration as an SDK joint-recorder CSV."""
    write_csv(path, rec.t, rec.q, rec.gripper)


def export_joint_trajectory_csv(
    skills: Mapping[Arm, Skill],
    path: str | os.PathLike[str],
    *,
    rest: np.ndarray | None = None,
    rate_hz: float | None = None,
    rest_gripper: tuple[float, float] = (100.0, 100.0),
) -> int:
    """Write learned skills' joint trajectories as a CSV the Baxter SDK playback example can run.

    Each skill (arm -> Skill) must have ``joint_trajectory``; the rows are sampled as Preview plays them
    (:func:`studio.core.sampling.sample_joints`, gripper included). The SDK's playback first moves slowly from
    wherever the arms are to the first row, then follows the rows' times, so the file starts at t = 0. An arm
    without a skill holds ``rest`` (the Baxter untuck pose by default) with its gripper at ``rest_gripper``.

    The learned joint trajectories are timed within Baxter's joint velocity and acceleration limits at
    their own rate (1 kHz, the paper's rate); by default the file keeps exactly those samples, so the
    playback sees the same limits. At another rate the rows are sampled from a C² cubic spline through them.

    Args:
        rate_hz: rows per second in the file (default: the joint trajectories' own rate; the SDK's recorder
            writes 100 and its playback interpolates any rate).

    Returns:
        The number of rows written.
    """
    if not skills:
        raise NotEnoughData("There is no learned skill to export yet; learn the skill first.")
    if rate_hz is not None and not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise InvalidInput("The export rate must be a positive number of rows per second.")
    for arm, sk in skills.items():
        check_arm(arm)
        if sk.joint_trajectory is None:
            raise NotEnoughData(
                f"The {arm} arm's skill has no joint trajectory (inverse kinematics was not run); learn it again."
            )
    if rate_hz is None:
        rate_hz = sampling.native_rate(skills)
    n = math.floor(sampling.duration(skills) * rate_hz + 1e-9) + 1
    if n > MAX_EXPORT_ROWS:
        raise InvalidInput(
            f"The learned trajectory would make {n:,} rows at {rate_hz:g} per second; the export makes at most "
            f"{MAX_EXPORT_ROWS:,} ({MAX_EXPORT_ROWS / 100 / 3600:.0f} hours at 100 per second). Nothing was written."
        )
    t = np.arange(n) / rate_hz
    if rest is None:
        from studio.core.kinematics import Baxter  # pinocchio: loaded only when a rest pose is needed

        b = Baxter.load()
        rest = np.concatenate([b.neutral(a) for a in ARMS])
    q, g = sampling.sample_joints(skills, t, rest, np.asarray(rest_gripper, dtype=np.float64))
    write_csv(path, t, q, g)
    return n


__all__ = [
    "CSV_COLUMNS",
    "CsvFormatError",
    "export_joint_trajectory_csv",
    "export_recording_csv",
    "import_csv",
    "write_csv",
]
