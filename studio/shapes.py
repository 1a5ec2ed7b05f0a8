"""Human-like demonstrations of continuous shapes (GUI-free): the quality benchmark's and tests' second teacher.

:func:`shape_demos` draws a shape of :data:`SHAPES` (circle, figure-eight, zigzag, spiral, handwriting,
wave) in the air in front of the robot as a person guiding the arm would, at any size and tempo, each demo
with its own offset, scale, turn, deformation, tempo, hesitations, tremor and sensor noise
(docs/decisions/026). :func:`shape_corners` gives the corners every demonstration shares (ground truth);
:func:`check_reachable` checks with Baxter's IK that the arm can draw it."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from studio.core.errors import InvalidInput
from studio.core.types import Arm, Demo, check_arm, readonly

if TYPE_CHECKING:
    from studio.core.kinematics import Baxter

SHAPES: tuple[str, ...] = ("circle", "figure-eight", "zigzag", "spiral", "handwriting", "wave")
#: Strokes from bottom to top around one obstacle (2 routes: on the robot's left or right of it) or two side by
#: side (3 routes: left of both, between, right of both): "around-<routes>-<route>", route 0 the leftmost.
ROUTE_SHAPES: tuple[str, ...] = ("around-2-0", "around-2-1", "around-3-0", "around-3-1", "around-3-2")
#: How a teacher draws: "careful" (the stroke starts and ends at the shape's own ends, small offsets) or "loose"
#: (each stroke starts up to 20 % of the size away and converges on the shared end, larger deformation, an
#: even tempo, recorded from the first move to the last, without rest: like a shape drawn quickly with a pen).
STYLES: tuple[str, ...] = ("careful", "loose")
_ALL_SHAPES = SHAPES + ROUTE_SHAPES

#: Centre of the drawing plane for the left arm (the right arm mirrors y), metres in Baxter's base frame. Shapes
#: are drawn on a vertical plane in front of the robot (like a whiteboard), the gripper pointing forward: with the
#: gripper pointing down, Baxter's arm reaches only about 40 cm of depth (x 0.35–0.75 m), too little for 60 cm.
CENTRE_LEFT = (0.75, 0.32, 0.15)
#: Tremor amplitude (m, per axis) and sensor noise (m, 1 σ) added to every sample.
TREMOR_M = 0.00015
SENSOR_NOISE_M = 0.00005
#: Open gripper (percent) held through a shape.
GRIPPER_OPEN = 100.0


# -- the unit shapes --------------------------------------------------------------------------------------------


def _polyline(points: list[tuple[float, float]], n_per: int = 400) -> np.ndarray:
    P = np.array(points, dtype=float)
    segs = [P[i] + np.outer(np.linspace(0.0, 1.0, n_per, endpoint=False), P[i + 1] - P[i]) for i in range(len(P) - 1)]
    return np.vstack([*segs, P[-1:]])


def _unit_curve(shape: str) -> tuple[np.ndarray, np.ndarray]:
    """Dense planar points (M, 2) of ``shape`` scaled to a largest extent of 1 and centred, and the indices of
    its sharp corners."""
    s = np.linspace(0.0, 1.0, 6001)
    corners: list[int] = []
    if shape == "circle":
        th = 2 * math.pi * s
        xy = np.column_stack([np.cos(th), np.sin(th)])
    elif shape == "figure-eight":
        th = 2 * math.pi * s  # lemniscate of Gerono
        xy = np.column_stack([np.sin(th), np.sin(th) * np.cos(th)])
    elif shape == "zigzag":
        pts = [(0.0, 0.0), (0.25, 0.6), (0.5, 0.0), (0.75, 0.6), (1.0, 0.0)]
        n_per = 1500
        xy = _polyline(pts, n_per)
        corners = [n_per * i for i in range(1, len(pts) - 1)]
    elif shape == "spiral":
        th = 2.5 * 2 * math.pi * s
        r = 0.15 + 0.85 * s
        xy = np.column_stack([r * np.cos(th), r * np.sin(th)])
    elif shape == "handwriting":
        th = 3 * 2 * math.pi * s  # prolate cycloid: three cursive loops
        xy = np.column_stack([th / (2 * math.pi) - 0.32 * np.sin(th), -0.32 * np.cos(th) + 0.08 * s])
    elif shape == "wave":
        th = 2.5 * 2 * math.pi * s  # a signature-like stroke: growing then shrinking waves with a slant
        env = 0.25 + 0.75 * np.sin(math.pi * s)
        xy = np.column_stack([s + 0.04 * np.sin(th), 0.3 * env * np.sin(th)])
    elif shape in ROUTE_SHAPES:
        _, n_routes, route = shape.split("-")
        # from (0, -0.5) to (0, 0.5); the detour's lateral offset, flat while passing the obstacle(s)
        lateral = {"2": (0.3, -0.3), "3": (0.42, 0.0, -0.42)}[n_routes][int(route)]
        bump = np.clip(1.6 * np.sin(math.pi * s), 0.0, 1.0)
        bump = bump * bump * (3.0 - 2.0 * bump)  # smoothstep: leaves and rejoins the straight line smoothly
        xy = np.column_stack([lateral * bump, s - 0.5])
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        return xy - np.array([0.0, (lo[1] + hi[1]) / 2]), np.asarray(corners, dtype=np.int64)
    else:
        raise InvalidInput(f'Unknown shape "{shape}": choose one of {", ".join(_ALL_SHAPES)}.')
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    xy = (xy - (lo + hi) / 2) / float(np.max(hi - lo))
    return xy, np.asarray(corners, dtype=np.int64)


@lru_cache(maxsize=16)
def _arc_param(shape: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit shape resampled uniformly in arc length: (u (M,), xy (M, 2), corner arc fractions)."""
    xy, corners = _unit_curve(shape)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    u = arc / arc[-1]
    return u, xy, u[corners]


