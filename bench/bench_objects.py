"""Skills that follow the objects (issue 20): task success where the objects were never demonstrated.

For stack-cup and pick-place the scripted teacher demonstrates with the objects at 3–5 random places each
(within ±15 cm and ±45° of the usual spots; places the arm cannot reach are drawn again). The skill is then
placed (``place_skill``: segments in the current object frames, whole-path IK) with the objects at new random
places inside the demonstrated region and outside it, previewed (joint trajectory played through the world)
and judged: success = every object ends within 1 cm of its goal relative to the object it was put on (or the
spot it came from). The same placements are previewed with the paper's absolute path and with a
frames-combined baseline (each whole demonstration in every object's frame, combined as TP-GMM does:
:class:`FramesCombined`).

    .venv/bin/python bench/bench_objects.py [--inside 50] [--outside 20] [--seed 1] [--tasks stack-cup pick-place]

Prints per task and mode: success rate, worst error, IK tracking (share of preview samples within 1 mm / 0.01
rad), the largest joint step at a segment border against the largest elsewhere, and how often the studio said
"outside" before the run (it must, every time, outside; never inside).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from studio import teacher
from studio.core import sampling
from studio.core.errors import IkFailed
from studio.core.execution import joint_trajectory
from studio.core.frames import ROBOT, frame_of, to_local, to_world, turn
from studio.core.kinematics import Baxter
from studio.core.pipeline import demo_from_recording, learn_skill
from studio.core.rotations import make_sign_continuous
from studio.core.segments import learn_relative, place_skill
from studio.core.types import Demo
from studio.teacher import Place, Places
from studio.world import preset, simulate, task_goal
from studio.world.reach import outside
from studio.world.relative import demo_objects, objects_now, relative_goal

SUCCESS_M = 0.01
SPAN_M, SPAN_RAD = 0.15, math.radians(45)


def _random_places(rng: np.random.Generator) -> Places:
    return Places(*(Place(*rng.uniform(-SPAN_M, SPAN_M, 2), rng.uniform(-SPAN_RAD, SPAN_RAD)) for _ in range(2)))


def demonstrate(task: str, n: int, rng: np.random.Generator, b: Baxter) -> tuple[list, list, list, list[Places]]:
    demos, objs, events, used = [], [], [], []
    seed = int(rng.integers(1000))
    while len(demos) < n:
        seed += 1
        pl = _random_places(rng)
        try:
            plan = teacher.teach(task, seed, places=pl)
        except RuntimeError:
            continue
        rec = teacher.recording_from_plan(plan)
        run = simulate(rec.t, rec.q, rec.gripper, preset(task, ("left",), pl), baxter=b)
        demos.append(demo_from_recording(rec, "left", b))
        events.append(run.events)
        objs.append(demo_objects(run.events, "left"))
        used.append(pl)
    return demos, objs, events, used


#: Samples over the normalised time of a demonstration (the frames-combined baseline).
N_TP = 600
#: The demonstrations' spread below this (m²) is noise (as the segments' weights).
FLOOR_M2 = 0.01**2


class FramesCombined:
    """A task-parameterised baseline without segments (the frames combined as TP-GMM/TP-ProMP do, on the
    time-normalised mean): each whole demonstration in the robot's frame and in the frame of every object the
    skill uses (where it stood at the start), the mean and spread per frame at each instant; reproduced as the
    product of the frames' isotropic Gaussians with the objects where they are now."""

    def __init__(self, demos: list, objs: list, names: list[str]) -> None:
        self.names = names
        grid = np.linspace(0.0, 1.0, N_TP)
        self.duration = float(np.mean([d.duration for d in demos]))
        locs: list[list[np.ndarray]] = [[] for _ in names]
        quats: list[list[np.ndarray]] = [[] for _ in names]
        grips = []
        for d, o in zip(demos, objs, strict=True):
            u = (np.asarray(d.t) - d.t[0]) / d.duration
            pos = np.column_stack([np.interp(grid, u, d.position[:, c]) for c in range(3)])
            q = np.column_stack([np.interp(grid, u, d.orientation[:, c]) for c in range(4)])
            grips.append(np.interp(grid, u, np.asarray(d.gripper, dtype=np.float64)))
            for j, n in enumerate(names):
                f = np.zeros(4) if n == ROBOT else frame_of(o.start_pose(n))
                locs[j].append(to_local(f, pos))
                quats[j].append(turn(q, -f[3]))
        self.mean = [np.mean(x, axis=0) for x in locs]
        self.var = [
            np.mean([np.sum((x - m) ** 2, axis=1) for x in xs], axis=0) + FLOOR_M2
            for xs, m in zip(locs, self.mean, strict=True)
        ]
        self.quat = [np.mean(x, axis=0) for x in quats]
        g = np.mean(grips, axis=0)
        closed = float(np.median([np.min(x) for x in grips]))
        self.gripper = np.where(g < 50.0, closed, 100.0)

    def path(self, now: list) -> Demo:
        at = {o.name: o for o in now}
        world, ori, w = [], [], []
        for j, n in enumerate(self.names):
            f = np.zeros(4) if n == ROBOT else frame_of(at[n])
            world.append(to_world(f, self.mean[j]))
            ori.append(turn(self.quat[j], f[3]))
            w.append(1.0 / self.var[j])
        W = np.array(w)
        pos = np.einsum("jt,jtc->tc", W, np.array(world)) / W.sum(axis=0)[:, None]
        q = np.array(ori)[np.argmax(W, axis=0), np.arange(N_TP)]
        q = make_sign_continuous(q / np.linalg.norm(q, axis=1, keepdims=True))
        t = np.linspace(0.0, self.duration, N_TP)
        return Demo(t, pos, q, self.gripper, name="frames combined")


