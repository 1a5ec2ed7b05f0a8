"""Object frames: where a skill taught with objects acts, and its path rebuilt where the objects are now.

A skill learned with objects (:mod:`studio.core.segments`) is a chain of :class:`Segment` s split at its
grasps and releases (:class:`Border`), each kept in the frame of an object. :func:`adapt` places the chain
where the objects are now and joins the segments without a jump; :class:`Region` is where the demonstrations
put each object, and :func:`outside` says in plain words which object stands where none did.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from studio.core.errors import InvalidInput

ROBOT = "robot"
#: Objects that look the same from every side: their frame keeps the robot's directions (no heading).
ROUND_KINDS = frozenset({"cup"})
#: A placement this far (m) from every demonstrated one, or turned this much (rad) beyond them, is "outside".
REGION_MARGIN_M = 0.03
REGION_MARGIN_RAD = math.radians(12.0)
#: Demonstrated places closer than this (m) count as one place.
ONE_PLACE_M = 0.01
#: Segments are joined by spreading what is left of a gap over this long (s) at the start of the next one.
JOIN_S = 0.6
#: A heading difference counts as this many metres per radian when spreads are compared.
YAW_M_PER_RAD = 0.05
#: Two frames whose places relative to each other differ by less than this (m) over the demonstrations cannot be
#: told apart by them: the frame follows the task's meaning (the goal). Decision 085.
DECIDE_M = 0.02
#: The demonstrations overrule the meaning only when they agree this much (m) better in another frame.
CONTRADICT_M = 0.01


@dataclass(frozen=True)
class ObjectAt:
    """An object's pose: name, kind ("cup", "block", "pad"), bottom centre (m), heading (rad), what it rests on."""

    name: str
    kind: str
    position: tuple[float, float, float]
    yaw: float = 0.0
    on: str | None = None


@dataclass(frozen=True)
class Contact:
    """A grasp or release by the skill's arm at ``t`` s (from the demonstration's start), with every object's
    pose just after it."""

    t: float
    kind: str
    object: str
    objects: tuple[ObjectAt, ...]

    def pose(self, name: str) -> ObjectAt | None:
        return next((o for o in self.objects if o.name == name), None)


@dataclass(frozen=True)
class DemoObjects:
    """A demonstration's objects: where they stood at its start and the arm's contacts in time order."""

    start: tuple[ObjectAt, ...]
    contacts: tuple[Contact, ...]

    def start_pose(self, name: str) -> ObjectAt | None:
        return next((o for o in self.start if o.name == name), None)


def frame_of(o: ObjectAt) -> np.ndarray:
    """(4,) x, y, z, heading of an object's frame (a round object's keeps the robot's directions)."""
    return np.array([*o.position, 0.0 if o.kind in ROUND_KINDS else o.yaw], dtype=np.float64)


