"""Skills that follow the objects (issues 20, 27): task success where the objects were never demonstrated.

For stack-cup and pick-place the scripted teacher demonstrates with the objects at 3–5 random places each
(within ±15 cm and ±45° of the usual spots; places the arm cannot reach are drawn again). The skill is then
placed (``place_skill``: segments in the current object frames, whole-path IK) with the objects at new random
places inside the demonstrated region and outside it, previewed (joint trajectory played through the world)
and judged by the task's goal (success = each object really on its target, read from the world's state;
"false claims": the task result's words said done when it was not). The same placements are previewed with
the paper's absolute path and with a frames-combined baseline (:class:`FramesCombined`). The one-place rows
(:func:`one_place`) teach at one placement through the controller and move one object 5–40 cm.

    .venv/bin/python bench/bench_objects.py [--inside 50] [--outside 20] [--seed 1] [--tasks stack-cup pick-place]
        [--one-place 40] [--runs 5] [--only-one-place]
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
from studio.world import START, TABLE, preset, session_goal, simulate, task_result
from studio.world.reach import outside
from studio.world.relative import demo_objects, objects_now, release_rules

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


def on_target(run, goal) -> bool:
    """Whether the run really did the goal, read from the world's own state (what each release left the object
    resting on, where it ended), not from the task result's words."""
    start = next(e for e in run.events if e.kind == "start")
    for name in goal.objects:
        rels = [e.pose(name) for e in run.events if e.kind == "release" and e.object == name]
        places = goal.of(name)
        final = next(p for p in run.final if p.name == name)
        if len(rels) != len(places) or final.held_by is not None:
            return False
        for pose, pl in [*zip(rels, places, strict=True), (final, places[-1])]:
            if pl.onto == START:
                if math.dist(pose.position, start.pose(name).position) > 0.02:
                    return False
            elif pl.onto != TABLE and pose.on != pl.onto:
                return False
    return True


def judge(task: str, skill, goal, pl: Places, b: Baxter, relative: bool, build=None) -> dict:
    """The skill previewed with the objects at ``pl``: the joints played through the world (forward kinematics),
    judged by the task's goal (``err``: how far from the spot on the target; inf when not done), whether the
    objects really ended on their targets, and whether the words claimed so."""
    scene = preset(task, ("left",), pl)
    warned = bool(outside(skill.frames, scene)) if skill.frames is not None else False
    sk = place_skill(skill, objects_now(scene), baxter=b) if relative else skill
    if build is not None:  # a baseline made for this scene
        sk = skill = build(scene)
        if sk is None:
            return {"err": math.inf, "ik": 0.0, "border": 0.0, "step": 0.0, "warned": warned, "false": False}
    jt = sk.joint_trajectory
    t = np.linspace(0.0, sampling.duration({"left": sk}), max(2, int(sampling.duration({"left": sk}) * 100)))
    q, g = sampling.sample_joints({"left": sk}, t, np.zeros(14), np.array([100.0, 100.0]))
    run = simulate(t, q, g, scene, baxter=b)
    result = task_result(run, goal)
    really = on_target(run, goal)
    errs = [r.distance if r.ok and r.distance is not None else math.inf for r in result.objects]
    ik = float(np.mean(jt.converged)) if jt is not None else 0.0
    step = np.max(np.abs(np.diff(jt.q, axis=0)), axis=1) if jt is not None else np.zeros(1)
    border_step = 0.0
    if relative and sk.frames is not None and jt is not None and jt.skill_time is not None:
        from studio.core.frames import adapt

        for tb in adapt(sk.frames, objects_now(scene)).borders:
            i = int(np.clip(np.searchsorted(jt.skill_time, tb), 1, len(step) - 1))
            border_step = max(border_step, float(step[max(i - 3, 0) : i + 3].max()))
    return {
        "err": max(errs) if really else math.inf,
        "ik": ik,
        "border": border_step,
        "step": float(step.max()),
        "warned": warned,
        "false": result.ok and not really,
    }


def run_task(task: str, args: argparse.Namespace, b: Baxter) -> None:
    rng = np.random.default_rng([args.seed, len(task)])
    n = int(rng.integers(3, 6))
    t0 = time.perf_counter()
    demos, objs, events, used = demonstrate(task, n, rng, b)
    t_demo = time.perf_counter() - t0
    t0 = time.perf_counter()
    scene = preset(task, ("left",))
    goal = session_goal(scene.preset, scene.goal, scene.names(), events)
    rel = learn_relative(demos, objs, arm="left", baxter=b, rules=release_rules(goal, objs[0]))
    t_rel = time.perf_counter() - t0
    t0 = time.perf_counter()
    ab = learn_skill(demos, arm="left", baxter=b)
    t_abs = time.perf_counter() - t0
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
            ok = np.isfinite(err)  # the goal holds: each object really on its target
            warned = sum(r["warned"] for r in rows)
            false = sum(r["false"] for r in rows)
            finite = err[np.isfinite(err)]
            worst = f"{finite.max() * 100:.1f} cm" if len(finite) else "-"
            ik = [r["ik"] for r in rows]
            missing = "" if len(finite) == len(err) else f" ({len(err) - len(finite)} not placed)"
            print(
                f"   {label:7s} {mode:7s}: success {ok.mean() * 100:5.1f} % ({ok.sum()}/{len(rows)}), "
                f"worst {worst}{missing}, IK tracked {np.mean(ik) * 100:5.1f} % (min {min(ik) * 100:.1f} %), "
                f"border step {max(r['border'] for r in rows):.3f} rad / max step "
                f"{max(r['step'] for r in rows):.3f} rad, said outside {warned}/{len(rows)}, false claims {false}, "
                f"{dt:.2f} s each"
            )