# -- one demonstration ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ShapeSpec:
    """What a teacher draws: a shape, how big (largest extent, m), how long the stroke takes (s), which arm, and
    how (:data:`STYLES`)."""

    shape: str
    size: float
    duration: float
    arm: Arm = "left"
    style: str = "careful"

    def __post_init__(self) -> None:
        if self.shape not in _ALL_SHAPES:
            raise InvalidInput(f'Unknown shape "{self.shape}": choose one of {", ".join(_ALL_SHAPES)}.')
        if self.style not in STYLES:
            raise InvalidInput(f'Unknown style "{self.style}": choose one of {", ".join(STYLES)}.')
        if not (0.005 <= self.size <= 0.8) or not (0.5 <= self.duration <= 120.0):
            raise InvalidInput("A shape is 5 mm to 80 cm across and takes 0.5 s to 2 minutes.")
        check_arm(self.arm)

    @property
    def centre(self) -> np.ndarray:
        c = np.array(CENTRE_LEFT)
        return c if self.arm == "left" else c * np.array([1.0, -1.0, 1.0])


def _smooth_noise(rng: np.random.Generator, x: np.ndarray, n_modes: int, amplitude: float) -> np.ndarray:
    """A smooth random function of x in [0, 1]: a few sine modes with random phases, RMS ≈ amplitude."""
    out = np.zeros_like(x)
    for k in range(1, n_modes + 1):
        out += rng.normal(0.0, 1.0) / k * np.sin(math.pi * k * x + rng.uniform(0, 2 * math.pi))
    return out * amplitude / math.sqrt(sum(1.0 / k**2 for k in range(1, n_modes + 1)) / 2.0)


def _progress(rng: np.random.Generator, u_nodes: np.ndarray, corner_u: np.ndarray, n: int) -> np.ndarray:
    """Arc-length progress (n,) in [0, 1] over n equal time steps: a human speed profile.

    Speed rises and falls smoothly at the ends, wanders (time warp), dips almost to zero at 1–2 hesitations
    and at sharp corners, and is then integrated and scaled so the stroke ends exactly at the end of the path.
    """
    tau = np.linspace(0.0, 1.0, n)
    speed = np.sin(math.pi * np.clip(tau, 0, 1)) ** 0.6 + 1e-3  # smooth start and stop
    speed *= np.exp(_smooth_noise(rng, tau, 4, 0.22))  # tempo wanders ±25 %
    for _ in range(int(rng.integers(1, 3))):  # hesitations
        c, w = rng.uniform(0.2, 0.8), rng.uniform(0.02, 0.05)
        speed *= 1.0 - 0.92 * np.exp(-0.5 * ((tau - c) / w) ** 2)
    s = np.cumsum(speed)
    s = (s - s[0]) / (s[-1] - s[0])
    if corner_u.size:  # slow down at the corners: warp progress so time is spent near each corner
        for cu in corner_u:
            # find when the progress passes the corner and dip the speed there (re-integrate)
            tc = float(np.interp(cu, s, tau))
            speed *= 1.0 - 0.97 * np.exp(-0.5 * ((tau - tc) / 0.025) ** 2)
        s = np.cumsum(speed)
        s = (s - s[0]) / (s[-1] - s[0])
    return s


