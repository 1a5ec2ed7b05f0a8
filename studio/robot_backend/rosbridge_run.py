"""A plan streamed to a real Baxter (:mod:`studio.robot_backend.rosbridge`): its clock, and why it ended; and
enabling the robot and calibrating its grippers as the SDK does (``robot_enable.py``, ``gripper.py``).

The plan's clock follows the wall clock (a late command tick sends the plan where it is *now*, it never
stretches the plan); a controlled stop lowers the clock's rate to 0 in about a second, so the robot slows
down along the path.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from studio.core.errors import StudioError
from studio.core.types import ARMS, check_arm
from studio.robot_backend.base import ExecutionProgress, RobotHealth
from studio.robot_backend.rosbridge_link import EMPTY_TYPE, ENABLE, ENABLE_TYPE, RESET, RosLink
from studio.robot_backend.rosbridge_state import (
    ESTOP_BUTTON_PRESSED,
    AssemblyState,
    GripperInfo,
    gripper_words,
)

if TYPE_CHECKING:  # pragma: no cover
    from studio.core.execution import ExecutionPlan

log = logging.getLogger(__name__)

#: Seconds to wait for the robot's state, a reset, enabling, a gripper calibration (robot_enable / gripper.py).
STATE_WAIT_S, RESET_WAIT_S, ENABLE_WAIT_S, CALIBRATE_WAIT_S = 2.0, 3.0, 2.0, 5.0


class PlanClock:
    """Progress along one plan, driven by the wall clock (monotonic seconds)."""

    def __init__(self, plan: ExecutionPlan, started_at: float, now: float) -> None:
        self.plan = plan
        self.p, self.rate, self.slowing = 0.0, 1.0, 0.0
        self._last = now
        self.wall0 = now
        self.progress = ExecutionProgress("running", 0.0, plan.duration, started_at, "The robot is running the skill.")

    def stop(self, seconds: float) -> None:
        """Slow down to rest in ``seconds`` (idempotent)."""
        if self.progress.state == "stopping":
            return
        self.slowing = 1.0 / seconds
        self.progress = replace(self.progress, state="stopping", message="The robot is stopping.")

    def advance(self, now: float) -> tuple[np.ndarray, np.ndarray]:
        """The plan at wall time ``now``: joint (14,) and gripper (2,) targets."""
        dt, self._last = max(now - self._last, 0.0), now
        if self.slowing:
            moving = min(dt, self.rate / self.slowing)  # the rate reaches 0 after this long
            new_rate = max(0.0, self.rate - self.slowing * moving)
            self.p += 0.5 * (self.rate + new_rate) * moving
            self.rate = new_rate
        else:
            self.p += dt
        duration = self.plan.duration
        self.p = min(self.p, duration)
        p = self.progress
        state, msg = p.state, p.message
        if self.p >= duration:
            state, msg = "done", "The robot finished the skill."
        elif state == "stopping" and self.rate <= 0.0:
            state, msg = "stopped", f"The robot stopped at {self.p:.1f} s of {duration:.1f} s."
        self.progress = ExecutionProgress(state, self.p, duration, p.started_at, msg)
        return self.plan.at(self.p)

    @property
    def finished(self) -> bool:
        return self.progress.state in ("done", "stopped")

    def end(self, state: str, message: str) -> ExecutionProgress:
        """The run ends here for a reason of the robot's (see :func:`why_ended`)."""
        self.progress = replace(self.progress, state=state, message=message)
        return self.progress


def why_ended(health: RobotHealth, robot: AssemblyState | None, p: ExecutionProgress, estop_ours: bool) -> str:
    """Why a run cannot go on, in plain words ("" when it can): the connection, the robot's e-stop, disabled."""
    pct = f"the skill was {round(p.fraction * 100)} % done"
    at = f"at {p.t:.1f} s"
    if not health.connected:
        return f"Connection to the robot lost {at}; {pct}. Nothing more was sent to the robot."
    if health.estopped and not estop_ours:
        if robot is not None and robot.estop_source == 1:
            return f"The robot's emergency stop was pressed {at}; {pct}."
        who = robot.why_stopped() if robot is not None else "its emergency stop"
        return f"The robot stopped itself {at} ({who}); {pct}."
    if health.estopped:
        return ""
    if robot is not None and robot.error:
        return f"The robot reported an error {at}; {pct}."
    if not health.enabled:
        return f"The robot was disabled {at}; {pct}."
    if health.message:
        return f"{health.message} The run ended {at}; {pct}."
    return ""


