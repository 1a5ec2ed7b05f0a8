"""Scene panel: the table and the task's objects drawn in the scene, following the world at the pose pump, and
the controls to set them up (add a cup, a block or a pad; move one with its handle in the room's axes or its x/y
boxes; remove; put back, or back to the task's layout; a preset). The handle: docs/decisions/072, 092."""

from __future__ import annotations

import html
import math
import threading
import time
import zlib
from collections.abc import Callable

import numpy as np
import viser

from studio.controller import SCENE_PRESETS, Controller, Layer, Step, Topic, WorldObject
from studio.core.errors import InvalidInput
from studio.core.rotations import matrix_from_quat_wxyz

#: Colours (RGB) of what stands on the table: none is used by a demonstration trace or the learned path.
COLORS = {"cup": (70, 120, 200), "block": (205, 150, 80), "pad": (70, 160, 95)}
RIM_COLOR = (35, 55, 95)
TABLE_COLOR = (214, 206, 192)
LEG_COLOR = (150, 140, 125)
TABLE_THICKNESS = 0.03
NONE = "(none)"
ADD = {"Cup": "cup", "Block": "block", "Pad": "pad"}
TURN = "Turn with the handle"
NO_CHOICE = (
    '<div class="object-where" data-name="" style="font-size:0.85em;color:#6b7280">Choose an object to move it with '
    "its handle or its x and y.</div>"
)
PUT_BACK = "Put all back"
LAYOUT = "Put back to the task's layout"
#: The objects' handle stays in the room's axes (x away from the robot, y to its left), never turned with the object.
ROOM_AXES = (1.0, 0.0, 0.0, 0.0)


