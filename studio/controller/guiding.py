"""Guiding the taught gripper in the room's axes: the handle, steps (keys and buttons, 1 cm or 5 cm),
a typed position, "Go above" an object, and the home posture. Every move goes through the teaching IK, which
keeps the arm off its joint limits (docs/decisions/070); the keys: docs/decisions/071, 092."""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.core.errors import InvalidInput, StudioError
from studio.core.kinematics import IkResult
from studio.core.rotations import matrix_from_quat_wxyz, quat_wxyz_from_matrix
from studio.core.types import Arm, check_arm
from studio.world import ObjectPose

#: One step of a key or an arrow button, m; with Shift (and a key held a while: :mod:`studio.panels._keys`),
#: :data:`BIG_STEP_M`.
STEP_M = 0.01
BIG_STEP_M = 0.05
#: "Go above": the gripper point (or the bottom of what it carries) this far above the object's top, m.
ABOVE_M = 0.03
#: The room's axes by name: x away from the robot, y to its left, z up.
AXES = {"x": 0, "y": 1, "z": 2}


class Hands(Protocol):
    """What guiding needs of :class:`studio.controller.teaching.Teaching`."""

    @property
    def selected_arms(self) -> tuple[Arm, ...]: ...
    def move_gripper(self, arm: Arm, position: np.ndarray, wxyz: np.ndarray) -> IkResult: ...
    def target_q(self, arm: Arm) -> np.ndarray: ...
    def home(self, arms: Sequence[Arm] | None = None) -> None: ...


