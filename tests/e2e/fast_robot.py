"""``studio serve`` whose simulated robot runs on a faster clock (tests only): ``python -m tests.e2e.fast_robot
SCALE serve …``. The robot moves, streams and records SCALE simulated seconds per wall second; the product's
default stays real time (docs/decisions/093)."""

from __future__ import annotations

import sys

from studio.robot_backend import simulated


def scaled(scale: float) -> type[simulated.SimulatedBaxter]:
    """The simulated Baxter, built with ``time_scale=scale`` unless told otherwise."""

    class Faster(simulated.SimulatedBaxter):
        def __init__(self, **kwargs: object) -> None:
            kwargs.setdefault("time_scale", scale)
            super().__init__(**kwargs)  # type: ignore[arg-type]

    return Faster


if __name__ == "__main__":
    simulated.SimulatedBaxter = scaled(float(sys.argv[1]))  # type: ignore[misc]
    from studio.cli import main

    raise SystemExit(main(sys.argv[2:]))
