"""Hostile Baxter SDK CSV files: every file is imported as a plausible demonstration, or refused in plain words
naming the file (and the line); nothing a CSV holds makes learning crash later."""

from __future__ import annotations

import uuid
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from studio.core.errors import StudioError
from studio.csv_io import CSV_COLUMNS, import_csv
from studio.storage import SessionStore
from tests.hostile.builders import BASE_Q, MiB, assert_plain, run_limited, studio_cli


def write(path: Path, t: np.ndarray, q: np.ndarray, g: np.ndarray | None = None) -> Path:
    """Full-precision numbers (``repr``), as a tool other than the SDK might write them."""
    g = np.full((len(t), 2), 100.0) if g is None else g
    rows = [",".join(CSV_COLUMNS)]
    for i in range(len(t)):
        vals = [t[i], *q[i, :7], g[i, 0], *q[i, 7:], g[i, 1]]
        rows.append(",".join(repr(float(v)) for v in vals))
    path.write_text("\n".join(rows) + "\n")
    return path


def shape(n: int = 300, seed: int = 0) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n)
    q = np.tile(BASE_Q * 2, (n, 1))
    q[:, 0] += 0.5 * s
    q[:, 1] += 0.3 * np.sin(3 * s + seed)
    q[:, 3] += 0.2 * s**2
    return q


def test_a_time_step_of_1e_300_is_refused_naming_the_line(tmp_path: Path) -> None:
    p = write(tmp_path / "tiny.csv", np.arange(300) * 1e-300, shape())
    with pytest.raises(StudioError, match=r'"tiny\.csv" has its samples 1e-300 s apart.*seconds'):
        import_csv(p)


def test_joints_at_1e300_rad_are_refused_naming_the_line(tmp_path: Path) -> None:
    q = shape()
    q[120, 3] = 1e300
    p = write(tmp_path / "far.csv", np.arange(300) / 100, q)
    with pytest.raises(StudioError, match=r'"far\.csv" line 122:.*joint'):
        import_csv(p)


def test_a_recording_of_a_million_years_is_refused(tmp_path: Path) -> None:
    p = write(tmp_path / "long.csv", np.arange(300) * 1e11, shape())
    with pytest.raises(StudioError, match=r'"long\.csv".*(hours|long)'):
        import_csv(p)


def test_import_then_learn_never_crashes_on_extreme_numbers(tmp_path: Path) -> None:
    """The issue's sequence: import-csv accepted 1e-300 s steps, then `studio learn` died with OverflowError."""
    root = tmp_path / "sessions"
    files = [str(write(tmp_path / f"c{i}.csv", np.arange(300) * 1e-300, shape(seed=i))) for i in range(3)]
    proc = studio_cli("import-csv", *files, "--session", "tiny", "--sessions-dir", str(root))
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "time" in proc.stdout
    if SessionStore(root).exists("tiny"):  # nothing was imported, so there is nothing to learn
        assert_plain(studio_cli("learn", "tiny", "--sessions-dir", str(root), timeout=300))


def test_a_session_refuses_implausible_demonstrations_from_any_source(tmp_path: Path) -> None:
    from studio.core.types import Recording

    s = SessionStore(tmp_path).create("s")
    n = 300
    bad = [
        Recording(t=np.arange(n) * 1e-300, q=shape(), gripper=np.full((n, 2), 50.0)),
        Recording(t=np.arange(n) / 100, q=shape() * 1e300, gripper=np.full((n, 2), 50.0)),
        Recording(t=np.arange(n) * 1e9, q=shape(), gripper=np.full((n, 2), 50.0)),
    ]
    for r in bad:
        with pytest.raises(StudioError):
            s.add_recording(r)
    assert len(SessionStore(tmp_path).open("s").recordings) == 0


VALID = None


def _valid_text() -> str:
    global VALID
    if VALID is None:
        n = 40
        t = np.arange(n) / 100
        q = shape(n)
        lines = [",".join(CSV_COLUMNS)]
        for i in range(n):
            lines.append(",".join(f"{v:.6f}" for v in [t[i], *q[i, :7], 100.0, *q[i, 7:], 100.0]))
        VALID = "\n".join(lines) + "\n"
    return VALID


