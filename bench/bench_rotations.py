"""Benchmark of the rotation helpers against scipy's Rotation, same run (prints figures; asserts nothing).

    .venv/bin/python bench/bench_rotations.py

On 30,000 random rotations (one demonstration at 1 kHz): the studio's function and the scipy expression
that would replace it, median ms over repeats, and their ratio. ``studio/core/rotations.py`` uses scipy
wherever it is not slower where it matters; the figures are quoted in its docstring.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _timer import median_ms

from studio.core import rotations as rot

N = 30_000


def main() -> int:
    a = Rotation.random(N, random_state=1)
    b = Rotation.random(N, random_state=2)
    qa, qb, ma = a.as_quat(scalar_first=True), b.as_quat(scalar_first=True), a.as_matrix()

    def sp(q: np.ndarray) -> Rotation:
        return Rotation.from_quat(q, scalar_first=True)

    cases: list[tuple[str, Callable[[], object], Callable[[], object]]] = [
        (
            "quat_wxyz_from_matrix",
            lambda: rot.quat_wxyz_from_matrix(ma),
            lambda: Rotation.from_matrix(ma).as_quat(canonical=True, scalar_first=True),
        ),
        ("matrix_from_quat_wxyz", lambda: rot.matrix_from_quat_wxyz(qa), lambda: sp(qa).as_matrix()),
        ("rotation_angle", lambda: rot.rotation_angle(qa, qb), lambda: (sp(qa).inv() * sp(qb)).magnitude()),
        ("quat_angle", lambda: rot.quat_angle(qa, qb), lambda: (sp(qa).inv() * sp(qb)).magnitude()),
        ("relative_rotvec", lambda: rot.relative_rotvec(qa, qb), lambda: (sp(qa).inv() * sp(qb)).as_rotvec()),
        ("relative_axis", lambda: rot.relative_axis(qa, qb), lambda: (sp(qa).inv() * sp(qb)).as_rotvec()),
    ]
    print(f"{N:,} rotations, median ms (studio's function | scipy expression | scipy / studio)")
    for name, ours, theirs in cases:
        t_ours, t_theirs = median_ms(ours, 15), median_ms(theirs, 15)
        print(f"  {name:<24}{t_ours:9.2f} {t_theirs:9.2f} {t_theirs / t_ours:8.1f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
