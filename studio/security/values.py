"""What a browser tab may set a GUI control to: :func:`refusal` checks one ``GuiUpdateMessage`` against its
control (a dropdown's options, a slider's range, a checkbox's truth value, a text's length) before viser stores
it or calls a panel (docs/decisions/053)."""

from __future__ import annotations

import math
from typing import Any

#: The longest text a tab may type into a text box (names have their own, shorter limit).
MAX_TEXT_CHARS = 1000


def refusal(handle: Any, updates: Any) -> str | None:
    """Why ``updates`` (a ``GuiUpdateMessage``'s) are refused for viser's GUI ``handle``; None when accepted.

    The studio's page only ever sends ``{"value": …}``; any other property (``options``, ``max``, ``disabled``)
    would let a tab change the control itself, so it is refused.
    """
    if not isinstance(updates, dict) or set(updates) != {"value"}:
        names = sorted(map(str, updates)) if isinstance(updates, dict) else []
        return f"it changes {', '.join(names)[:80] or 'nothing'} (only a value may change)"
    return value_refusal(handle, updates["value"])


def value_refusal(handle: Any, value: Any) -> str | None:
    """Why ``value`` is not a value of viser's GUI ``handle`` (None: it is)."""
    import viser

    if isinstance(handle, viser.GuiButtonHandle):
        return None if value is True else f"a button pressed with {_show(value)}"
    if isinstance(handle, (viser.GuiDropdownHandle, viser.GuiButtonGroupHandle)):
        options = tuple(handle.options)
        return None if isinstance(value, str) and value in options else f"{_show(value)} is not one of its options"
    if isinstance(handle, viser.GuiCheckboxHandle):
        return None if isinstance(value, bool) else f"{_show(value)} is not on or off"
    if isinstance(handle, viser.GuiTextHandle):
        if not isinstance(value, str):
            return f"{_show(value)} is not a text"
        if len(value) > MAX_TEXT_CHARS:
            return f"a text of {len(value):,} characters (at most {MAX_TEXT_CHARS:,})"
        return None
    if isinstance(handle, (viser.GuiSliderHandle, viser.GuiNumberHandle)):
        return _number_refusal(value, handle.min, handle.max)
    if isinstance(handle, viser.GuiMultiSliderHandle):
        return _numbers_refusal(value, len(handle.value), handle.min, handle.max)
    if isinstance(handle, (viser.GuiVector2Handle, viser.GuiVector3Handle)):
        return _numbers_refusal(value, len(handle.value), handle.min, handle.max)
    if isinstance(handle, (viser.GuiRgbHandle, viser.GuiRgbaHandle)):
        n = len(handle.value)
        ok = isinstance(value, (list, tuple)) and len(value) == n and all(_whole(v) and 0 <= v <= 255 for v in value)
        return None if ok else f"{_show(value)} is not a colour"
    # A control the studio does not use today: the value must at least be of the type it holds.
    current = handle.value
    if isinstance(current, bool) or isinstance(value, bool):
        return None if type(value) is type(current) else f"{_show(value)} is not a {type(current).__name__}"
    if isinstance(current, (int, float)):
        return _number_refusal(value, None, None)
    if isinstance(current, str):
        return None if isinstance(value, str) and len(value) <= MAX_TEXT_CHARS else f"{_show(value)} is not a text"
    return f"the control ({type(handle).__name__}) takes no value from a tab"


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _whole(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _within(v: float, lo: float | None, hi: float | None) -> bool:
    """``lo <= v <= hi`` up to a rounding of the browser's slider (a millionth of the range)."""
    slack = 1e-6 * abs(hi - lo) if lo is not None and hi is not None else 0.0
    return (lo is None or v >= lo - slack) and (hi is None or v <= hi + slack)


def _number_refusal(value: Any, lo: float | None, hi: float | None) -> str | None:
    if not _number(value):
        return f"{_show(value)} is not a number"
    if not _within(float(value), lo, hi):
        return f"{_show(value)} is outside {lo}…{hi}"
    return None


def _numbers_refusal(value: Any, n: int, lo: Any, hi: Any) -> str | None:
    if not isinstance(value, (list, tuple)) or len(value) != n or not all(_number(v) for v in value):
        return f"{_show(value)} is not {n} numbers"
    los = lo if isinstance(lo, (list, tuple)) else [lo] * n
    his = hi if isinstance(hi, (list, tuple)) else [hi] * n
    if not all(_within(float(v), a, b) for v, a, b in zip(value, los, his, strict=True)):
        return f"{_show(value)} is outside {lo}…{hi}"
    return None


def _show(value: Any) -> str:
    """A value for a log line: its type and at most 60 characters of it."""
    text = repr(value)
    return f"{type(value).__name__} {text[:60]}{'…' if len(text) > 60 else ''}"
