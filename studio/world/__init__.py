"""The task scene without a GUI: a table, the task's objects, and how they respond to Baxter's grippers.

A :class:`Scene` is what the teacher sets up (a table and cups, blocks and pads with sizes and poses; presets
"empty table", "stack-cup" and "pick-place"; objects added, moved and removed). A :class:`World` plays a
stream of robot poses (time, 14 joint angles, 2 gripper openings) against a scene, whatever produces it:
the live simulated robot, a demonstration replay, the skill preview or a robot execution. It is a
``RobotBackend.subscribe`` listener (:meth:`World.on_batch`) and also a plain function, :func:`simulate`.

Grasp on close within a tolerance, carry, drop straight down on open (the rules are in :mod:`.simulation`);
a pad lies flat and cannot be grasped; cups nest; off the table an object falls to the floor; an object the
teacher holds out in the air (the stack-cup task's handed-over cup) stays there until grasped.

Events (:class:`WorldEvent`) record every object's pose at the start and end of a demonstration and at each
grasp, release and miss; they are frozen and convert to and from JSON-ready dicts (:func:`events_to_dict`,
:func:`events_from_dict`, versioned) for the session. :func:`task_goal` reads the demonstrations' events and
:func:`task_result` judges a simulated run against them in plain words ("The cup ended 0.6 cm from where you
put it — the skill works").

Modules, one concern each::

    geometry.py    constants, the table, where a let-go object comes to rest
    scene.py       WorldObject, Scene (set-up, edits, versioned dict)
    presets.py     preset(): "empty table", "stack-cup", "pick-place"
    events.py      ObjectPose, WorldEvent, events_to_dict / events_from_dict
    rules.py       grasp, carry and release, object by object; the gripper close/open detector
    simulation.py  World (live), simulate (a whole stream), WorldRun
    result.py      task_goal, task_result: the task result in plain words
"""

from studio.world.events import (
    ObjectPose,
    WorldEvent,
    bounded,
    events_from_dict,
    events_to_dict,
    on_clock,
    retime,
)
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
from studio.world.presets import preset
from studio.world.result import (
    ObjectGoal,
    ObjectResult,
    TaskGoal,
    TaskResult,
    describe_offset,
    format_distance,
    task_goal,
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
    "SUCCESS_TOL",
    "SWING",
    "TABLE_CENTER",
    "TABLE_SIZE",
    "TABLE_TOP_Z",
    "Grip",
    "ObjectGoal",
    "ObjectPose",
    "ObjectResult",
    "Scene",
    "Table",
    "TaskGoal",
    "TaskResult",
    "World",
    "WorldEvent",
    "WorldObject",
    "WorldRun",
    "bounded",
    "describe_offset",
    "events_from_dict",
    "events_to_dict",
    "format_distance",
    "gripper_actions",
    "on_clock",
    "preset",
    "retime",
    "simulate",
    "task_goal",
    "task_result",
    "trimmed_events",
]
