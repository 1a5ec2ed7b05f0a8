"""Small SVG charts for the side panel (heat map, position over time): presentation only, no learning."""

from __future__ import annotations

import html
from collections.abc import Sequence

import numpy as np

AXIS_COLORS = ("#d62728", "#2ca02c", "#1f77b4")  # x red, y green, z blue (as the scene's axes)


def heatmap_svg(m: np.ndarray, *, title: str, size: int = 300, css_class: str = "heatmap") -> str:
    """Transition matrix as a white→dark-blue heat map with state numbers on the axes (rows: from, columns: to)."""
    m = np.asarray(m, dtype=float)
    n = m.shape[0]
    pad = 22
    cell = (size - pad) / max(n, 1)
    parts = [
        f'<svg class="{css_class}" data-states="{n}" width="100%" viewBox="0 0 {size} {size + 14}" '
        f'xmlns="http://www.w3.org/2000/svg" style="font-family:sans-serif">',
        f'<text x="{size / 2}" y="11" font-size="11" text-anchor="middle">{html.escape(title)}</text>',
        f'<text x="{size - 2}" y="{14 + 9}" font-size="7" text-anchor="end" fill="#555">to state →</text>',
        f'<text x="2" y="{size + 12}" font-size="7" fill="#555">↑ from state (probability of each step)</text>',
    ]
    top = 14
    for i in range(n):
        for j in range(n):
            v = float(np.clip(m[i, j], 0.0, 1.0))
            r, g, b = (int(255 - v * (255 - c)) for c in (8, 48, 107))
            parts.append(
                f'<rect x="{pad + j * cell:.2f}" y="{top + pad + i * cell:.2f}" width="{cell + 0.3:.2f}" '
                f'height="{cell + 0.3:.2f}" fill="rgb({r},{g},{b})"><title>from {i} to {j}: {v:.2f}</title></rect>'
            )
    step = max(1, n // 10)
    for i in range(0, n, step):
        parts.append(
            f'<text x="{pad - 3}" y="{top + pad + (i + 0.7) * cell:.1f}" font-size="8" text-anchor="end">{i}</text>'
        )
        parts.append(
            f'<text x="{pad + (i + 0.5) * cell:.1f}" y="{top + pad - 4}" font-size="8" text-anchor="middle">{i}</text>'
        )
    parts.append("</svg>")
    return "".join(parts)


def position_plot_svg(
    t: np.ndarray,
    position: np.ndarray,
    keypoints: Sequence[int] | np.ndarray,
    *,
    title: str,
    color: tuple[int, int, int],
    width: int = 320,
    height: int = 150,
    max_points: int = 400,
) -> str:
    """The paper's "position over time": x, y, z (m, on the left axis) against time (s, along the bottom),
    key-points marked with triangles."""
    t = np.asarray(t, dtype=float)
    p = np.asarray(position, dtype=float)
    if len(t) < 2:
        return f"<div>{html.escape(title)}: too short to plot.</div>"
    step = max(1, len(t) // max_points)
    sel = np.arange(0, len(t), step)
    left, right, top, bottom = 40, 8, 16, 18
    w, h = width - left - right, height - top - bottom
    t0, t1 = float(t[0]), float(t[-1])
    lo, hi = float(p.min()), float(p.max())
    if hi - lo < 1e-6:
        hi = lo + 1e-3

    def sx(v: np.ndarray | float) -> np.ndarray:
        return left + (np.asarray(v) - t0) / max(t1 - t0, 1e-9) * w

    def sy(v: np.ndarray | float) -> np.ndarray:
        return top + (1.0 - (np.asarray(v) - lo) / (hi - lo)) * h

    kp = np.asarray(list(keypoints), dtype=int)
    parts = [
        f'<svg class="position-plot" data-keypoints="{len(kp)}" width="100%" viewBox="0 0 {width} {height}" '
        f'xmlns="http://www.w3.org/2000/svg" style="font-family:sans-serif">',
        f'<text x="{left}" y="11" font-size="10" fill="rgb{color}">{html.escape(title)}</text>',
        f'<rect x="{left}" y="{top}" width="{w}" height="{h}" fill="none" stroke="#bbb" stroke-width="0.5"/>',
        f'<text x="{left - 3}" y="{top + 7}" font-size="8" text-anchor="end">{hi:.2f} m</text>',
        f'<text x="{left - 3}" y="{top + h}" font-size="8" text-anchor="end">{lo:.2f} m</text>',
        f'<text x="{left}" y="{height - 4}" font-size="8">{t0:.0f} s</text>',
        f'<text x="{left + w / 2}" y="{height - 4}" font-size="8" text-anchor="middle">time, s</text>',
        f'<text x="{left + w}" y="{height - 4}" font-size="8" text-anchor="end">{t1:.1f} s</text>',
    ]
    for c in range(3):
        xs, ys = sx(t[sel]), sy(p[sel, c])
        pts = " ".join(f"{x:.1f},{y:.1f}" for x, y in zip(xs, ys, strict=True))
        parts.append(f'<polyline points="{pts}" fill="none" stroke="{AXIS_COLORS[c]}" stroke-width="1"/>')
        for i in kp:
            if 0 <= i < len(t):
                x, y = float(sx(t[i])), float(sy(p[i, c]))
                parts.append(
                    f'<path d="M{x:.1f},{y - 3.2:.1f} L{x + 3:.1f},{y + 2:.1f} L{x - 3:.1f},{y + 2:.1f} Z" '
                    f'fill="rgb{color}" stroke="#222" stroke-width="0.4"/>'
                )
    parts.append(  # on the title line, above the plot: never over a curve
        f'<text class="legend" x="{left + w}" y="11" font-size="8" text-anchor="end">'
        f'<tspan fill="{AXIS_COLORS[0]}">x</tspan> <tspan fill="{AXIS_COLORS[1]}">y</tspan> '
        f'<tspan fill="{AXIS_COLORS[2]}">z</tspan> ▲ key-point</text>'
    )
    parts.append("</svg>")
    return "".join(parts)


#: The robot's run in the scene (:mod:`studio.panels.run`), told in Preview's legend: where the gripper really went
#: (the plan, the learned path, is cyan) and the planned way from where the robot was to the skill's start.
EXECUTED_COLOR = (200, 0, 170)
APPROACH_COLOR = (120, 120, 140)


def downsample_path(points: np.ndarray, max_points: int = 600) -> np.ndarray:
    """Every k-th point of a (N, 3) path (keeping the last) so a 30,000-sample demo draws quickly."""
    n = len(points)
    if n <= max_points:
        return np.asarray(points)
    idx = np.unique(np.concatenate([np.linspace(0, n - 1, max_points).astype(int), [n - 1]]))
    return np.asarray(points)[idx]


def segments(points: np.ndarray) -> np.ndarray:
    """(N-1, 2, 3) line segments joining consecutive points (viser's add_line_segments)."""
    p = np.asarray(points, dtype=np.float32)
    if len(p) < 2:
        return np.zeros((0, 2, 3), dtype=np.float32)
    return np.stack([p[:-1], p[1:]], axis=1)


def dashes(points: np.ndarray, n: int = 120) -> np.ndarray:
    """(n, 2, 3) segments of a dashed line along a (N, 3) path: the path cut into 2n equal lengths, every other
    one drawn (a fixed count, so a redrawn path updates the same scene node in place)."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) < 2:
        return np.zeros((0, 2, 3), dtype=np.float32)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    if s[-1] <= 1e-9:
        return np.zeros((0, 2, 3), dtype=np.float32)
    keep = np.concatenate([[True], np.diff(s) > 0])
    u = np.linspace(0.0, s[-1], 2 * n + 1)
    q = np.column_stack([np.interp(u, s[keep], p[keep, k]) for k in range(3)]).astype(np.float32)
    return np.stack([q[0:-1:2], q[1::2]], axis=1)
