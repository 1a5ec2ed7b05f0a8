"""Robot panel: the Baxter model in the scene following the streamed joint states, and the arm selector."""

from __future__ import annotations

import html
import math
import threading
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import viser
from viser.extras import ViserUrdf

from studio import viser_adapter
from studio.controller import Controller, Topic
from studio.core.arms import arm_columns, gripper_column
from studio.core.types import ALL_ARM_JOINTS

#: Finger travel of Baxter's electric gripper (URDF prismatic limit), metres; 100 % open = full travel.
FINGER_TRAVEL = 0.020833
GRIPPER_JOINTS = {"l_gripper_l_finger_joint": 0, "r_gripper_l_finger_joint": 1}
ARM_CHOICES = {"Left arm": ("left",), "Right arm": ("right",), "Both arms": ("left", "right")}
#: The out-of-reach words keep room for two lines: the controls below do not move when they come and go.
MESSAGE_SLOT = "min-height:3.2em"


_MODELS: dict[tuple[Path, int, int], Any] = {}
_MODELS_LOCK = threading.Lock()


def robot_model(urdf_path: Path) -> Any:
    """The robot's model (a ``yourdfpy.URDF`` with its meshes) read from ``urdf_path``, once per process for
    the file as it is (its size and modification time). Shared read-only: ``ViserUrdf`` copies the meshes it
    draws, and only its ``update_cfg`` (never called on a shared model, see :class:`RobotPanel`) changes it."""
    import yourdfpy

    st = urdf_path.stat()
    key = (urdf_path.resolve(), st.st_size, st.st_mtime_ns)
    with _MODELS_LOCK:
        model = _MODELS.get(key)
        if model is None:
            model = yourdfpy.URDF.load(
                urdf_path,
                build_scene_graph=True,
                load_meshes=True,
                build_collision_scene_graph=False,
                load_collision_meshes=False,
                filename_handler=partial(yourdfpy.filename_handler_magic, dir=urdf_path.parent),
            )
            _MODELS[key] = model
        return model


def arms_label(arms: tuple[str, ...]) -> str:
    for label, a in ARM_CHOICES.items():
        if tuple(a) == tuple(arms):
            return label
    return "Left arm"


