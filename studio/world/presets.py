"""Scene presets: the objects of the paper's two tasks where the scripted teacher (:mod:`studio.teacher`) acts."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from studio.core.errors import InvalidInput
from studio.core.types import ARMS, check_arm
from studio.world.geometry import CUP_GRASP_HEIGHT, PRESETS, TABLE_TOP_Z
from studio.world.goal import declared
from studio.world.scene import Scene

if TYPE_CHECKING:
    from studio.teacher import Places


def _at(p: tuple[float, float, float], dx: float, dy: float, m: float) -> tuple[float, float]:
    return p[0] + dx, m * (p[1] + dy)


def preset(name: str, arms: Sequence[str] = ("left",), places: Places | None = None) -> Scene:
    """A scene preset, its objects where the scripted teacher's demonstrations act (one set per teaching arm;
    the right arm's set mirrors the left one across the robot's middle).

    * "empty table": the table only;
    * "stack-cup": the cup the teacher hands over, held out in the air, and the cup it is stacked on;
    * "pick-place": a block at A and the target pad at B (with both arms one pad in the middle: the two arms'
      B points are 4 cm apart).

    Each states its goal (:func:`studio.world.goal.declared`): the block on the pad, the cup in the bottom cup.

    ``places`` (:class:`studio.teacher.Places`) moves and turns the objects as the scripted teacher's
    demonstrations with the same ``places`` expect them (one arm).
    """
    from studio import teacher

    if name not in PRESETS:
        raise InvalidInput(f'Unknown scene "{name}": choose {", ".join(PRESETS)}.')
    arms = tuple(check_arm(a) for a in arms) or ("left",)
    pl = places if places is not None else teacher.Places()
    pk, pt = pl.pick, pl.put
    scene = Scene(preset=name)
    for arm in ARMS:
        if arm not in arms:
            continue
        m = 1.0 if arm == "left" else -1.0
        tag = f" ({arm})" if len(arms) > 1 else ""
        if name == "stack-cup":
            hx, hy = _at(teacher.STACK_CUP_HANDOVER, pk.dx, pk.dy, m)
            sx, sy = _at(teacher.STACK_CUP_STACK, pt.dx, pt.dy, m)
            hz = teacher.STACK_CUP_HANDOVER[2]
            scene = scene.add("cup", (sx, sy, TABLE_TOP_Z), _wrap(m * pt.dyaw), name=f"bottom cup{tag}")
            cup = (hx, hy, hz - CUP_GRASP_HEIGHT)
            scene = scene.add("cup", cup, _wrap(m * pk.dyaw), name=f"cup{tag}", held_out=True)
        elif name == "pick-place":
            ax, ay = _at(teacher.PICK_PLACE_A, pk.dx, pk.dy, m)
            bx, by = _at(teacher.PICK_PLACE_B, pt.dx, pt.dy, m)
            if len(arms) == 1:
                scene = scene.add("pad", (bx, by, TABLE_TOP_Z), m * (teacher.PICK_PLACE_YAW_B + pt.dyaw), name="pad")
            elif arm == "left":
                scene = scene.add("pad", (bx, 0.0, TABLE_TOP_Z), 0.0, name="pad", size=(0.12, 0.16, 0.004))
            yaw_a = m * (teacher.PICK_PLACE_YAW_A + pk.dyaw)
            scene = scene.add("block", (ax, ay, TABLE_TOP_Z), yaw_a, name=f"block{tag}")
    return scene.with_goal(declared(name, scene.names()))


def _wrap(a: float) -> float:
    """An angle in (-π, π]."""
    return math.atan2(math.sin(a), math.cos(a)) + 0.0  # never -0.0
