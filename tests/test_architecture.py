"""The layout holds: no import cycle (function-level and TYPE_CHECKING imports included), layers import only
downwards, panels use the controller and never each other, the controller's parts never take each other; and
a loose ceiling on module and class size (a review guide: split by concept, never to meet a number)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from tests.sources import tree as parsed

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
    "viser_adapter": {"core", "viser_adapter"},
    "security": {"core", "viser_adapter", "security"},
    "words": {"core", "words"},
    "controller": {"core", "robot_backend", "recorder", "storage", "csv_io", "world", "words", "controller"},
    "panels": {"core", "controller", "words", "viser_adapter", "panels"},
    "app": {"core", "robot_backend", "storage", "controller", "panels", "security", "app"},
    "commands": {
        "core",
        "robot_backend",
        "recorder",
        "storage",
        "csv_io",
        "teacher",
        "world",
        "words",
        "controller",
        "commands",
    },
    "cli": {"core", "storage", "security", "app", "commands", "cli"},  # security: an address refused first
}
#: A ceiling, not a target: below it, cohesion decides (one concept a module, one responsibility a class).
MAX_MODULE_LINES = 600
MAX_CLASS_LINES = 400


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
    for node in ast.walk(parsed(path)):
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
            tree = parsed(path)
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
        for node in ast.walk(parsed(path)):
            if isinstance(node, ast.Attribute):
                chain = ast.unparse(node)
                assert ".panels" not in chain, f"{name}: {chain} reaches into another panel"
                if node.attr.startswith("_") and not node.attr.startswith("__"):
                    root = ast.unparse(node.value)
                    assert "ctl" not in root, f"{name}: {chain} reads the controller's private state"


def _controller_parts() -> set[str]:
    """The classes ``Controller.__init__`` builds its parts from (``self.x = Part(...)``)."""
    tree = parsed(MODULES["studio.controller"])
    init = next(
        n
        for c in tree.body
        if isinstance(c, ast.ClassDef) and c.name == "Controller"
        for n in c.body
        if isinstance(n, ast.FunctionDef) and n.name == "__init__"
    )
    return {
        node.value.func.id
        for node in ast.walk(init)
        if isinstance(node, ast.Assign)
        and isinstance(node.value, ast.Call)
        and isinstance(node.value.func, ast.Name)
        and node.value.func.id[0].isupper()
        and node.value.func.id not in ("Context", "LogNotifier")
    }


def test_controller_parts_never_take_each_other() -> None:
    parts = _controller_parts()
    assert {"Teaching", "Training", "SessionActions", "ExecutionActions"} <= parts
    bad = []
    for name, path in MODULES.items():
        if _layer(name) != "controller":
            continue
        for cls in ast.walk(parsed(path)):
            if not (isinstance(cls, ast.ClassDef) and cls.name in parts):
                continue
            for fn in cls.body:
                if isinstance(fn, ast.FunctionDef) and fn.name == "__init__":
                    for a in [*fn.args.args, *fn.args.kwonlyargs]:
                        ann = ast.unparse(a.annotation) if a.annotation is not None else ""
                        if set(re.findall(r"\w+", ann)) & parts:  # names in the annotation, quoted or not
                            bad.append(f"{cls.name}.__init__({a.arg}: {ann})")
    assert not bad, "a controller part takes another part (give it a narrow Protocol or a callable):\n" + "\n".join(bad)


def test_modules_and_classes_stay_under_the_ceiling() -> None:
    big = []
    for name, path in MODULES.items():
        src = path.read_text()
        if len(src.splitlines()) > MAX_MODULE_LINES:
            big.append(f"{name}: {len(src.splitlines())} lines")
        for node in ast.walk(parsed(path)):
            if isinstance(node, ast.ClassDef) and node.end_lineno is not None:
                n = node.end_lineno - node.lineno + 1
                if n > MAX_CLASS_LINES:
                    big.append(f"{name}.{node.name}: {n} lines")
    assert not big, (
        "Past the ceiling: does this hold more than one concept? Split it by concept (what changes together stays "
        "together), not by moving helpers elsewhere to meet the number.\n" + "\n".join(big)
    )