def tick_forever(period: float, tick: Callable[[], None], stop: threading.Event, ping: Callable[[float], None]) -> None:
    """Call ``tick`` every ``period`` seconds of wall time until ``stop`` (a late tick is not caught up), and
    ``ping`` a callback to the event loop that reads the robot (see :meth:`RobotWatch.ping`)."""
    next_t = time.monotonic()
    while not stop.is_set():
        try:
            tick()
        except Exception:  # keep commanding: a lost message must not end the loop
            log.exception("rosbridge command tick failed")
        try:
            ping(time.monotonic())
        except Exception:  # the loop is gone (closing)
            log.debug("pinging the rosbridge loop", exc_info=True)
        next_t += period
        delay = next_t - time.monotonic()
        if delay < 0:
            next_t = time.monotonic()
            delay = 0.0
        stop.wait(delay)


def wait(test: Callable[[], bool], seconds: float, body: Callable[[], object] | None = None) -> bool:
    """Run ``body`` every 50 ms until ``test()`` holds or ``seconds`` pass (baxter_dataflow.wait_for)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if test():
            return True
        if body is not None:
            body()
        time.sleep(0.05)
    return test()


def enable_robot(link: RosLink, state: Callable[[], AssemblyState | None]) -> None:
    """As ``robot_enable.py``: wait for the robot's state, reset it when stopped, publish enable until it is
    enabled. Raises :class:`StudioError` in plain words when it cannot."""
    if not link.connected:
        raise StudioError("The robot is not connected; check the network and that rosbridge runs on it.")
    if not wait(lambda: state() is not None, STATE_WAIT_S):
        raise StudioError("The robot does not report its state (/robot/state): is Baxter's SDK running on it?")

    def pressed() -> bool:
        r = state()
        return r is not None and r.stopped and r.estop_button == ESTOP_BUTTON_PRESSED

    if pressed() and not wait(lambda: not pressed(), 0.3):  # a button just turned is told by the next state message
        raise StudioError("The robot's emergency-stop button is pressed: turn it to release it, then try again.")

    def is_reset() -> bool:
        r = state()
        return r is not None and not (r.stopped or r.error)

    if not is_reset():
        if not wait(is_reset, RESET_WAIT_S, lambda: link.publish(RESET, EMPTY_TYPE, {})):
            raise StudioError("The robot did not reset within 3 s; check its screen for a fault.")

    def is_enabled() -> bool:
        r = state()
        return r is not None and r.enabled

    if not wait(is_enabled, ENABLE_WAIT_S, lambda: link.publish(ENABLE, ENABLE_TYPE, {"data": True})):
        raise StudioError("The robot did not enable within 2 s; check its screen for a fault.")


def calibrate(info: Callable[[int], GripperInfo], send: Callable[[int, str], None], arms: tuple[str, ...]) -> None:
    """Calibrate each electric gripper of ``arms`` that needs it (``send(i, "calibrate")``, after "reset" when
    it is in error), then wait until each says calibrated and ready; plain errors."""
    todo = [ARMS.index(check_arm(a)) for a in arms]
    todo = [i for i in todo if info(i).kind == "electric" and gripper_words(ARMS[i], info(i))]
    for i in todo:
        if info(i).error:
            send(i, "reset")
        send(i, "calibrate")
    for i in todo:
        if not wait(lambda i=i: info(i).calibrated and info(i).ready, CALIBRATE_WAIT_S):  # type: ignore[misc]  # bound i
            raise StudioError(f"The {ARMS[i]} gripper did not calibrate within 5 s; check that nothing blocks it.")


__all__ = ["PlanClock", "calibrate", "enable_robot", "tick_forever", "wait", "why_ended"]
