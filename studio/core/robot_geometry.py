"""Baxter's collision geometry: each body of the light URDF, the joint it moves with, the spheres that cover it.

:class:`RobotGeometry` (loaded once per process) reads pinocchio's ``GeometryModel`` from the light URDF (arms,
fingers at their opening, torso, head, pedestal), leaves out the SRDF's pairs that never meet, names each body's
:class:`Part` and computes the moving joints' frames for many poses at once. The checks built on it:
:mod:`studio.core.collision`. Decisions 087 and 096."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from studio.core.kinematics import LIGHT_SRDF, LIGHT_URDF, Baxter, baxter_description_dir, package_share_dir
from studio.core.types import ARMS, Arm

#: Up to this many poses, each is taken on its own (pinocchio's kinematics pose by pose, no coarse pass): fewer
#: steps than in batch for a move by hand.
FEW = 24
#: A finger's travel (m) from closed to fully open (the URDF's prismatic finger joints).
FINGER_TRAVEL_M = 0.020833
#: Parts of an arm by the URDF link its geometry hangs on (a link name without the arm's prefix).
ARM_PARTS: dict[str, str] = {
    "upper_shoulder": "shoulder",
    "lower_shoulder": "shoulder",
    "upper_elbow": "upper arm",
    "upper_elbow_visual": "upper arm",
    "lower_elbow": "elbow",
    "upper_forearm": "forearm",
    "upper_forearm_visual": "forearm",
    "lower_forearm": "forearm",
    "wrist": "wrist",
    "hand_link": "hand",
    "gripper_base_link": "hand",
    "gripper_l_finger": "fingers",
    "gripper_r_finger": "fingers",
    "gripper_l_finger_tip": "fingers",
    "gripper_r_finger_tip": "fingers",
}
#: The robot's body by link: torso, pedestal and the two spheres the URDF puts round the head.
BODY_PARTS: dict[str, str] = {
    "torso": "torso",
    "pedestal": "pedestal",
    "collision_head_link_1": "head",
    "collision_head_link_2": "head",
}
#: The parts of an arm whose place the arm's posture decides (the gripper's place is the path's).
ARM_NOT_GRIPPER = frozenset({"shoulder", "upper arm", "elbow", "forearm"})
#: Parts of one arm that never meet each other (one rigid mechanism, fingers sliding on it).
_GRIPPER = frozenset({"wrist", "hand", "fingers"})
#: Geometry smaller than this (m, a sphere's radius) is a placeholder in the URDF, not a body.
_PLACEHOLDER_M = 0.002


@dataclass(frozen=True)
class Part:
    """What one body of the model is: ``arm`` ("left", "right" or None for the robot's body and obstacles),
    ``part`` ("fingers", "forearm", "torso", or the obstacle's name) and ``robot`` (a part of Baxter)."""

    arm: Arm | None
    part: str
    robot: bool


@dataclass(frozen=True)
class _Geom:
    name: str
    part: Part
    joint: int  # index into the frames of :func:`_frames` (-1: fixed in the world)
    R: np.ndarray  # (3, 3) placement in that joint's frame
    p: np.ndarray  # (3,)
    geometry: coal.CollisionGeometry
    spheres: np.ndarray  # (k, 3) centres of its covering spheres in its own frame
    radius: float  # of each covering sphere
    box: np.ndarray | None  # half extents of its bounding box in its own frame (static bodies)


def cover(g: coal.CollisionGeometry) -> tuple[np.ndarray, float, np.ndarray | None]:
    """Spheres that cover a geometry (centres in its frame, one radius) and, for a mesh, its bounding box."""
    if isinstance(g, coal.Sphere):
        return np.zeros((1, 3)), float(g.radius), np.full(3, float(g.radius))
    if isinstance(g, coal.Cylinder):
        r, half = float(g.radius), float(g.halfLength)
        n = max(1, math.ceil(half / r))
        z = -half + (np.arange(n) + 0.5) * (2 * half / n)
        return np.column_stack([np.zeros(n), np.zeros(n), z]), math.hypot(r, half / n), np.array([r, r, half])
    if isinstance(g, coal.Box):
        h = np.asarray(g.halfSide, dtype=np.float64)
        axis = int(np.argmax(h))
        rest = np.delete(h, axis)
        n = max(1, round(h[axis] / max(float(rest.max()), 1e-6)))
        c = np.zeros((n, 3))
        c[:, axis] = -h[axis] + (np.arange(n) + 0.5) * (2 * h[axis] / n)
        return c, float(np.sqrt((h[axis] / n) ** 2 + float(rest @ rest))), h
    g.computeLocalAABB()
    lo, hi = np.asarray(g.aabb_local.min_), np.asarray(g.aabb_local.max_)
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return centre[None, :], float(np.linalg.norm(half)), half


class RobotGeometry:
    """Baxter's collision geometry from the URDF (loaded once per process with :meth:`load`): each body, the
    joint it moves with, its covering spheres, and the pairs of bodies that can meet (the SRDF's others left out)."""

    def __init__(self, baxter: Baxter) -> None:
        model = baxter.model
        urdf = baxter.urdf_path
        light = urdf.resolve() == LIGHT_URDF.resolve()
        dirs = [str(urdf.parent)] if light else [str(package_share_dir())]
        gm = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION, package_dirs=dirs)
        gm.addAllCollisionPairs()
        srdf = LIGHT_SRDF if light else baxter_description_dir() / "srdf" / "baxter_manipulation.srdf"
        pin.removeCollisionPairs(model, gm, str(srdf))
        # the joints whose frames move bodies: each arm's seven and its two fingers, in pinocchio's order
        self.joint_ids = [j for j in range(1, model.njoints) if model.names[j] != "head_pan"]
        self.parents = [
            self.joint_ids.index(model.parents[j]) if model.parents[j] in self.joint_ids else -1 for j in self.joint_ids
        ]
        self.placements = [model.jointPlacements[j] for j in self.joint_ids]
        self.prismatic = [model.joints[j].shortname().startswith("JointModelP") for j in self.joint_ids]
        self.q_index = [model.joints[j].idx_q for j in self.joint_ids]
        self._model = model
        data = model.createData()
        pin.forwardKinematics(model, data, pin.neutral(model))
        geoms: list[_Geom] = []
        keep: dict[int, int] = {}
        for k, go in enumerate(gm.geometryObjects):
            link = model.frames[go.parentFrame].name
            part = _part_of(link)
            g = go.geometry
            if part is None or (isinstance(g, coal.Sphere) and g.radius < _PLACEHOLDER_M):
                continue
            if isinstance(g, coal.BVHModelBase):  # a mesh (torso, pedestal): its convex hull gives signed distances
                g.buildConvexRepresentation(False)
                g = g.convex
            spheres, radius, box = cover(g)
            M = go.placement
            j = go.parentJoint
            if j in self.joint_ids:
                joint = self.joint_ids.index(j)
            else:  # fixed in the world (on the root or on the head, which stays at its zero)
                joint, M = -1, data.oMi[j] * M
            keep[k] = len(geoms)
            geoms.append(
                _Geom(
                    go.name,
                    part,
                    joint,
                    np.array(M.rotation),
                    np.array(M.translation),
                    g,
                    spheres,
                    radius,
                    box if joint < 0 else None,
                )
            )
        self.geoms = geoms
        pairs = []
        for cp in gm.collisionPairs:
            a, b = keep.get(cp.first), keep.get(cp.second)
            if a is None or b is None or (geoms[a].joint < 0 and geoms[b].joint < 0):
                continue
            pa, pb = geoms[a].part, geoms[b].part
            if pa.arm is not None and pa.arm == pb.arm and {pa.part, pb.part} <= _GRIPPER:
                continue  # the wrist, hand and fingers of one arm are one rigid mechanism: they never meet
            pairs.append((a, b) if geoms[a].joint >= 0 else (b, a))  # the moving one first
        self.pairs = np.array(sorted(pairs), dtype=np.int64).reshape(-1, 2)
        self.arm_q = {
            arm: np.array(
                [
                    self.q_index.index(model.joints[model.getJointId(f"{arm}_{s}")].idx_q)
                    for s in ("s0", "s1", "e0", "e1", "w0", "w1", "w2")
                ]
            )
            for arm in ARMS
        }
        self.fingers = {
            arm: [self.joint_ids.index(model.getJointId(f"{arm[0]}_gripper_{s}_finger_joint")) for s in "lr"]
            for arm in ARMS
        }
        self.finger_sign = {arm: [1.0, -1.0] for arm in ARMS}
        self.reach = self._reach(baxter)

    def _frames_each(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        model = self._model
        data = model.createData()  # this call's own: safe from any thread
        q = pin.neutral(model)
        R = np.empty((v.shape[0], len(self.joint_ids), 3, 3))
        p = np.empty((v.shape[0], len(self.joint_ids), 3))
        for k in range(v.shape[0]):
            q[self.q_index] = v[k]
            pin.forwardKinematics(model, data, q)
            for j, jid in enumerate(self.joint_ids):
                M = data.oMi[jid]
                R[k, j], p[k, j] = M.rotation, M.translation
        return R, p

    def _reach(self, baxter: Baxter) -> np.ndarray:
        """(7,) per arm joint (s0..w2), how far (m) any part of the arm beyond it reaches from it (sampled over
        postures, 5 % added): a joint turned by θ moves nothing farther than that × θ."""
        rng = np.random.default_rng(11)
        n = 256
        Q = np.concatenate([baxter.random_configuration(a, rng, n) for a in ARMS], axis=1)
        Rj, pj = self.frames(Q, np.full((n, 2), 100.0))
        below = [{j} for j in range(len(self.joint_ids))]  # each joint and those it carries
        for j in range(len(self.joint_ids)):
            p = self.parents[j]
            while p >= 0:
                below[p].add(j)
                p = self.parents[p]
        out = np.zeros(7)
        for arm in ARMS:
            for k, j in enumerate(self.arm_q[arm].tolist()):
                for g in self.geoms:
                    if g.joint in below[j]:
                        c = rotate(Rj[:, g.joint], g.spheres @ g.R.T + g.p) + pj[:, g.joint, None, :]
                        far = float(np.linalg.norm(c - pj[:, j, None, :], axis=2).max()) + g.radius
                        out[k] = max(out[k], far)
        return out * 1.05

    @classmethod
    @functools.cache
    def load(cls) -> RobotGeometry:
        return cls(Baxter.load())

    def joint_values(self, Q: np.ndarray, G: np.ndarray) -> np.ndarray:
        """(N, J) the moving joints' values for arm joints Q (N, 14) and gripper openings G (N, 2) percent."""
        n = Q.shape[0]
        out = np.zeros((n, len(self.joint_ids)))
        for i, arm in enumerate(ARMS):
            out[:, self.arm_q[arm]] = Q[:, 7 * i : 7 * i + 7]
            w = np.clip(G[:, i], 0.0, 100.0) / 100.0 * FINGER_TRAVEL_M
            for f, s in zip(self.fingers[arm], self.finger_sign[arm], strict=True):
                out[:, f] = s * w
        return out

    def frames(self, Q: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World rotations (N, J, 3, 3) and origins (N, J, 3) of the moving joints: vectorised over N, or pose by
        pose with pinocchio for a few (fewer steps)."""
        v = self.joint_values(Q, G)
        n, J = v.shape
        if n <= FEW:
            return self._frames_each(v)
        R = np.empty((n, J, 3, 3))
        p = np.empty((n, J, 3))
        for j in range(J):
            P = self.placements[j]
            Pr, Pt = np.asarray(P.rotation), np.asarray(P.translation)
            par = self.parents[j]
            if par < 0:
                Rj = np.broadcast_to(Pr, (n, 3, 3))
                pj = np.broadcast_to(Pt, (n, 3))
            else:
                Rj = _times_const(R[:, par], Pr)
                pj = p[:, par] + rotate(R[:, par], Pt[None, :])[:, 0]
            if self.prismatic[j]:  # along the joint's y axis
                p[:, j] = pj + Rj[:, :, 1] * v[:, j, None]
                R[:, j] = Rj
            else:  # about its z axis
                c, s = np.cos(v[:, j])[:, None], np.sin(v[:, j])[:, None]
                R[:, j, :, 0] = Rj[:, :, 0] * c + Rj[:, :, 1] * s
                R[:, j, :, 1] = Rj[:, :, 1] * c - Rj[:, :, 0] * s
                R[:, j, :, 2] = Rj[:, :, 2]
                p[:, j] = pj
        return R, p


def _times_const(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A (N, 3, 3) times a constant B (3, 3): one matrix product of the rows (N·3, 3) · (3, 3)."""
    return (np.ascontiguousarray(A).reshape(-1, 3) @ B).reshape(A.shape)


def _part_of(link: str) -> Part | None:
    if link in BODY_PARTS:
        return Part(None, BODY_PARTS[link], True)
    for arm, prefixes in (("left", ("left_", "l_")), ("right", ("right_", "r_"))):
        for pre in prefixes:
            if link.startswith(pre) and link[len(pre) :] in ARM_PARTS:
                return Part(arm, ARM_PARTS[link[len(pre) :]], True)  # type: ignore[arg-type]
    return None


def rotate(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotations R (N, 3, 3) applied to vectors v (k, 3): (N, k, 3)."""
    return (
        v[None, :, 0, None] * R[:, None, :, 0]
        + v[None, :, 1, None] * R[:, None, :, 1]
        + v[None, :, 2, None] * R[:, None, :, 2]
    )


__all__ = [
    "ARM_NOT_GRIPPER",
    "ARM_PARTS",
    "BODY_PARTS",
    "FEW",
    "FINGER_TRAVEL_M",
    "Part",
    "RobotGeometry",
    "cover",
    "rotate",
]
