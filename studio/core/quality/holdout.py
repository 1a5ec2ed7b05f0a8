"""Held-out fidelity: learn from all demonstrations but one and measure the learned path on the one left out
(leave-one-demo-out), for as many folds as asked."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from studio.core.errors import NotEnoughData, StudioError
from studio.core.quality.curves import curve, frechet_pairs, ndtw, spread
from studio.core.types import Demo


@dataclass(frozen=True)
class HeldOut:
    """Leave-one-demo-out: a skill learned without demo i, measured on demo i.

    Attributes:
        distance: root of the mean over folds of the normalised DTW to the left-out demo, m.
        g_over_r: that mean ÷ the demos' mean pairwise normalised DTW (G/R held out).
        frechet: mean over folds of the Fréchet distance to the left-out demo, m.
        per_demo: the root normalised DTW of each fold, m (NaN where learning failed).
        failed: folds where learning failed (their demo indices).
    """

    distance: float
    g_over_r: float
    frechet: float
    per_demo: tuple[float, ...]
    failed: tuple[int, ...] = ()


def held_out(
    demos: Sequence[Demo],
    learn: Callable[[list[Demo]], Demo],
    *,
    r: float | None = None,
    folds: Sequence[int] | None = None,
    demo_curves: Sequence[np.ndarray] | None = None,
) -> HeldOut:
    """Leave-one-demo-out fidelity: ``learn(other demos)`` returns a trajectory, measured on the left-out demo.

    Args:
        demos: at least two demonstrations.
        learn: a function from a list of demos to the learned trajectory (a :class:`Demo`); a
            :class:`~studio.core.errors.StudioError` it raises marks the fold as failed.
        r: the demos' spread if known.
        folds: which demos to leave out (default all).
    """
    demos = list(demos)
    if len(demos) < 2:
        raise NotEnoughData("Held-out fidelity needs at least two demonstrations.")
    curves = list(demo_curves) if demo_curves is not None else [curve(d) for d in demos]
    if r is None:
        r = spread(curves)[0]
    idx = list(range(len(demos))) if folds is None else list(folds)
    per, pairs, failed = [], [], []
    for i in idx:
        try:
            tr = learn([d for j, d in enumerate(demos) if j != i])
        except StudioError:
            failed.append(i)
            per.append(float("nan"))
            continue
        c = curve(tr)
        per.append(ndtw(c, curves[i]))
        pairs.append((c, curves[i]))
    fr = frechet_pairs(pairs)
    ok = [p for p in per if math.isfinite(p)]
    g = float(np.mean(ok)) if ok else float("inf")
    return HeldOut(
        distance=math.sqrt(g),
        g_over_r=g / r if r > 0 else float("nan"),
        frechet=float(np.mean(fr)) if fr else float("inf"),
        per_demo=tuple(math.sqrt(p) if math.isfinite(p) else p for p in per),
        failed=tuple(failed),
    )
