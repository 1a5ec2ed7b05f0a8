"""The handle's IK (issue 18): dragged out of reach and back it never leaves the arm trapped at its limits, it
reaches every place the bundled examples reach from any posture, and it stays near the arm's own joints."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from studio.core.errors import InvalidInput
from studio.core.kinematics import Baxter
from studio.core.posture_ik import LIMIT_MARGIN_RAD, REACH_POSITION_M, reach_pose
from studio.storage import SessionStore

ROOT = Path(__file__).resolve().parents[2]
#: Postures the old handle IK left the left arm in (issue 18: upper-arm twist -174°, forearm twist 175.5°).
TRAPPED = (
    np.radians([-55.4, -0.5, -172.6, -2.9, 175.3, 92.4, -13.5]),
    np.radians([97.5, -123.0, -150.3, 82.9, -13.7, 67.5, -10.2]),
    np.radians([-56.0, 32.0, -175.0, 58.4, -175.3, 120.0, -14.7]),
)


@pytest.fixture(scope="module")
def b() -> Baxter:
    return Baxter.load()


@pytest.fixture(scope="module")
def stack_cup_demo(b: Baxter) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """The first stack-cup demonstration: joints, gripper poses, and the grasp and release samples."""
    rec = SessionStore(ROOT / "sessions").open("stack-cup").recordings[0]
    Q, g = rec.arm_q("left"), rec.arm_gripper("left")
    P, W = b.fk_batch("left", Q)
    return Q, P, W, int(np.argmax(g < 50)), int(len(g) - 1 - np.argmax(g[::-1] < 50))


def _pinned(b: Baxter, q: np.ndarray, arm: str = "left") -> list[int]:
    """Joints within 1° of a limit (the elbow's straight end is not a trap)."""
    lo, hi = b.lower_limits(arm), b.upper_limits(arm)  # type: ignore[arg-type]
    near = np.minimum(q - lo, hi - q) < math.radians(1.0)
    near[3] &= q[3] > 0.5 * (lo[3] + hi[3])
    return [int(i) for i in np.flatnonzero(near)]


def test_out_of_reach_and_back_while_carrying_never_traps_the_arm(b: Baxter, stack_cup_demo) -> None:
    Q, P, W, grasp, release = stack_cup_demo
    rng = np.random.default_rng(0)
    for _ in range(8):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        far = P[grasp] + d * rng.uniform(0.6, 1.5)
        q = Q[grasp].copy()
        for p in np.linspace(P[grasp], far, 30):
            q = np.asarray(reach_pose(b, "left", p, W[grasp], q).result.q)
        assert not _pinned(b, q), f"out of reach towards {d}: joints {_pinned(b, q)} at a limit"
        for p in np.linspace(far, P[release], 30):
            found = reach_pose(b, "left", p, W[grasp], q)
            q = np.asarray(found.result.q)
        assert found.result.converged, f"back from {d}: the release place said out of reach"
        assert not _pinned(b, q)


def test_the_old_ik_was_trapped_by_the_same_drag(b: Baxter, stack_cup_demo) -> None:
    """The reproduction: the plain warm-started IK, dragged 1 m away from the robot and back, ends with the
    upper-arm twist at its limit and cannot reach the release; the handle IK reaches it."""
    Q, P, W, grasp, release = stack_cup_demo
    far = P[grasp] + np.array([1.0, 0.0, 0.0])
    q = Q[grasp].copy()
    for p in [*np.linspace(P[grasp], far, 40), *np.linspace(far, P[release], 40)]:
        r = b.ik("left", p, W[grasp], q, max_iterations=60)
        q = np.asarray(r.q)
    assert not r.converged and 2 in _pinned(b, q)
    q = Q[grasp].copy()
    for p in [*np.linspace(P[grasp], far, 40), *np.linspace(far, P[release], 40)]:
        found = reach_pose(b, "left", p, W[grasp], q)
        q = np.asarray(found.result.q)
    assert found.result.converged and not _pinned(b, q)


def test_reaches_every_place_the_examples_reach_from_any_posture(b: Baxter) -> None:
    store = SessionStore(ROOT / "sessions")
    for session in ("stack-cup", "pick-place"):
        for rec in store.open(session).recordings:
            for arm in rec.arms:
                P, W = b.fk_batch(arm, rec.arm_q(arm)[::600])
                for seed in (b.neutral(arm), *(TRAPPED if arm == "left" else ())):
                    for p, w in zip(P, W, strict=True):
                        r = reach_pose(b, arm, p, w, seed).result
                        assert r.converged, f"{session} {rec.name}: {p} not reached from {np.degrees(seed)}"
                        assert r.position_error <= REACH_POSITION_M
                        lo, hi = b.lower_limits(arm), b.upper_limits(arm)
                        assert np.all(r.q >= lo + LIMIT_MARGIN_RAD - 1e-9) and np.all(
                            r.q <= hi - LIMIT_MARGIN_RAD + 1e-9
                        )


def test_a_small_move_stays_near_the_arm_and_far_targets_are_told(b: Baxter) -> None:
    q0 = b.neutral("left")
    p, w = b.fk("left", q0)
    near = reach_pose(b, "left", p + np.array([0.0, 0.01, -0.01]), w, q0)
    assert near.result.converged and near.start == "arm" and near.tried == 1
    assert float(np.abs(near.result.q - q0).max()) < 0.1
    far = reach_pose(b, "left", p + np.array([3.0, 0.0, 0.0]), w, q0)
    assert not far.result.converged and np.all(np.isfinite(far.result.q))
    assert far.tried == 1  # beyond the stretched arm: no other start is tried
    assert not _pinned(b, np.asarray(far.result.q))


def test_bad_targets_are_refused_in_words(b: Baxter) -> None:
    q0 = b.neutral("left")
    with pytest.raises(InvalidInput):
        reach_pose(b, "left", np.array([np.nan, 0.0, 0.0]), np.array([1.0, 0, 0, 0]), q0)
    with pytest.raises(InvalidInput):
        reach_pose(b, "left", np.zeros(3), np.zeros(4), q0)
    with pytest.raises(InvalidInput):
        reach_pose(b, "left", np.zeros(2), np.array([1.0, 0, 0, 0]), q0)
