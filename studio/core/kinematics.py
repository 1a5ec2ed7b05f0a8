"""Baxter kinematics: the model from Baxter's URDF (pinocchio), FK, IK and the paper's DH table.

The end-effector frame is ``<arm>_gripper``: the point between the fingertips, 0.1577 m past the hand.
It is the frame the Baxter SDK reports as the endpoint pose and the one its IK service (which the paper
uses for execution) solves for, so demonstrations, the learned skill and execution all speak of it.

Poses are given in the URDF root frame ``base`` (Baxter's torso base), positions in metres and
orientations as unit quaternions w, x, y, z.
"""

from __future__ import annotations

import functools
import math
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from studio.core.errors import InvalidInput
from studio.core.rotations import make_sign_continuous, matrix_from_quat_wxyz, quat_angle, quat_wxyz_from_matrix
from studio.core.types import ARM_JOINTS, ARMS, Arm, check_arm, readonly

#: The paper's Table I (Denavit–Hartenberg, standard convention): rows (d, a, alpha) for joints 1..7.
DH_TABLE: np.ndarray = readonly(
    [
        [0.2703, 0.069, -1.571],
        [0.0, 0.0, 1.571],
        [0.3644, 0.069, -1.571],
        [0.0, 0.0, 1.571],
        [0.3743, 0.01, -1.571],
        [0.0, 0.0, 1.571],
        [0.2295, 0.0, 0.0],
    ]
)
#: Table I with α = ±π/2 exactly (the paper prints ±1.571): the URDF's joints are exactly perpendicular.
DH_TABLE_EXACT_ALPHA: np.ndarray = readonly(
    np.column_stack([DH_TABLE[:, :2], np.round(DH_TABLE[:, 2] / 1.571) * math.pi / 2])
)
#: Joint offset that maps URDF joint angles onto the table's θ (only s1 differs, by +π/2).
DH_JOINT_OFFSET: np.ndarray = readonly([0.0, math.pi / 2, 0.0, 0.0, 0.0, 0.0, 0.0])
#: Constant translation from ``<arm>_arm_mount`` to the DH base frame, metres.
DH_BASE_OFFSET: np.ndarray = readonly([0.055695, 0.0, 0.011038])

EE_FRAME = "{arm}_gripper"

#: Joint acceleration limits (rad/s², joints s0..w2) used to time every trajectory the robot executes.
#: Rethink publishes none for Baxter: its URDF and the SDK's Hardware Specifications page give position,
#: velocity and effort limits only, and Baxter's own controllers ramp internally. The published planning
#: configurations are deliberately slow placeholders — MoveIt's baxter_moveit_config uses 0.5 rad/s²
#: (moveit_robots) and 1.0 rad/s² (RethinkRobotics/baxter_simulator) for every joint — and would slow down
#: every demonstration, which the robot itself made under a person's hand. CoppeliaSim's Baxter model
#: (PyRep ``BaxterLeft``) uses 4 rad/s². We take 4 rad/s² for the shoulder and elbow (s0–e1, URDF speed
#: 1.5 rad/s reached in 0.375 s) and 8 rad/s² for the lighter wrist (w0–w2, 4 rad/s in 0.5 s); the scripted
#: teacher's demonstrations stay below them except in their fastest reaches (docs/decisions/010).
ACCELERATION_LIMITS: np.ndarray = readonly([4.0, 4.0, 4.0, 4.0, 8.0, 8.0, 8.0])


def baxter_description_dir() -> Path:
    """Folder ``baxter_description`` installed by the ``example-robot-data`` wheel.

    example-robot-data >= 4.4 ships no importable module; its files live under pinocchio's
    ``cmeel.prefix/share`` in site-packages.
    """
    for base in map(Path, sys.path):
        cand = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots" / "baxter_description"
        if (cand / "urdf" / "baxter.urdf").is_file():
            return cand
    raise FileNotFoundError(
        "The Baxter robot description was not found. Install the studio's dependencies "
        "(pip install -e .) so that the example-robot-data package is present."
    )


def package_share_dir() -> Path:
    """Directory that ``package://example-robot-data/...`` mesh URIs are relative to."""
    return baxter_description_dir().parents[2]


def baxter_urdf_path() -> Path:
    return baxter_description_dir() / "urdf" / "baxter.urdf"


