"""Baxter's collision model (studio.core.collision) against pinocchio and coal used directly: the bodies are where
pinocchio puts them, the batch check finds exactly the pairs a check of every pair finds, the home posture touches
nothing, an overlap is measured as deep as it is."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest

from studio.core.collision import MARGIN_M, CollisionModel
from studio.core.kinematics import Baxter, baxter_urdf_path, package_share_dir
from studio.core.obstacles import Obstacle, obstacle_pose
from studio.core.robot_geometry import Part, RobotGeometry
from studio.core.touches import stretches

TABLE_TOP = -0.07


def table() -> Obstacle:
    return Obstacle("table", "box", (0.7, 1.5, 0.86), obstacle_pose((0.75, 0.0, TABLE_TOP - 0.43)))


def full_q(model: pin.Model, q14: np.ndarray, g: np.ndarray) -> np.ndarray:
    q = pin.neutral(model)
    for i, arm in enumerate(("left", "right")):
        for k, s in enumerate(("s0", "s1", "e0", "e1", "w0", "w1", "w2")):
            q[model.joints[model.getJointId(f"{arm}_{s}")].idx_q] = q14[7 * i + k]
        w = float(np.clip(g[i], 0, 100)) / 100 * 0.020833
        q[model.joints[model.getJointId(f"{arm[0]}_gripper_l_finger_joint")].idx_q] = w
        q[model.joints[model.getJointId(f"{arm[0]}_gripper_r_finger_joint")].idx_q] = -w
    return q


def random_poses(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    b = Baxter.load()
    rng = np.random.default_rng(seed)
    Q = np.concatenate([b.random_configuration("left", rng, n), b.random_configuration("right", rng, n)], axis=1)
    return Q, rng.uniform(0, 100, (n, 2))


def test_the_bodies_are_where_pinocchio_puts_them() -> None:
    b = Baxter.load()
    gm = pin.buildGeomFromUrdf(
        b.model, str(baxter_urdf_path()), pin.GeometryType.COLLISION, package_dirs=[str(package_share_dir())]
    )
    data, gdata = b.model.createData(), gm.createData()
    names = [g.name for g in gm.geometryObjects]
    model = CollisionModel([table()])
    Q, G = random_poses(6, 1)
    from studio.core.collision import _Frames

    at = _Frames(model, Q, G, {})
    for n in range(len(Q)):
        pin.forwardKinematics(b.model, data, full_q(b.model, Q[n], G[n]))
        pin.updateGeometryPlacements(b.model, data, gm, gdata)
        for i, g in enumerate(model.robot.geoms):
            R, p = at.placement(n, i)
            M = gdata.oMg[names.index(g.name)]
            np.testing.assert_allclose(p, M.translation, atol=1e-12)
            np.testing.assert_allclose(R, M.rotation, atol=1e-12)


def test_the_batch_check_finds_every_pair_a_check_of_all_pairs_finds() -> None:
    """The bounding spheres never rule out a pair coal puts within the margin (random postures, arms crossing, a
    table, a cup and a moving block)."""
    cup = Obstacle("cup", "cylinder", (0.07, 0.07, 0.095), obstacle_pose((0.6, 0.1, TABLE_TOP + 0.0475)))
    block = Obstacle("block", "box", (0.05, 0.05, 0.05))
    model = CollisionModel([table(), cup, block], moving=["block"])
    Q, G = random_poses(120, 7)
    rng = np.random.default_rng(3)
    block_at = np.tile(np.eye(4), (len(Q), 1, 1))
    block_at[:, :3, 3] = rng.uniform([0.3, -0.5, -0.2], [1.0, 0.5, 0.4], (len(Q), 3))
    near = model.near(Q, G, {"block": block_at})
    found = {(int(s), int(k)) for s, k in zip(near.sample, near.pair, strict=True)}
    from studio.core.collision import _Frames

    at = _Frames(model, Q, G, {"block": block_at})
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    expected = set()
    for s in range(len(Q)):
        for k, (a, b) in enumerate(model.pairs.tolist()):
            Ra, pa = at.placement(s, a)
            Rb, pb = at.placement(s, b)
            res.clear()
            d = coal.distance(
                model._geometry[a], coal.Transform3s(Ra, pa), model._geometry[b], coal.Transform3s(Rb, pb), req, res
            )
            if d < MARGIN_M:
                expected.add((s, k))
    assert expected, "the random postures should touch something"
    assert found == expected


def test_the_home_posture_touches_nothing_and_an_overlap_is_as_deep_as_it_is() -> None:
    b = Baxter.load()
    home = np.concatenate([b.neutral("left"), b.neutral("right")])
    model = CollisionModel([table()], moving=["block"])
    assert len(model.near(home[None], np.array([[100.0, 100.0]]))) == 0
    block = CollisionModel([table(), Obstacle("block", "box", (0.05, 0.05, 0.05))], moving=["block"])
    T = obstacle_pose((0.8, 0.0, TABLE_TOP - 0.068 + 0.025))  # its bottom 6.8 cm into the table top
    near = block.near(home[None], np.array([[100.0, 100.0]]), {"block": T})
    pair = [
        (block.parts[a].part, block.parts[b].part, d) for a, b, d in zip(near.a, near.b, near.distance, strict=True)
    ]
    assert [(a, b) for a, b, _ in pair] == [("block", "table")]
    assert -pair[0][2] == pytest.approx(0.068, abs=1e-6)


def test_touches_are_stretches_per_pair_of_parts() -> None:
    from studio.core.posture_ik import reach_pose

    model = CollisionModel([table()])
    b = Baxter.load()
    q, w = b.neutral("left"), b.fk("left", b.neutral("left"))[1]
    t = np.arange(60) * 0.1
    z = np.concatenate([np.linspace(0.1, -0.15, 30), np.linspace(-0.15, 0.1, 30)])  # the gripper dips and back
    rows = []
    for zi in z:
        q = np.asarray(reach_pose(b, "left", np.array([0.7, 0.3, zi]), w, q).result.q)
        rows.append(np.concatenate([q, b.neutral("right")]))
    near = model.near(np.array(rows), np.full((60, 2), 100.0))
    out = stretches(near, model.parts, t)
    assert out, "the dip should reach the table"
    first = out[0]
    assert first.b == Part(None, "table", False) and first.a.arm == "left"
    assert 0.0 < first.t_start < first.at < first.t_end < 6.0
    assert len({(x.a, x.b) for x in out}) == len(out)  # one stretch per pair: the dip is one stretch


def test_robot_geometry_is_the_urdfs() -> None:
    rg = RobotGeometry.load()
    parts = {(g.part.arm, g.part.part) for g in rg.geoms}
    for arm in ("left", "right"):
        assert {(arm, p) for p in ("shoulder", "upper arm", "elbow", "forearm", "wrist", "hand", "fingers")} <= parts
    assert {(None, "torso"), (None, "pedestal"), (None, "head")} <= parts


def test_the_light_urdfs_collision_geometry_is_the_originals() -> None:
    """The studio builds its collision model from the light URDF (the first start does not install example-robot-
    data): the same bodies, placements, covering spheres and pairs as from the original URDF and SRDF (a mesh is
    copied as its convex hull, which is what the model takes of it)."""
    light, original = RobotGeometry.load(), RobotGeometry(Baxter(baxter_urdf_path()))
    assert Baxter.load().urdf_path != baxter_urdf_path()
    assert [(g.name, g.part, g.joint) for g in light.geoms] == [(g.name, g.part, g.joint) for g in original.geoms]
    for a, b in zip(light.geoms, original.geoms, strict=True):
        np.testing.assert_allclose(a.R, b.R, atol=1e-12)
        np.testing.assert_allclose(a.p, b.p, atol=1e-12)
        np.testing.assert_allclose(a.spheres, b.spheres, atol=1e-6)
        assert a.radius == pytest.approx(b.radius, abs=1e-6)
        assert (a.box is None) == (b.box is None)
        if a.box is not None and b.box is not None:
            np.testing.assert_allclose(a.box, b.box, atol=1e-6)
    np.testing.assert_array_equal(light.pairs, original.pairs)
