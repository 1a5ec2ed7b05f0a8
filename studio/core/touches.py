"""Contacts as stretches of a motion: which two things come within the margin of each other, when, how deep.

:func:`stretches` groups the rows of a :class:`~studio.core.collision.Near` per pair of parts into
:class:`Touch` facts (the rules of what may touch: :mod:`studio.world.contacts`; the words:
:func:`studio.words.touch_words`). Decisions 087 and 096."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from studio.core.collision import Near
from studio.core.robot_geometry import Part
from studio.core.types import Arm


@dataclass(frozen=True)
class Touch:
    """One stretch of a motion during which two things come within the margin of each other (a fact; its words:
    :func:`studio.words.touch_words`).

    Attributes:
        a, b: what touches what (a robot part or a carried object first; of two arms, the left first).
        t_start, t_end: the stretch (s on the motion's clock); i_start, i_end: its samples (inclusive).
        depth: how far they overlap at the deepest (m); at most 0 when they only came within the margin.
        at: when they overlap the most (s).
        carry: what ``a``'s arm carries meanwhile (None: nothing).
        new: ``b`` is an object no demonstration had.
    """

    a: Part
    b: Part
    t_start: float
    t_end: float
    i_start: int
    i_end: int
    depth: float
    at: float
    carry: str | None = None
    new: bool = False

    @property
    def arms(self) -> tuple[Arm, ...]:
        """The arms whose parts touch."""
        return tuple(p.arm for p in (self.a, self.b) if p.arm is not None)


def stretches(near: Near, parts: Sequence[Part], t: np.ndarray, *, gap_s: float = 0.1) -> list[Touch]:
    """The rows of ``near`` as stretches per pair of parts (samples closer than ``gap_s`` joined), earliest first."""
    t = np.asarray(t, dtype=np.float64)
    groups: dict[tuple[Part, Part], list[int]] = {}
    for m, (a, b) in enumerate(zip(near.a.tolist(), near.b.tolist(), strict=True)):
        pa, pb = parts[a], parts[b]
        if pa.arm == "right" and pb.arm == "left":
            pa, pb = pb, pa
        groups.setdefault((pa, pb), []).append(m)
    out: list[Touch] = []
    for (pa, pb), rows in groups.items():
        r = np.asarray(rows)
        s = near.sample[r]
        d = near.distance[r]
        order = np.argsort(s, kind="stable")
        s, d = s[order], d[order]
        cut = np.flatnonzero((np.diff(s) > 1) & (np.diff(t[s]) > gap_s * (1 + 1e-9))) + 1
        for seg_s, seg_d in zip(np.split(s, cut), np.split(d, cut), strict=True):
            k = int(np.argmin(seg_d))
            out.append(
                Touch(
                    pa,
                    pb,
                    float(t[seg_s[0]]),
                    float(t[seg_s[-1]]),
                    int(seg_s[0]),
                    int(seg_s[-1]),
                    float(-seg_d[k]),
                    float(t[seg_s[k]]),
                )
            )
    out.sort(key=lambda x: (x.t_start, -x.depth))
    return out


__all__ = ["Touch", "stretches"]
