"""The simulated Baxter's own state, as a real one reports it: the link to the studio, enabled, its red
e-stop button, and the studio's emergency stop (:mod:`studio.robot_backend.simulated` uses it).

A pressed button stops and disables the robot until it is released *and* the robot is enabled again (a reset,
as ``robot_enable.py`` does); a lost link delivers no joint states and refuses every command, and the robot
holds where it is (position mode has no command timeout).
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from studio.core.errors import StudioError
from studio.robot_backend.base import ExecutionProgress, RobotHealth

if TYPE_CHECKING:  # pragma: no cover
    from studio.robot_backend._clock import BatchClock
    from studio.robot_backend.motion import SimArms

log = logging.getLogger(__name__)

HALTED = "Emergency stop: the robot halted. Release the emergency stop to move it again."


@dataclass
class SimSafety:
    """Link, enabled, the robot's e-stop button (and whether it still stops the robot), the studio's e-stop."""

    link_up: bool = True
    enabled: bool = True
    button: bool = False
    stopped: bool = False
    ours: bool = False

    def health(self) -> RobotHealth:
        if not self.link_up:
            return RobotHealth(False, False, self.ours, "Connection to the robot lost: nothing is sent to it.")
        if self.ours:
            return RobotHealth(True, False, True, HALTED)
        if self.button:
            msg = "The robot's emergency-stop button is pressed: turn it to release it, then press Enable robot."
            return RobotHealth(True, False, True, msg)
        if self.stopped:
            return RobotHealth(True, False, True, "The robot is stopped: press Enable robot when it is safe.")
        if not self.enabled:
            return RobotHealth(True, False, False, "The robot is disabled: press Enable robot.")
        return RobotHealth()

    @property
    def moves(self) -> bool:
        """The robot obeys motion commands now."""
        return self.health().ready

    def enable(self) -> None:
        """Reset (when stopped) and enable, as ``robot_enable.py``; plain errors when it cannot."""
        if not self.link_up:
            raise StudioError("The robot is not connected; check the network and that rosbridge runs on it.")
        if self.button:
            raise StudioError("The robot's emergency-stop button is pressed: turn it to release it, then try again.")
        self.stopped, self.enabled = False, True

    def ended(self, p: ExecutionProgress, cause: str) -> ExecutionProgress:
        """A run ended by ``cause`` ("button", "disabled", "link", "ours") at ``p``, in words."""
        if cause == "ours":
            return replace(p, state="emergency-stopped", message=HALTED)
        pct = f"the skill was {round(p.fraction * 100)} % done"
        words = {
            "button": f"The robot's emergency stop was pressed at {p.t:.1f} s; {pct}.",
            "disabled": f"The robot was disabled at {p.t:.1f} s; {pct}.",
            "link": f"Connection to the robot lost at {p.t:.1f} s; {pct}. Nothing more was sent to the robot.",
        }
        return replace(p, state="failed", message=words[cause])


class SimFaults:
    """The simulated robot's health, enabling, and the faults the teacher (and the tests) may cause; a part of
    :class:`~studio.robot_backend.simulated.SimulatedBaxter`, which provides the attributes below."""

    _lock: threading.RLock
    _safety: SimSafety
    _halt_k: int | None
    _halt_cause: str
    _arms: SimArms
    _clock: BatchClock
    rate_hz: float

    def _apply_halt(self) -> None:  # pragma: no cover - SimulatedBaxter's
        raise NotImplementedError

    def emergency_stop(self) -> str:
        """Hold the arms and grippers from the first sample after this call; ignore motion until cleared.
        "undelivered" while the (simulated) link is down: the robot then holds where it is anyway."""
        with self._lock:
            self._safety.ours = True
            if not self._safety.link_up:
                return "undelivered"
            self._halt("ours")
        return "halted"

    @property
    def emergency_stopped(self) -> bool:
        with self._lock:
            return self._safety.ours

    @property
    def held_from(self) -> float | None:
        """Time stamp (s) of the first sample the studio's emergency stop holds; None when it holds none."""
        with self._lock:
            return None if self._halt_k is None or not self._safety.ours else self._halt_k / self.rate_hz

    def _halt(self, cause: str) -> None:
        """Hold from the first sample after now, for ``cause`` (caller holds the lock)."""
        k = self._arms.k
        due = math.floor(self._clock.now() * self.rate_hz + 1e-6) + 1 if self._clock.running else k
        if self._halt_k is None or cause == "ours":
            self._halt_k, self._halt_cause = max(k, due), cause
        if self._halt_k <= k:  # nothing produced yet past the call: apply now
            self._apply_halt()

    def enable(self) -> None:
        with self._lock:
            self._safety.enable()

    def health(self) -> RobotHealth:
        with self._lock:
            return self._safety.health()

    # -- the robot's own faults, for the teacher and the tests to try --------------------------------------
    def press_estop_button(self) -> None:
        """The robot's red button: it stops and is disabled until released and enabled again."""
        with self._lock:
            self._safety.button, self._safety.stopped, self._safety.enabled = True, True, False
            self._halt("button")

    def release_estop_button(self) -> None:
        with self._lock:
            self._safety.button = False

    def disable(self) -> None:
        with self._lock:
            self._safety.enabled = False
            self._halt("disabled")

    def drop_link(self) -> None:
        """The network to the robot fails: no joint states arrive, no command is delivered; the robot holds."""
        with self._lock:
            self._safety.link_up = False
            self._halt("link")

    def restore_link(self) -> None:
        with self._lock:
            self._safety.link_up = True

    def fault_switches(self) -> dict[str, Callable[[], None]]:
        return {
            "Press the robot's e-stop button": self.press_estop_button,
            "Release the robot's e-stop button": self.release_estop_button,
            "Disable the robot": self.disable,
            "Disconnect the robot": self.drop_link,
            "Reconnect the robot": self.restore_link,
        }

    def _obeys(self, what: str) -> bool:
        """A motion command is obeyed now; ignored during the studio's e-stop; refused in words otherwise."""
        if self._safety.ours:
            log.info("emergency-stopped: %s command ignored", what)
            return False
        if not self._safety.moves:
            raise StudioError(self._safety.health().message)
        return True


__all__ = ["HALTED", "SimFaults", "SimSafety"]
