"""The task scene without a GUI: a table, the task's objects, and how they respond to Baxter's grippers.

A :class:`Scene` is what the teacher sets up (presets: "empty table", "stack-cup", "pick-place"); a
:class:`World` plays a stream of robot poses against a scene, live (:meth:`World.on_batch`) or as a function
(:func:`simulate`); grasp, carry and release are deterministic rules (:mod:`.rules`,
docs/decisions/027). Events (:class:`WorldEvent`) record the objects at a take's start, end, grasps,
releases, misses; the task's goal is data (:mod:`.goal`), :func:`task_result` judges a run by it."""

from studio.world.events import (
    ObjectPose,
    WorldEvent,
    bounded,
    events_from_dict,
    events_to_dict,
    on_clock,
    retime,
)
from studio.world.feedback import GraspNote, grasp_note
from studio.world.geometry import (
    CUP_GRASP_HEIGHT,
    DEFAULT_SIZE,
    EVENT_KINDS,
    EVENTS_VERSION,
    FLOOR_Z,
    GRASP_ABOVE_TOL,
    GRASP_BELOW_TOL,
    GRASP_XY_TOL,
    GRASPABLE,
    KINDS,
    MAX_EVENTS,
    MAX_OBJECTS,
    NEST_STEP,
    PRESETS,
    SCENE_VERSION,
    SNAP_UP,
    SUCCESS_TOL,
    SWING,
    TABLE_CENTER,
    TABLE_SIZE,
    TABLE_TOP_Z,
    Table,
)
from studio.world.goal import START, TABLE, Goal, Placement, declared, read_goal, session_goal
from studio.world.presets import preset
from studio.world.result import (
    ObjectResult,
    TaskResult,
    describe_offset,
    format_distance,
    task_result,
)
from studio.world.rules import Grip, gripper_actions
from studio.world.scene import Scene, WorldObject
from studio.world.simulation import World, WorldRun, simulate, trimmed_events

__all__ = [
    "CUP_GRASP_HEIGHT",
    "DEFAULT_SIZE",
    "EVENTS_VERSION",
    "EVENT_KINDS",
    "FLOOR_Z",
    "GRASPABLE",
    "GRASP_ABOVE_TOL",
    "GRASP_BELOW_TOL",
    "GRASP_XY_TOL",
    "KINDS",
    "MAX_EVENTS",
    "MAX_OBJECTS",
    "NEST_STEP",
    "PRESETS",
    "SCENE_VERSION",
    "SNAP_UP",
    "START",
    "SUCCESS_TOL",
    "SWING",
    "TABLE",
    "TABLE_CENTER",
    "TABLE_SIZE",
    "TABLE_TOP_Z",
    "Goal",
    "GraspNote",
    "Grip",
    "ObjectPose",
    "ObjectResult",
    "Placement",
    "Scene",
    "Table",
    "TaskResult",
    "World",
    "WorldEvent",
    "WorldObject",
    "WorldRun",
    "bounded",
    "declared",
    "describe_offset",
    "events_from_dict",
    "events_to_dict",
    "format_distance",
    "grasp_note",
    "gripper_actions",
    "on_clock",
    "preset",
    "read_goal",
    "retime",
    "session_goal",
    "simulate",
    "task_result",
    "trimmed_events",
]