def _loose_progress(rng: np.random.Generator, n: int) -> np.ndarray:
    """Arc-length progress (n,) of a quick, even stroke: a bell-shaped speed, a mild time warp, no hesitation."""
    tau = np.linspace(0.0, 1.0, n)
    speed = np.sin(math.pi * tau) ** 1.5 + 1e-3
    speed *= np.exp(_smooth_noise(rng, tau, 3, 0.1))
    s = np.cumsum(speed)
    return (s - s[0]) / (s[-1] - s[0])


def shape_demo(spec: ShapeSpec, seed: int, *, rate_hz: float = 1000.0, name: str | None = None) -> Demo:
    """One human-like demonstration of ``spec`` (its variation: docs/decisions/026); deterministic for a given seed.

    Returns:
        A :class:`Demo`: rest, stroke, rest; about ``spec.duration`` × (0.85–1.15) s of stroke plus 0.2–0.5 s
        of rest at each end, sampled at ``rate_hz``; gripper open; no joint angles.
    """
    key = [seed, _ALL_SHAPES.index(spec.shape), round(spec.size * 1e4), round(spec.duration * 10)]
    loose = spec.style == "loose"
    rng = np.random.default_rng([*key, STYLES.index(spec.style)] if loose else key)
    u_nodes, xy_unit, corner_u = _arc_param(spec.shape)
    size = spec.size
    stroke = spec.duration * rng.uniform(0.85, 1.15)
    rest0, rest1 = rng.uniform(0.2, 0.5), rng.uniform(0.2, 0.5)
    n_stroke = max(50, round(stroke * rate_hz))
    n0, n1 = (0, 0) if loose else (round(rest0 * rate_hz), round(rest1 * rate_hz))  # a loose stroke never rests
    s = _loose_progress(rng, n_stroke) if loose else _progress(rng, u_nodes, corner_u, n_stroke)
    s = np.concatenate([np.zeros(n0), s, np.ones(n1)])
    n = s.shape[0]
    t = np.arange(n) / rate_hz
    # geometry: the unit shape at progress s, deformed, scaled, turned, offset
    x = np.interp(s, u_nodes, xy_unit[:, 0])
    y = np.interp(s, u_nodes, xy_unit[:, 1])
    deform = 0.04 if loose else 0.015
    x = x + _smooth_noise(rng, s, 3, deform)
    y = y + _smooth_noise(rng, s, 3, deform)
    if loose:  # the pen lands away from the shape's start and converges on it by mid-stroke
        land = rng.uniform(0.05, 0.2) * np.array([math.cos(a := rng.uniform(0, 2 * math.pi)), math.sin(a)])
        fade = np.clip(1.0 - s / 0.6, 0.0, 1.0) ** 2
        x, y = x + land[0] * fade, y + land[1] * fade
    ang = math.radians(rng.normal(0.0, 3.0))
    scale = size * (1.0 + rng.uniform(-0.04, 0.04))
    c, sn = math.cos(ang), math.sin(ang)
    px, py = scale * (c * x - sn * y), scale * (sn * x + c * y)
    depth = _smooth_noise(rng, s, 2, 0.01 * size) + 0.002 * (s - 0.5) * rng.normal()
    offset = rng.normal(0.0, max((0.01 if loose else 0.03) * size, 0.001), 3) * np.array([0.5, 1.0, 1.0])
    pos = np.column_stack([depth, px, py]) + spec.centre + offset
    if spec.arm == "right":
        pos[:, 1] = 2 * spec.centre[1] - pos[:, 1]  # mirrored drawing for the right hand
    # tremor (8–12 Hz, per axis) and sensor noise
    for k in range(3):
        f = rng.uniform(8.0, 12.0)
        pos[:, k] += (
            TREMOR_M
            * np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi))
            * (1.0 + 0.3 * np.sin(2 * math.pi * 0.7 * t))
        )
    pos += rng.normal(0.0, SENSOR_NOISE_M, pos.shape)
    # orientation: pointing forward, a slow wobble of a couple of degrees
    yaw = rng.normal(0.0, 0.05) + _smooth_noise(rng, t / max(t[-1], 1e-9), 3, 0.02)
    tilt = np.column_stack([_smooth_noise(rng, t / max(t[-1], 1e-9), 3, 0.015) for _ in range(2)] + [np.zeros(n)])
    rot = Rotation.from_rotvec(tilt) * Rotation.from_euler("x", yaw[:, None]) * Rotation.from_euler("y", math.pi / 2)
    xyzw = rot.as_quat()
    wxyz = np.column_stack([xyzw[:, 3], xyzw[:, :3]])
    flips = np.einsum("ij,ij->i", wxyz[1:], wxyz[:-1]) < 0
    wxyz *= np.where(np.concatenate([[False], np.cumsum(flips) % 2 == 1]), -1.0, 1.0)[:, None]
    grip = np.full(n, GRIPPER_OPEN)
    return Demo(t, pos, wxyz, grip, name=name or f"{spec.shape} {seed + 1}")