def _rot(yaw: float | np.ndarray) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def to_world(f: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Points (..., 3) in frame ``f`` to the robot's frame."""
    return np.asarray(p) @ _rot(f[3]).T + f[:3]


def to_local(f: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Points (..., 3) in the robot's frame to frame ``f``."""
    return (np.asarray(p) - f[:3]) @ _rot(f[3])


def turn(q: np.ndarray, yaw: float) -> np.ndarray:
    """Quaternions (..., 4) w, x, y, z turned by ``yaw`` about the vertical (left-multiplied)."""
    c, s = math.cos(yaw / 2.0), math.sin(yaw / 2.0)
    q = np.asarray(q, dtype=np.float64)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([c * w - s * z, c * x - s * y, c * y + s * x, c * z + s * w], axis=-1)


def resolve(role: str, now: Mapping[str, ObjectAt], start: Mapping[str, ObjectAt]) -> np.ndarray:
    """The frame a role names: "robot", "object:<name>" (where it is now) or "start:<name>" (where it stood)."""
    if role == ROBOT:
        return np.zeros(4)
    kind, _, name = role.partition(":")
    table = now if kind == "object" else start
    if name not in table:
        raise InvalidInput(f"The skill needs the {name}, but there is no {name} on the table: put it back.")
    return frame_of(table[name])


@dataclass(frozen=True)
class Border:
    """Where two segments meet: a "grasp" or "release" of ``object``, in the frame ``role`` names. A release
    also says where the object comes to rest in that frame: ``landed`` (x, y, z, heading)."""

    kind: str
    object: str
    role: str
    landed: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    on: str | None = None


@dataclass(frozen=True, eq=False)
class Segment:
    """One stretch between borders, learned in frame ``path_role`` (the start's or the end's).

    ``t`` (M,) s from its start; ``position`` (M, 3), ``orientation`` (M, 4) in that frame; ``gripper`` (M,).
    ``mine``/``other`` (M, 3) and ``q_mine``/``q_other`` (M, 4): the demonstrations' mean pose at each instant
    in the path's frame and in the other one; ``weight`` (M,): how much the path's frame decides (1 at the
    contact it is learned for; lower where the demonstrations agree better in the other frame).
    """

    start_role: str
    end_role: str
    path_role: str
    t: np.ndarray
    position: np.ndarray
    orientation: np.ndarray
    gripper: np.ndarray
    mine: np.ndarray
    other: np.ndarray
    q_mine: np.ndarray
    q_other: np.ndarray
    weight: np.ndarray

    @property
    def other_role(self) -> str:
        return self.end_role if self.path_role == self.start_role else self.start_role

    @property
    def duration(self) -> float:
        return float(self.t[-1])


@dataclass(frozen=True, eq=False)
class Region:
    """Where the demonstrations put one object: ``places`` (n, 3) x, y, heading, one row per demonstration."""

    name: str
    kind: str
    places: np.ndarray

    @property
    def one_place(self) -> bool:
        p = self.places[:, :2]
        return bool(np.max(np.linalg.norm(p - p.mean(axis=0), axis=1)) < ONE_PLACE_M)

    def distance(self, x: float, y: float) -> tuple[float, np.ndarray]:
        """How far (m) the point (x, y) is outside the demonstrated places' outline, and the nearest point of it."""
        pts = np.unique(np.round(self.places[:, :2], 6), axis=0)
        q = np.array([x, y])
        hull = _hull(pts)
        if len(hull) >= 3 and _inside(hull, q):
            return 0.0, q
        best, near = math.inf, pts[0]
        ring = hull if len(hull) >= 2 else pts
        for i in range(len(ring)):
            a, b = ring[i], ring[(i + 1) % len(ring)]
            ab = b - a
            u = 0.0 if not ab.any() else float(np.clip(np.dot(q - a, ab) / np.dot(ab, ab), 0.0, 1.0))
            c = a + u * ab
            d = float(np.linalg.norm(q - c))
            if d < best:
                best, near = d, c
        return best, near

    def yaw_beyond(self, yaw: float) -> float:
        """How far (rad) a heading is outside the demonstrated ones (0 for a round object)."""
        if self.kind in ROUND_KINDS:
            return 0.0
        ref = float(self.places[0, 2])
        rel = np.array([_wrap(a - ref) for a in self.places[:, 2]])
        r = _wrap(yaw - ref)
        return float(max(rel.min() - r, r - rel.max(), 0.0))


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def _hull(pts: np.ndarray) -> np.ndarray:
    """Convex hull (counter-clockwise) of 2-D points (Andrew's monotone chain; a segment or a point as is)."""
    p = sorted(map(tuple, pts))
    if len(p) <= 2:
        return np.array(p)

    def cross(o: tuple, a: tuple, b: tuple) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple] = []
    for c in p:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], c) <= 1e-12:
            lower.pop()
        lower.append(c)
    upper: list[tuple] = []
    for c in reversed(p):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], c) <= 1e-12:
            upper.pop()
        upper.append(c)
    return np.array(lower[:-1] + upper[:-1])


def _inside(hull: np.ndarray, q: np.ndarray) -> bool:
    for i in range(len(hull)):
        a, b = hull[i], hull[(i + 1) % len(hull)]
        if (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]) < -1e-12:
            return False
    return True