NUMBERS = st.sampled_from(
    ["1e-300", "1e300", "-1e300", "nan", "inf", "-0", "0x10", "1_0", "١", "1e", "", " ", "+5", "1e-320", "9" * 400]
)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    edits=st.lists(
        st.tuples(st.integers(0, 40), st.integers(0, 16), NUMBERS | st.text(max_size=12)), min_size=1, max_size=6
    ),
    tail=st.binary(max_size=64),
)
@example(edits=[(5, 0, "1e-300")], tail=b"")
@example(edits=[(9, 4, "1e300")], tail=b"")
def test_fuzzed_csv_files_are_imported_plausibly_or_refused_in_plain_words(
    tmp_path: Path, edits: list[tuple[int, int, str]], tail: bytes
) -> None:
    lines = _valid_text().splitlines()
    for row, col, value in edits:
        parts = lines[row].split(",")
        parts[col % len(parts)] = value
        lines[row] = ",".join(parts)
    p = tmp_path / "fuzz.csv"
    p.write_bytes(("\n".join(lines) + "\n").encode("utf-8", "surrogatepass") + tail)
    try:
        rec = import_csv(p)
    except StudioError as exc:
        assert "fuzz.csv" in str(exc)
        return
    assert len(rec) >= 2 and rec.duration <= 6 * 3600
    assert np.all(np.abs(rec.q) <= 2 * np.pi) and np.median(np.diff(rec.t)) >= 1e-5
    SessionStore(tmp_path / uuid.uuid4().hex).create("s").add_recording(rec)  # what imports, a session keeps


def test_a_csv_of_tiny_lines_is_refused_at_its_first_bad_line_without_holding_the_file(tmp_path: Path) -> None:
    """180 MB of "00" lines after a valid header: reading it whole made 3.5 GB of line objects. Now more lines than
    a demonstration may have are refused from their count, before any is parsed; fewer are refused at the first."""
    for lines, words in [
        (60_000_000, '"lines.csv" holds 60,000,000 rows'),
        (3_000_000, '"lines.csv" line 2 has 1 values'),
    ]:
        p = tmp_path / "lines.csv"
        with open(p, "wb") as f:
            f.write((",".join(CSV_COLUMNS) + "\n").encode())
            f.write(b"00\n" * lines)
        code = f"""
            import sys
            from studio.core.errors import StudioError
            from studio.csv_io import import_csv
            try:
                import_csv({str(p)!r})
            except StudioError as exc:
                print(exc)
        """
        proc = run_limited(code, memory=1024 * MiB, timeout=120)
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert words in proc.stdout, proc.stdout


def test_one_endless_line_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "endless.csv"
    p.write_text(",".join(CSV_COLUMNS) + "\n" + "1," * 2_000_000)
    with pytest.raises(StudioError, match=r'"endless\.csv" line 2 is too long'):
        import_csv(p)


def test_a_real_stream_with_jitter_is_kept(tmp_path: Path) -> None:
    """Plausibility judges the sampling interval (mean and median), not one pair of samples a microsecond apart."""
    t = np.arange(300) / 100
    t[150] = t[149] + 1e-6
    rec = import_csv(write(tmp_path / "jitter.csv", t, shape()))
    SessionStore(tmp_path / "s").create("s").add_recording(rec)


@pytest.mark.parametrize("number", ["1_00.0", "\u0661\u0660\u0660", "0x10", "1\u00a0", "\uff11"])
def test_numbers_are_read_strictly_naming_the_line(tmp_path: Path, number: str) -> None:
    """Issue 21 §7: Python's float() reads ``1_00.0`` as 100, and digits of other scripts (Arabic-Indic,
    full-width) and a no-break space as numbers."""
    p = write(tmp_path / "odd.csv", np.arange(300) / 100, shape())
    lines = p.read_text().splitlines()
    cells = lines[50].split(",")
    cells[4] = number
    lines[50] = ",".join(cells)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(StudioError, match=r'"odd\.csv" line 51 contains something that is not a number'):
        import_csv(p)


def test_joints_beyond_baxters_limits_are_refused(tmp_path: Path) -> None:
    """Issue 21 §7: a joint at 6.28 rad (a full turn, beyond every Baxter joint's range) was accepted."""
    q = shape()
    q[80, 0] = 6.28  # left_s0 turns ±1.70 rad
    p = write(tmp_path / "turn.csv", np.arange(300) / 100, q)
    with pytest.raises(StudioError, match=r'"turn\.csv" line 82'):
        import_csv(p)
    q = shape()
    q[80, 0] = 1.70 + 0.04  # within the slack for encoder noise
    import_csv(write(tmp_path / "edge.csv", np.arange(300) / 100, q))