@lru_cache(maxsize=128)
def shape_demos(spec: ShapeSpec, n_demos: int = 3, *, first_seed: int = 0, rate_hz: float = 1000.0) -> tuple[Demo, ...]:
    """``n_demos`` demonstrations of ``spec`` (seeds ``first_seed`` …), named "demo 1", "demo 2", … (cached)."""
    if n_demos < 1:
        raise InvalidInput("Ask for at least one demonstration.")
    return tuple(shape_demo(spec, first_seed + i, rate_hz=rate_hz, name=f"demo {i + 1}") for i in range(int(n_demos)))


def route_demos(
    n_routes: int, size: float, duration: float, n_demos: int, *, seed: int = 0, style: str = "careful"
) -> tuple[tuple[Demo, ...], tuple[int, ...]]:
    """``n_demos`` demonstrations that go ``n_routes`` (2 or 3) ways around obstacles (:data:`ROUTE_SHAPES`),
    every route taken at least once, the routes shuffled among the demos by ``seed``.

    Returns:
        (the demos, named "demo 1", …; the route each one takes, 0 = the robot's leftmost).
    """
    if n_routes not in (2, 3) or n_demos < n_routes:
        raise InvalidInput("Ask for 2 or 3 routes and at least one demonstration per route.")
    rng = np.random.default_rng([seed, n_routes, n_demos, round(size * 1e4)])
    routes = [i % n_routes for i in range(n_demos)]
    rng.shuffle(routes)
    specs = [ShapeSpec(f"around-{n_routes}-{r}", size, duration, style=style) for r in routes]
    demos = tuple(shape_demo(sp, 100 * seed + i, name=f"demo {i + 1}") for i, sp in enumerate(specs))
    return demos, tuple(int(r) for r in routes)


