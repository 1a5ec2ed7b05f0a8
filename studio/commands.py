"""Headless commands behind ``studio learn | import-csv | export-csv | make-examples``: each takes the parsed
``argparse`` namespace (:mod:`studio.cli`), prints plain words and returns an exit code (errors: the CLI)."""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from studio.core import sampling
from studio.core.arms import normalize_arms
from studio.core.errors import InvalidInput, NotEnoughData, StudioError
from studio.core.quality import Remedy
from studio.core.types import Recording, Skill
from studio.storage import DEFAULT_ROOT, Session, SessionStore
from studio.words import SHARED_REMEDIES, Remedies, tune_summary
from studio.words import verdict_lines as verdict_words

if TYPE_CHECKING:
    from studio.core.autotune import TuneResult
    from studio.teacher import TeacherPlan

#: The example sessions: task -> (seeds of the three demonstrations, taught arm, notes).
EXAMPLES: dict[str, tuple[tuple[int, ...], str, str]] = {
    "stack-cup": (
        (0, 1, 2),
        "left",
        "Stacking cup task (paper, Table II): take a cup handed over in the air and put it on a stack of cups. "
        "Three demonstrations by the scripted teacher (studio/teacher.py) driving the simulated Baxter "
        "through the recorder at 1 kHz; re-create with `studio make-examples`.",
    ),
    "pick-place": (
        (0, 1, 2),
        "left",
        "Pick and place task (paper, Table III): pick a block at A, place it at B, pick it again and bring it "
        "back to A. Three demonstrations by the scripted teacher (studio/teacher.py) driving the simulated "
        "Baxter through the recorder at 1 kHz; re-create with `studio make-examples`.",
    ),
}


def _sessions_dir(args: argparse.Namespace) -> Path:
    d = getattr(args, "sessions_dir", None)
    return DEFAULT_ROOT if d is None else Path(d)


def _arms(value: str | None, default: Sequence[str]) -> tuple[str, ...]:
    return tuple(default) if value is None else normalize_arms(value)