class ScenePanel:
    """Draws the table and the objects; "Objects on the table" in the Teach step sets them up."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        self.scene = server.scene
        gui = server.gui
        self._lock = threading.RLock()
        self._nodes: dict[str, viser.FrameHandle] = {}
        self._drawn: tuple[object, ...] | None = None
        self._table: list[viser.SceneNodeHandle] = []
        self._table_key: object = ()
        self._keys: dict[str, tuple[object, ...]] = {}  # what each object node was drawn from
        self._dragging = False
        self._drag_end = 0.0
        with gui.add_folder("Objects on the table", order=1.5):
            gui.add_markdown(
                "Each recording starts with the objects where you put them. Close the gripper around a cup or a "
                "block to pick it up; open it to let go.",
            )
            self.add = gui.add_button_group("Add", options=tuple(ADD))
            self.pick = gui.add_dropdown(
                "Object", options=[NONE], initial_value=NONE, hint="Choose an object to move it with its handle."
            )
            self.boxes = {
                axis: gui.add_number(f"Object {axis} (cm)", initial_value=0.0, step=0.5, hint=hint, disabled=True)
                for axis, hint in (
                    ("x", "Away from the robot (its front), in centimetres: type a number and press Enter."),
                    ("y", "To the robot's left, in centimetres: type a number and press Enter."),
                )
            }
            self.where = gui.add_html(NO_CHOICE)  # where the chosen object is, x/y/z (see where_html)
            self.turn = gui.add_checkbox(
                TURN,
                initial_value=ctl.guide.turning,
                hint="On: the handle shows a ring that turns the object (or the gripper). Off: arrows that move it.",
            )
            self.actions = gui.add_button_group(
                "Object action",
                options=("Remove", PUT_BACK),
                hint="Put all back: every object back where you set it up (what a gripper holds is let go).",
            )
            self.layout = gui.add_button(LAYOUT, hint=self._layout_hint())
            self.preset = gui.add_dropdown(
                "Task set-up",
                options=SCENE_PRESETS,
                initial_value=ctl.scene.scene.preset if ctl.scene.scene.preset in SCENE_PRESETS else SCENE_PRESETS[0],
            )
            self.use_preset = gui.add_button(
                "Use this set-up", hint="Replace the objects on the table by the chosen task's objects."
            )
        self.handle = self.scene.add_transform_controls(
            "/objects_handle",
            line_width=2.5,
            active_axes=(True, True, False),  # on the table: x and y only (and the turn about z)
            depth_test=False,
            disable_sliders=True,
            visible=False,
        )
        self._apply_mode()
        self._turn_from = 0.0  # the object's heading when a turn started
        self.add.on_click(ctl.guarded("Could not add the object")(self._on_add))
        self.pick.on_update(ctl.guarded()(self._on_pick))
        self.actions.on_click(ctl.guarded("Could not change the objects")(self._on_action))
        self.layout.on_click(ctl.guarded("Could not put the objects back")(lambda _: ctl.scene.put_back_layout()))
        self.use_preset.on_click(ctl.guarded("Could not set up the task")(self._on_preset))
        self.handle.on_update(ctl.guarded("Could not move the object")(self._on_handle))
        self.turn.on_update(ctl.guarded()(self._on_turn))
        for axis, box in self.boxes.items():
            box.on_update(ctl.guarded("Could not move the object")(self._make_box(axis)))
        for topic in (Topic.SCENE, Topic.SESSION):
            ctl.events.on(topic, self.refresh)
        ctl.events.on(Topic.VIEW, self._apply_view)
        ctl.events.on(Topic.PLAYBACK, self._apply_view)
        ctl.events.on(Topic.GUIDE, self._on_guide)
        self.refresh()

    # -- the set-up controls -------------------------------------------------------------------------------
    def _on_add(self, event: viser.GuiEvent) -> None:
        name = self.ctl.scene.add(ADD[event.target.value])
        self.pick.value = name

    def _on_pick(self, event: viser.GuiEvent) -> None:
        self.ctl.guide.choose(None if self.pick.value == NONE else str(self.pick.value))  # one handle at a time
        self._place_handle()
        self._apply_view()

    def _on_action(self, event: viser.GuiEvent) -> None:
        if event.target.value == "Remove":
            name = self.pick.value
            if name == NONE:
                raise InvalidInput("Choose the object to remove in the list first.")
            self.ctl.scene.remove(name)
        else:
            self.ctl.scene.put_back()

    def _on_preset(self, event: viser.GuiEvent) -> None:
        self.ctl.scene.use_preset(self.preset.value)

    def _on_turn(self, event: viser.GuiEvent) -> None:
        if event.client is not None:
            self.ctl.guide.set_turning(bool(self.turn.value))

    def _on_guide(self) -> None:
        """The handle's mode changed (here or in the Move panel): arrows or the ring."""
        self.turn.value = self.ctl.guide.turning
        self._apply_mode()

    def _apply_mode(self) -> None:
        turning = self.ctl.guide.turning
        for key, value in (("disable_axes", turning), ("disable_rotations", not turning)):
            if getattr(self.handle, key) != value:
                setattr(self.handle, key, value)
        scale = 0.15 if turning else 0.2
        if self.handle.scale != scale:
            self.handle.scale = scale

    def _make_box(self, axis: str) -> Callable[[viser.GuiEvent], None]:
        def cb(event: viser.GuiEvent) -> None:
            name = self.pick.value
            if event.client is None or name == NONE or name not in self.ctl.scene.scene.names():
                return
            p = list(self.ctl.scene.scene.object(name).position)
            p["xy".index(axis)] = float(self.boxes[axis].value) / 100.0
            self.ctl.scene.move(name, tuple(p))  # SCENE redraws, the handle goes with it

        return cb

    def _layout_hint(self) -> str:
        preset = self.ctl.scene.scene.preset
        if preset not in SCENE_PRESETS or preset == SCENE_PRESETS[0]:
            return "This table has no task layout: choose a task set-up below."
        return f'Every object back where the task "{preset}" starts (your moves of them are undone).'

    def _on_handle(self, event: viser.TransformControlsEvent) -> None:
        name = self.pick.value
        if name == NONE or name not in self.ctl.scene.scene.names():
            return
        phase = getattr(event, "phase", "update")
        h = self.handle
        obj = self.ctl.scene.scene.object(name)
        if phase == "start" or not self._dragging:
            self._turn_from = obj.yaw
        R = matrix_from_quat_wxyz(np.asarray(h.wxyz))  # the handle's turn from the room's axes (its ring only)
        yaw = self._turn_from + (math.atan2(R[1, 0], R[0, 0]) if self.ctl.guide.turning else 0.0)
        # The handle sits on the object's top and moves in x and y only: the object keeps its height.
        bottom = (float(h.position[0]), float(h.position[1]), obj.position[2])
        if phase == "end":
            self._dragging = False
            self._drag_end = time.monotonic()
            h.wxyz = ROOM_AXES
            self.ctl.scene.move(name, bottom, yaw)  # settles; SCENE redraws
            self._place_handle()
            return
        self._dragging = True
        node = self._nodes.get(name)
        if node is not None:  # the object follows the handle while it is dragged
            node.position = bottom
            node.wxyz = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))

    # -- drawing ---------------------------------------------------------------------------------------------
    def refresh(self) -> None:
        """The set-up changed (or another session is open): table, object nodes, list, handle."""
        scene = self.ctl.scene.scene
        with self._lock, self.server.atomic():
            self._draw_table()
            for name in list(self._nodes):
                if name not in scene.names():
                    self._nodes.pop(name).remove()
                    self._keys.pop(name, None)
            for o in scene.objects:
                if name_key(o) != self._keys.get(o.name):
                    old = self._nodes.pop(o.name, None)
                    if old is not None:
                        old.remove()
                    self._nodes[o.name] = self._make_node(o)
                    self._keys[o.name] = name_key(o)
            self._drawn = None
            names = scene.names()
            current = self.pick.value
            self.pick.options = [NONE, *names]
            if current not in names:
                self.pick.value = NONE
                self.ctl.guide.choose(None)
            self.preset.value = scene.preset if scene.preset in self.preset.options else self.preset.options[0]
            self.layout.hint = self._layout_hint()
        self._place_handle()
        self._apply_view()
        self.tick(time.perf_counter())

    def _draw_table(self) -> None:
        table = self.ctl.scene.scene.table
        key = None if table is None else (table.center, table.size, table.top_z)
        if key == self._table_key:
            return
        self._table_key = key
        for n in self._table:
            n.remove()
        self._table = []
        if table is None:
            return
        (cx, cy), (sx, sy), top = table.center, table.size, table.top_z
        top_node = self.scene.add_box(
            "/table/top",
            color=TABLE_COLOR,
            dimensions=(sx, sy, TABLE_THICKNESS),
            position=(cx, cy, top - TABLE_THICKNESS / 2),
            cast_shadow=False,
            receive_shadow=False,
        )
        self._table.append(top_node)
        floor = -0.93
        h = top - TABLE_THICKNESS - floor
        for i, (dx, dy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
            self._table.append(
                self.scene.add_box(
                    f"/table/leg{i}",
                    color=LEG_COLOR,
                    dimensions=(0.04, 0.04, h),
                    position=(cx + dx * (sx / 2 - 0.05), cy + dy * (sy / 2 - 0.05), floor + h / 2),
                    cast_shadow=False,
                    receive_shadow=False,
                )
            )

    def _make_node(self, o: WorldObject) -> viser.FrameHandle:
        """A frame at the object's bottom centre with its shape above it (a cup has a dark rim on top)."""
        kind, (sx, sy, h) = o.kind, o.size
        path = f"/objects/{_safe(o.name)}"
        frame = self.scene.add_frame(path, show_axes=False, position=o.position)
        color = COLORS[kind]
        if kind == "cup":
            self.scene.add_cylinder(
                f"{path}/body", radius=sx / 2, height=h, color=color, position=(0, 0, h / 2), cast_shadow=False
            )
            self.scene.add_cylinder(
                f"{path}/rim", radius=sx / 2 * 0.82, height=0.004, color=RIM_COLOR, position=(0, 0, h - 0.0015)
            )
        else:
            self.scene.add_box(
                f"{path}/body", color=color, dimensions=(sx, sy, h), position=(0, 0, h / 2), cast_shadow=False
            )
        return frame

    def tick(self, now: float) -> None:
        """Pose pump: move the object nodes to the world shown (live, replay or preview) when it changed."""
        key, poses = self.ctl.scene.shown()
        with self._lock:
            if key == self._drawn:
                return
            self._drawn = key
            with self.server.atomic():
                for p in poses:
                    node = self._nodes.get(p.name)
                    if node is None or (self._dragging and p.name == self.pick.value):
                        continue
                    node.position = p.position
                    node.wxyz = p.wxyz
                    if p.name == self.pick.value:
                        self.where.content = where_html(p.name, p.position)

    def _place_handle(self) -> None:
        """The handle on the chosen object's top, in the room's axes; its x/y boxes show where it stands."""
        name = self.pick.value
        scene = self.ctl.scene.scene
        chosen = name != NONE and name in scene.names()
        with self.server.atomic():
            for box in self.boxes.values():
                box.disabled = not chosen  # a fixed slot: the boxes stay where they are
            if not chosen:
                self.where.content = NO_CHOICE
                return
            o = scene.object(name)
            self.where.content = where_html(name, o.position)
            for axis, box in self.boxes.items():
                box.value = round(100.0 * o.position["xy".index(axis)], 1)
            self.handle.position = (o.position[0], o.position[1], o.position[2] + o.size[2])
            self.handle.wxyz = ROOM_AXES

    def _apply_view(self) -> None:
        """Objects follow the "Objects" toggle; their handle shows in the Teach step on the live robot only."""
        ctl = self.ctl
        shown = ctl.view.shown(Layer.OBJECTS)
        with self._lock, self.server.atomic():
            for node in self._nodes.values():
                node.visible = shown
            self.handle.visible = (
                shown and ctl.view.step == Step.TEACH and self.pick.value != NONE and ctl.display.is_live
            )


def name_key(o: WorldObject) -> tuple[object, ...]:
    """What the drawn shape depends on (a node is made again when it changes)."""
    return (o.name, o.kind, tuple(o.size))


def where_html(name: str, position: tuple[float, float, float]) -> str:
    """The chosen object's place as the gripper's position boxes take it (robot axes: x forward, y to its left,
    z up; centimetres)."""
    x, y, z = (100.0 * v for v in position)
    return (
        f'<div class="object-where" data-name="{html.escape(name)}" style="font-size:0.85em;color:#333" '
        'title="x: forward from the robot, y: to its left, z: up, as in the gripper\'s position boxes">'
        f"The {html.escape(name)} stands at x {x:.1f}, y {y:.1f}, z {z:.1f} cm.</div>"
    )


def _safe(name: str) -> str:
    """A scene-node path part for an object's name (no slashes)."""
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name) + f"-{zlib.crc32(name.encode()):08x}"


__all__ = ["COLORS", "ScenePanel"]
