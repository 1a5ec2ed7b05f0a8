"""The studio's Python sources as syntax trees, parsed once in a child process.

CPython 3.11's ``ast.parse`` shares its recursion counter between threads (python/cpython#106905): a traceback
formatted at the same moment in another thread (3.11 parses the failing line to draw its carets) makes it raise
``SystemError``. A child process has no such threads.
"""

from __future__ import annotations

import ast
import functools
import pickle
import subprocess
import sys
from pathlib import Path

_CHILD = """
import ast, pickle, sys
paths = sys.stdin.read().split("\\n")
sys.stdout.buffer.write(pickle.dumps({p: ast.parse(open(p, encoding="utf-8").read(), p) for p in paths if p}))
"""


@functools.cache
def _trees(root: Path) -> dict[str, ast.Module]:
    paths = "\n".join(str(p) for p in sorted(root.rglob("*.py")))
    out = subprocess.run([sys.executable, "-c", _CHILD], input=paths.encode(), capture_output=True, check=True)
    return pickle.loads(out.stdout)


def tree(path: Path) -> ast.Module:
    """The syntax tree of ``path`` (a file under ``studio/`` or ``tests/``)."""
    root = Path(__file__).resolve().parents[1]
    top = root / Path(path).resolve().relative_to(root).parts[0]
    return _trees(top)[str(Path(path).resolve())]