def _object_names(skill) -> list[str]:
    """The robot's frame (where the arm starts and ends) and every object the skill's frames name."""
    names: list[str] = [ROBOT]
    for b in skill.frames.borders:
        for n in (b.object, b.role.partition(":")[2]):
            if n and n not in names:
                names.append(n)
    return names


def _combined_skill(ab, rel, tp: FramesCombined, scene, b: Baxter, q_seed: np.ndarray):
    """The frames-combined path where the objects are in ``scene``, with its joint trajectory (judged like the
    paper's skill: as played, with the relative skill's regions and goal frames)."""
    import dataclasses

    traj = tp.path(objects_now(scene))
    try:
        jt = joint_trajectory(traj, "left", q_seed, b)
    except IkFailed:  # its start out of reach: played from nowhere, it does nothing
        return None
    return dataclasses.replace(ab, trajectory=traj, joint_trajectory=jt, frames=rel.frames)


def _inside(used: list[Places], rng: np.random.Generator) -> Places:
    """A placement inside the demonstrated places: each object at a random convex mix of where it stood."""
    out = []
    for site in ("pick", "put"):
        w = rng.dirichlet(np.ones(len(used)))
        ps = [getattr(u, site) for u in used]
        out.append(Place(*(float(np.dot(w, [getattr(p, a) for p in ps])) for a in ("dx", "dy", "dyaw"))))
    return Places(*out)


def _outside(task: str, skill, rng: np.random.Generator) -> Places:
    """A placement with at least one object more than 4 cm outside the demonstrated places (within ±25 cm)."""
    assert skill.frames is not None
    while True:
        pl = Places(*(Place(*rng.uniform(-0.25, 0.25, 2), rng.uniform(-SPAN_RAD, SPAN_RAD)) for _ in range(2)))
        scene = preset(task, ("left",), pl)
        objs = {o.name: o for o in scene.objects}
        far = [r.distance(*objs[r.name].position[:2])[0] for r in skill.frames.regions if r.name in objs]
        if far and max(far) > 0.04:
            return pl