@dataclass(frozen=True, eq=False)
class ObjectFrames:
    """What a skill taught with objects keeps besides its path: the borders, the segments and the regions."""

    borders: tuple[Border, ...]
    segments: tuple[Segment, ...]
    regions: tuple[Region, ...] = field(default=())
    #: The clusters' centroids and the paper-mode path points (8-D) in their segment's frame, and which segment.
    local_centroids: np.ndarray = field(default_factory=lambda: np.zeros((0, 8)))
    centroid_segment: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    local_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 8)))
    point_segment: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    # -- saving -------------------------------------------------------------------------------------------
    def to_arrays(self, prefix: str = "frames_") -> dict[str, np.ndarray]:
        meta = {
            "borders": [[b.kind, b.object, b.role, list(b.landed), b.on] for b in self.borders],
            "segments": [[s.start_role, s.end_role, s.path_role] for s in self.segments],
            "regions": [[r.name, r.kind] for r in self.regions],
        }
        out = {f"{prefix}meta": np.array(json.dumps(meta))}
        for i, s in enumerate(self.segments):
            for name in _SEGMENT_ARRAYS:
                out[f"{prefix}s{i}_{name}"] = np.asarray(getattr(s, name), dtype=np.float64)
        for i, r in enumerate(self.regions):
            out[f"{prefix}r{i}"] = np.asarray(r.places, dtype=np.float64)
        out[f"{prefix}centroids"] = np.asarray(self.local_centroids, dtype=np.float64)
        out[f"{prefix}centroid_segment"] = np.asarray(self.centroid_segment, dtype=np.int64)
        out[f"{prefix}points"] = np.asarray(self.local_points, dtype=np.float64)
        out[f"{prefix}point_segment"] = np.asarray(self.point_segment, dtype=np.int64)
        return out

    @classmethod
    def from_arrays(cls, d: Mapping[str, np.ndarray], prefix: str = "frames_") -> ObjectFrames | None:
        """The frames saved by :meth:`to_arrays` (None when there are none); raises InvalidInput when damaged."""
        if f"{prefix}meta" not in d:
            return None
        try:
            meta = json.loads(str(d[f"{prefix}meta"]))
            borders = tuple(
                Border(str(k), str(o), str(r), tuple(float(x) for x in landed), None if on is None else str(on))  # type: ignore[arg-type]
                for k, o, r, landed, on in meta["borders"]
            )
            segments = tuple(
                _segment(str(a), str(b), str(p), {n: np.asarray(d[f"{prefix}s{i}_{n}"]) for n in _SEGMENT_ARRAYS})
                for i, (a, b, p) in enumerate(meta["segments"])
            )
            regions = tuple(
                Region(str(n), str(k), _finite(np.asarray(d[f"{prefix}r{i}"], dtype=np.float64).reshape(-1, 3)))
                for i, (n, k) in enumerate(meta["regions"])
            )
            cents = _finite(np.asarray(d[f"{prefix}centroids"], dtype=np.float64).reshape(-1, 8))
            points = _finite(np.asarray(d[f"{prefix}points"], dtype=np.float64).reshape(-1, 8))
            c_seg = np.asarray(d[f"{prefix}centroid_segment"], dtype=np.int64).reshape(-1)
            p_seg = np.asarray(d[f"{prefix}point_segment"], dtype=np.int64).reshape(-1)
        except (KeyError, TypeError, ValueError) as exc:
            raise InvalidInput(f"The skill's object frames are damaged ({exc}).") from exc
        n = len(segments)
        if (
            n != len(borders) + 1
            or len(c_seg) != len(cents)
            or len(p_seg) != len(points)
            or np.any((c_seg < 0) | (c_seg >= n))
            or np.any((p_seg < 0) | (p_seg >= n))
        ):
            raise InvalidInput("The skill's object frames are damaged (their parts do not match).")
        return cls(borders, segments, regions, cents, c_seg, points, p_seg)

    # -- the demonstrated region ------------------------------------------------------------------------
    def one_place(self) -> bool:
        """Every object stood in one place in all demonstrations."""
        return all(r.one_place for r in self.regions)


_SEGMENT_ARRAYS = ("t", "position", "orientation", "gripper", "mine", "other", "q_mine", "q_other", "weight")


def _finite(a: np.ndarray) -> np.ndarray:
    if not np.all(np.isfinite(a)):
        raise ValueError("not finite")
    a = np.array(a, dtype=np.float64)
    a.setflags(write=False)
    return a


def _segment(a: str, b: str, p: str, arrays: Mapping[str, np.ndarray]) -> Segment:
    m = len(arrays["t"])
    shapes = {"t": (m,), "gripper": (m,), "weight": (m,), "position": (m, 3), "mine": (m, 3), "other": (m, 3)}
    shapes |= {"orientation": (m, 4), "q_mine": (m, 4), "q_other": (m, 4)}
    checked = {}
    for name, shape in shapes.items():
        x = _finite(np.asarray(arrays[name], dtype=np.float64))
        if x.shape != shape:
            raise ValueError(f"{name} has shape {x.shape}")
        checked[name] = x
    if m < 2 or np.any(np.diff(checked["t"]) <= 0):
        raise ValueError("segment times do not increase")
    return Segment(a, b, p, **checked)


# -- placing the chain where the objects are now ---------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class AdaptedPath:
    """The skill's path where the objects are now: ``t`` (N,) s, ``position`` (N, 3), ``orientation`` (N, 4),
    ``gripper`` (N,); ``borders`` (K,) s: when each grasp or release happens; ``frames`` (K + 2, 4): the frame of
    the start, of each border and of the end."""

    t: np.ndarray
    position: np.ndarray
    orientation: np.ndarray
    gripper: np.ndarray
    borders: np.ndarray
    frames: np.ndarray


def border_frames(frames: ObjectFrames, now: Sequence[ObjectAt]) -> np.ndarray:
    """(K + 2, 4) the frames of the start, each border and the end, with the objects where they are ``now``
    (an object the skill has put down is where the demonstrations let it land)."""
    return frames_at(frames.borders, now)


