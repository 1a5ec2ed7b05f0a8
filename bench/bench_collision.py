"""Collision benchmark (issue 29, decision 087): what checking for contacts costs, with the plain IK beside it.

* a 30 s skill at 100 Hz (3000 samples; the scripted pick-place, both grasps and releases, timed to 30 s) through
  the pick-place scene: ``studio.world.contacts.touches`` (the objects moved with the world's events, the carried
  block with the gripper, the rules of what may touch) and the bare ``CollisionModel.near``; baseline: the plain
  path IK of the same 3000 poses (``solve_path``) and ``simulate`` (the world's events);
* one handle move: the way from where the arm is to the IK's answer checked every 5 mm
  (``studio.world.contacts.first_contact``, as ``Teaching.free_way`` does) for a 1 cm key step and a 6 cm drag;
  baseline: the handle IK of that move (``reach_pose``).

Prints medians of wall time and, in brackets, of this process's CPU time (on a machine other work loads, the
CPU time is what the check itself costs); never asserts on time. Run: ``.venv/bin/python bench/bench_collision.py``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from _timer import median_ms

from studio.core.collision import CollisionModel
from studio.core.ik_path import solve_path
from studio.core.kinematics import Baxter
from studio.core.posture_ik import reach_pose
from studio.teacher import teach
from studio.world import World, preset, simulate
from studio.world.contacts import first_contact, scene_model, touches

CHECK_STEP_M = 0.005  # as studio.controller.teaching


def medians(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """Median wall and CPU milliseconds of ``repeats`` calls."""
    return median_ms(fn, repeats), median_ms(fn, repeats, time.process_time)


def said(m: tuple[float, float]) -> str:
    return f"{m[0]:.1f} ms (CPU {m[1]:.1f} ms)"


def skill_30s(b: Baxter) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The scripted pick-place, resampled to 3000 samples over 30 s."""
    plan = teach("pick-place", 0)
    n = 3000
    t = np.linspace(0.0, 30.0, n)
    src = np.linspace(0.0, float(plan.t[-1]), n)
    q = np.column_stack([np.interp(src, plan.t, plan.q[:, j]) for j in range(14)])
    g = np.column_stack([np.interp(src, plan.t, plan.gripper[:, j]) for j in range(2)])
    return t, q, g


def main() -> None:
    b = Baxter.load()
    scene = preset("pick-place")
    t, q, g = skill_30s(b)
    run = simulate(t, q, g, scene, baxter=b)
    touches(t, q, g, scene, run, b)  # the model built once per scene (cached), as in the studio
    found = touches(t, q, g, scene, run, b)
    t_touch = medians(lambda: touches(t, q, g, scene, run, b), 7)
    model: CollisionModel = scene_model(scene, moving={"block"})
    poses = {o.name: np.eye(4) for o in scene.objects}
    for o in scene.objects:
        poses[o.name][:3, 3] = (o.position[0], o.position[1], o.position[2] + o.size[2] / 2)
    t_near = medians(lambda: model.near(q, g, poses), 7)
    t_sim = medians(lambda: simulate(t, q, g, scene, baxter=b), 5)
    P, W = b.fk_batch("left", q[:, :7])
    t_ik = medians(lambda: solve_path(t, P, W, "left", q[0, :7], b), 5)
    print(f"a 30 s skill at 100 Hz ({len(t)} samples), pick-place scene, {len(found)} contacts found:")
    print(f"  contacts check (touches: objects along the motion, rules): median {said(t_touch)}")
    print(f"  the model's batch check alone, the block left where it stands (CollisionModel.near): {said(t_near)}")
    print(
        f"  baseline plain path IK of the same poses (solve_path): median {said(t_ik)} "
        f"(check / IK {t_touch[0] / t_ik[0]:.2f}, CPU {t_touch[1] / t_ik[1]:.2f})"
    )
    print(f"  baseline the world's events (simulate): median {said(t_sim)}")

    world = World(scene, b)
    objects = world.poses()
    home = np.concatenate([b.neutral("left"), b.neutral("right")])
    p0, w0 = b.fk("left", home[:7])
    start = np.asarray(reach_pose(b, "left", p0 + np.array([0.1, 0.0, -0.1]), w0, home[:7]).result.q)
    for label, move in (("1 cm key step", np.array([0.0, 0.0, -0.01])), ("6 cm drag", np.array([0.04, 0.03, -0.03]))):
        p_start = b.fk("left", start)[0]

        def ik(move: np.ndarray = move, p_start: np.ndarray = p_start) -> np.ndarray:
            return np.asarray(reach_pose(b, "left", p_start + move, w0, start, rest=b.neutral("left")).result.q)

        q_to = ik()
        a, z = np.concatenate([start, home[7:]]), np.concatenate([q_to, home[7:]])
        n = int(min(max(math.ceil(max(float(np.linalg.norm(move)), 0.5 * np.abs(z - a).max()) / CHECK_STEP_M), 1), 80))
        Q = a + np.linspace(0.0, 1.0, n + 1)[:, None] * (z - a)
        G = np.array([[100.0, 100.0]])
        first_contact(Q, G, objects, scene, b)
        t_check = medians(lambda Q=Q, G=G: first_contact(Q, G, objects, scene, b), 41)
        t_handle = medians(ik, 41)
        print(f"one handle move, {label} ({n + 1} poses checked): median {said(t_check)}")
        print(
            f"  baseline handle IK of that move (reach_pose): median {said(t_handle)} "
            f"(check / IK {t_check[0] / t_handle[0]:.1f})"
        )


if __name__ == "__main__":
    main()
