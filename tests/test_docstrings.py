"""House style of the text in studio/: module docstrings say what a module does in a few lines, and no comment or
docstring carries a timing (figures live in bench/README.md, reasons in docs/decisions/)."""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

from tests.sources import tree as parsed

STUDIO = Path(__file__).resolve().parent.parent / "studio"
DECISIONS = Path(__file__).resolve().parent.parent / "docs" / "decisions"
#: "A docstring says what a thing does in a few lines": the longest module docstring allowed, in characters.
MAX_MODULE_DOCSTRING = 600

_NUM = r"\d[\d.,]*(?:\s*[–-]\s*\d[\d.,]*)?"
_TIME = r"(?:ms|µs|us|ns|s|seconds?|minutes?)\b"
#: What a timing looks like: "~12 ms", "about 20 ms", "took 5.9 s", "30 µs an iteration", "measured … 9 ms",
#: "3-5x faster".
TIMING = re.compile(
    rf"(?:~|≈|\babout |\baround |\btook |\btakes |\bcosts? ){_NUM}\s*{_TIME}"
    rf"|{_NUM}\s*(?:ms|µs|us|ns)\s+(?:a|an|per|each)\b"
    rf"|\bmeasured\b[^\n]*?{_NUM}\s*{_TIME}"
    rf"|{_NUM}\s*[x×]\s*(?:faster|slower)\b",
    re.IGNORECASE,
)


def _modules() -> list[Path]:
    return sorted(STUDIO.rglob("*.py"))


def _texts(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every comment and docstring in ``path``."""
    src = path.read_text()
    out = [
        (tok.start[0], tok.string)
        for tok in tokenize.generate_tokens(io.StringIO(src).readline)
        if tok.type == tokenize.COMMENT
    ]
    for node in ast.walk(parsed(path)):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            doc = ast.get_docstring(node, clean=False)
            if doc and node.body:
                out.append((node.body[0].lineno, doc))
    return out


def test_module_docstrings_say_what_in_a_few_lines() -> None:
    long = []
    for path in _modules():
        doc = ast.get_docstring(parsed(path), clean=False) or ""
        if len(doc) > MAX_MODULE_DOCSTRING:
            long.append(f"{path.relative_to(STUDIO.parent)}: {len(doc)} characters")
    assert not long, "module docstrings over 600 characters (reasons go to docs/decisions/):\n" + "\n".join(long)


def test_no_comment_or_docstring_in_studio_carries_a_timing() -> None:
    found = [
        f"{path.relative_to(STUDIO.parent)}:{line}: {m.group(0)!r}"
        for path in _modules()
        for line, text in _texts(path)
        for m in TIMING.finditer(text)
    ]
    assert not found, "timings belong in bench/README.md:\n" + "\n".join(found)


def test_the_timing_pattern_finds_what_it_should() -> None:
    for text in (
        "yourdfpy's scene graph (~12 ms a pose)",
        "about 20 ms for 30,000 samples",
        "16 learns took 5.9 s serially",
        "(≈ 30 µs an iteration)",
        "measured in the same run: 9–17 ms",
        "this is 3-5x faster than stacked products",
        "OpenBLAS's thread start-up costs 5–30 ms",
    ):
        assert TIMING.search(text), text
    for text in (
        "poses are smoothed by a 50 ms moving average",
        "between 20 ms and 0.5 s",
        "grid spacing is 10 ms below that",
        "Publish a hold at the measured joints now",
        "within one 1 ms cycle",
    ):
        assert not TIMING.search(text), text


def test_every_decision_record_is_in_the_index() -> None:
    index = (DECISIONS / "README.md").read_text()
    records = sorted(p.name for p in DECISIONS.glob("[0-9][0-9][0-9]-*.md"))
    assert records, "docs/decisions/ has no records"
    missing = [r for r in records if f"]({r})" not in index]
    assert not missing, f"docs/decisions/README.md does not list {missing}"
    numbers = [r[:3] for r in records]
    assert len(numbers) == len(set(numbers)), f"two decision records share a number: {numbers}"