def frames_at(borders: Sequence[Border], now: Sequence[ObjectAt]) -> np.ndarray:
    """:func:`border_frames` for ``borders`` alone (before a skill is learned)."""
    start = {o.name: o for o in now}
    state = dict(start)
    out = [np.zeros(4)]
    for b in borders:
        f = resolve(b.role, state, start)
        out.append(f)
        if b.kind == "release" and b.object in state:
            old = state[b.object]
            landed = np.asarray(b.landed)
            p = to_world(f, landed[:3])
            state[b.object] = ObjectAt(old.name, old.kind, (p[0], p[1], p[2]), f[3] + landed[3], b.on)
    out.append(np.zeros(4))
    return np.array(out)


def _place(seg: Segment, fa: np.ndarray, fb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A segment's positions and orientations in the robot's frame, its start in ``fa``, its end in ``fb``."""
    fp, fo = (fa, fb) if seg.path_role == seg.start_role else (fb, fa)
    pos = to_world(fp, seg.position)
    ori = turn(seg.orientation, fp[3])
    k = (1.0 - seg.weight)[:, None]
    pos = pos + k * (to_world(fo, seg.other) - to_world(fp, seg.mine))
    # the same blend for the turn: the other frame's mean orientation relative to this one's, in part
    qa, qb = turn(seg.q_mine, fp[3]), turn(seg.q_other, fo[3])
    delta = _rotvec_between(qa, qb) * k
    ori = _compose(_quat_from_rotvec(delta), ori)
    return pos, ori


def adapt(frames: ObjectFrames, now: Sequence[ObjectAt], rate_hz: float = 100.0) -> AdaptedPath:
    """The skill's path with the objects where they are ``now`` (the segments joined without a jump)."""
    F = border_frames(frames, now)
    ts: list[np.ndarray] = []
    ps: list[np.ndarray] = []
    qs: list[np.ndarray] = []
    gs: list[np.ndarray] = []
    borders: list[float] = []
    t0 = 0.0
    for k, seg in enumerate(frames.segments):
        pos, ori = _place(seg, F[k], F[k + 1])
        t = seg.t + t0
        if ps:
            gap_p, gap_q = ps[-1][-1] - pos[0], _rotvec_between(ori[0], qs[-1][-1])
            u = np.clip(seg.t / max(min(JOIN_S, 0.4 * seg.duration), 1e-6), 0.0, 1.0)
            fade = (1.0 - u**3 * (10 - 15 * u + 6 * u * u))[:, None]
            pos = pos + fade * gap_p
            ori = _compose(_quat_from_rotvec(fade * gap_q), ori)
            t, pos, ori, g = t[1:], pos[1:], ori[1:], _continued(seg.gripper, float(gs[-1][-1]))[1:]
            borders.append(t0)
        else:
            g = seg.gripper
        ts.append(t)
        ps.append(pos)
        qs.append(ori)
        gs.append(g)
        t0 = float(t[-1])
    t = np.concatenate(ts)
    q = np.concatenate(qs)
    q = _sign_continuous(q / np.linalg.norm(q, axis=1, keepdims=True))
    return AdaptedPath(t, np.concatenate(ps), q, np.concatenate(gs), np.array(borders), F)


def _continued(g: np.ndarray, before: float) -> np.ndarray:
    """A segment's gripper levels with its first level replaced by the one it follows (a segment cut in the middle
    of a close or an open starts half-way: that half-way level is not an action of its own)."""
    g = np.array(g, dtype=np.float64)
    change = np.flatnonzero(g != g[0])
    if len(change):
        g[: change[0]] = before
    return g


# -- small quaternion helpers (w, x, y, z) -------------------------------------------------------------------


def _compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = (a[..., i] for i in range(4))
    bw, bx, by, bz = (b[..., i] for i in range(4))
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def _rotvec_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) of the rotations taking ``a`` to ``b`` (b = r ∘ a), in the robot's frame."""
    conj = np.asarray(a) * np.array([1.0, -1.0, -1.0, -1.0])
    r = _compose(np.asarray(b), conj)
    r = r * np.where(r[..., :1] < 0, -1.0, 1.0)
    v = r[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    ang = 2.0 * np.arctan2(s, r[..., :1])
    return np.where(s > 1e-12, v / np.maximum(s, 1e-12) * ang, 2.0 * v)


def _quat_from_rotvec(v: np.ndarray) -> np.ndarray:
    ang = np.linalg.norm(v, axis=-1, keepdims=True)
    axis = np.where(ang > 1e-12, v / np.maximum(ang, 1e-12), 0.0)
    return np.concatenate([np.cos(ang / 2.0), axis * np.sin(ang / 2.0)], axis=-1)


def _sign_continuous(q: np.ndarray) -> np.ndarray:
    q = np.array(q)
    flips = np.einsum("ij,ij->i", q[1:], q[:-1]) < 0
    sign = np.concatenate([[1.0], np.where(np.cumsum(flips) % 2 == 1, -1.0, 1.0)])
    return q * sign[:, None]
