"""Text a browser page can be sent: :func:`unsendable` says what in a text cannot be encoded for a page or would not
show as itself (a lone surrogate, a control character), :func:`sendable` replaces it, :func:`first_unsendable`
finds the first such text in decoded JSON (docs/decisions/090)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

#: What no page text may hold: lone (unpaired) surrogates, which UTF-8 cannot encode, and control characters
#: (C0 without tab, line feed and carriage return; DEL; C1).
_BAD = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f\ud800-\udfff]")
#: The same, with tab, line feed and carriage return too (a name is one line).
_BAD_IN_LINE = re.compile(r"[\x00-\x1f\x7f-\x9f\ud800-\udfff]")
REPLACEMENT = "\ufffd"


def _what(c: str) -> str:
    code = ord(c)
    if 0xD800 <= code <= 0xDFFF:
        return f"U+{code:04X}, half of a character pair cut from its other half"
    return f"U+{code:04X}, a control character"


def unsendable(text: str, *, line: bool = False) -> str | None:
    """What in ``text`` cannot be sent to a page or shown as itself, in words; None when nothing. ``line``: tab,
    line feed and carriage return count too."""
    found = (_BAD_IN_LINE if line else _BAD).search(text)
    return None if found is None else _what(found.group())


def sendable(text: str, *, line: bool = False) -> str:
    """``text`` with every character :func:`unsendable` names replaced by U+FFFD (the text itself when clean)."""
    pattern = _BAD_IN_LINE if line else _BAD
    return text if pattern.search(text) is None else pattern.sub(REPLACEMENT, text)


def _strings(value: Any) -> Iterator[tuple[tuple[str | int, ...], str]]:
    """Every text in decoded JSON ``value`` with its path, keys too; in document order, without recursion (a
    manifest may nest as deeply as the JSON reader allows)."""
    stack: list[tuple[tuple[str | int, ...], Any]] = [((), value)]
    while stack:
        path, v = stack.pop()
        if isinstance(v, str):
            yield path, v
        elif isinstance(v, dict):
            for k, x in reversed(list(v.items())):
                stack.append(((*path, k), x))
                if isinstance(k, str):
                    stack.append(((*path, k), k))
        elif isinstance(v, (list, tuple)):
            stack.extend(((*path, i), x) for i, x in reversed(list(enumerate(v))))


def first_unsendable(value: Any) -> tuple[tuple[str | int, ...], str] | None:
    """The first text in decoded JSON ``value`` (keys included) that :func:`unsendable` refuses: (its path of keys
    and indices, what is wrong in words); None when every text can be sent."""
    for path, text in _strings(value):
        why = unsendable(text)
        if why is not None:
            return path, why
    return None


__all__ = ["REPLACEMENT", "first_unsendable", "sendable", "unsendable"]
