"""Which arm is which: one place that maps an arm to its joint and gripper columns, and reads arm choices.

Joint order everywhere is :data:`~studio.core.types.ALL_ARM_JOINTS` (left s0..w2, then right s0..w2);
grippers are two columns, left then right.
"""

from __future__ import annotations

from collections.abc import Iterable

from studio.core.errors import InvalidInput
from studio.core.types import ARMS, Arm, check_arm

_COLUMNS: dict[Arm, slice] = {"left": slice(0, 7), "right": slice(7, 14)}
_GRIPPER: dict[Arm, int] = {"left": 0, "right": 1}


def arm_columns(arm: Arm) -> slice:
    """The columns of ``arm``'s 7 joints in a (…, 14) joint array."""
    return _COLUMNS[check_arm(arm)]


def gripper_column(arm: Arm) -> int:
    """The column of ``arm``'s gripper in a (…, 2) gripper array."""
    return _GRIPPER[check_arm(arm)]


def arm_of_joint(index: int) -> Arm:
    """The arm that joint ``index`` (0–13, order ALL_ARM_JOINTS) belongs to."""
    return "left" if index < 7 else "right"


def normalize_arms(arms: str | Iterable[str]) -> tuple[Arm, ...]:
    """A choice of taught arm(s) as a tuple in the canonical order ("left" before "right").

    Accepts "left", "right", "both" (an unknown single name raises :class:`InvalidInput`), or any iterable of
    arm names (unknown ones are ignored); an empty choice raises :class:`InvalidInput`.
    """
    if isinstance(arms, str):
        arms = ARMS if arms == "both" else (check_arm(arms),)
    chosen = set(arms)
    out = tuple(a for a in ARMS if a in chosen)
    if not out:
        raise InvalidInput('Choose the taught arm(s): "left", "right" or both.')
    return out
