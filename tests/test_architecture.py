"""The layout holds: no import cycle (function-level and TYPE_CHECKING imports included), layers import only
downwards, panels use the controller and never each other, and modules and classes stay a readable size."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

STUDIO = Path(__file__).resolve().parent.parent / "studio"
#: Each layer may import only the layers listed (and itself); see ARCHITECTURE.md.
ALLOWED = {
    "core": {"core"},
    "robot_backend": {"core", "robot_backend"},
    "recorder": {"core", "robot_backend", "recorder"},
    "storage": {"core", "robot_backend", "recorder", "world", "storage"},
    "csv_io": {"core", "storage", "csv_io"},
    "teacher": {"core", "teacher"},
    "world": {"core", "robot_backend", "teacher", "world"},
    "security": {"core", "security"},
    "words": {"core", "words"},
    "controller": {"core", "robot_backend", "recorder", "storage", "csv_io", "world", "words", "controller"},
    "panels": {"core", "controller", "words", "panels"},
    "app": {"core", "robot_backend", "storage", "controller", "panels", "security", "app"},
    "commands": {"core", "robot_backend", "recorder", "storage", "csv_io", "teacher", "world", "words", "commands"},
    "cli": {"core", "storage", "app", "commands", "cli"},
}
#: "About 400 lines a module (outside studio/core), about 250 a class": past that, split by concern.
MAX_MODULE_LINES = 410
MAX_CLASS_LINES = 255
#: Merged before the split (issues 10 and 13 split them next); this set must shrink to empty, never grow.
SPLIT_PENDING: set[str] = set()


def _module_name(path: Path) -> str:
    rel = path.relative_to(STUDIO.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


MODULES = {_module_name(p): p for p in sorted(STUDIO.rglob("*.py"))}


def _imports(path: Path) -> set[str]:
    """Every studio module ``path`` imports, anywhere in the file (functions and TYPE_CHECKING blocks too)."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            full = [f"{node.module}.{a.name}" for a in node.names]
            names = [f if f in MODULES else node.module for f in full]
        out.update(n for n in names if n in MODULES)
    return out


GRAPH = {name: _imports(path) - {name} for name, path in MODULES.items()}


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "studio"


def test_no_import_cycle_even_under_type_checking() -> None:
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for n in sorted(GRAPH[m]):
            if state.get(n) == 1:
                cycle = [*stack[stack.index(n) :], n]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(GRAPH):
        if m not in state:
            visit(m)


def test_layers_import_only_downwards() -> None:
    bad = [
        f"{m} imports {n}"
        for m, deps in GRAPH.items()
        if _layer(m) in ALLOWED
        for n in deps
        if _layer(n) not in ALLOWED[_layer(m)]
    ]
    assert not bad, "\n".join(bad)


def test_core_and_controller_know_nothing_of_viser() -> None:
    for name, path in MODULES.items():
        if _layer(name) in ("core", "controller", "storage", "recorder", "robot_backend"):
            tree = ast.parse(path.read_text())
            mods = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
            mods += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
            assert not [m for m in mods if m.split(".")[0] == "viser"], f"{name} imports viser"


def test_panels_never_touch_each_other_or_private_state() -> None:
    for name, path in MODULES.items():
        if not name.startswith("studio.panels.") or name == "studio.panels":
            continue
        # studio/panels/_*.py are shared helpers (charts, slider tables, page behaviour), not panels
        others = {n for n in GRAPH[name] if n.startswith("studio.panels.") and not n.split(".")[-1].startswith("_")}
        assert not others, f"{name} imports another panel: {others}"
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute):
                chain = ast.unparse(node)
                assert ".panels" not in chain, f"{name}: {chain} reaches into another panel"
                if node.attr.startswith("_") and not node.attr.startswith("__"):
                    root = ast.unparse(node.value)
                    assert "ctl" not in root, f"{name}: {chain} reads the controller's private state"


def test_modules_and_classes_stay_readable() -> None:
    big = []
    for name, path in MODULES.items():
        src = path.read_text()
        if _layer(name) != "core" and len(src.splitlines()) > MAX_MODULE_LINES:
            big.append(f"{name}: {len(src.splitlines())} lines")
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, ast.ClassDef) and node.end_lineno is not None:
                n = node.end_lineno - node.lineno + 1
                if n > MAX_CLASS_LINES:
                    big.append(f"{name}.{node.name}: {n} lines")
    big = [b for b in big if b.split(":")[0] not in SPLIT_PENDING]
    assert not big, "\n".join(big)