#: The light Baxter the studio draws (scripts/decimate_meshes.py): example-robot-data's links and joints.
LIGHT_URDF = Path(__file__).resolve().parents[2] / "urdf" / "baxter_light.urdf"
#: example-robot-data's SRDF (the pairs of collision bodies that never meet), copied beside the light URDF.
LIGHT_SRDF = LIGHT_URDF.parent / "baxter_manipulation.srdf"


def model_urdf_path() -> Path:
    """The URDF the kinematic model is built from: the light one in the repository (the same joints and links as
    example-robot-data's, checked by tests/core/test_kinematics.py), else example-robot-data's."""
    return LIGHT_URDF if LIGHT_URDF.is_file() else baxter_urdf_path()


@dataclass(frozen=True)
class IkResult:
    """Outcome of one IK solve.

    Attributes:
        q: (7,) joint angles in radians, always within the URDF limits and finite.
        converged: True when both errors are within the requested tolerances.
        position_error: distance between reached and requested position, metres.
        orientation_error: rotation angle between reached and requested orientation, radians.
        iterations: damped least-squares iterations used.
    """

    q: np.ndarray
    converged: bool
    position_error: float
    orientation_error: float
    iterations: int


def _as_array(name: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput(f"The {name} must be numbers, got {value!r}.") from exc
    if a.shape != shape:
        raise InvalidInput(f"The {name} must have shape {shape}, got {a.shape}.")
    if not np.all(np.isfinite(a)):
        raise InvalidInput(f"The {name} contains missing or invalid values (NaN or infinity).")
    return a


def dh_fk(q: np.ndarray, table: np.ndarray = DH_TABLE) -> np.ndarray:
    """Forward kinematics by the paper's DH table (Eq. 2 per joint, Eq. 3 for the chain).

    Args:
        q: (7,) the table's θ1..θ7 in radians (URDF angles + :data:`DH_JOINT_OFFSET`).
        table: (7, 3) rows d, a, α.

    Returns:
        (4, 4) homogeneous transform T = A1 · … · A7 from the DH base to the hand frame, metres.
    """
    q = _as_array("joint angles", q, (7,))
    T = np.eye(4)
    for th, (d, a, al) in zip(q, table, strict=True):
        ct, st, ca, sa = math.cos(th), math.sin(th), math.cos(al), math.sin(al)
        A = np.array(
            [[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0.0, sa, ca, d], [0, 0, 0, 1.0]]
        )
        T = T @ A
    return T


def _mix(row: list[Any], col: np.ndarray) -> Any:
    """Σ_k row[k]·col[k], skipping the zero entries of ``col`` (the placements are mostly axis permutations)."""
    out: Any = 0.0
    for k in range(3):
        if col[k] != 0.0:
            out = out + row[k] * col[k]
    return out


class _ArmChain:
    """One arm as seven z-axis revolute joints with fixed placements: FK vectorised over N configurations."""

    def __init__(self, model: pin.Model, arm: Arm) -> None:
        names = ARM_JOINTS[arm]
        self.joint_ids = [model.getJointId(n) for n in names]
        self.idx_q = np.array([model.joints[j].idx_q for j in self.joint_ids])
        first = self.joint_ids[0]
        # Placement of s0 in the world: chain of parents up to the root (all fixed for an arm).
        M = pin.SE3.Identity()
        j = model.parents[first]
        while j > 0:  # pragma: no cover - Baxter's arms hang off the root
            M = model.jointPlacements[j] * M
            j = model.parents[j]
        self.base = np.asarray(M.homogeneous)
        self.placements = np.stack([np.asarray(model.jointPlacements[j].homogeneous) for j in self.joint_ids])
        fid = model.getFrameId(EE_FRAME.format(arm=arm))
        if model.frames[fid].parentJoint != self.joint_ids[-1]:  # pragma: no cover - URDF sanity
            raise RuntimeError("Unexpected Baxter URDF: gripper frame not attached to w2")
        self.ee = np.asarray(model.frames[fid].placement.homogeneous)
        self.lower = model.lowerPositionLimit[self.idx_q].copy()
        self.upper = model.upperPositionLimit[self.idx_q].copy()
        self.velocity = model.velocityLimit[[model.joints[j].idx_v for j in self.joint_ids]].copy()

    def pose_columns(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gripper rotation (N, 3, 3) and position (N, 3) in the world for joint angles Q (N, 7).

        Works on the nine rotation entries as separate (N,) arrays with plain element-wise arithmetic and
        skips the placements' zero entries (they are axis permutations), rather than stacked (N,3,3) matrix
        products, whose BLAS threads contend with other work (bench/README.md, "Kinematics").
        """
        rot, pos, _, _ = self._chain(Q, joints=False)
        return rot, pos

    def pose_jacobian_columns(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Gripper rotation (N, 3, 3), position (N, 3) and the 6×7 Jacobian (N, 6, 7) for joint angles Q (N, 7).

        The Jacobian is given in the world-aligned frame at the gripper point (pinocchio's
        ``LOCAL_WORLD_ALIGNED``): rows vx, vy, vz, wx, wy, wz. Each joint turns about its frame's z axis,
        so column i is (z_i × (p − o_i), z_i) with o_i, z_i that joint's origin and axis — the same
        element-wise arithmetic as :meth:`pose_columns`, vectorised over N.
        """
        rot, pos, origins, axes = self._chain(Q, joints=True)
        n = Q.shape[0]
        J = np.empty((n, 6, 7))
        for i in range(7):
            z, o = axes[i], origins[i]
            dx, dy, dz = pos[:, 0] - o[0], pos[:, 1] - o[1], pos[:, 2] - o[2]
            J[:, 0, i] = z[1] * dz - z[2] * dy
            J[:, 1, i] = z[2] * dx - z[0] * dz
            J[:, 2, i] = z[0] * dy - z[1] * dx
            J[:, 3, i] = z[0]
            J[:, 4, i] = z[1]
            J[:, 5, i] = z[2]
        return rot, pos, J

    def _chain(self, Q: np.ndarray, *, joints: bool) -> tuple[np.ndarray, np.ndarray, list[Any], list[Any]]:
        """Gripper rotation (N, 3, 3) and position (N, 3) by the element-wise product chain of
        :meth:`pose_columns`; with ``joints``, also each joint's origin and z axis (3 columns each, for the
        Jacobian)."""
        n = Q.shape[0]
        c, s = np.cos(Q).T.copy(), np.sin(Q).T.copy()
        B = self.base
        R: list[list[Any]] = [[np.full(n, B[r, k]) for k in range(3)] for r in range(3)]
        p: list[Any] = [np.full(n, B[r, 3]) for r in range(3)]
        origins: list[Any] = []
        axes: list[Any] = []
        for i in range(7):
            P = self.placements[i]
            p = [p[r] + _mix(R[r], P[:3, 3]) for r in range(3)]
            A = [[_mix(R[r], P[:3, j]) for j in range(3)] for r in range(3)]
            if joints:
                origins.append(p)
                axes.append([A[r][2] for r in range(3)])
            ci, si = c[i], s[i]
            # A · Rz(q_i): only the first two columns mix.
            R = [[ci * A[r][0] + si * A[r][1], ci * A[r][1] - si * A[r][0], A[r][2]] for r in range(3)]
        E = self.ee
        pos = np.column_stack([p[r] + _mix(R[r], E[:3, 3]) for r in range(3)])
        rot = np.empty((n, 3, 3))
        for r in range(3):
            for j in range(3):
                rot[:, r, j] = _mix(R[r], E[:3, j])
        return rot, pos, origins, axes

    def transforms(self, Q: np.ndarray) -> np.ndarray:
        """(N, 4, 4) world transforms of the gripper frame for joint angles Q (N, 7)."""
        rot, pos = self.pose_columns(Q)
        T = np.zeros((Q.shape[0], 4, 4))
        T[:, :3, :3] = rot
        T[:, :3, 3] = pos
        T[:, 3, 3] = 1.0
        return T


class Baxter:
    """The Baxter model: both arms (7 joints each), grippers and head pan, loaded once per process.

    Use :meth:`load`; the instance is shared and thread-safe for FK and IK (each call uses its own data).
    """

    def __init__(self, urdf: Path) -> None:
        self.urdf_path = Path(urdf)
        self.model: pin.Model = pin.buildModelFromUrdf(str(self.urdf_path))
        self._chains = {arm: _ArmChain(self.model, arm) for arm in ARMS}
        self._local = threading.local()
        self._reduced: dict[str, tuple[pin.Model, int]] = {}
        for arm in ARMS:
            keep = set(ARM_JOINTS[arm])
            lock = [j for j in range(1, self.model.njoints) if self.model.names[j] not in keep]
            red = pin.buildReducedModel(self.model, lock, pin.neutral(self.model))
            self._reduced[arm] = (red, red.getFrameId(EE_FRAME.format(arm=arm)))

    @classmethod
    @functools.cache
    def load(cls) -> Baxter:
        """The process-wide Baxter model (:func:`model_urdf_path`)."""
        return cls(model_urdf_path())

    # -- limits -------------------------------------------------------------------------------------------
    def lower_limits(self, arm: Arm) -> np.ndarray:
        """(7,) lower joint limits of ``arm`` in radians (URDF)."""
        return self._chains[check_arm(arm)].lower.copy()

    def upper_limits(self, arm: Arm) -> np.ndarray:
        """(7,) upper joint limits of ``arm`` in radians (URDF)."""
        return self._chains[check_arm(arm)].upper.copy()

    def velocity_limits(self, arm: Arm) -> np.ndarray:
        """(7,) joint velocity limits of ``arm`` in rad/s (URDF)."""
        return self._chains[check_arm(arm)].velocity.copy()

    def acceleration_limits(self, arm: Arm) -> np.ndarray:
        """(7,) joint acceleration limits of ``arm`` in rad/s² (see :data:`ACCELERATION_LIMITS`)."""
        check_arm(arm)
        return np.array(ACCELERATION_LIMITS, dtype=np.float64)

    def neutral(self, arm: Arm) -> np.ndarray:
        """A comfortable working configuration in front of the robot (the Baxter SDK's "untuck" pose)."""
        q = np.array([0.08, -1.0, -1.19, 1.94, 0.67, 1.03, -0.50])
        if check_arm(arm) == "right":
            q = q * np.array([-1, 1, -1, 1, -1, 1, -1])
        return q

    # -- forward kinematics -------------------------------------------------------------------------------
    def fk(self, arm: Arm, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gripper pose for one configuration.

        Args:
            arm: "left" or "right".
            q: (7,) joint angles s0..w2, radians.

        Returns:
            position (3,) in metres and orientation (4,) unit quaternion w, x, y, z with w >= 0.
        """
        check_arm(arm)
        q = _as_array("joint angles", q, (7,))
        model, fid = self._reduced[arm]
        data = self._reduced_data(arm)
        pin.forwardKinematics(model, data, q)
        M = pin.updateFramePlacement(model, data, fid)
        x, y, z, w = pin.Quaternion(M.rotation).coeffs()
        quat = np.array([w, x, y, z]) if w >= 0 else -np.array([w, x, y, z])
        return np.array(M.translation), quat / np.linalg.norm(quat)

    def gripper_transform(self, arm: Arm, q: np.ndarray) -> np.ndarray:
        """(4, 4) world transform of the gripper frame for one configuration ``q`` (7,) (no input checks)."""
        model, fid = self._reduced[arm]
        data = self._reduced_data(arm)
        pin.forwardKinematics(model, data, np.asarray(q, dtype=np.float64))
        return np.array(pin.updateFramePlacement(model, data, fid).homogeneous)

    def fk_batch(self, arm: Arm, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gripper poses for N configurations, vectorised.

        Args:
            arm: "left" or "right".
            Q: (N, 7) joint angles, radians.

        Returns:
            positions (N, 3) in metres and orientations (N, 4) w, x, y, z, made sign-continuous along N
            (so a demonstration's quaternion series has no jumps between q and −q).
        """
        chain = self._chains[check_arm(arm)]
        Q = np.asarray(Q, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != 7:
            raise InvalidInput(f"Joint angles must have shape (N, 7), got {Q.shape}.")
        if not np.all(np.isfinite(Q)):
            raise InvalidInput("The joint angles contain missing or invalid values (NaN or infinity).")
        if Q.shape[0] == 0:
            return np.zeros((0, 3)), np.zeros((0, 4))
        rot, pos = chain.pose_columns(Q)
        return pos, make_sign_continuous(quat_wxyz_from_matrix(rot))

    def pose_jacobian_batch(self, arm: Arm, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Gripper rotations (N, 3, 3), positions (N, 3) and Jacobians (N, 6, 7) for N configurations.

        The Jacobian maps joint velocities to the gripper's linear and angular velocity in world axes
        (pinocchio ``LOCAL_WORLD_ALIGNED``). No input checks: the path IK calls it in its inner loop.
        """
        return self._chains[check_arm(arm)].pose_jacobian_columns(np.asarray(Q, dtype=np.float64))

    def rotations_batch(self, arm: Arm, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gripper rotation matrices (N, 3, 3) and positions (N, 3) for N configurations (no quaternions)."""
        return self._chains[check_arm(arm)].pose_columns(np.asarray(Q, dtype=np.float64))

    def elbow_swivel(self, arm: Arm, q: np.ndarray) -> float:
        """Swivel angle (rad) of the elbow about the shoulder–wrist line; 0 = elbow straight up.

        A 7-joint arm reaches one gripper pose with the elbow anywhere on a circle about the line from
        the shoulder (s1) to the wrist (w1); this angle says where on that circle it is. Measured from the
        world's up direction projected onto the circle's plane (from +x when that line is vertical),
        positive counter-clockwise about the shoulder→wrist direction.
        """
        check_arm(arm)
        model, _ = self._reduced[arm]
        data = self._reduced_data(arm)
        pin.forwardKinematics(model, data, np.asarray(q, dtype=np.float64))
        names = ARM_JOINTS[arm]
        S = data.oMi[model.getJointId(names[1])].translation
        E = data.oMi[model.getJointId(names[3])].translation
        W = data.oMi[model.getJointId(names[5])].translation
        u = W - S
        u = u / max(float(np.linalg.norm(u)), 1e-12)
        v = (E - S) - float(np.dot(E - S, u)) * u
        ref = np.array([0.0, 0.0, 1.0])
        if abs(float(np.dot(ref, u))) > 0.95:
            ref = np.array([1.0, 0.0, 0.0])
        ref = ref - float(np.dot(ref, u)) * u
        ref /= np.linalg.norm(ref)
        return float(math.atan2(float(np.dot(np.cross(ref, v), u)), float(np.dot(ref, v))))

    def frame_transform(self, q_full: np.ndarray, frame: str) -> np.ndarray:
        """(4, 4) world transform of any URDF frame for a full pinocchio configuration (nq = 19)."""
        q_full = _as_array("configuration", q_full, (self.model.nq,))
        data = self._data()
        pin.framesForwardKinematics(self.model, data, q_full)
        return np.asarray(data.oMf[self.model.getFrameId(frame)].homogeneous).copy()

    def _data(self) -> pin.Data:
        d = getattr(self._local, "data", None)
        if d is None:
            d = self._local.data = self.model.createData()
        return d

    # -- inverse kinematics -------------------------------------------------------------------------------
    def ik(
        self,
        arm: Arm,
        position: np.ndarray,
        wxyz: np.ndarray,
        q_seed: np.ndarray,
        *,
        max_iterations: int = 100,
        position_tolerance: float = 1e-4,
        orientation_tolerance: float = 1e-3,
        damping: float = 1e-3,
    ) -> IkResult:
        """Full 6-D pose IK by damped least squares, clamped to the URDF joint limits at every step.

        Damped least squares (Levenberg–Marquardt with adaptive damping on the SE(3) log error); clamping keeps
        every iterate within the limits. Meant to be warm-started from a nearby pose (how it compares with pink:
        docs/decisions/009). A target the arm cannot reach ends at the closest pose found, ``converged=False``.

        Args:
            arm: "left" or "right".
            position: (3,) target gripper position, metres.
            wxyz: (4,) target orientation, quaternion w, x, y, z (normalised here).
            q_seed: (7,) starting joint angles, radians (clamped into the limits first).

        Returns:
            :class:`IkResult`; never raises for an unreachable target, never returns NaN.
        """
        check_arm(arm)
        p = _as_array("target position", position, (3,))
        qt = _as_array("target orientation", wxyz, (4,))
        nrm = float(np.linalg.norm(qt))
        if nrm < 1e-9:
            raise InvalidInput("The target orientation must be a non-zero quaternion (w, x, y, z).")
        seed = _as_array("seed joint angles", q_seed, (7,))
        model, fid = self._reduced[arm]
        data = self._reduced_data(arm)
        lo, hi = model.lowerPositionLimit, model.upperPositionLimit
        R_t = matrix_from_quat_wxyz(qt / nrm)
        q = np.clip(seed, lo, hi)
        lam = damping
        best_q, best_cost, best_err = q.copy(), math.inf, (math.inf, math.inf)
        iterations = 0
        for iterations in range(1, max_iterations + 1):  # noqa: B007 - reported in the result
            pin.forwardKinematics(model, data, q)
            pin.updateFramePlacement(model, data, fid)
            cur = data.oMf[fid]
            # Error in the world-aligned frame at the gripper: translation and rotation vector.
            e_pos = p - cur.translation
            e_rot = pin.log3(R_t @ cur.rotation.T)
            pe, oe = float(np.linalg.norm(e_pos)), float(np.linalg.norm(e_rot))
            cost = pe + 0.1 * oe
            if cost < best_cost:
                best_q, best_cost, best_err = q.copy(), cost, (pe, oe)
            if pe <= position_tolerance and oe <= orientation_tolerance:
                break
            J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
            e = np.concatenate([e_pos, e_rot])
            # Active set: a joint resting on a limit that the step would push further out is frozen and the
            # step re-solved with the other joints, so a limit never stalls the solve (plain clamping does).
            free = np.ones(7, dtype=bool)
            for _ in range(3):
                Jf = J * free
                dq = Jf.T @ np.linalg.solve(Jf @ Jf.T + lam * np.eye(6), e)
                pushing = ((q <= lo + 1e-9) & (dq < 0)) | ((q >= hi - 1e-9) & (dq > 0))
                if not np.any(pushing & free):
                    break
                free &= ~pushing
            q_new = np.clip(q + dq, lo, hi)
            # Adaptive damping: relax when progress is good, damp harder near singularities/limits.
            lam = max(lam * 0.5, 1e-6) if np.linalg.norm(dq) < 0.5 else min(lam * 4.0, 1.0)
            q = q_new
        pe, oe = best_err
        converged = pe <= position_tolerance * 10 and oe <= orientation_tolerance * 10
        return IkResult(
            q=readonly(best_q),
            converged=bool(converged),
            position_error=pe,
            orientation_error=oe,
            iterations=iterations,
        )

    def _reduced_data(self, arm: Arm) -> pin.Data:
        key = f"rdata_{arm}"
        d = getattr(self._local, key, None)
        if d is None:
            d = self._reduced[arm][0].createData()
            setattr(self._local, key, d)
        return d

    def clamp(self, arm: Arm, q: np.ndarray) -> np.ndarray:
        """Joint angles clipped into the URDF limits."""
        c = self._chains[check_arm(arm)]
        return np.clip(np.asarray(q, dtype=np.float64), c.lower, c.upper)

    def random_configuration(self, arm: Arm, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
        """Uniform random joint angles within the limits: (7,) or (n, 7)."""
        c = self._chains[check_arm(arm)]
        size = (7,) if n is None else (n, 7)
        return rng.uniform(c.lower, c.upper, size=size)

    def hand_in_mount(self, arm: Arm, q: np.ndarray) -> np.ndarray:
        """(4, 4) transform from ``<arm>_arm_mount`` to ``<arm>_hand_link`` from the URDF (for the DH check)."""
        check_arm(arm)
        q = _as_array("joint angles", q, (7,))
        full = pin.neutral(self.model)
        full[self._chains[arm].idx_q] = q
        Tm = self.frame_transform(full, f"{arm}_arm_mount")
        Th = self.frame_transform(full, f"{arm}_hand_link")
        return np.linalg.inv(Tm) @ Th


__all__ = [
    "ACCELERATION_LIMITS",
    "DH_BASE_OFFSET",
    "DH_JOINT_OFFSET",
    "DH_TABLE",
    "DH_TABLE_EXACT_ALPHA",
    "Baxter",
    "IkResult",
    "baxter_description_dir",
    "baxter_urdf_path",
    "dh_fk",
    "make_sign_continuous",
    "matrix_from_quat_wxyz",
    "model_urdf_path",
    "package_share_dir",
    "quat_angle",
    "quat_wxyz_from_matrix",
]