def judge(task: str, skill, goal, pl: Places, b: Baxter, relative: bool, build=None) -> dict:
    scene = preset(task, ("left",), pl)
    warned = bool(outside(skill.frames, scene)) if skill.frames is not None else False
    sk = place_skill(skill, objects_now(scene), baxter=b) if relative else skill
    if build is not None:  # a baseline made for this scene
        sk = skill = build(scene)
        if sk is None:
            return {"err": math.inf, "ik": 0.0, "border": 0.0, "step": 0.0, "warned": warned}
    jt = sk.joint_trajectory
    t = np.linspace(0.0, sampling.duration({"left": sk}), max(2, int(sampling.duration({"left": sk}) * 100)))
    q, g = sampling.sample_joints({"left": sk}, t, np.zeros(14), np.array([100.0, 100.0]))
    run = simulate(t, q, g, scene, baxter=b)
    ref = skill if skill.frames is not None else None
    rel_goal = relative_goal(goal, ref.frames, scene) if ref is not None else goal
    errs = []
    for og in rel_goal.objects:
        fp = next(p for p in run.final if p.name == og.name)
        rels = [e for e in run.events if e.kind == "release" and e.object == og.name]
        ok_count = len(rels) == len(og.releases)
        e_final = float(np.linalg.norm(np.asarray(fp.position) - np.asarray(og.final)))
        e_rel = max(
            (
                float(np.linalg.norm(np.asarray(r.pose(og.name).position) - np.asarray(t_)))
                for r, t_ in zip(rels, og.releases, strict=False)
            ),
            default=math.inf,
        )
        errs.append(max(e_final, e_rel) if ok_count and fp.held_by is None else math.inf)
    ik = float(np.mean(jt.converged)) if jt is not None else 0.0
    step = np.max(np.abs(np.diff(jt.q, axis=0)), axis=1) if jt is not None else np.zeros(1)
    border_step = 0.0
    if relative and sk.frames is not None and jt is not None and jt.skill_time is not None:
        from studio.core.frames import adapt

        for tb in adapt(sk.frames, objects_now(scene)).borders:
            i = int(np.clip(np.searchsorted(jt.skill_time, tb), 1, len(step) - 1))
            border_step = max(border_step, float(step[max(i - 3, 0) : i + 3].max()))
    return {"err": max(errs), "ik": ik, "border": border_step, "step": float(step.max()), "warned": warned}


def run_task(task: str, args: argparse.Namespace, b: Baxter) -> None:
    rng = np.random.default_rng([args.seed, len(task)])
    n = int(rng.integers(3, 6))
    t0 = time.perf_counter()
    demos, objs, events, used = demonstrate(task, n, rng, b)
    t_demo = time.perf_counter() - t0
    t0 = time.perf_counter()
    rel = learn_relative(demos, objs, arm="left", baxter=b)
    t_rel = time.perf_counter() - t0
    t0 = time.perf_counter()
    ab = learn_skill(demos, arm="left", baxter=b)
    t_abs = time.perf_counter() - t0
    goal = task_goal(events)
    print(
        f"\n== {task}: {n} demonstrations ({t_demo:.0f} s to make); learned in {t_rel:.1f} s (objects), "
        f"{t_abs:.1f} s (paper)"
    )
    print("   frames:", ", ".join(f"{x.kind} {x.object} in {x.role}" for x in rel.frames.borders))
    inside = [_inside(used, rng) for _ in range(args.inside)]
    out = [_outside(task, rel, rng) for _ in range(args.outside)]
    tp = FramesCombined(demos, objs, _object_names(rel))
    q_seed = demos[0].q[0] if demos[0].q is not None else b.neutral("left")

    def combined(scene):
        return _combined_skill(ab, rel, tp, scene, b, q_seed)

    for label, pls in (("inside", inside), ("outside", out)):
        for mode, sk, relative in (("objects", rel, True), ("paper", ab, False), ("frames", ab, False)):
            t0 = time.perf_counter()
            build = combined if mode == "frames" else None
            rows = [judge(task, sk if relative else _with_frames(ab, rel), goal, pl, b, relative, build) for pl in pls]
            dt = (time.perf_counter() - t0) / max(len(pls), 1)
            err = np.array([r["err"] for r in rows])
            ok = err <= SUCCESS_M
            warned = sum(r["warned"] for r in rows)
            finite = err[np.isfinite(err)]
            worst = f"{finite.max() * 100:.1f} cm" if len(finite) else "-"
            ik = [r["ik"] for r in rows]
            missing = "" if len(finite) == len(err) else f" ({len(err) - len(finite)} not placed)"
            print(
                f"   {label:7s} {mode:7s}: success {ok.mean() * 100:5.1f} % ({ok.sum()}/{len(rows)}), "
                f"worst {worst}{missing}, IK tracked {np.mean(ik) * 100:5.1f} % (min {min(ik) * 100:.1f} %), "
                f"border step {max(r['border'] for r in rows):.3f} rad / max step "
                f"{max(r['step'] for r in rows):.3f} rad, said outside {warned}/{len(rows)}, {dt:.2f} s each"
            )


def _with_frames(ab, rel):
    """The paper's skill carrying the relative skill's regions and goal frames (only to judge it the same way)."""
    import dataclasses

    return dataclasses.replace(ab, frames=rel.frames)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--inside", type=int, default=50)
    ap.add_argument("--outside", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--tasks", nargs="+", default=["stack-cup", "pick-place"])
    args = ap.parse_args()
    b = Baxter.load()
    for task in args.tasks:
        run_task(task, args, b)


if __name__ == "__main__":
    main()