class RobotPanel:
    """Draws the robot and owns the arm selector ("Arms to teach")."""

    def __init__(self, ctl: Controller, server: viser.ViserServer, urdf_path: Path) -> None:
        self.ctl = ctl
        self.server = server
        gui = server.gui
        self.urdf = ViserUrdf(server, urdf_or_path=robot_model(urdf_path), root_node_name="/robot")
        names = self.urdf.get_actuated_joint_names()
        # yourdfpy orders joints differently from the backend (head, right, left, grippers): map by name.
        self._arm_idx = np.array([ALL_ARM_JOINTS.index(n) if n in ALL_ARM_JOINTS else -1 for n in names])
        self._grip_idx = np.array([GRIPPER_JOINTS.get(n, -1) for n in names])
        self._cfg = np.zeros(len(names))
        self._names = names
        self.updates = 0  # scene pose updates sent (the benchmark reads it)
        with server.atomic():
            self._fast = _FastPose.build(self.urdf)  # places the fixed joints' frames once
        if self._fast is None:  # posed by ViserUrdf.update_cfg, which changes its model: a model of its own
            self.urdf.remove()
            self.urdf = ViserUrdf(server, urdf_or_path=urdf_path, root_node_name="/robot")
        _v, _t, q0, grip0 = ctl.display.get()
        self.show_pose(q0, grip0)  # and the movable ones: the robot is drawn where it is from the start
        self._status_dirty = True
        self._last_status = 0.0
        self._status_html = ""

        with gui.add_folder("Robot", order=0):
            self.arms = gui.add_dropdown(
                "Arms to teach",
                options=list(ARM_CHOICES),
                initial_value=arms_label(ctl.teaching.selected_arms),
                hint="Which gripper(s) you guide: the handles, recordings and learning use these arms.",
            )
            self.status = gui.add_html("")

        self.arms.on_update(ctl.guarded("Could not switch arms")(self._on_arms))
        ctl.events.on(Topic.SESSION, self._on_session)
        ctl.events.on(Topic.RECORDING, self._on_recording)
        ctl.events.on(Topic.REACH, self._on_reach)

    def _on_arms(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        try:
            self.ctl.teaching.set_arms(ARM_CHOICES[self.arms.value])
        except Exception:
            self.arms.value = arms_label(self.ctl.teaching.selected_arms)  # a refused choice does not stay shown
            raise

    def _on_session(self) -> None:
        self.arms.value = arms_label(self.ctl.teaching.selected_arms)

    def _on_recording(self) -> None:
        self.arms.disabled = self.ctl.teaching.recording  # the arms of a take cannot change mid-way

    def _on_reach(self) -> None:
        self._status_dirty = True  # the "cannot reach" line follows the controller's reach state

    def show_pose(self, q: np.ndarray, gripper: np.ndarray) -> None:
        """Move the drawn robot to joints ``q`` (14,) rad and grippers (2,) percent."""
        cfg = self._cfg
        m = self._arm_idx >= 0
        cfg[m] = q[self._arm_idx[m]]
        g = self._grip_idx >= 0
        cfg[g] = np.clip(gripper[self._grip_idx[g]], 0.0, 100.0) / 100.0 * FINGER_TRAVEL
        with self.server.atomic():
            if self._fast is not None:
                self._fast.update(dict(zip(self._names, cfg, strict=True)))
            else:
                self.urdf.update_cfg(cfg)
        self.updates += 1

    def tick(self, now: float) -> None:
        """Refresh the plain-words robot status (gripper positions and openings) a few times a second."""
        if now - self._last_status < 0.25 and not self._status_dirty:
            return
        self._last_status = now
        self._status_dirty = False
        ctl = self.ctl
        _v, _t, q, grip = ctl.display.get()
        lines = []
        for arm in ctl.teaching.selected_arms:
            pos, _ = ctl.baxter.fk(arm, q[arm_columns(arm)])
            g = float(grip[gripper_column(arm)])
            lines.append(
                f'<div class="gripper-status" data-arm="{arm}" data-x="{pos[0]:.3f}" data-y="{pos[1]:.3f}" '
                f'data-z="{pos[2]:.3f}" data-open="{g:.0f}">{arm.capitalize()} gripper at '
                f"x {pos[0]:+.2f} · y {pos[1]:+.2f} · z {pos[2]:+.2f} m, {g:.0f} % open</div>"
            )
        src = ctl.playback.label()
        text = (
            f'<div style="font-size:0.85em"><div class="robot-source">{src}</div>{"".join(lines)}'
            f'<div class="robot-message" style="{MESSAGE_SLOT}">{html.escape(ctl.teaching.reach_message())}</div></div>'
        )
        if text != self._status_html:
            self._status_html = text
            self.status.content = text


class _FastPose:
    """Places every frame of the URDF: fixed joints once, movable joints only when their value changed.

    The fixed joints' frames (arm mounts, hands, gripper bases, head screen, ...) are placed once from their URDF
    origin when the panel is built, and each moving joint is one quaternion product in plain floats, instead of
    ``ViserUrdf.update_cfg`` recomputing every frame (why: docs/decisions/020). ``tests/test_robot_drawing.py``
    composes what the server sends to the browser and compares every link with pinocchio's FK.
    """

    MOVABLE = ("revolute", "continuous", "prismatic")

    def __init__(self, items: list[tuple[Any, ...]], fixed: list[tuple[Any, tuple[float, ...], np.ndarray]]) -> None:
        self.items = items
        self.fixed = fixed
        self._last: list[float | None] = [None] * len(items)

    @classmethod
    def build(cls, urdf: ViserUrdf) -> _FastPose | None:
        from studio.core.kinematics import quat_wxyz_from_matrix

        joints, frames = viser_adapter.urdf_parts(urdf)
        if len(frames) != len(joints):
            return None
        items = []
        fixed = []
        for joint, frame in zip(joints, frames, strict=True):
            origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=np.float64)
            q0 = tuple(float(x) for x in quat_wxyz_from_matrix(origin[:3, :3]))
            if joint.type not in cls.MOVABLE:  # fixed (and any joint without a 1-D motion): its origin
                fixed.append((frame, q0, origin[:3, 3].copy()))
                continue
            axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), dtype=np.float64)
            axis = axis / np.linalg.norm(axis)
            mimic = (
                (joint.mimic.joint, float(joint.mimic.multiplier or 1.0), float(joint.mimic.offset or 0.0))
                if joint.mimic is not None
                else (joint.name, 1.0, 0.0)
            )
            items.append((frame, q0, origin, joint.type == "prismatic", tuple(float(a) for a in axis), mimic))
        fast = cls(items, fixed)
        fast.place_fixed()
        return fast

    def place_fixed(self) -> None:
        """Put every fixed joint's frame at its URDF origin (they never move afterwards)."""
        for frame, wxyz, position in self.fixed:
            frame.wxyz = wxyz
            frame.position = position

    def update(self, values: dict[str, float]) -> None:
        """Move the movable joints' frames to ``values`` (joint name -> rad or m; missing names are 0)."""
        for k, (frame, (w0, x0, y0, z0), origin, prismatic, (ax, ay, az), (src, mult, off)) in enumerate(self.items):
            v = mult * float(values.get(src, 0.0)) + off
            last = self._last[k]
            if last is not None and abs(v - last) < 1e-7:
                continue
            self._last[k] = v
            if prismatic:
                if last is None:
                    frame.wxyz = (w0, x0, y0, z0)
                frame.position = origin[:3, 3] + origin[:3, :3] @ np.array([ax * v, ay * v, az * v])
                continue
            c, s_ = math.cos(v / 2), math.sin(v / 2)
            w1, x1, y1, z1 = c, s_ * ax, s_ * ay, s_ * az
            # origin rotation ∘ rotation about the joint axis (Hamilton product)
            frame.wxyz = (
                w0 * w1 - x0 * x1 - y0 * y1 - z0 * z1,
                w0 * x1 + x0 * w1 + y0 * z1 - z0 * y1,
                w0 * y1 - x0 * z1 + y0 * w1 + z0 * x1,
                w0 * z1 + x0 * y1 - y0 * x1 + z0 * w1,
            )
            if last is None:
                frame.position = origin[:3, 3]
