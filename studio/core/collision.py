"""Baxter's collision model and what stands around it: which pairs come closer than a margin, one pose or a path.

:class:`CollisionModel` (built once per scene): the robot from example-robot-data's collision geometry (in the
light URDF) (pinocchio's ``GeometryModel``: arms, fingers at their opening, torso, head,
pedestal; the SRDF's pairs that never meet left out) and the obstacles given (boxes, cylinders; moving per sample
or not). :meth:`CollisionModel.near`: bounding spheres first, coal's signed distance for what they leave in.
Rules and words: :mod:`studio.world.contacts`. Decision 087."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field

import coal
import numpy as np
import pinocchio as pin

from studio.core.errors import InvalidInput
from studio.core.kinematics import LIGHT_SRDF, LIGHT_URDF, Baxter, baxter_description_dir, package_share_dir
from studio.core.types import ARMS, Arm

#: Pairs closer than this (m) touch: the safety margin every check keeps.
MARGIN_M = 0.005
#: A path's broad phase looks at every this many samples (each standing for its neighbours, the margin widened by
#: how far anything moves to them); the exact distances are then taken at every sample it leaves in.
COARSE_STRIDE = 4
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
class Obstacle:
    """Something the robot must not go through: a box or an upright cylinder.

    Attributes:
        name: how it is called ("table", "cup 2").
        shape: "box" or "cylinder".
        size: box: its extents x, y, z; cylinder: diameter, diameter, height (m).
        pose: (4, 4) where its centre is (the default where it stands; :meth:`CollisionModel.near` may move it).
    """

    name: str
    shape: str
    size: tuple[float, float, float]
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        if self.shape not in ("box", "cylinder"):
            raise InvalidInput(f'An obstacle is a box or a cylinder, not "{self.shape}".')
        s = np.asarray(self.size, dtype=np.float64)
        T = np.asarray(self.pose, dtype=np.float64)
        if s.shape != (3,) or not np.all(np.isfinite(s)) or s.min() <= 0 or T.shape != (4, 4):
            raise InvalidInput(f"The {self.name} needs three positive sizes and a pose.")
        object.__setattr__(self, "pose", T)

    @property
    def half(self) -> np.ndarray:
        """Half extents (3,) of its bounding box in its own frame."""
        return 0.5 * np.asarray(self.size, dtype=np.float64)

    def geometry(self) -> coal.CollisionGeometry:
        if self.shape == "box":
            return coal.Box(*self.size)
        return coal.Cylinder(0.5 * self.size[0], self.size[2])


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


def _cover(g: coal.CollisionGeometry) -> tuple[np.ndarray, float, np.ndarray | None]:
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
            spheres, radius, box = _cover(g)
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
                        c = _apply(Rj[:, g.joint], g.spheres @ g.R.T + g.p) + pj[:, g.joint, None, :]
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
                pj = p[:, par] + _apply(R[:, par], Pt[None, :])[:, 0]
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


def _of(p: Part, arm: Arm, parts: Collection[str]) -> bool:
    return p.robot and p.arm == arm and p.part in parts


def _part_of(link: str) -> Part | None:
    if link in BODY_PARTS:
        return Part(None, BODY_PARTS[link], True)
    for arm, prefixes in (("left", ("left_", "l_")), ("right", ("right_", "r_"))):
        for pre in prefixes:
            if link.startswith(pre) and link[len(pre) :] in ARM_PARTS:
                return Part(arm, ARM_PARTS[link[len(pre) :]], True)  # type: ignore[arg-type]
    return None


@dataclass(frozen=True, eq=False)
class Near:
    """Pairs of bodies closer than the margin along a path: one row per (sample, pair).

    Attributes:
        sample: (M,) sample index; a, b: (M,) body indices into :attr:`CollisionModel.parts` (a moving body
            first); distance: (M,) coal's signed distance (m; negative: they overlap by that much); pair: (M,)
            index into :attr:`CollisionModel.pairs`.
    """

    sample: np.ndarray
    a: np.ndarray
    b: np.ndarray
    distance: np.ndarray
    pair: np.ndarray

    def __len__(self) -> int:
        return int(self.sample.shape[0])

    def rows(self, mask: np.ndarray) -> Near:
        """The rows where ``mask`` holds."""
        m = np.asarray(mask, dtype=bool)
        return Near(self.sample[m], self.a[m], self.b[m], self.distance[m], self.pair[m])


class CollisionModel:
    """Baxter and the obstacles of one scene (build once per scene; safe to call from several threads).

    Args:
        obstacles: boxes and cylinders around the robot (the table, the objects).
        moving: names of obstacles that may move per sample (a carried object): they are also checked against
            the other obstacles and the robot's body.
        margin: pairs closer than this (m) are reported.
    """

    def __init__(
        self,
        obstacles: Sequence[Obstacle] = (),
        *,
        moving: Sequence[str] = (),
        margin: float = MARGIN_M,
        robot: RobotGeometry | None = None,
    ) -> None:
        self.robot = robot or RobotGeometry.load()
        self.margin = float(margin)
        self.obstacles = tuple(obstacles)
        names = [o.name for o in self.obstacles]
        if len(set(names)) != len(names):
            raise InvalidInput("Two obstacles have the same name.")
        self.moving = frozenset(moving)
        geoms = self.robot.geoms
        R = self.n_robot = len(geoms)
        self.parts: tuple[Part, ...] = tuple(g.part for g in geoms) + tuple(Part(None, n, False) for n in names)
        # pairs: (a, b) body indices; the robot's own from the SRDF, each moving robot body against every obstacle,
        # each moving obstacle against the other obstacles and the robot's fixed body
        pairs = [tuple(p) for p in self.robot.pairs.tolist()]
        mov = [i for i, g in enumerate(geoms) if g.joint >= 0]
        fixed = [i for i, g in enumerate(geoms) if g.joint < 0]
        for k, o in enumerate(self.obstacles):
            pairs += [(i, R + k) for i in mov]
            if o.name in self.moving:
                pairs += [(R + k, R + m) for m in range(len(self.obstacles)) if m != k]
                pairs += [(R + k, i) for i in fixed]
        self.pairs = np.array(pairs, dtype=np.int64).reshape(-1, 2)
        self._geometry = [g.geometry for g in geoms] + [o.geometry() for o in self.obstacles]
        self._request = coal.DistanceRequest()
        self._request.enable_signed_distance = True
        self._index_bounds()

    def _index_bounds(self) -> None:
        """The broad phase's arrays: the moving robot bodies' covering spheres (in their joints' frames) and one
        bounding sphere each, the obstacles' covering spheres, and a box round every fixed body and obstacle."""
        geoms = self.robot.geoms
        R = self.n_robot
        sj: list[int] = []
        sl: list[np.ndarray] = []
        sr: list[float] = []
        sb: list[int] = []
        self._bj = np.full(R, -1)
        self._bl = np.zeros((R, 3))
        self._br = np.zeros(R)
        self._cols: dict[int, np.ndarray] = {}  # robot body -> its columns among the spheres
        self._box: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}  # fixed body -> (R0, p0, half)
        for i, g in enumerate(geoms):
            c, r, box = _cover(g.geometry)
            local = c @ g.R.T + g.p  # in the joint's frame (the world's for a fixed body)
            if g.joint < 0:
                # a ball (the head's) is its own bound: half extents < 0 say "a ball of that radius"
                half = np.full(3, -r) if isinstance(g.geometry, coal.Sphere) else box
                self._box[i] = (g.R, g.p + g.R @ c.mean(axis=0), half if half is not None else np.full(3, r))
                continue
            self._cols[i] = np.arange(len(sj), len(sj) + c.shape[0])
            sj += [g.joint] * c.shape[0]
            sl.append(local)
            sr += [r] * c.shape[0]
            sb += [i] * c.shape[0]
            m = local.mean(axis=0)
            self._bj[i], self._bl[i], self._br[i] = g.joint, m, float(np.linalg.norm(local - m, axis=1).max()) + r
        self._sj = np.array(sj, dtype=np.int64)
        self._sl = np.concatenate(sl) if sl else np.zeros((0, 3))
        self._sr = np.array(sr)
        self._sb = np.array(sb, dtype=np.int64)
        self._ob_cover = []
        for o in self.obstacles:
            c, r, _ = _cover(o.geometry())
            self._ob_cover.append((c, r))
        # each pair: checked against a box (b is a fixed body or an obstacle) or by spheres (two moving robot bodies)
        self._kind = np.array([0 if (b in self._box or b >= R) else 1 for b in self.pairs[:, 1].tolist()])
        # clusters: the moving bodies of one part of one arm ("left fingers"), bounded together first
        keys = sorted({(g.part.arm or "", g.part.part) for g in geoms if g.joint >= 0})
        self._cluster = np.full(R, -1)
        for i, g in enumerate(geoms):
            if g.joint >= 0:
                self._cluster[i] = keys.index((g.part.arm or "", g.part.part))
        self._members = [np.flatnonzero(self._cluster == c) for c in range(len(keys))]
        width = max(len(m) for m in self._members)
        self._cl_index = np.array([[*m, *[m[0]] * (width - len(m))] for m in self._members], dtype=np.int64)
        self._cl_weight = np.array([[1.0 / len(m)] * len(m) + [0.0] * (width - len(m)) for m in self._members])
        self._moving = np.flatnonzero(self._bj >= 0)

    def arm_touching(
        self,
        arm: Arm,
        other: np.ndarray | None,
        poses: Mapping[str, np.ndarray] | None = None,
        *,
        parts: Collection[str] = ARM_NOT_GRIPPER,
    ) -> Callable[[np.ndarray], np.ndarray]:
        """For the path IK: joints (K, 7) of ``arm`` -> (K,) True where its ``parts`` (default: all but the wrist,
        hand and fingers, whose place the path decides) come within the margin of anything: the obstacles at
        ``poses``, the robot's body, the other arm held at ``other`` (7,; None: the other arm is left out)."""
        mine = [
            k
            for k, (a, b) in enumerate(self.pairs.tolist())
            if (_of(self.parts[a], arm, parts) or _of(self.parts[b], arm, parts))
            and (other is not None or None in (self.parts[a].arm, self.parts[b].arm))
        ]
        chosen = np.asarray(mine, dtype=np.int64)
        cols = slice(0, 7) if arm == "left" else slice(7, 14)
        rest = slice(7, 14) if arm == "left" else slice(0, 7)

        def touching(Q: np.ndarray) -> np.ndarray:
            Q = np.atleast_2d(np.asarray(Q, dtype=np.float64))
            full = np.empty((Q.shape[0], 14))
            full[:, cols] = Q
            full[:, rest] = Q if other is None else other  # (left out when None: mirrored, never checked)
            near = self.near(full, np.full((Q.shape[0], 2), 100.0), poses, pairs=chosen)
            out = np.zeros(Q.shape[0], dtype=bool)
            out[near.sample] = True
            return out

        return touching

    def index(self, name: str) -> int:
        """The body index of obstacle ``name``."""
        for k, o in enumerate(self.obstacles):
            if o.name == name:
                return self.n_robot + k
        raise InvalidInput(f'There is no "{name}" among the obstacles.')

    # -- the check ----------------------------------------------------------------------------------------
    def near(
        self,
        Q: np.ndarray,
        G: np.ndarray,
        poses: Mapping[str, np.ndarray] | None = None,
        *,
        pairs: np.ndarray | None = None,
        skip: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    ) -> Near:
        """Every pair closer than the margin at each sample of a path.

        Args:
            Q: (N, 14) arm joints (rad, left then right); G: (N, 2) gripper openings (percent).
            poses: obstacle name -> (N, 4, 4) or (4, 4): where its centre is (default: its own pose).
            pairs: (P,) indices into :attr:`pairs` to check (default: all).
            skip: (samples (M,), pair indices (M,)) -> (M,) True for the pairs that may touch there (left out
                before coal measures them).

        Returns:
            :class:`Near`, sorted by sample.
        """
        Q = np.atleast_2d(np.asarray(Q, dtype=np.float64))
        G = np.atleast_2d(np.asarray(G, dtype=np.float64))
        if Q.ndim != 2 or Q.shape[1] != 14 or G.shape != (Q.shape[0], 2):
            raise InvalidInput("A collision check needs 14 joint angles and 2 gripper openings per sample.")
        if not (np.all(np.isfinite(Q)) and np.all(np.isfinite(G))):
            raise InvalidInput("The joint angles contain missing or invalid values (NaN or infinity).")
        poses = dict(poses or {})
        idx = np.arange(self.pairs.shape[0]) if pairs is None else np.asarray(pairs, dtype=np.int64)
        sel = self.pairs[idx]
        n = Q.shape[0]
        at = None
        if n > 4 * FEW:
            cand_s, cand_p = self._coarse(Q, G, poses, sel, self._kind[idx])
        else:
            at = _Frames(self, Q, G, poses)
            cand_s, cand_p = self._broad(at, sel, self._kind[idx], np.full(n, self.margin))
        if skip is not None and cand_s.size:
            keep = ~np.asarray(skip(cand_s, idx[cand_p]), dtype=bool)
            cand_s, cand_p = cand_s[keep], cand_p[keep]
        if at is not None:
            near = self._narrow(at, sel, cand_s, cand_p)
            return Near(near.sample, near.a, near.b, near.distance, idx[near.pair])
        # the exact distances, at the candidates' samples only
        rows, at_rows = np.unique(cand_s, return_inverse=True)
        sub = {k: (v[rows] if np.ndim(v) == 3 else v) for k, v in poses.items()}
        near = self._narrow(_Frames(self, Q[rows], G[rows], sub), sel, at_rows.reshape(-1), cand_p)
        return Near(rows[near.sample], near.a, near.b, near.distance, idx[near.pair])

    def _coarse(
        self, Q: np.ndarray, G: np.ndarray, poses: dict[str, np.ndarray], sel: np.ndarray, kind: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The broad phase of a path at every :data:`COARSE_STRIDE`-th sample, each with the margin widened by how
        far anything may move to the samples it stands for (the joints' changes times the arm's reach beyond each
        joint, the obstacles' own moves); its candidates stand for those samples."""
        n = Q.shape[0]
        coarse = np.unique(np.append(np.arange(0, n, COARSE_STRIDE), n - 1))
        owner = np.clip(np.searchsorted(coarse, np.arange(n) - COARSE_STRIDE / 2.0), 0, coarse.shape[0] - 1)
        rep = coarse[owner]
        dq = np.abs(Q - Q[rep])
        reach = self.robot.reach
        move = np.maximum(dq[:, :7] @ reach, dq[:, 7:] @ reach)
        move += np.abs(G - G[rep]).max(axis=1) / 100.0 * FINGER_TRAVEL_M
        for o in self.obstacles:
            T = poses.get(o.name)
            if T is not None and np.ndim(T) == 3:
                c, r, _ = _cover(o.geometry())
                turn = np.linalg.norm((T[:, :3, :3] - T[rep, :3, :3]).reshape(n, 9), axis=1)  # ≥ the turn's angle
                move += np.linalg.norm(T[:, :3, 3] - T[rep, :3, 3], axis=1) + turn * (float(np.abs(c).max()) + r)
        widen = np.zeros(coarse.shape[0])
        np.maximum.at(widen, owner, move)
        sub = {k: (v[coarse] if np.ndim(v) == 3 else v) for k, v in poses.items()}
        at = _Frames(self, Q[coarse], G[coarse], sub)
        c_s, c_p = self._broad(at, sel, kind, self.margin + widen)
        if not c_s.size:
            return c_s, c_p
        # each coarse candidate stands for the samples it owns
        first = np.searchsorted(owner, np.arange(coarse.shape[0]), side="left")
        last = np.searchsorted(owner, np.arange(coarse.shape[0]), side="right")
        count = last[c_s] - first[c_s]
        s = np.repeat(first[c_s], count) + (np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count))
        return s, np.repeat(c_p, count)

    def _broad(
        self, at: _Frames, sel: np.ndarray, kind: np.ndarray, margin: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(sample, pair) candidates: pairs whose bounds come within ``margin`` (N,) of each other, tested coarse to
        fine (a part's bodies together, each body's bounding sphere, its covering spheres) against the other's
        bounding box (an obstacle, a fixed body) or spheres (two moving robot bodies)."""
        out_s: list[np.ndarray] = []
        out_p: list[np.ndarray] = []
        Cb = at.robot_bounds()  # (N, R, 3)
        Pc, Pr = at.cluster_bounds()  # (N, C, 3), (N, C)
        by_box: dict[int, list[int]] = {}
        for k in np.flatnonzero(kind == 0).tolist():
            by_box.setdefault(int(sel[k, 1]), []).append(k)
        for box, group in by_box.items():
            Rb, pb, h = at.box(box)
            for a_group, k_group in _split_by_kind(sel, group, self.n_robot):
                if a_group is not None:  # a moving obstacle's spheres
                    pts, rad = at.obstacle_centres(a_group)
                    hit = (_box_gap2(pts, Rb, pb, h) < np.square(margin[:, None] + rad)).any(axis=1)
                    out_s.append(np.flatnonzero(hit))
                    out_p.append(np.full(int(hit.sum()), k_group[0]))
                    continue
                bodies = sel[k_group, 0]
                clusters = np.unique(self._cluster[bodies])
                reach = np.square(margin[:, None] + Pr[:, clusters])
                s_c, c_c = np.nonzero(_box_gap2(Pc[:, clusters], Rb, pb, h) < reach)
                for c in np.unique(c_c).tolist():
                    rows = s_c[c_c == c]
                    Rr, pr = (Rb, pb) if Rb.shape[0] == 1 else (Rb[rows], pb[rows])
                    for j in np.flatnonzero(self._cluster[bodies] == clusters[c]).tolist():
                        body = int(bodies[j])
                        gap = _box_gap2(Cb[rows, body, None], Rr, pr, h)[:, 0]
                        near = gap < np.square(margin[rows] + self._br[body])
                        r2 = rows[near]
                        if not r2.size:
                            continue
                        cols = self._cols[body]
                        R2, p2 = (Rr, pr) if Rr.shape[0] == 1 else (Rr[near], pr[near])
                        gaps = _box_gap2(at.centres(body, r2), R2, p2, h)
                        hit = (gaps < np.square(margin[r2][:, None] + self._sr[cols])).any(axis=1)
                        out_s.append(r2[hit])
                        out_p.append(np.full(int(hit.sum()), k_group[j]))
        spheres = np.flatnonzero(kind == 1)
        if spheres.size:
            self._sphere_pairs(at, sel, spheres, margin, out_s, out_p)
        if not out_s:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        s = np.concatenate(out_s)
        p = np.concatenate(out_p)
        order = np.lexsort((p, s))
        return s[order], p[order]

    def _sphere_pairs(
        self,
        at: _Frames,
        sel: np.ndarray,
        ks: np.ndarray,
        margin: np.ndarray,
        out_s: list[np.ndarray],
        out_p: list[np.ndarray],
    ) -> None:
        """Candidates among pairs of moving robot bodies ``ks``: their parts' bounds, their bodies', their spheres."""
        Cb = at.robot_bounds()
        Pc, Pr = at.cluster_bounds()
        a, b = sel[ks, 0], sel[ks, 1]
        ca, cb = self._cluster[a], self._cluster[b]
        combos = np.unique(np.stack([ca, cb], axis=1), axis=0)
        X, Y = combos[:, 0], combos[:, 1]
        close = np.square(Pc[:, X] - Pc[:, Y]).sum(axis=2) < np.square(Pr[:, X] + Pr[:, Y] + margin[:, None])
        for m in np.flatnonzero(close.any(axis=0)).tolist():
            x, y = int(X[m]), int(Y[m])
            rows = np.flatnonzero(close[:, m])
            for c in np.flatnonzero((ca == x) & (cb == y)).tolist():
                ia, ib = int(a[c]), int(b[c])
                d2 = np.square(Cb[rows, ia] - Cb[rows, ib]).sum(axis=1)
                s_k = rows[d2 < (self._br[ia] + self._br[ib] + margin[rows]) ** 2]
                if not s_k.size:
                    continue
                pa, pb = at.centres(ia, s_k), at.centres(ib, s_k)
                dd = np.sqrt(np.square(pa[:, :, None, :] - pb[:, None, :, :]).sum(axis=3)).min(axis=(1, 2))
                keep = dd - self._sr[self._cols[ia][0]] - self._sr[self._cols[ib][0]] < margin[s_k]
                out_s.append(s_k[keep])
                out_p.append(np.full(int(keep.sum()), ks[c]))

    def _narrow(self, at: _Frames, sel: np.ndarray, cand_s: np.ndarray, cand_p: np.ndarray) -> Near:
        """coal's signed distance of each candidate; the pairs within the margin."""
        req = self._request
        res = coal.DistanceResult()
        ta, tb = coal.Transform3s(), coal.Transform3s()
        dist = np.empty(cand_s.shape[0])
        geometry, distance = self._geometry, coal.distance
        for m, (s, k) in enumerate(zip(cand_s.tolist(), cand_p.tolist(), strict=True)):
            a, b = int(sel[k, 0]), int(sel[k, 1])
            Ra, pa = at.placement(s, a)
            Rb, pb = at.placement(s, b)
            ta.setRotation(Ra)
            ta.setTranslation(pa)
            tb.setRotation(Rb)
            tb.setTranslation(pb)
            res.clear()  # (coal's ComputeDistance kept a guess between calls that led it astray: decision 087)
            dist[m] = distance(geometry[a], ta, geometry[b], tb, req, res)
        keep = dist < self.margin
        return Near(cand_s[keep], sel[cand_p[keep], 0], sel[cand_p[keep], 1], dist[keep], cand_p[keep])


class _Frames:
    """Where each body of a :class:`CollisionModel` is along one path (the joints' frames, the obstacles' poses)."""

    def __init__(self, model: CollisionModel, Q: np.ndarray, G: np.ndarray, poses: Mapping[str, np.ndarray]) -> None:
        self.m = model
        self.n = Q.shape[0]
        self.Rj, self.pj = model.robot.frames(Q, G)
        self.T: list[np.ndarray] = []
        for o in model.obstacles:
            T = np.asarray(poses.get(o.name, o.pose), dtype=np.float64)
            if T.shape not in ((4, 4), (self.n, 4, 4)) or not np.all(np.isfinite(T)):
                raise InvalidInput(f"The pose of the {o.name} must be one 4 × 4 transform or one per sample.")
            self.T.append(T if T.ndim == 3 else T[None])
        self._B: np.ndarray | None = None
        self._P: tuple[np.ndarray, np.ndarray] | None = None

    def cluster_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Per sample, a sphere round each part's moving bodies: centres (N, C, 3) and radii (N, C)."""
        if self._P is None:
            m = self.m
            X = self.robot_bounds()[:, m._cl_index]  # (N, C, M, 3): each part's bodies, padded with its first
            C = (X * m._cl_weight[None, :, :, None]).sum(axis=2)
            r = (np.sqrt(np.square(X - C[:, :, None, :]).sum(axis=3)) + m._br[m._cl_index]).max(axis=2)
            self._P = (C, r)
        return self._P

    def centres(self, body: int, rows: np.ndarray) -> np.ndarray:
        """(m, k, 3) world centres of moving robot ``body``'s covering spheres at samples ``rows``."""
        m = self.m
        j = int(m._bj[body])
        return _apply(self.Rj[rows, j], m._sl[m._cols[body]]) + self.pj[rows, j, None, :]

    def robot_bounds(self) -> np.ndarray:
        """(N, R, 3) world centres of the robot bodies' bounding spheres (meaningful for the moving ones)."""
        if self._B is None:
            m = self.m
            B = np.zeros((self.n, m.n_robot, 3))
            mov, j = m._moving, m._bj[m._moving]
            B[:, mov] = np.einsum("nbij,bj->nbi", self.Rj[:, j], m._bl[mov]) + self.pj[:, j]
            self._B = B
        return self._B

    def obstacle_centres(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """World centres (N, k, 3) of obstacle body ``i``'s covering spheres, and their radii (k,)."""
        c, r = self.m._ob_cover[i - self.m.n_robot]
        T = self.T[i - self.m.n_robot]
        pts = _apply(T[:, :3, :3], c) + T[:, None, :3, 3]
        if pts.shape[0] != self.n:
            pts = np.broadcast_to(pts, (self.n, *pts.shape[1:]))
        return pts, np.full(c.shape[0], r)

    def box(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rotation (N or 1, 3, 3), centre (N or 1, 3) and half extents (3,) of the box round body ``i``."""
        m = self.m
        if i >= m.n_robot:
            T = self.T[i - m.n_robot]
            return T[:, :3, :3], T[:, :3, 3], m.obstacles[i - m.n_robot].half
        R0, p0, h = m._box[i]
        return R0[None], p0[None], h

    def placement(self, s: int, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Rotation (3, 3) and position (3,) of body ``i``'s geometry at sample ``s``."""
        m = self.m
        if i >= m.n_robot:
            T = self.T[i - m.n_robot]
            T = T[s] if T.shape[0] > 1 else T[0]
            return T[:3, :3], T[:3, 3]
        g = m.robot.geoms[i]
        if g.joint < 0:
            return g.R, g.p
        Rj, pj = self.Rj[s, g.joint], self.pj[s, g.joint]
        return Rj @ g.R, pj + Rj @ g.p


def _split_by_kind(sel: np.ndarray, ks: list[int], n_robot: int) -> list[tuple[int | None, list[int]]]:
    """The pairs ``ks`` against one box, as (None, the robot bodies' pairs) and (a moving obstacle, [its pair])."""
    robot = [k for k in ks if int(sel[k, 0]) < n_robot]
    out: list[tuple[int | None, list[int]]] = [(None, robot)] if robot else []
    return out + [(int(sel[k, 0]), [k]) for k in ks if int(sel[k, 0]) >= n_robot]


def _box_gap2(pts: np.ndarray, R: np.ndarray, p: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Squared distance (N, S) from points (N, S, 3) to a box (rotation (N or 1, 3, 3), centre (N or 1, 3))."""
    d = pts - p[:, None, :]
    if half[0] < 0:  # a ball
        return np.square(np.maximum(np.sqrt(np.square(d).sum(axis=2)) + half[0], 0.0))
    if R.shape[0] == 1:  # a box that stands still: one matrix product
        local = d @ R[0]
    else:
        local = (
            d[:, :, 0, None] * R[:, None, 0, :]
            + d[:, :, 1, None] * R[:, None, 1, :]
            + d[:, :, 2, None] * R[:, None, 2, :]
        )
    out = np.abs(local)
    out -= half
    np.maximum(out, 0.0, out=out)
    np.square(out, out=out)
    return out.sum(axis=2)


def _apply(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotations R (N, 3, 3) applied to vectors v (k, 3): (N, k, 3)."""
    return (
        v[None, :, 0, None] * R[:, None, :, 0]
        + v[None, :, 1, None] * R[:, None, :, 1]
        + v[None, :, 2, None] * R[:, None, :, 2]
    )


@dataclass(frozen=True)
class Touch:
    """One stretch of a motion during which two things come within the margin of each other (a fact; its words:
    :func:`studio.words.touch_words`).

    Attributes:
        a, b: what touches what (a robot part or a carried object first; of two arms, the left first).
        t_start, t_end: the stretch (s on the motion's clock); i_start, i_end: its samples (inclusive).
        depth: how far they overlap at the deepest (m); at most 0 when they only came within the margin.
        at: when they overlap the most (s).
        carry: what ``a``'s arm carries meanwhile (None: nothing).
        new: ``b`` is an object no demonstration had.
    """

    a: Part
    b: Part
    t_start: float
    t_end: float
    i_start: int
    i_end: int
    depth: float
    at: float
    carry: str | None = None
    new: bool = False

    @property
    def arms(self) -> tuple[Arm, ...]:
        """The arms whose parts touch."""
        return tuple(p.arm for p in (self.a, self.b) if p.arm is not None)


def stretches(near: Near, parts: Sequence[Part], t: np.ndarray, *, gap_s: float = 0.1) -> list[Touch]:
    """The rows of ``near`` as stretches per pair of parts (samples closer than ``gap_s`` joined), earliest first."""
    t = np.asarray(t, dtype=np.float64)
    groups: dict[tuple[Part, Part], list[int]] = {}
    for m, (a, b) in enumerate(zip(near.a.tolist(), near.b.tolist(), strict=True)):
        pa, pb = parts[a], parts[b]
        if pa.arm == "right" and pb.arm == "left":
            pa, pb = pb, pa
        groups.setdefault((pa, pb), []).append(m)
    out: list[Touch] = []
    for (pa, pb), rows in groups.items():
        r = np.asarray(rows)
        s = near.sample[r]
        d = near.distance[r]
        order = np.argsort(s, kind="stable")
        s, d = s[order], d[order]
        cut = np.flatnonzero((np.diff(s) > 1) & (np.diff(t[s]) > gap_s * (1 + 1e-9))) + 1
        for seg_s, seg_d in zip(np.split(s, cut), np.split(d, cut), strict=True):
            k = int(np.argmin(seg_d))
            out.append(
                Touch(
                    pa,
                    pb,
                    float(t[seg_s[0]]),
                    float(t[seg_s[-1]]),
                    int(seg_s[0]),
                    int(seg_s[-1]),
                    float(-seg_d[k]),
                    float(t[seg_s[k]]),
                )
            )
    out.sort(key=lambda x: (x.t_start, -x.depth))
    return out


def obstacle_pose(position: Sequence[float] | np.ndarray, R: np.ndarray | None = None) -> np.ndarray:
    """(4, 4) pose of an obstacle's centre at ``position`` with rotation ``R`` (default upright)."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = position
    return T


__all__ = [
    "ARM_NOT_GRIPPER",
    "ARM_PARTS",
    "BODY_PARTS",
    "MARGIN_M",
    "CollisionModel",
    "Near",
    "Obstacle",
    "Part",
    "RobotGeometry",
    "Touch",
    "obstacle_pose",
    "stretches",
]