# -- learn ----------------------------------------------------------------------------------------------------
def learn(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """Learn a session's skill headless, save it into the session and print a short report and the verdict.

    Thresholds still at the old fixed defaults are automatic (they follow the demonstrations); with ``--auto``
    Suggest runs first for each arm and its thresholds and k are used (and saved, for a single arm).
    """
    out = out or sys.stdout
    store = SessionStore(_sessions_dir(args))
    session = store.open(args.session)
    if session.recovery_message:
        print(session.recovery_message, file=out)
    for p in session.problems:
        print(p, file=out)
    if len(session.recordings) < 2:
        raise NotEnoughData(
            f'Session "{session.name}" has {len(session.recordings)} demonstration(s); record or import at least '
            "two (the paper uses three) before learning."
        )
    arms = _arms(getattr(args, "arm", None), session.arms)
    from studio.core import pipeline
    from studio.core.thresholds import ThresholdSettings

    # automatic thresholds follow each arm's demos; values off the old fixed defaults count as the teacher's
    settings: ThresholdSettings = session.thresholds
    k = session.n_clusters
    t0 = time.perf_counter()
    tuned: dict[str, TuneResult] = {}
    if getattr(args, "auto", False):
        from studio.core import autotune

        for arm in arms:
            demos_arm = [pipeline.demo_from_recording(r, arm) for r in session.recordings if arm in r.arms]
            if len(demos_arm) < 2:
                continue
            res = autotune.suggest(demos_arm, current=settings, n_clusters=k, generalization=session.generalization)
            tuned[arm] = res
            k_words = res.n_clusters or "mean key-points per demonstration"
            print(
                f"{arm.capitalize()} arm — suggested thresholds (Detail {res.settings.detail:+.1f}, k = {k_words}) "
                f"in {res.seconds:.1f} s. {tune_summary(res)}",
                file=out,
            )
    if tuned:
        skills: dict[str, Skill] = {}
        for arm in arms:
            r = tuned.get(arm)
            skills.update(
                pipeline.learn_arms(
                    session.recordings,
                    params=r.params if r is not None else settings,
                    arms=(arm,),
                    n_clusters=r.n_clusters if r is not None else k,
                    seed=0,
                    generalization=session.generalization,
                )
            )
    else:
        skills = pipeline.learn_arms(
            session.recordings, params=settings, arms=arms, n_clusters=k, seed=0, generalization=session.generalization
        )
    elapsed = time.perf_counter() - t0
    demos = {arm: list(skill.demo_names) for arm, skill in skills.items()}
    if len(tuned) == 1 and len(arms) == 1:
        # Suggest applied: its settings (Detail, every threshold automatic) and k become the session's
        only = next(iter(tuned.values()))
        session.set_skills(skills, params=only.params, demos=demos)
        session.set_params(only.params, only.settings)
        session.set_n_clusters(only.n_clusters)
    else:
        used = next(iter(skills.values())).params if skills else session.params  # what older studios read
        session.set_skills(skills, params=used, demos=demos)
    print(report(session, skills, elapsed), file=out)
    for arm, skill in skills.items():
        lines = verdict_lines(session, arm, skill, bool(tuned))
        if lines:
            print(f"\nHow good is the {arm} arm's skill?", file=out)
            for line in lines:
                print(f"  {line}", file=out)
    return 0


def cli_remedies(session: str, auto: bool) -> Remedies:
    """The knob that would help, said with ``studio learn``'s options (it has no Suggest or Detail)."""
    again = f'learn again with `studio learn "{session}" --auto`, which searches for better thresholds'
    search = "record one or two more demonstrations (--auto already chose the thresholds)" if auto else again
    redo = "re-record it, or hide it in the studio"
    return {**SHARED_REMEDIES, Remedy.MORE_KEYPOINTS: search, Remedy.SHARPER_CORNERS: search, Remedy.REDO_DEMO: redo}


def verdict_lines(session: Session, arm: str, skill: Skill | None, auto: bool = False) -> list[str]:
    """The quality verdict of one arm's skill in plain words (empty for something that is not a learned skill)."""
    from studio.core.pipeline import demo_from_recording, judge_skill

    if not isinstance(skill, Skill):
        return []
    recs = {r.name: r for r in session.recordings}
    demos = [demo_from_recording(recs[n], arm) for n in skill.demo_names if n in recs]
    if len(demos) != len(skill.demo_names):
        return []
    _, verdict = judge_skill(skill, demos, fixed_k=session.n_clusters is not None)
    return list(verdict_words(verdict, cli_remedies(session.name, auto)))


def _fmt(x: float, spec: str = ".3g") -> str:
    try:
        return format(float(x), spec)
    except (TypeError, ValueError):
        return "—"


def report(session: Session, skills: Mapping[str, Skill], elapsed: float | None = None) -> str:
    """The plain-text learning report: per demo samples and key-points, k, log-likelihood, reference, quality."""
    lines = [f'Session "{session.name}": {len(session.recordings)} demonstrations, learned ' + ", ".join(skills)]
    if elapsed is not None:
        lines[0] += f" in {elapsed:.1f} s"
    for arm, sk in skills.items():
        lines += _arm_report(session, arm, sk)
    lines.append("")
    lines.append(f"Saved into the session ({session.path}).")
    return "\n".join(lines)


def _arm_report(session: Session, arm: str, sk: Skill) -> list[str]:
    info = session.skill_info.get(arm)
    names = list(sk.demo_names or (info.demos if info is not None else ()))
    names = names or [r.name for r in session.recordings if arm in r.arms]
    kps = list(sk.keypoints)
    ll = np.atleast_1d(np.asarray(sk.loglik, dtype=float))
    ref = int(sk.reference)
    lines = ["", f"{arm} arm", f"  {'demonstration':<28}{'samples':>10}{'key-points':>12}{'log-likelihood':>16}"]
    recs = {r.name: r for r in session.recordings}
    for i, nm in enumerate(names):
        n = len(recs[nm]) if nm in recs else 0
        k = len(kps[i]) if i < len(kps) else 0
        llv = _fmt(ll[i], ".1f") if i < ll.shape[0] else "—"
        mark = "  ← reference" if i == ref else ""
        lines.append(f"  {nm[:27]:<28}{n:>10}{k:>12}{llv:>16}{mark}")
    lines.append(f"  clusters (HMM states) k = {sk.n_clusters}")
    tr = sk.trajectory
    lines.append(f"  generalized trajectory: {len(tr)} samples, {tr.duration:.1f} s")
    jt = sk.joint_trajectory
    if jt is not None:
        pe = np.asarray(jt.position_error, dtype=float)
        oe = np.asarray(jt.orientation_error, dtype=float)
        conv = np.asarray(jt.converged, dtype=bool)
        lines.append(
            f"  joint trajectory (IK): {conv.mean() * 100:.1f} % of poses reached; position error "
            f"median {np.median(pe) * 1000:.2f} mm, max {pe.max() * 1000:.2f} mm; orientation error max "
            f"{np.degrees(oe.max()):.2f}°"
        )
    dists = _distances_to_demos(tr.position, [recs[nm] for nm in names if nm in recs], arm)
    if dists:
        lines.append(
            f"  distance of the generalized path to the demonstrations: mean {np.mean(dists) * 1000:.1f} mm "
            f"(per demo {', '.join(f'{x * 1000:.1f}' for x in dists)} mm)"
        )
    return lines


def _distances_to_demos(path: np.ndarray, recordings: list[Recording], arm: str) -> list[float]:
    """How far the generalized path stays from each demonstration (mean nearest distance, m)."""
    if not recordings:
        return []
    from studio.core.kinematics import Baxter  # pinocchio: loaded only for a report

    b = Baxter.load()
    dists = []
    p = np.asarray(path)[:: max(1, len(path) // 2000)]
    for r in recordings:
        pos, _ = b.fk_batch(arm, r.arm_q(arm)[:: max(1, len(r) // 2000)])
        d = np.sqrt(((p[:, None, :] - pos[None, :, :]) ** 2).sum(-1)).min(axis=1)
        dists.append(float(d.mean()))
    return dists


# -- CSV ------------------------------------------------------------------------------------------------------
def import_csv(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """Import Baxter SDK joint-recorder CSV files into a session (created if missing).

    Good files are imported even when others fail; the exit code is 1 if any file failed.
    """
    from studio.csv_io import import_csv as read_csv

    out = out or sys.stdout
    store = SessionStore(_sessions_dir(args))
    arms = _arms(getattr(args, "arm", None), ("left",))
    recs: list[tuple[Path, Recording]] = []
    failed: list[str] = []
    for f in args.files:
        try:
            recs.append((Path(f), read_csv(f, arms=arms)))
        except StudioError as exc:
            failed.append(f"  {f}: {exc}")
    if recs:
        if store.exists(args.session):
            session = store.open(args.session)
        else:
            session = store.create(args.session, arms=arms)
            print(f'Created session "{session.name}".', file=out)
        for f, r in recs:
            try:
                i = session.add_recording(r)
            except StudioError as exc:  # this file is named; the others are still imported
                failed.append(f"  {f}: {exc}")
                continue
            rr = session.recordings[i]
            print(f'Imported {f.name} as "{rr.name}": {len(rr)} samples, {rr.duration:.1f} s.', file=out)
    if failed:
        print("These files were not imported:\n" + "\n".join(failed), file=out)
        return 1
    return 0


def export_csv(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """Write a session's learned joint trajectory as a CSV for the Baxter SDK's playback example."""
    from studio.csv_io import export_joint_trajectory_csv

    out = out or sys.stdout
    store = SessionStore(_sessions_dir(args))
    session = store.open(args.session, recover=False)
    skills = sampling.executable(session.skills)
    if not skills:
        raise NotEnoughData(
            f'Session "{session.name}" has no learned joint trajectory yet. '
            f'Learn it first: studio learn "{session.name}"'
        )
    if session.skills_stale:
        print(
            "Note: the demonstrations changed since the skill was learned; exporting the last learned skill.", file=out
        )
    n = export_joint_trajectory_csv(skills, args.out)
    print(
        f"Wrote {args.out}: {n} rows ({', '.join(skills)} arm). Run it on Baxter with "
        f"`rosrun baxter_examples joint_trajectory_file_playback.py -f {Path(args.out).name}`.",
        file=out,
    )
    return 0


# -- example sessions -----------------------------------------------------------------------------------------
def record_plan(session: Session, plan: TeacherPlan, name: str, *, noise_seed: int) -> int:
    """Drive a :class:`SimulatedBaxter` through ``plan`` in manual-step mode, record it, add it to ``session``
    with its object events (a :class:`~studio.world.World` listening to the robot): the real path of the studio
    (backend → recorder → session), faster than real time and deterministic."""
    from studio import teacher
    from studio.recorder import Recorder
    from studio.robot_backend.base import JointStateBatch
    from studio.robot_backend.simulated import SimulatedBaxter
    from studio.world import World, on_clock

    sim = SimulatedBaxter(
        rate_hz=plan.rate_hz,
        q0=plan.q[0],
        gripper0=plan.gripper[0],
        sensor_noise=teacher.JOINT_NOISE_RAD,
        quantum=teacher.JOINT_QUANTUM_RAD,
        gripper_noise=teacher.GRIPPER_NOISE_PERCENT,
        seed=noise_seed,
    )
    world = World(session.objects.scene)
    first: list[float] = []  # the robot's time of the recording's first sample

    def follow(batch: JointStateBatch) -> None:
        if not first and len(batch):
            first.append(float(batch.t[0]))
        world.on_batch(batch)

    unsubscribe = sim.subscribe(follow)
    world.snapshot("start")
    rec = Recorder(sim, session.recording_dir, plan.arms, name=name)
    rec.start()
    sim.run_targets(plan.q, plan.gripper, batch=16)
    recording = rec.stop()
    unsubscribe()
    world.snapshot("end")
    events = on_clock(world.events, first[0] if first else 0.0, float(recording.duration))
    index = session.add_recording(recording, events=events)
    rec.discard()
    shutil.rmtree(session.recording_dir, ignore_errors=True)
    return index


def build_example(store: SessionStore, task: str, *, learn_skill: bool = False, out: TextIO | None = None) -> Session:
    """(Re)create the example session ``task`` in ``store``; replaces an existing one only when complete."""
    from studio import teacher
    from studio.world import preset

    out = out or sys.stdout
    seeds, arm, notes = EXAMPLES[task]
    store.root.mkdir(parents=True, exist_ok=True)
    tmp = store.root / f".tmp-example-{uuid.uuid4().hex[:8]}"
    tmp_store = SessionStore(tmp)
    try:
        session = tmp_store.create(task, arms=(arm,), notes=notes, precision="float32")
        session.created = "2026-11-22T00:00:00+00:00"  # fixed: regenerating does not churn the manifest
        session.set_scene(preset(task, (arm,)))  # the task's objects, where the scripted teacher acts
        for i, seed in enumerate(seeds):
            plan = teacher.teach(task, seed, arm=arm)
            record_plan(session, plan, f"demo {i + 1}", noise_seed=1000 * (i + 1) + seed)
            r = session.recordings[-1]
            print(f"  {task} demo {i + 1}: {len(r)} samples, {r.duration:.1f} s", file=out)
        if learn_skill:
            try:
                from studio.core.pipeline import learn_arms
            except ImportError:
                print("  (the learning pipeline is not available; the skill was not learned)", file=out)
            else:
                skills = learn_arms(session.recordings, params=session.params, arms=(arm,), seed=0)
                session.set_skills(skills, demos={a: list(sk.demo_names) for a, sk in skills.items()})
                print(report(session, skills), file=out)
        final = store.root / task
        old = store.root / f".tmp-old-{uuid.uuid4().hex[:8]}"
        if final.exists():
            os.rename(final, old)
        os.rename(tmp / task, final)
        shutil.rmtree(old, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return store.open(task, recover=False)


def make_examples(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """(Re)create the example sessions "stack-cup" and "pick-place" with the scripted teacher."""
    out = out or sys.stdout
    store = SessionStore(_sessions_dir(args))
    only = getattr(args, "only", None)
    tasks = [only] if only else list(EXAMPLES)
    for task in tasks:
        if task not in EXAMPLES:
            raise InvalidInput(f'Unknown example "{task}": choose one of {", ".join(EXAMPLES)}.')
        t0 = time.perf_counter()
        print(f'Making example session "{task}"...', file=out)
        # demonstrations only: a stored skill would tie the examples to today's skill file format
        s = build_example(store, task, learn_skill=bool(getattr(args, "learn", False)), out=out)
        size = sum(p.stat().st_size for p in s.path.rglob("*") if p.is_file())
        print(f"  done in {time.perf_counter() - t0:.1f} s: {s.path} ({size / 1e6:.1f} MB)", file=out)
    return 0


__all__ = [
    "EXAMPLES",
    "build_example",
    "cli_remedies",
    "export_csv",
    "import_csv",
    "learn",
    "make_examples",
    "record_plan",
    "report",
    "verdict_lines",
]
