"""Baxter SDK joint-recorder CSV: exact header, round trip within CSV precision, bad files, skill export."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import cast

import numpy as np
import pytest

from studio.core.arms import arm_columns
from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.kinematics import Baxter
from studio.core.types import ARMS, Recording, Skill
from studio.csv_io import (
    CSV_COLUMNS,
    JOINT_DECIMALS,
    CsvFormatError,
    export_joint_trajectory_csv,
    export_recording_csv,
    import_csv,
)
from tests.hostile.builders import make_rec

SDK_HEADER = (
    "time,left_s0,left_s1,left_e0,left_e1,left_w0,left_w1,left_w2,left_gripper,"
    "right_s0,right_s1,right_e0,right_e1,right_w0,right_w1,right_w2,right_gripper"
)


def rec(n: int = 2000, seed: int = 0) -> Recording:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 1000.0
    q = np.cumsum(rng.normal(0, 1e-3, (n, 14)), axis=0)
    g = np.clip(np.cumsum(rng.normal(0, 0.5, (n, 2)), axis=0) + 50, 0, 100)
    return Recording(t=t, q=q, gripper=g, arms=("left",), name="r")


def test_header_is_the_sdk_format(tmp_path: Path) -> None:
    assert ",".join(CSV_COLUMNS) == SDK_HEADER
    f = tmp_path / "a.csv"
    export_recording_csv(rec(10), f)
    lines = f.read_text().splitlines()
    assert lines[0] == SDK_HEADER and len(lines) == 11
    assert len(lines[1].split(",")) == 17


def test_export_import_round_trip_within_csv_precision(tmp_path: Path) -> None:
    r = rec()
    f = tmp_path / "demo.csv"
    export_recording_csv(r, f)
    back = import_csv(f, arms="both")
    assert back.name == "demo" and back.arms == ("left", "right") and len(back) == len(r)
    assert np.abs(back.t - r.t).max() <= 0.5e-6
    assert np.abs(back.q - r.q).max() <= 0.5 * 10.0**-JOINT_DECIMALS + 1e-15
    assert np.abs(back.gripper - r.gripper).max() <= 0.5e-4 + 1e-12


@pytest.mark.parametrize("end", ["\r", "\r\n", "\n"], ids=["CR", "CRLF", "LF"])
def test_every_line_end_a_spreadsheet_writes_is_read(tmp_path: Path, end: str) -> None:
    """Issue 31 §5, today: a file with CR-only line ends was refused as "changed while it was read" (its rows
    were counted by LF, then read by every line end). A 1 MiB read may also cut a CR LF in two."""
    src = tmp_path / "lf.csv"
    export_recording_csv(make_rec(n=9000), src)  # plausible joints all along
    text = src.read_text(encoding="utf-8")
    lf = import_csv(src)
    p = tmp_path / "ends.csv"
    p.write_bytes(text.replace("\n", end).encode())
    got = import_csv(p)
    assert len(got) == len(lf) == 9000
    assert np.array_equal(got.t, lf.t) and np.array_equal(got.q, lf.q)
    if end == "\r\n":  # a CR LF across the 1 MiB boundary of the row count
        raw = text.replace("\n", end).encode()
        cut = 1 << 20
        if len(raw) > cut + 10:
            i = raw.index(b"\r\n", cut - 200)
            pad = cut - 1 - i  # spaces at the end of the header move that CR onto the boundary
            head, rest = raw.split(b"\r\n", 1)
            p.write_bytes(head + b" " * pad + b"\r\n" + rest)
            assert p.read_bytes()[cut - 1 : cut + 1] == b"\r\n"
            assert len(import_csv(p)) == 9000


def test_a_long_file_name_gives_a_demo_name_within_the_limit(tmp_path: Path) -> None:
    f = tmp_path / ("x" * 120 + ".csv")
    export_recording_csv(rec(10), f)
    assert import_csv(f).name == "x" * 100


def test_real_sdk_style_file_imports(tmp_path: Path) -> None:
    # As baxter_examples/joint_recorder.py writes it: "%f" time, str() angles, ~100 Hz, a repeated stamp,
    # columns in the SDK order, time not starting at zero.
    rows = [SDK_HEADER]
    for i in range(50):
        t = 12.5 + i * 0.01 if i != 7 else 12.5 + 6 * 0.01
        vals = [0.1 * i / 50] * 7 + [100.0] + [0.2] * 7 + [0.0]
        rows.append(f"{t:f}," + ",".join(str(v) for v in vals))
    f = tmp_path / "real.csv"
    f.write_text("\n".join(rows) + "\n\n")
    r = import_csv(f)
    assert len(r) == 49  # the repeated time stamp is dropped
    assert r.t[0] == 0.0 and r.t[-1] == pytest.approx(0.49)
    assert r.gripper[0].tolist() == [100.0, 0.0]


def test_columns_in_another_order(tmp_path: Path) -> None:
    cols = list(CSV_COLUMNS)
    order = [0, *range(16, 0, -1)]
    f = tmp_path / "x.csv"
    r = rec(5)
    data = np.column_stack([r.t, r.q[:, :7], r.gripper[:, 0], r.q[:, 7:], r.gripper[:, 1]])
    f.write_text(
        ",".join(cols[i] for i in order)
        + "\n"
        + "\n".join(",".join(repr(float(v)) for v in row[order]) for row in data)
    )
    back = import_csv(f)
    assert np.allclose(back.q, r.q) and np.allclose(back.gripper, r.gripper)


@pytest.mark.parametrize(
    ("content", "pattern"),
    [
        ("a,b,c\n1,2,3\n", 'first line must start with "time,"'),
        ("time,left_s0\n0,1\n", "lacks the column"),
        (SDK_HEADER + "\n0," + ",".join(["1"] * 15) + "\n", "line 2 has 16 values, expected 17"),
        (SDK_HEADER + "\n0," + ",".join(["x"] * 16) + "\n", "line 2 contains something that is not a number"),
        (SDK_HEADER + "\n0," + ",".join(["1"] * 15) + ",nan\n0.1," + ",".join(["1"] * 16) + "\n", "NaN"),
        (SDK_HEADER + "\n1," + ",".join(["1"] * 16) + "\n0.5," + ",".join(["1"] * 16) + "\n", "time goes backwards"),
        (SDK_HEADER + "\n0," + ",".join(["1"] * 7 + ["150"] + ["1"] * 8) + "\n0.1," + ",".join(["1"] * 16), "0..100"),
    ],
)
def test_bad_files_name_the_problem(tmp_path: Path, content: str, pattern: str) -> None:
    f = tmp_path / "bad.csv"
    f.write_text(content)
    with pytest.raises(CsvFormatError, match=pattern) as ei:
        import_csv(f)
    assert "bad.csv" in str(ei.value)


def test_too_short_missing_and_binary_files(tmp_path: Path) -> None:
    f = tmp_path / "short.csv"
    f.write_text(SDK_HEADER + "\n0," + ",".join(["1"] * 16) + "\n")
    with pytest.raises(NotEnoughData, match="fewer than two samples"):
        import_csv(f)
    with pytest.raises(CsvFormatError, match="cannot be opened"):
        import_csv(tmp_path / "nope.csv")
    b = tmp_path / "bin.csv"
    b.write_bytes(b"\xff\xfe\x00\x81" * 100)
    with pytest.raises(CsvFormatError, match="not a text"):
        import_csv(b)


def _fake_skill(t: np.ndarray, q: np.ndarray, grip: np.ndarray, jgrip: np.ndarray | None = None) -> Skill:
    """Only what the export reads (a learned Skill needs demonstrations)."""
    return cast(
        Skill,
        SimpleNamespace(
            joint_trajectory=SimpleNamespace(t=t, q=q, gripper=jgrip),
            trajectory=SimpleNamespace(t=t, gripper=grip),
        ),
    )


def test_skill_export_is_playable_sdk_csv(tmp_path: Path) -> None:
    t = np.linspace(0, 2.0, 201)
    q = np.tile(Baxter.load().neutral("left"), (201, 1)) + 0.1 * np.sin(t)[:, None]
    grip = np.where(t < 1.0, 100.0, 30.0)
    f = tmp_path / "skill.csv"
    n = export_joint_trajectory_csv({"left": _fake_skill(t, q, grip)}, f, rate_hz=100.0)
    assert n == 201
    assert f.read_text().splitlines()[0] == SDK_HEADER
    back = import_csv(f)
    assert np.allclose(back.q[:, :7], q, atol=1e-7)
    assert np.allclose(back.q[:, 7:], Baxter.load().neutral("right"))  # the other arm holds its rest pose
    assert back.gripper[0, 0] == 100.0 and back.gripper[-1, 0] == 30.0 and np.all(back.gripper[:, 1] == 100.0)


def test_skill_export_refuses_missing_or_bad_trajectories(tmp_path: Path) -> None:
    with pytest.raises(NotEnoughData, match="learn the skill first"):
        export_joint_trajectory_csv({}, tmp_path / "x.csv")
    with pytest.raises(NotEnoughData, match="no joint trajectory"):
        export_joint_trajectory_csv({"left": cast(Skill, SimpleNamespace(joint_trajectory=None))}, tmp_path / "x.csv")
    t = np.linspace(0, 1, 11)
    q = np.zeros((11, 7))
    q[3, 2] = np.nan
    with pytest.raises(InvalidInput, match="nothing was written"):
        export_joint_trajectory_csv({"left": _fake_skill(t, q, np.full(11, 50.0))}, tmp_path / "x.csv")
    assert not (tmp_path / "x.csv").exists()


def test_skill_export_prefers_the_joint_trajectory_gripper(tmp_path: Path) -> None:
    t = np.linspace(0, 1.0, 101)
    q = np.tile(Baxter.load().neutral("right"), (101, 1))
    sk = _fake_skill(t, q, np.full(101, 100.0), jgrip=np.where(t < 0.5, 80.0, 20.0))
    f = tmp_path / "r.csv"
    export_joint_trajectory_csv({"right": sk}, f)
    back = import_csv(f, arms="right")
    assert back.gripper[0, 1] == 80.0 and back.gripper[-1, 1] == 20.0
    assert np.allclose(back.q[:, :7], Baxter.load().neutral("left"))


def test_exported_skills_respect_velocity_and_acceleration_limits_at_1khz(tmp_path: Path) -> None:
    """Both arms' learned skills, exported as the SDK CSV and read back: every row-to-row velocity and
    acceleration at 1 kHz is within Baxter's limits (URDF velocity, ACCELERATION_LIMITS)."""
    from studio.teacher import recording_from_plan, teach
    from tests.core.teacher_demos import skills_of

    b = Baxter.load()
    recs = [recording_from_plan(teach("pick-place", s, arm="both")) for s in (0, 1)]
    skills = skills_of(recs, baxter=b)
    assert set(skills) == {"left", "right"}
    f = tmp_path / "both.csv"
    n = export_joint_trajectory_csv(skills, f)
    back = import_csv(f, arms="both")
    assert len(back) == n and np.allclose(np.diff(back.t), 1e-3, atol=2e-9)
    v = np.abs(np.diff(back.q, axis=0)) / 1e-3
    a = np.abs(np.diff(back.q, 2, axis=0)) / 1e-6
    vlim = np.concatenate([b.velocity_limits("left"), b.velocity_limits("right")])
    alim = np.concatenate([b.acceleration_limits("left"), b.acceleration_limits("right")])
    # the file rounds angles to 1e-8 rad: ±0.02 rad/s² of rounding noise in a second difference at 1 kHz
    assert np.all(v <= vlim + 1e-4) and np.all(a <= alim + 0.02)
    for arm in ARMS:
        cols = arm_columns(arm)
        jt = skills[arm].joint_trajectory
        assert jt is not None
        assert np.allclose(back.q[: len(jt), cols], jt.q, atol=1e-8)
