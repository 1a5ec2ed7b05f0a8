"""What a dropdown keeps chosen when its options change."""

from __future__ import annotations

from collections.abc import Sequence


def kept_choice(before: Sequence[str], current: str, options: Sequence[str], fallback: int) -> str:
    """``current`` while it is still offered; its new name when it alone was renamed (as many options as
    ``before``, and the one at its place is new); otherwise ``options[fallback]``."""
    if current in options:
        return current
    i = list(before).index(current) if current in before else -1
    if len(before) == len(options) and i >= 0 and options[i] not in before:
        return options[i]
    return options[fallback]
