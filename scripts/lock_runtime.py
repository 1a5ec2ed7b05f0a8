"""The packages the studio needs to run, and those its tests add, pinned: what `scripts/bootstrap.sh` installs
without pip's resolver.

It follows pyproject.toml's dependencies (and those of the TESTED extras) through the installed packages'
metadata, leaving out what is never imported (OMITTED, decision 091). Writes scripts/runtime-requirements.txt and
scripts/test-requirements.txt from this virtual environment; `--check` says how the files differ from it."""

from __future__ import annotations

import argparse
import sys
import tomllib
from importlib import metadata
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
LOCK = ROOT / "scripts" / "runtime-requirements.txt"
#: What the test command installs beside LOCK: the TESTED extras' packages and theirs, less those in LOCK.
TEST_LOCK = ROOT / "scripts" / "test-requirements.txt"
#: The extras the test command asks for (scripts/run-tests.sh), in bootstrap.sh's spelling.
TESTED = "test,mesh"
#: (package, what it asks for) → why the studio runs without it (installed with `--no-deps`).
OMITTED: dict[tuple[str, str], str] = {
    ("yourdfpy", "trimesh[easy]"): "trimesh alone loads the light robot's .glb meshes; its extras (embree, shapely, "
    "rtree, manifold3d, …) are for other formats and mesh processing",
}
HEADER = (
    "# What scripts/bootstrap.sh installs to run the studio, with --no-deps (no resolver): pyproject.toml's\n"
    "# dependencies and theirs, pinned. Written by `python scripts/lock_runtime.py` in a virtual environment\n"
    "# that has them; tests/test_install.py checks it. Left out on purpose: scripts/lock_runtime.py OMITTED.\n"
)
TEST_HEADER = (
    f"# What scripts/bootstrap.sh installs for the extras {TESTED} (the test command), with --no-deps, beside\n"
    "# scripts/runtime-requirements.txt: those extras' packages and theirs, pinned, less the run-time ones. Written\n"
    "# by `python scripts/lock_runtime.py`; tests/test_install.py checks it.\n"
)


def runtime_requirements(pyproject: Path = ROOT / "pyproject.toml") -> list[Requirement]:
    """The studio's own run-time dependencies (pyproject.toml's [project] dependencies)."""
    data = tomllib.loads(pyproject.read_text())
    return [Requirement(r) for r in data["project"]["dependencies"]]


def extra_requirements(extras: str = TESTED, pyproject: Path = ROOT / "pyproject.toml") -> list[Requirement]:
    """The packages pyproject.toml's optional dependencies ``extras`` (comma-separated) ask for."""
    data = tomllib.loads(pyproject.read_text())["project"]["optional-dependencies"]
    return [Requirement(r) for extra in extras.split(",") for r in data[extra]]


def closure(roots: list[Requirement]) -> dict[str, Requirement]:
    """Every package the roots need, by canonical name, as found installed here; OMITTED edges are not followed
    (an omitted "name[extras]" keeps the package, without those extras).

    Raises:
        LookupError: a needed package is not installed in this environment.
    """
    found: dict[str, Requirement] = {}
    done: set[tuple[str, str]] = set()  # (package, extra or "") whose requirements were followed
    todo: list[tuple[str | None, Requirement]] = [(None, r) for r in roots]
    while todo:
        parent, req = todo.pop()
        name = canonicalize_name(req.name)
        extras = sorted(req.extras)
        if parent is not None and (parent, name) in OMITTED:
            continue
        if parent is not None and (parent, f"{name}[{','.join(extras)}]") in OMITTED:
            extras = []
        try:
            dist = metadata.distribution(name)
        except metadata.PackageNotFoundError as exc:
            raise LookupError(f"{name} (needed by {parent or 'pyproject.toml'}) is not installed here") from exc
        found.setdefault(name, req)
        for extra in ["", *extras]:
            if (name, extra) in done:
                continue
            done.add((name, extra))
            for text in dist.requires or []:
                sub = Requirement(text)
                if _needed(sub, extra):
                    todo.append((name, sub))
    return found


def _needed(req: Requirement, extra: str) -> bool:
    """Whether a package's requirement holds here for ``extra`` ("" : the package itself, not an extra)."""
    if req.marker is None:
        return extra == ""
    plain = req.marker.evaluate({"extra": ""})
    return plain if extra == "" else req.marker.evaluate({"extra": extra}) and not plain


def pinned(names: dict[str, Requirement]) -> dict[str, Version]:
    """The installed version of each package."""
    return {n: Version(metadata.version(n)) for n in names}


def read_lock(path: Path = LOCK) -> dict[str, Version]:
    out: dict[str, Version] = {}
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, version = line.split("==")
            out[canonicalize_name(name)] = Version(version)
    return out


def lock_text(versions: dict[str, Version], header: str = HEADER) -> str:
    return header + "".join(f"{n}=={v}\n" for n, v in sorted(versions.items()))


def test_differences(runtime: dict[str, Version], tests: dict[str, Version]) -> list[str]:
    """How the test lock ``tests`` differs from what the tested extras need beside ``runtime``: the two together
    closed and consistent (:func:`differences`), and nothing pinned twice."""
    out = [f"pinned twice: {n}" for n in sorted(set(runtime) & set(tests))]
    return out + differences(runtime | tests, runtime_requirements() + extra_requirements())


def differences(lock: dict[str, Version], roots: list[Requirement]) -> list[str]:
    """How ``lock`` differs from what the roots need here: missing or extra packages, versions outside a range
    that pyproject.toml or a needed package asks for (an empty list: the lock is closed and consistent)."""
    need = closure(roots)
    out = [f"missing: {n}" for n in sorted(set(need) - set(lock))]
    out += [f"not needed: {n}" for n in sorted(set(lock) - set(need))]
    for parent in sorted(set(need) & set(lock)):
        for text in metadata.distribution(parent).requires or []:
            sub = Requirement(text)
            name = canonicalize_name(sub.name)
            if name in lock and sub.specifier and lock[name] not in sub.specifier and _needed(sub, ""):
                out.append(f"{name}=={lock[name]} is outside {parent}'s {sub}")
    for r in roots:
        name = canonicalize_name(r.name)
        if name in lock and lock[name] not in r.specifier:
            out.append(f"{name}=={lock[name]} is outside pyproject.toml's {r}")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--check", action="store_true", help="only say how the file differs from this environment")
    args = p.parse_args(argv)
    roots = runtime_requirements()
    if args.check:
        diff = differences(read_lock(), roots) + test_differences(read_lock(), read_lock(TEST_LOCK))
        print("\n".join(diff) or "scripts/runtime-requirements.txt and test-requirements.txt are closed and consistent")
        return 1 if diff else 0
    runtime = closure(roots)
    LOCK.write_text(lock_text(pinned(runtime)))
    tests = {n: r for n, r in closure(roots + extra_requirements()).items() if n not in runtime}
    TEST_LOCK.write_text(lock_text(pinned(tests), TEST_HEADER))
    print(f"wrote {LOCK.relative_to(ROOT)} and {TEST_LOCK.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