def _with_frames(ab, rel):
    """The paper's skill carrying the relative skill's regions and goal frames (only to judge it the same way)."""
    import dataclasses

    return dataclasses.replace(ab, frames=rel.frames)


#: Where one take of the one-place rows lets go, off the target (the hand's place, m): the pad's centre 7 cm away
#: (the block lands on the table), the bottom cup's 5 cm (the cup lands beside it).
SLOPPY = {"pick-place": Place(0.07, 0.0, 0.0), "stack-cup": Place(0.05, 0.0, 0.0)}
#: What each task carries and what it puts it onto (one arm).
CARRIED = {"pick-place": ("block", "pad"), "stack-cup": ("cup", "bottom cup")}


def one_place(task: str, args: argparse.Namespace) -> None:
    """Three takes at one placement (clean, and with one take's release a few cm off the target) taught through the
    studio's controller on the simulated robot; then the carried object moved 5–40 cm, and separately the target:
    each placement previewed (the joints Play plays, through the world) and, for the first ``--runs``, run on the
    robot (its recorded joint states, through the live world). Counted: the words that claim the task while the
    object is not on its target (must be 0), and how often the task is done."""
    import shutil
    import tempfile
    from pathlib import Path

    from studio.controller import Controller
    from studio.robot_backend.simulated import SimulatedBaxter
    from studio.storage import SessionStore

    carried, target = CARRIED[task]
    rng = np.random.default_rng([args.seed, 27, len(task)])
    for variant in ("clean", "sloppy"):
        root = Path(tempfile.mkdtemp(prefix="bench-one-place-"))
        sim = SimulatedBaxter()
        ctl = Controller(store=SessionStore(root), session="bench", backend=sim)
        ctl.start()
        sim.stop()
        try:
            ctl.sessions.new("one place", scene=task)
            t0 = time.perf_counter()
            seed = 0
            while len(ctl.session.recordings) < 3:
                seed += 1
                sloppy = variant == "sloppy" and len(ctl.session.recordings) == 1
                try:
                    plan = teacher.teach(task, seed, places=Places(put=SLOPPY[task]) if sloppy else Places(), once=True)
                except RuntimeError:  # the arm cannot follow this take's key-frames: the next seed
                    continue
                sim.teleport(plan.q[0], plan.gripper[0])
                sim.step(20)
                ctl.teaching.start_recording()
                sim.run_targets(plan.q, plan.gripper, batch=16)
                ctl.teaching.stop_recording()
            ctl.training.train().result(timeout=600)
            took = time.perf_counter() - t0
            landed = [
                next(e for e in ctl.session.objects.events(f) if e.kind == "release").pose(carried).on
                for f in ctl.session.demo_files
            ]
            frames = [f"{x.kind} in {x.role}" for x in ctl.session.skills["left"].frames.borders]
            print(f"\n== {task}, one place, {variant}: takes landed on {landed}; frames {frames} ({took:.0f} s)")
            for moving in (carried, target):
                o = ctl.scene.scene.object(moving)
                rows = []
                for k in range(args.one_place):
                    d, a = rng.uniform(0.05, 0.40), rng.uniform(-math.pi, math.pi)
                    at = (o.position[0] + d * math.cos(a), o.position[1] + d * math.sin(a), o.position[2])
                    try:
                        ctl.scene.move(moving, at)
                    except Exception:  # out of the workspace: drawn again
                        continue
                    rows.append(_one_placement(ctl, sim, carried, target, run=k < args.runs))
                    ctl.scene.move(moving, o.position, o.yaw)
                done = [r for r in rows if r["really"]]
                false = sum(r["claim"] and not r["really"] for r in rows)
                claimed = sum(r["claim"] for r in rows)
                runs = [r for r in rows if r["run"] is not None]
                run_false = sum(r["run"][0] and not r["run"][1] for r in runs)
                run_done = sum(r["run"][1] for r in runs)
                print(
                    f"   {moving} moved 5–40 cm: previews {len(rows)}, done {len(done)}, claimed {claimed}, "
                    f"false claims {false}; runs {len(runs)}, done {run_done}, false claims {run_false}"
                )
        finally:
            ctl.close()
            ctl.shutdown()
            shutil.rmtree(root, ignore_errors=True)


def _one_placement(ctl, sim, carried: str, target: str, *, run: bool) -> dict:
    """The preview (and a run) with the objects where the scene has them now: the words' claim against where the
    carried object really ended (forward kinematics on the executed joints)."""
    result = ctl.scene.task_result()
    rec = ctl.playback.preview_recording()
    final = {p.name: p for p in simulate(rec.t, rec.q, rec.gripper, ctl.scene.scene, baxter=ctl.baxter).final}
    out = {"claim": bool(result is not None and result.ok), "really": final[carried].on == target, "run": None}
    if run and not ctl.execution.why_not():
        ctl.execution.run()
        while sim.progress().active:
            sim.step(200)
        deadline = time.monotonic() + 60
        while ctl.execution.running and time.monotonic() < deadline:
            time.sleep(0.05)
        st = ctl.execution.status
        live = {p.name: p for p in ctl.scene.live.poses()}
        out["run"] = (bool(st.ok), live[carried].on == target)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--inside", type=int, default=50)
    ap.add_argument("--outside", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--tasks", nargs="+", default=["stack-cup", "pick-place"])
    ap.add_argument("--one-place", type=int, default=40, help="placements per one-place row (0: none)")
    ap.add_argument("--runs", type=int, default=5, help="of those, run on the simulated robot")
    ap.add_argument("--only-one-place", action="store_true", help="only the one-place rows")
    args = ap.parse_args()
    b = Baxter.load()
    for task in args.tasks:
        if not args.only_one_place:
            run_task(task, args, b)
        if args.one_place:
            one_place(task, args)


if __name__ == "__main__":
    main()
