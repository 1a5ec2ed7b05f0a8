"""Scene presets: the objects of the paper's two tasks where the scripted teacher (:mod:`studio.teacher`) acts."""

from __future__ import annotations

from collections.abc import Sequence

from studio.core.errors import InvalidInput
from studio.core.types import ARMS, check_arm
from studio.world.geometry import CUP_GRASP_HEIGHT, PRESETS, TABLE_TOP_Z
from studio.world.scene import Scene


def preset(name: str, arms: Sequence[str] = ("left",)) -> Scene:
    """A scene preset, its objects where the scripted teacher's demonstrations act (one set per teaching arm;
    the right arm's set mirrors the left one across the robot's middle).

    * "empty table": the table only;
    * "stack-cup": the cup the teacher hands over, held out in the air, and the cup it is stacked on;
    * "pick-place": a block at A and the target pad at B (with both arms one pad in the middle: the two arms'
      B points are 4 cm apart).
    """
    from studio import teacher

    if name not in PRESETS:
        raise InvalidInput(f'Unknown scene "{name}": choose {", ".join(PRESETS)}.')
    arms = tuple(check_arm(a) for a in arms) or ("left",)
    scene = Scene(preset=name)
    for arm in ARMS:
        if arm not in arms:
            continue
        m = 1.0 if arm == "left" else -1.0
        tag = f" ({arm})" if len(arms) > 1 else ""
        if name == "stack-cup":
            hx, hy, hz = teacher.STACK_CUP_HANDOVER
            sx, sy, _ = teacher.STACK_CUP_STACK
            scene = scene.add("cup", (sx, m * sy, TABLE_TOP_Z), name=f"bottom cup{tag}")
            scene = scene.add("cup", (hx, m * hy, hz - CUP_GRASP_HEIGHT), name=f"cup{tag}", held_out=True)
        elif name == "pick-place":
            ax, ay, _ = teacher.PICK_PLACE_A
            bx, by, _ = teacher.PICK_PLACE_B
            if len(arms) == 1:
                scene = scene.add("pad", (bx, m * by, TABLE_TOP_Z), m * teacher.PICK_PLACE_YAW_B, name="pad")
            elif arm == "left":
                scene = scene.add("pad", (bx, 0.0, TABLE_TOP_Z), 0.0, name="pad", size=(0.12, 0.16, 0.004))
            scene = scene.add("block", (ax, m * ay, TABLE_TOP_Z), m * teacher.PICK_PLACE_YAW_A, name=f"block{tag}")
    return scene
