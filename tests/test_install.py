"""The first start's install (issue 30, docs/decisions/091): the pinned run-time packages are closed under what
they need (less the omissions on purpose) and within every range asked for; the bootstrap installs them without
the resolver; the progress line; what the studio says without the packages it no longer installs at first."""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest
from packaging.requirements import Requirement
from packaging.version import Version

from studio.core.errors import StudioError
from tests.conftest import ROOT


def load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


lock_runtime = load("lock_runtime")
install_progress = load("install_progress")


def test_the_runtime_pins_are_closed_and_within_every_range() -> None:
    lock = lock_runtime.read_lock()
    diff = lock_runtime.differences(lock, lock_runtime.runtime_requirements())
    assert diff == [], "run `.venv/bin/python scripts/lock_runtime.py`; differences:\n" + "\n".join(diff)
    for gone in ("example-robot-data", "roslibpy", "embreex", "twisted"):
        assert gone not in lock  # only what the studio imports when it runs


def test_the_test_pins_are_closed_and_within_every_range() -> None:
    """The test command's extras, pinned beside the run-time packages: together closed and consistent, nothing
    pinned twice, and not what the resolver used to bring for the omitted edges."""
    runtime, tests = lock_runtime.read_lock(), lock_runtime.read_lock(lock_runtime.TEST_LOCK)
    diff = lock_runtime.test_differences(runtime, tests)
    assert diff == [], "run `.venv/bin/python scripts/lock_runtime.py`; differences:\n" + "\n".join(diff)
    assert {"pytest", "playwright", "example-robot-data", "roslibpy"} <= set(tests)
    for gone in ("embreex", "shapely", "manifold3d"):
        assert gone not in tests
    twice = tests | {"numpy": runtime["numpy"]}
    assert "pinned twice: numpy" in lock_runtime.test_differences(runtime, twice)
    short = {n: v for n, v in tests.items() if n != "greenlet"}  # playwright's
    assert "missing: greenlet" in lock_runtime.test_differences(runtime, short)


def test_the_first_start_trains_with_the_run_time_pins_alone(tmp_path: Path) -> None:
    """Every installed package the first start does not install is hidden (those of the tests, and any other), and
    `studio learn` trains an example: the first start's packages are enough to train, time and save a skill."""
    from importlib import metadata

    first_start = {*lock_runtime.read_lock(), "teaching-studio", "pip", "setuptools"}  # a new venv has pip's own
    hidden = sorted(
        module
        for module, dists in metadata.packages_distributions().items()
        if not any(lock_runtime.canonicalize_name(d) in first_start for d in dists)
    )
    assert {"pytest", "playwright", "roslibpy"} <= set(hidden)
    shutil.copytree(ROOT / "sessions" / "pick-place", tmp_path / "pick-place")
    code = (
        f"import sys\nfor m in {hidden!r}: sys.modules[m] = None\nfrom studio.cli import main\n"
        f"raise SystemExit(main(['learn', 'pick-place', '--sessions-dir', {str(tmp_path)!r}]))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 0 and "Saved into the session" in done.stdout, done.stdout + done.stderr


def test_a_broken_lock_is_told() -> None:
    roots = lock_runtime.runtime_requirements()
    lock = lock_runtime.read_lock()
    missing = {n: v for n, v in lock.items() if n != "scipy"}
    assert "missing: scipy" in lock_runtime.differences(missing, roots)
    extra = lock | {"shapely": Version("2.0.0")}
    assert "not needed: shapely" in lock_runtime.differences(extra, roots)
    old = lock | {"numpy": Version("1.20.0")}
    assert any(d.startswith("numpy==1.20.0 is outside") for d in lock_runtime.differences(old, roots))


def test_the_omissions_are_edges_that_exist() -> None:
    """Each omission names a requirement its package really declares (else the table is stale)."""
    from importlib import metadata

    for parent, wanted in lock_runtime.OMITTED:
        names = {Requirement(r).name.lower() for r in metadata.distribution(parent).requires or []}
        assert wanted.split("[")[0] in names, (parent, wanted)


def test_the_bootstrap_installs_the_pins_without_the_resolver() -> None:
    script = (ROOT / "scripts" / "bootstrap.sh").read_text()
    install = next(line for line in script.splitlines() if '-r "$LOCK"' in line)
    assert "--no-deps" in install and "--no-compile" in install and '-e "$ROOT"' in install
    assert "--upgrade pip" not in script  # no self-upgrade of pip
    assert "install_progress.py" in script
    tests = next(line for line in script.splitlines() if '-r "$ROOT/scripts/test-requirements.txt"' in line)
    assert "--no-deps" in tests  # the test command's extras, pinned too
    run = (ROOT / "scripts" / "run-studio.sh").read_text()
    assert "--robot" in run and 'EXTRAS="robot"' in run


def test_no_file_belongs_to_two_installed_packages() -> None:
    """The bootstrap installs the test pins while the run-time pins install: safe while no two packages write the
    same file (a shared folder is fine)."""
    from importlib import metadata

    owner: dict[str, str] = {}
    twice = []
    for dist in metadata.distributions():
        name = lock_runtime.canonicalize_name(dist.metadata["Name"])
        for f in dist.files or []:
            path = str(f)
            if "__pycache__" in path or ".dist-info/" in path:
                continue
            if owner.setdefault(path, name) != name:
                twice.append((path, owner[path], name))
    assert owner, "no installed package lists its files"
    assert not twice, twice[:10]


def test_the_progress_line_counts_then_says_installing() -> None:
    p = install_progress.Progress(packages=3)
    assert "0 of 3 packages fetched" in p.line(1.0, 45.0)
    p.feed("Processing /nowhere/numpy-2.4.6-cp311-cp311-manylinux_2_28_x86_64.whl\n")
    p.feed("  Downloading scipy-1.17.1-cp311-cp311-manylinux_2_28_x86_64.whl (35.3 MB)\n")
    line = p.line(12.0, 45.0)
    assert "12 s of about 45 s" in line and "2 of 3 packages fetched (scipy, 35.3 MB)" in line
    p.feed("Installing collected packages: numpy, scipy\n")
    assert "installing 3 packages" in p.line(30.0, 45.0)
    assert "still working" in p.line(60.0, 45.0)  # past the usual time, it says it is not stuck
    assert p.errors == []
    p.feed("ERROR: Could not find a version that satisfies the requirement nothing==1\n")
    assert p.errors


def test_the_progress_filter_passes_on_pips_failure() -> None:
    lines = "Processing /nowhere/six-1.17.0-py2.py3-none-any.whl\nERROR: No matching distribution found for x\n"
    done = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "install_progress.py"), "--packages", "2", "--about", "30"],
        input=lines,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 1 and "No matching distribution found for x" in done.stderr


def test_without_the_extras_the_studio_says_what_to_do(monkeypatch: pytest.MonkeyPatch) -> None:
    import studio.app as app

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "roslibpy" else real(name, *a))
    with pytest.raises(StudioError, match=r"run-studio.sh --robot ws://robot:9090"):
        app.robot_backend("ws://robot:9090")

    def missing() -> Path:
        raise FileNotFoundError("no example-robot-data")

    monkeypatch.setattr(app, "baxter_urdf_path", missing)
    with pytest.raises(StudioError, match="example-robot-data"):
        app.robot_urdf_path("full")
    assert app.robot_urdf_path("auto") == app.LIGHT_URDF  # the studio itself needs neither