def shape_corners(spec: ShapeSpec, seed: int = 0) -> np.ndarray:
    """The sharp corners of a shape for demonstration ``seed`` (positions (C, 3), metres; empty if none)."""
    d = shape_demo(spec, seed)
    _, _, corner_u = _arc_param(spec.shape)
    if corner_u.size == 0:
        return readonly(np.zeros((0, 3)))
    # the corner is where the (noise-free) progress passes corner_u: the slowest sample near it
    from scipy.ndimage import uniform_filter1d

    p = uniform_filter1d(d.position, 25, axis=0, mode="nearest")
    v = np.linalg.norm(np.gradient(p, d.t, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    frac = arc / arc[-1]
    out = []
    for cu in corner_u:
        near = np.flatnonzero(np.abs(frac - cu) < 0.03)
        out.append(p[near[np.argmin(v[near])]])
    return readonly(np.array(out))


@lru_cache(maxsize=2)
def ready_pose(arm: Arm = "left") -> np.ndarray:
    """(7,) joint angles holding the gripper at the drawing plane's centre, pointing forward: the seed for IK
    along a shape (the studio's untuck pose points the gripper down, too far from this for one IK solve)."""
    from studio.core.kinematics import Baxter

    b = Baxter.load()
    check_arm(arm)
    centre = np.array(CENTRE_LEFT) * (np.array([1.0, -1.0, 1.0]) if arm == "right" else 1.0)
    xyzw = Rotation.from_euler("y", math.pi / 2).as_quat()
    wxyz = np.r_[xyzw[3], xyzw[:3]]
    lo, hi = b.lower_limits(arm), b.upper_limits(arm)
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    rng = np.random.default_rng(7)
    best, best_cost = None, math.inf
    for k in range(24):
        seed = b.neutral(arm) if k == 0 else b.random_configuration(arm, rng)
        r = b.ik(arm, centre, wxyz, seed, max_iterations=300)
        if r.position_error < 1e-4 and r.orientation_error < 1e-3:
            cost = float(np.max(np.abs(r.q - mid) / half))  # stay away from the joint limits
            if cost < best_cost:
                best, best_cost = np.array(r.q), cost
    if best is None:  # pragma: no cover - the centre is chosen reachable
        raise RuntimeError("The drawing plane's centre cannot be reached.")
    best.setflags(write=False)
    return best


def check_reachable(
    spec: ShapeSpec, seed: int = 0, *, every_s: float = 0.05, baxter: Baxter | None = None
) -> tuple[float, float]:
    """Follow one demonstration of ``spec`` with Baxter's IK (each solve seeded by the previous one).

    A sample where the warm-started solve got trapped at a joint limit is solved again from :func:`ready_pose`
    and a few other seeds (the arm could have been held differently there): the check is that every pose is
    within the arm's reach, not that one damped-least-squares tracker follows the whole stroke (on 60 cm circles
    it drifts into a joint limit: a matter for execution, which the quality report measures separately).

    Returns:
        (largest position error m, largest orientation error rad) over the samples every ``every_s`` seconds.
    """
    from studio.core.kinematics import Baxter

    b = baxter or Baxter.load()
    d = shape_demo(spec, seed)
    rng = np.random.default_rng(11)
    step = max(1, round(every_s / float(np.median(np.diff(d.t)))))
    idx = np.arange(0, len(d), step)
    res = b.ik(spec.arm, d.position[0], d.orientation[0], ready_pose(spec.arm), max_iterations=500)
    q = res.q
    worst_p = worst_o = 0.0
    for i in idx:
        r = b.ik(spec.arm, d.position[i], d.orientation[i], q, max_iterations=200)
        if r.position_error > 1e-3 or r.orientation_error > 1e-2:  # the warm start got trapped at a limit
            seeds = [ready_pose(spec.arm), *b.random_configuration(spec.arm, rng, 8)]
            for s0 in seeds:
                r2 = b.ik(spec.arm, d.position[i], d.orientation[i], s0, max_iterations=300)
                if r2.position_error + 0.1 * r2.orientation_error < r.position_error + 0.1 * r.orientation_error:
                    r = r2
                if r.position_error <= 1e-3 and r.orientation_error <= 1e-2:
                    break
        q = r.q
        worst_p, worst_o = max(worst_p, r.position_error), max(worst_o, r.orientation_error)
    return worst_p, worst_o


def joint_angles(demo: Demo, arm: Arm, *, knots_hz: float = 50.0, baxter: Baxter | None = None) -> np.ndarray:
    """(N, 7) joint angles that draw ``demo`` with ``arm`` (IK at ``knots_hz``, cubic between), e.g. to seed
    execution like a recording's joints."""
    from studio.core.kinematics import Baxter

    b = baxter or Baxter.load()
    step = max(1, round((1.0 / knots_hz) / float(np.median(np.diff(demo.t)))))
    idx = np.unique(np.concatenate([np.arange(0, len(demo), step), [len(demo) - 1]]))
    q = b.ik(arm, demo.position[0], demo.orientation[0], ready_pose(arm), max_iterations=500).q
    qs = np.empty((idx.shape[0], 7))
    for j, i in enumerate(idx):
        q = b.ik(arm, demo.position[i], demo.orientation[i], q, max_iterations=200).q
        qs[j] = q
    return CubicSpline(demo.t[idx], qs, axis=0)(demo.t)


__all__ = [
    "CENTRE_LEFT",
    "ROUTE_SHAPES",
    "SHAPES",
    "STYLES",
    "ShapeSpec",
    "check_reachable",
    "joint_angles",
    "ready_pose",
    "route_demos",
    "shape_corners",
    "shape_demo",
    "shape_demos",
]
