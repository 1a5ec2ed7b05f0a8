"""The scripted teacher's two tasks: their key-frames (jittered per demonstration) and where they act."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from studio.core.errors import InvalidInput
from studio.teacher.places import USUAL, Places

TASKS: tuple[str, ...] = ("stack-cup", "pick-place")

#: Where the left arm's demonstrations act (base frame, metres; the right arm mirrors y and the yaws). The
#: task scene (:mod:`studio.world.presets`) puts the objects here: the cup handed over in the air and the stack it
#: goes on; the block at A (grasped turned by YAW_A) and the target pad at B.
STACK_CUP_HANDOVER = (0.66, 0.47, 0.20)  # gripper point where the handed-over cup is taken
STACK_CUP_STACK = (0.78, 0.14, 0.06)  # gripper point where it is let go over the stack
PICK_PLACE_A = (0.72, 0.40, -0.03)  # gripper point grasping the block at its start
PICK_PLACE_B = (0.64, 0.02, -0.03)  # gripper point placing it on the pad
PICK_PLACE_YAW_A = 0.35
PICK_PLACE_YAW_B = -0.25


@dataclass
class _Key:
    """A key-frame: pose, how it is approached and what happens there."""

    position: np.ndarray
    yaw: float
    hold: float  # pause after arriving, s
    speed: float  # nominal average speed of the motion that arrives here, m/s
    grip: str | None = None  # "close" or "open" during the pause
    kind: str = "via"  # "via" (jitter cm), "contact" (jitter mm), "home"
    site: str | None = None  # "pick" / "put": the key-frame moves with that object (see :class:`Places`)
    bow: float = 0.0  # sideways detour of the motion that arrives here, m (+: left of the motion's direction)
    dip: float = 0.0  # how far the motion that arrives here sags at mid-way, m (+: down)


def _task_keys(
    task: str,
    rng: np.random.Generator,
    home: np.ndarray,
    places: Places = USUAL,
    detour: float = 0.0,
    once: bool = False,
    dip: float = 0.0,
) -> list[_Key]:
    """The task's key-frames for the left arm (the right arm mirrors y), jittered per demonstration, at the
    objects' ``places``; the first carry bows ``detour`` metres sideways at mid-way (around an obstacle) and sags
    ``dip`` metres (a careless carry);
    ``once``: pick-place puts the block on the pad and goes home (it does not bring it back)."""
    P = np.array
    if task == "stack-cup":
        hand_over, stack = P(STACK_CUP_HANDOVER), P(STACK_CUP_STACK)
        keys = [
            _Key(home, 0.0, rng.uniform(0.8, 1.6), 0.1, kind="home"),
            _Key(hand_over + P([0, 0, 0.10]), 0.0, rng.uniform(0.0, 0.4), 0.11, site="pick"),
            _Key(hand_over, 0.0, rng.uniform(1.4, 2.2), 0.05, "close", "contact", "pick"),
            _Key(hand_over + P([0, 0, 0.12]), 0.0, rng.uniform(0.0, 0.3), 0.08, site="pick"),
            _Key(stack + P([0, 0, 0.16]), 0.0, rng.uniform(0.2, 0.6), 0.10, site="put", bow=detour, dip=dip),
            _Key(stack, 0.0, rng.uniform(1.4, 2.2), 0.04, "open", "contact", "put"),
            _Key(stack + P([0, 0, 0.14]), 0.0, rng.uniform(0.1, 0.4), 0.08, site="put"),
            _Key(home, 0.0, rng.uniform(0.8, 1.5), 0.11, kind="home"),
        ]
    elif task == "pick-place":
        a, b = P(PICK_PLACE_A), P(PICK_PLACE_B)
        ya, yb = PICK_PLACE_YAW_A, PICK_PLACE_YAW_B
        up = P([0, 0, 0.13])
        keys = [
            _Key(home, 0.0, rng.uniform(0.6, 1.2), 0.1, kind="home"),
            _Key(a + up, ya, rng.uniform(0.1, 0.4), 0.15, site="pick"),
            _Key(a, ya, rng.uniform(1.1, 1.6), 0.06, "close", "contact", "pick"),
            _Key(a + up, ya, rng.uniform(0.0, 0.3), 0.10, site="pick"),
            _Key(b + up, yb, rng.uniform(0.1, 0.4), 0.16, site="put", bow=detour, dip=dip),
            _Key(b, yb, rng.uniform(1.1, 1.6), 0.06, "open", "contact", "put"),
            _Key(b + up, yb, rng.uniform(0.4, 0.8), 0.10, site="put"),
            _Key(b, yb, rng.uniform(1.1, 1.6), 0.06, "close", "contact", "put"),
            _Key(b + up, yb, rng.uniform(0.0, 0.3), 0.10, site="put"),
            _Key(a + up, ya, rng.uniform(0.1, 0.4), 0.16, site="pick"),
            _Key(a, ya, rng.uniform(1.1, 1.6), 0.06, "open", "contact", "pick"),
            _Key(a + up, ya, rng.uniform(0.0, 0.3), 0.10, site="pick"),
            _Key(home, 0.0, rng.uniform(0.6, 1.2), 0.12, kind="home"),
        ]
        if once:  # as a newcomer shows "put the block on the pad": no way back
            keys = [*keys[:7], keys[-1]]
    else:
        raise InvalidInput(f'Unknown task "{task}": choose one of {", ".join(TASKS)}.')
    sites = {"stack-cup": (STACK_CUP_HANDOVER, STACK_CUP_STACK), "pick-place": (PICK_PLACE_A, PICK_PLACE_B)}
    for k in keys:
        if k.site is not None:
            k.position, k.yaw = places.move(k.site, sites[task], k.position, k.yaw, turn=task != "stack-cup")
    out = []
    for k in keys:
        if k.kind == "home":
            jit = rng.normal(0, 0.003, 3)
        elif k.kind == "contact":
            jit = np.concatenate([rng.normal(0, 0.004, 2), rng.normal(0, 0.002, 1)])
        else:
            jit = np.clip(rng.normal(0, 0.018, 3), -0.04, 0.04)
        bow = k.bow * rng.uniform(0.8, 1.2) if k.bow else 0.0
        sag = k.dip * rng.uniform(0.9, 1.1) if k.dip else 0.0
        out.append(
            _Key(k.position + jit, k.yaw + rng.normal(0, 0.02), k.hold, k.speed, k.grip, k.kind, k.site, bow, sag)
        )
    return out
