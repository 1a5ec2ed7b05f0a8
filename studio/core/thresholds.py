"""Key-point thresholds that follow the demonstrations, one ``detail`` number, and teacher-set values (GUI-free).

:func:`auto_params` derives the paper's fourteen thresholds (metres, seconds, m/s, radians) from what was
shown (:class:`DemoStats`) and ``detail``. A :class:`ThresholdSettings` holds ``detail`` and ``teacher`` (the
thresholds set by hand, in real units; every other one is automatic); :meth:`ThresholdSettings.resolve` gives
the :class:`~studio.core.types.KeypointParams` for the demos at hand, and :meth:`ThresholdSettings.from_params`
reads older sessions. Why: docs/decisions/012."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace

import numpy as np
from scipy.ndimage import uniform_filter1d

from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.types import Demo, KeypointParams

#: Key-points per demonstration the travel-distance test aims at with detail 0 (before pauses, corners and
#: gripper events add theirs).
KEYPOINTS_PER_DEMO = 20.0
#: Each step of detail multiplies the aimed count by this.
DETAIL_STEP = 1.6
#: The range of ``detail`` (fewer ↔ more key-points).
DETAIL_MIN, DETAIL_MAX = -3.0, 3.0
#: The fourteen names.
NAMES: tuple[str, ...] = tuple(f.name for f in fields(KeypointParams))
#: Thresholds the automatic rules move (ε1, ε8, ε9 keep their defaults).
AUTO_NAMES: tuple[str, ...] = tuple(n for n in NAMES if n not in ("eps1", "eps8", "eps9"))


@dataclass(frozen=True)
class DemoStats:
    """What the automatic thresholds follow, measured on the demonstrations (medians over demos).

    Attributes:
        size: largest side of the position bounding box, m.
        path_length: length of the (50 ms smoothed) path, m.
        duration: s.
        speed: mean speed = path length ÷ duration, m/s.
        rest_speed: the hand's apparent speed while it rests (10th percentile of speed), m/s.
        rotation: how much the hand turned along the way (sum of rotation steps, smoothed), rad.
    """

    size: float
    path_length: float
    duration: float
    speed: float
    rest_speed: float
    rotation: float

    @classmethod
    def of(cls, demos: Sequence[Demo]) -> DemoStats:
        demos = [d for d in demos if len(d) >= 2]
        if not demos:
            raise NotEnoughData("There are no demonstrations to measure: record at least one.")
        size, length, dur, rest, rot = [], [], [], [], []
        for d in demos:
            t = np.asarray(d.t)
            dt = float(t[-1] - t[0]) / (len(t) - 1)
            w = max(1, round(0.05 / max(dt, 1e-9)))
            p = uniform_filter1d(np.asarray(d.position, dtype=np.float64), w, axis=0, mode="nearest")
            steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
            size.append(float(np.max(np.ptp(p, axis=0))))
            length.append(float(steps.sum()))
            dur.append(d.duration)
            h = max(1, round(0.02 / max(dt, 1e-9)))
            idx = np.arange(len(p))
            lo, hi = np.maximum(idx - h, 0), np.minimum(idx + h, len(p) - 1)
            sp = np.linalg.norm(p[hi] - p[lo], axis=1) / np.maximum(t[hi] - t[lo], 1e-12)
            rest.append(float(np.percentile(sp, 10)))
            o = np.asarray(d.orientation, dtype=np.float64)
            o = uniform_filter1d(o * np.sign(o @ o[0])[:, None], w, axis=0, mode="nearest")
            o /= np.linalg.norm(o, axis=1, keepdims=True)
            sub = o[:: max(1, round(0.05 / max(dt, 1e-9)))]
            dots = np.abs(np.einsum("ij,ij->i", sub[1:], sub[:-1]))
            rot.append(float(np.sum(2 * np.arccos(np.minimum(dots, 1.0)))))
        duration = float(np.median(dur))
        length_m = float(np.median(length))
        return cls(
            size=float(np.median(size)),
            path_length=length_m,
            duration=duration,
            speed=length_m / max(duration, 1e-9),
            rest_speed=float(np.median(rest)),
            rotation=float(np.median(rot)),
        )


def auto_params(stats: DemoStats | Sequence[Demo], detail: float = 0.0) -> KeypointParams:
    """The automatic thresholds for these demonstrations at ``detail`` (each step of +1 asks for about 1.6× as
    many key-points; why they follow the demos: docs/decisions/012).

    * ε5 travel distance = path length ÷ (:data:`KEYPOINTS_PER_DEMO` · 1.6^d), at most half the size;
      ε7 travel radius = 2 · ε5 (ε7 = ε5 with a small ε5 yields *fewer* key-points: the arm leaves the ε7
      ball before ε6 has passed);
    * ε6 travel wait = ε3 pause wait = a third of the typical time between two such key-points (ε5 ÷ mean
      speed), between 20 ms and 0.5 s; ε4 pause distance = ε5 ÷ 2;
    * ε2 pause speed = a tenth of the mean speed, at least twice the speed of the hand at rest, between
      1 mm/s and 5 cm/s; ε1 corner sharpness stays at 2π − 2.2 (an angle needs no scale);
    * orientation: ε12 = the rotation the hand goes through ÷ the same count, between 0.15 and 0.6 rad,
      ε14 = 2 · ε12, ε11 = ε12 ÷ 2, ε13 = ε10 = ε6; ε8 and ε9 keep their defaults.

    Args:
        stats: :class:`DemoStats` or the demonstrations themselves.
        detail: fewer (negative) ↔ more (positive) key-points; clipped to [DETAIL_MIN, DETAIL_MAX].
    """
    s = stats if isinstance(stats, DemoStats) else DemoStats.of(stats)
    d = float(np.clip(detail, DETAIL_MIN, DETAIL_MAX))
    count = KEYPOINTS_PER_DEMO * DETAIL_STEP**d
    base = KeypointParams()
    if s.path_length <= 1e-6:  # the hand did not move: nothing to scale on
        return base
    eps5 = min(s.path_length / count, s.size / 2.0 if s.size > 0 else math.inf)
    eps5 = max(eps5, 2e-4)
    wait = float(np.clip(eps5 / max(s.speed, 1e-6) / 3.0, 0.02, 0.5))
    eps2 = float(np.clip(max(0.1 * s.speed, 2.0 * s.rest_speed), 0.001, 0.05))
    eps12 = float(np.clip(s.rotation / count, 0.15, 0.6))
    return replace(
        base,
        eps2=eps2,
        eps3=wait,
        eps4=eps5 / 2.0,
        eps5=eps5,
        eps6=wait,
        eps7=2.0 * eps5,
        eps10=wait,
        eps11=eps12 / 2.0,
        eps12=eps12,
        eps13=wait,
        eps14=2.0 * eps12,
    )


@dataclass(frozen=True)
class ThresholdSettings:
    """``detail`` plus the thresholds the teacher set by hand (every other threshold is automatic).

    Attributes:
        detail: fewer (−) ↔ more (+) key-points, [DETAIL_MIN, DETAIL_MAX]; 0 is the automatic default.
        teacher: threshold name → value in real units, for the sliders the teacher moved.
    """

    detail: float = 0.0
    teacher: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        d = float(self.detail)
        if not math.isfinite(d):
            raise InvalidInput("The detail setting must be a number.")
        object.__setattr__(self, "detail", float(np.clip(d, DETAIL_MIN, DETAIL_MAX)))
        unknown = set(self.teacher) - set(NAMES)
        if unknown:
            raise InvalidInput(f"Unknown key-point thresholds: {', '.join(sorted(unknown))}.")
        vals = {k: float(v) for k, v in self.teacher.items()}
        KeypointParams(**vals)  # validates the values (ranges, numbers)
        object.__setattr__(self, "teacher", dict(sorted(vals.items())))

    def __hash__(self) -> int:
        return hash((self.detail, tuple(self.teacher.items())))

    def resolve(self, stats: DemoStats | Sequence[Demo]) -> KeypointParams:
        """The fourteen values for these demos: automatic ones at :attr:`detail`, the teacher's as set."""
        return replace(auto_params(stats, self.detail), **self.teacher)

    def is_auto(self, name: str) -> bool:
        return name not in self.teacher

    def set(self, name: str, value: float) -> ThresholdSettings:
        """The teacher moved one slider: keep this value (real units)."""
        if name not in NAMES:
            raise InvalidInput(f"Unknown key-point threshold {name}.")
        return replace(self, teacher={**self.teacher, name: float(value)})

    def set_many(self, values: Mapping[str, float]) -> ThresholdSettings:
        """Several values at once (e.g. a suggestion applied as one change the teacher can undo)."""
        return replace(self, teacher={**self.teacher, **{k: float(v) for k, v in values.items()}})

    def auto(self, name: str) -> ThresholdSettings:
        """Back to automatic for one threshold."""
        return replace(self, teacher={k: v for k, v in self.teacher.items() if k != name})

    def all_auto(self) -> ThresholdSettings:
        return replace(self, teacher={})

    def with_detail(self, detail: float) -> ThresholdSettings:
        return replace(self, detail=float(detail))

    def as_dict(self) -> dict[str, object]:
        return {"detail": self.detail, "teacher": dict(self.teacher)}

    @classmethod
    def from_dict(cls, d: Mapping[str, object]) -> ThresholdSettings:
        if not isinstance(d, Mapping):
            raise InvalidInput("The saved threshold settings are damaged.")
        teacher = d.get("teacher", {})
        if not isinstance(teacher, Mapping):
            raise InvalidInput("The saved threshold settings are damaged.")
        detail = d.get("detail", 0.0)
        if isinstance(detail, bool) or not isinstance(detail, (int, float)):
            raise InvalidInput("The saved detail setting must be a number.")
        return cls(detail=float(detail), teacher={str(k): float(v) for k, v in teacher.items()})

    @classmethod
    def from_params(cls, params: KeypointParams) -> ThresholdSettings:
        """Settings for a session saved with fixed thresholds only: values that differ from the old fixed
        defaults were the teacher's; the others become automatic."""
        base = KeypointParams()
        teacher = {n: getattr(params, n) for n in NAMES if not math.isclose(getattr(params, n), getattr(base, n))}
        return cls(0.0, teacher)


def detail_params(
    stats: DemoStats | Sequence[Demo], detail: float, teacher: Mapping[str, float] | None = None
) -> KeypointParams:
    """Shorthand: ``ThresholdSettings(detail, teacher).resolve(stats)``."""
    return ThresholdSettings(detail, dict(teacher or {})).resolve(stats)


__all__ = [
    "AUTO_NAMES",
    "DETAIL_MAX",
    "DETAIL_MIN",
    "DETAIL_STEP",
    "KEYPOINTS_PER_DEMO",
    "NAMES",
    "DemoStats",
    "ThresholdSettings",
    "auto_params",
    "detail_params",
]
