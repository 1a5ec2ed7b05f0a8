"""Which pairs of bodies come closer than a margin, at one pose or along a path: Baxter and what stands around it.

:class:`CollisionModel` (built once per scene): the robot's bodies (:mod:`studio.core.robot_geometry`) and the
obstacles given (:mod:`studio.core.obstacles`; moving per sample or not). :meth:`CollisionModel.near`: bounding
spheres first (every few samples on a long path, the margin widened), coal's signed distance for what they leave
in. As stretches of time: :mod:`studio.core.touches`; rules and words: :mod:`studio.world.contacts`. Decision 087."""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass

import coal
import numpy as np

from studio.core.errors import InvalidInput
from studio.core.obstacles import Obstacle
from studio.core.robot_geometry import ARM_NOT_GRIPPER, FEW, FINGER_TRAVEL_M, Part, RobotGeometry, cover, rotate
from studio.core.types import Arm

#: Pairs closer than this (m) touch: the safety margin every check keeps.
MARGIN_M = 0.005
#: A path's broad phase looks at every this many samples (each standing for its neighbours, the margin widened by
#: how far anything moves to them); the exact distances are then taken at every sample it leaves in.
COARSE_STRIDE = 4


def _of(p: Part, arm: Arm, parts: Collection[str]) -> bool:
    return p.robot and p.arm == arm and p.part in parts


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
            c, r, box = cover(g.geometry)
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
            c, r, _ = cover(o.geometry())
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
                c, r, _ = cover(o.geometry())
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
        return rotate(self.Rj[rows, j], m._sl[m._cols[body]]) + self.pj[rows, j, None, :]

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
        pts = rotate(T[:, :3, :3], c) + T[:, None, :3, 3]
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


__all__ = ["COARSE_STRIDE", "MARGIN_M", "CollisionModel", "Near"]
