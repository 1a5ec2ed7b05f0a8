"""The GUI-free core: the paper's pipeline over numpy arrays. It never imports viser; threading only for the
robot model's per-thread solver data (kinematics) and the auto-tune's cancel flag (autotune). Learning keeps
no module-level state: what it reuses is a :class:`~studio.core.caches.LearningCaches` its caller owns (the
auto-tune's worker processes keep their search's data, autotune)."""

from typing import TYPE_CHECKING

from studio.core.errors import (
    IkFailed,
    InvalidInput,
    LearningFailed,
    NotEnoughData,
    RecordingError,
    SessionFormatError,
    StudioError,
)
from studio.core.types import (
    ALL_ARM_JOINTS,
    ARM_JOINTS,
    ARMS,
    Demo,
    JointTrajectory,
    KeypointParams,
    Recording,
    Skill,
)

if TYPE_CHECKING:  # loaded lazily below; named here for the type checker
    from studio.core.keypoints import KeypointCache, extract_keypoints
    from studio.core.learn import learn, learn_and_judge
    from studio.core.pipeline import demo_from_recording, learn_skill

# The learning pipeline pulls in pinocchio, scipy and hmmlearn; load it on first use so that importing
# the types (sessions, backends) stays light.
_LAZY = {
    "KeypointCache": "studio.core.keypoints",
    "extract_keypoints": "studio.core.keypoints",
    "demo_from_recording": "studio.core.pipeline",
    "learn": "studio.core.learn",
    "learn_and_judge": "studio.core.learn",
    "learn_skill": "studio.core.pipeline",
    "compare_execution": "studio.core.execution",
    "joint_trajectory": "studio.core.execution",
    "plan_execution": "studio.core.execution",
    "skill_feasibility": "studio.core.execution",
}


def __getattr__(name: str) -> object:
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'studio.core' has no attribute {name!r}")


__all__ = [
    "ALL_ARM_JOINTS",
    "ARMS",
    "ARM_JOINTS",
    "Demo",
    "IkFailed",
    "InvalidInput",
    "JointTrajectory",
    "KeypointCache",
    "KeypointParams",
    "LearningFailed",
    "NotEnoughData",
    "Recording",
    "RecordingError",
    "SessionFormatError",
    "Skill",
    "StudioError",
    "compare_execution",
    "demo_from_recording",
    "extract_keypoints",
    "joint_trajectory",
    "learn",
    "learn_and_judge",
    "learn_skill",
    "plan_execution",
    "skill_feasibility",
]
