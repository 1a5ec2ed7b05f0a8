"""Baxter SDK joint-recorder CSV: import real-robot recordings, export learned joint trajectories.

The Baxter SDK's ``joint_recorder.py`` example writes one header line
``time,left_s0,…,left_w2,left_gripper,right_s0,…,right_w2,right_gripper`` and then one line per sample:
seconds since the start, 7 left joint angles (rad), the left gripper position (percent, 0 = closed ..
100 = open), the same for the right arm. Its ``joint_trajectory_file_playback.py`` example reads the same
format (columns by header name, first column time) and sends it as a joint trajectory, so an exported
skill can be run on a real Baxter with it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from studio.core import sampling
from studio.core.arms import normalize_arms
from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.types import ALL_ARM_JOINTS, ARM_JOINTS, ARMS, Recording, Skill, check_arm
from studio.storage.atomic import atomic_write_bytes

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
    header_line, body = _read_text(p, label)
    header = _check_header(header_line, label)
    col = {h: i for i, h in enumerate(header)}
    rows = _parse_rows(body, len(header), label)
    t = rows[:, col["time"]]
    keep = np.concatenate([[True], np.diff(t) > 0]) if len(t) else np.zeros(0, bool)
    # A time stamp that goes backwards (not just repeats) means the file is not one recording.
    if len(t) > 1 and np.any(np.diff(t) < 0):
        i = int(np.argmax(np.diff(t) < 0)) + 3
        raise CsvFormatError(f'"{label}" line {i}: the time goes backwards.')
    rows = rows[keep]
    if rows.shape[0] < 2:
        raise NotEnoughData(f'"{label}" holds fewer than two samples; there is nothing to learn from.')
    q = rows[:, [col[j] for j in ALL_ARM_JOINTS]]
    g = rows[:, [col["left_gripper"], col["right_gripper"]]]
    if np.any(g < -0.5) or np.any(g > 100.5):
        raise CsvFormatError(f'"{label}": gripper positions must be percent 0..100.')
    t = rows[:, col["time"]]
    return Recording(t=t - t[0], q=q, gripper=np.clip(g, 0.0, 100.0), arms=tuple(arms), name=name or p.stem[:100])


def _read_text(p: Path, label: str) -> tuple[str, str]:
    """The header line and the rest of the file (size checked before reading)."""
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise CsvFormatError(f'The file "{label}" cannot be opened ({exc.strerror}).') from exc
    if size > MAX_CSV_BYTES:
        raise CsvFormatError(f'The file "{label}" is too large to be a joint recording ({size / 1e9:.1f} GB).')
    try:
        with open(p, encoding="utf-8-sig", newline="") as f:
            return f.readline(), f.read()
    except UnicodeDecodeError as exc:
        raise CsvFormatError(f'The file "{label}" is not a text (CSV) file.') from exc
    except OSError as exc:
        raise CsvFormatError(f'The file "{label}" cannot be read ({exc.strerror}).') from exc


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


def _parse_rows(body: str, ncol: int, label: str) -> np.ndarray:
    """(rows, ncol) numbers; every problem names its line (the header is line 1)."""
    lines = body.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    rows = np.empty((len(lines), ncol))
    for i, ln in enumerate(lines):
        parts = ln.split(",")
        if len(parts) != ncol:
            if not ln.strip():
                raise CsvFormatError(f'"{label}" line {i + 2} is empty.')
            raise CsvFormatError(f'"{label}" line {i + 2} has {len(parts)} values, expected {ncol}.')
        try:
            rows[i] = [float(x) for x in parts]
        except ValueError as exc:
            raise CsvFormatError(f'"{label}" line {i + 2} contains something that is not a number.') from exc
    bad = ~np.all(np.isfinite(rows), axis=1)
    if bad.any():
        raise CsvFormatError(
            f'"{label}" line {int(np.argmax(bad)) + 2} contains a missing or invalid value (NaN or infinity).'
        )
    return rows


def _fmt_rows(t: np.ndarray, q: np.ndarray, g: np.ndarray) -> str:
    n = t.shape[0]
    cols = np.column_stack([t, q[:, :7], g[:, 0], q[:, 7:], g[:, 1]])
    fmt = (
        [f"%.{TIME_DECIMALS}f"]
        + [f"%.{JOINT_DECIMALS}f"] * 7
        + [f"%.{GRIPPER_DECIMALS}f"]
        + [f"%.{JOINT_DECIMALS}f"] * 7
        + [f"%.{GRIPPER_DECIMALS}f"]
    )
    line = ",".join(fmt)
    out = [",".join(CSV_COLUMNS)]
    out += [line % tuple(r) for r in cols] if n else []
    return "\n".join(out) + "\n"


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
    atomic_write_bytes(Path(path), _fmt_rows(t, q, g).encode())


def export_recording_csv(rec: Recording, path: str | os.PathLike[str]) -> None:
    """Write a recorded demonstration as an SDK joint-recorder CSV."""
    write_csv(path, rec.t, rec.q, rec.gripper)


def export_joint_trajectory_csv(
    skills: Mapping[str, Skill],
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
