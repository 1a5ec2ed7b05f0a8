"""What one learning is asked to do (:class:`LearnSettings`): thresholds, k, the path's mode, the frames, which
way, how it is judged. Every field has the studio's default."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from studio.core.errors import InvalidInput
from studio.core.generalize import SMOOTHING
from studio.core.thresholds import ThresholdSettings, auto_params
from studio.core.types import DEFAULT_GENERALIZATION, FRAMES, GENERALIZATIONS, Demo, Generalization, KeypointParams

#: The paper mode's path points (docs/decisions/004).
SPLINE_THROUGH = ("state-means", "centroids")


@dataclass(frozen=True)
class LearnSettings:
    """How to learn (and judge) one arm's skill.

    Attributes:
        params: key-point thresholds: fixed values, :class:`ThresholdSettings` resolved for the demonstrations,
            or None (automatic for them, :func:`studio.core.thresholds.auto_params`).
        n_clusters: k (None: the mean number of key-points per demonstration); a skill judged with a k chosen by
            hand is held out with the same k.
        seed: seed for k-means and hmmlearn.
        generalization: "aligned-mean" (default) or "paper" (docs/decisions/003).
        spline_through: paper mode's path points, "state-means" (default) or "centroids".
        smoothing: the paper's spline smoothing.
        frames: "objects" (each stretch follows the object it acts on, when the demonstrations' objects allow)
            or "robot" (the paper: one path in the robot's frame).
        route: when the demos go several ways, which one to learn (None: the way most go; a way that no longer
            exists is the default again).
        split_routes: False learns from every demo even when they go several ways (a part of an object-relative
            skill, whose parts must keep every demo).
        folds: at most this many demonstrations are left out in turn when the skill is judged.
    """

    params: KeypointParams | ThresholdSettings | None = None
    n_clusters: int | None = None
    seed: int = 0
    generalization: Generalization | str = DEFAULT_GENERALIZATION
    spline_through: str = "state-means"
    smoothing: float = SMOOTHING
    frames: str = "objects"
    route: int | None = None
    split_routes: bool = True
    folds: int = 3

    def __post_init__(self) -> None:
        if self.spline_through not in SPLINE_THROUGH:
            raise InvalidInput(
                f'spline_through must be one of {", ".join(SPLINE_THROUGH)} (got "{self.spline_through}").'
            )
        if self.generalization not in GENERALIZATIONS:
            raise InvalidInput(
                f'generalization must be one of {", ".join(GENERALIZATIONS)} (got "{self.generalization}").'
            )
        if self.frames not in FRAMES:
            raise InvalidInput(f'frames must be one of {", ".join(FRAMES)} (got "{self.frames}").')

    def thresholds(self, demos: Sequence[Demo]) -> KeypointParams:
        """The fourteen values for ``demos``."""
        if isinstance(self.params, KeypointParams):
            return self.params
        if isinstance(self.params, ThresholdSettings):
            return self.params.resolve(demos)
        return auto_params(demos)


__all__ = ["SPLINE_THROUGH", "LearnSettings"]
