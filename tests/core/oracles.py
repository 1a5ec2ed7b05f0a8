"""Test oracles: literal, slow implementations the fast code in ``studio/core`` is checked against."""

from __future__ import annotations

import math

import numpy as np

from studio.core.keypoints import KeypointSeries, precompute
from studio.core.types import Demo, KeypointParams


def extract_keypoints_reference(
    demo: Demo, params: KeypointParams | None = None, *, series: KeypointSeries | None = None
) -> np.ndarray:
    """Literal per-sample implementation of the criteria over the same derived series (the test oracle).

    Walks every sample in order, evaluates the six tests exactly as written in
    :func:`studio.core.keypoints.extract_keypoints`' docstring and the paper's equations, with the last
    key-point τ updated as it goes (far slower than the fast path: bench/README.md, "Learning pipeline").
    """
    p = params or KeypointParams()
    s = series if series is not None else precompute(demo)
    n = len(s)
    t, P, O = s.t.tolist(), s.position.tolist(), s.orientation.tolist()
    speed, aspeed = s.speed.tolist(), s.angular_speed.tolist()
    grip = set(s.gripper_events.tolist())

    def corner_flags(angle: np.ndarray, thr: float) -> list[bool]:
        a = angle.tolist()
        flags = [False] * n
        i = 0
        while i < n:
            if a[i] < thr:
                j = i
                while j < n and a[j] < thr:
                    j += 1
                run = a[i:j]
                flags[i + run.index(min(run))] = True
                i = j
            else:
                i += 1
        return flags

    cp = corner_flags(s.corner_angle, 2 * math.pi - p.eps1)
    co = corner_flags(s.corner_angle_o, 2 * math.pi - p.eps8)

    def dpos(i: int, j: int) -> float:
        a, b = P[i], P[j]
        d0, d1, d2 = a[0] - b[0], a[1] - b[1], a[2] - b[2]
        return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)

    def dori(i: int, j: int) -> float:
        a, b = O[i], O[j]
        d = abs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3])
        return 2.0 * math.acos(min(d, 1.0))

    out = [0]
    tau = 0
    max_p = max_o = 0.0  # max distance over [τ, i)
    for i in range(1, n - 1):
        dp, do = dpos(i, tau), dori(i, tau)
        el = t[i] - t[tau]
        key = (
            i in grip
            or (cp[i] and dp > p.eps4)
            or (speed[i] < p.eps2 and el > p.eps3 and dp > p.eps4)
            or (dp >= p.eps5 and el > p.eps6 and max_p < p.eps7)
            or (co[i] and do > p.eps11)
            or (aspeed[i] < p.eps9 and el > p.eps10 and do > p.eps11)
            or (do >= p.eps12 and el > p.eps13 and max_o < p.eps14)
        )
        if key:
            out.append(i)
            tau = i
            max_p = max_o = 0.0
        else:
            max_p, max_o = max(max_p, dp), max(max_o, do)
    if n > 1:
        out.append(n - 1)
    return np.asarray(out, dtype=np.int64)