class Guiding:
    """Moves of the taught gripper by position in room axes; the orientation asked for is kept between moves.

    Args:
        hands: the teaching part (IK, where the arm is going, home).
        objects: the objects where they are now (the live world), for "Go above".
    """

    def __init__(self, ctx: Context, hands: Hands, objects: Callable[[], Sequence[ObjectPose]]) -> None:
        self.ctx = ctx
        self.hands = hands
        self.objects = objects
        self._lock = threading.Lock()
        self._moving = threading.RLock()  # a step reads where the gripper is going, then moves it: one at a time
        self._asked: dict[Arm, tuple[np.ndarray, np.ndarray]] = {}  # arm: (orientation asked, joints it gave)
        self._chosen: str | None = None
        self._key_arm: Arm | None = None
        self._turning = False

    # -- the object chosen (its handle; "Go above") -------------------------------------------------------
    @property
    def chosen(self) -> str | None:
        """The object chosen in "Objects on the table" (None: none)."""
        return self._chosen

    def choose(self, name: str | None) -> None:
        """Choose the object to move with its handle or to go above (None: no object)."""
        if name == self._chosen:
            return
        self._chosen = name
        self.ctx.emit(Topic.GUIDE)

    # -- what the handle does -----------------------------------------------------------------------------
    @property
    def turning(self) -> bool:
        """True: the gripper's handle turns the gripper (rings); False: it moves it (arrows in room axes)."""
        return self._turning

    def set_turning(self, turning: bool) -> None:
        if bool(turning) != self._turning:
            self._turning = bool(turning)
            self.ctx.emit(Topic.GUIDE)

    # -- which gripper the keys move ----------------------------------------------------------------------
    @property
    def key_arm(self) -> Arm:
        """The gripper the keys and the position boxes move: the chosen one if taught, else the first taught."""
        arms = self.hands.selected_arms
        return self._key_arm if self._key_arm in arms else arms[0]

    def set_key_arm(self, arm: str) -> None:
        self._key_arm = check_arm(arm)
        self.ctx.emit(Topic.GUIDE)

    # -- where the gripper is going ---------------------------------------------------------------------------
    def pose(self, arm: Arm) -> tuple[np.ndarray, np.ndarray]:
        """Position (3,) m and orientation (4,) wxyz the gripper is going to: where its joints were sent, with
        the orientation last asked for while the joints are still the ones that gave it."""
        q = self.hands.target_q(arm)
        p, w = self.ctx.baxter.fk(arm, q)
        with self._lock:
            asked = self._asked.get(arm)
        if asked is not None and np.allclose(asked[1], q, atol=1e-9):
            w = asked[0]
        return p, np.array(w)

    def move(self, arm: Arm, position: np.ndarray, wxyz: np.ndarray | None = None) -> IkResult:
        """Send the gripper to ``position`` (m, room axes) with ``wxyz`` (default: the orientation it has)."""
        p = np.asarray(position, dtype=np.float64)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise InvalidInput("A gripper position needs three numbers (x, y, z).")
        w = self.pose(arm)[1] if wxyz is None else np.asarray(wxyz, dtype=np.float64)
        res = self.hands.move_gripper(arm, p, w)
        with self._lock:
            self._asked[arm] = (w / np.linalg.norm(w), np.array(res.q))
        return res

    def move_axis(self, arm: Arm, axis: str, value_m: float) -> IkResult:
        """Send the gripper to ``value_m`` along one room axis ("x", "y" or "z"), the other two kept."""
        if axis not in AXES:
            raise InvalidInput(f'The axis must be "x", "y" or "z", not "{axis}".')
        if not math.isfinite(value_m):
            raise InvalidInput("Type a number of centimetres.")
        with self._moving:
            p = self.pose(arm)[0]
            p[AXES[axis]] = value_m
            return self.move(arm, p)

    def step(self, axis: str, sign: int, arm: Arm | None = None, *, big: bool = False) -> IkResult:
        """One step of the gripper along a room axis (``sign`` +1 or -1): :data:`STEP_M`, or :data:`BIG_STEP_M`
        with ``big``."""
        if axis not in AXES or sign not in (1, -1):
            raise InvalidInput("A step goes along x, y or z, forwards (+1) or back (-1).")
        arm = self.key_arm if arm is None else check_arm(arm)
        with self._moving:
            p = self.pose(arm)[0]
            p[AXES[axis]] += sign * (BIG_STEP_M if big else STEP_M)
            return self.move(arm, p)

    def above(self, name: str | None = None, arm: Arm | None = None) -> IkResult:
        """Send the gripper above an object (default: the chosen one), pointing down, its heading kept; what
        it carries ends :data:`ABOVE_M` above the object's top (the gripper point itself when empty). It goes over,
        never through: up to that height first, or across first when it is lower."""
        name = self._chosen if name is None else name
        arm = self.key_arm if arm is None else check_arm(arm)
        poses = {o.name: o for o in self.objects()}
        if name is None or name not in poses:
            raise StudioError('Choose an object in "Objects on the table" first.')
        obj = poses[name]
        if obj.held_by is not None:
            raise StudioError(f"The {name} is in the gripper already.")
        p_now, w_now = self.pose(arm)
        carried = [o for o in poses.values() if o.held_by == arm]
        hang = max((p_now[2] - o.position[2] for o in carried), default=0.0)
        top = obj.position[2] + obj.size[2]
        target = np.array([obj.position[0], obj.position[1], top + ABOVE_M + max(hang, 0.0)])
        down = pointing_down(w_now)
        # over, never through: up to the height first when it is higher, across first when it is lower
        via = np.array([*(p_now[:2] if target[2] > p_now[2] else target[:2]), max(target[2], p_now[2])])
        if float(np.linalg.norm(via - target)) > 1e-3 and float(np.linalg.norm(via - p_now)) > 1e-3:
            first = self.move(arm, via, down)
            if not first.converged:
                return first
        return self.move(arm, target, down)

    def home(self) -> None:
        """Send the taught arms back to their home posture."""
        self.hands.home()
        with self._lock:
            self._asked.clear()


def pointing_down(wxyz: np.ndarray) -> np.ndarray:
    """The orientation (wxyz) with the gripper pointing straight down and its heading (x axis seen from above)
    kept."""
    R = matrix_from_quat_wxyz(np.asarray(wxyz, dtype=np.float64))
    heading = R[:, 0].copy()
    heading[2] = 0.0
    if np.linalg.norm(heading) < 1e-3:  # the gripper's x axis is vertical: take its y axis's heading
        heading = np.cross(R[:, 1], [0.0, 0.0, 1.0])
    heading /= np.linalg.norm(heading)
    z = np.array([0.0, 0.0, -1.0])
    y = np.cross(z, heading)
    return quat_wxyz_from_matrix(np.column_stack([heading, y, z]))
