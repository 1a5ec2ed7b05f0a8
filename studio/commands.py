"""Headless commands behind ``studio learn | import-csv | export-csv | make-examples``: each takes the parsed
``argparse`` namespace (:mod:`studio.cli`), prints plain words and returns an exit code (errors: the CLI)."""

from __future__ import annotations

import argparse
import logging
import os
import shutil
import sys
import time
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from studio.core import sampling
from studio.core.arms import normalize_arms
from studio.core.errors import InvalidInput, NotEnoughData, StudioError
from studio.core.types import Arm, Recording, Skill
from studio.storage import DEFAULT_ROOT, Session, SessionStore, check_demo_name
from studio.words import count_words, tune_summary
from studio.words.controls import CLI_CONTROLS
from studio.words.quality import cli_remedies
from studio.words.quality import verdict_lines as verdict_words

if TYPE_CHECKING:
    from studio.controller import Controller
    from studio.teacher import TeacherPlan

log = logging.getLogger(__name__)

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


def _arms(value: str | None, default: Sequence[str]) -> tuple[Arm, ...]:
    return normalize_arms(default if value is None else value)


# -- learn ----------------------------------------------------------------------------------------------------
@contextmanager
def headless(store: SessionStore, session: Session) -> Iterator[Controller]:
    """The studio's controller on ``session`` without a GUI or a running robot: commands learn through it, so
    they choose demonstrations, thresholds and k as the Train button does. Failures raise."""
    from studio.controller import Controller
    from studio.robot_backend.simulated import SimulatedBaxter

    ctl = Controller(
        store=store, session=session, backend=SimulatedBaxter(), notifier=_Quiet(), headless=True, controls=CLI_CONTROLS
    )
    try:
        yield ctl
    finally:
        ctl.close()
        ctl.shutdown()


class _Quiet:
    """A headless controller's notifications: failures raise instead, and the GUI's hints would not fit here."""

    def notify(self, title: str, body: str, *, kind: str = "error", client: object | None = None) -> None:
        log.info("%s: %s", title, body)


def train(ctl: Controller, arms: Sequence[Arm] | None = None) -> dict[Arm, Skill]:
    """Train as the Train button does (the shown demonstrations, the session's thresholds and k) and wait for
    the skill and its verdict."""
    skills = ctl.training.train(arms).result()
    assert skills is not None  # a headless controller raises failures
    if ctl.training.judgement is not None:
        ctl.training.judgement.result()
    return skills


def learn(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """Learn a session's skill headless (as the studio's Train button does: the shown demonstrations), save it
    into the session and print a short report and the verdict.

    With ``--auto`` Suggest runs first (on the first chosen arm with demonstrations, as in the studio) and its
    thresholds and k are applied and saved.
    """
    out = out or sys.stdout
    store = SessionStore(_sessions_dir(args))
    session = store.open(args.session)
    if session.recovery_message:
        print(session.recovery_message, file=out)
    for p in session.problems:
        print(p, file=out)
    arms = _arms(getattr(args, "arm", None), session.arms)
    hidden = [r.name for r in session.recordings if r.name in session.hidden_demos]
    if hidden:
        print(f"Left out (hidden in the studio): {', '.join(hidden)}.", file=out)
    t0 = time.perf_counter()
    auto = bool(getattr(args, "auto", False))
    with headless(store, session) as ctl:
        if auto:
            arm = next((a for a in arms if len(ctl.demos.for_arm(a)) >= 2), arms[0])
            ctl.suggest.start(arm).result()
            res = ctl.suggest.state.result
            if res is not None and res.changed:
                print(
                    f"{arm.capitalize()} arm — suggested thresholds (Detail {res.settings.detail:+.1f}, "
                    f"k = {res.n_clusters or 'mean key-points per demonstration'}) in {res.seconds:.1f} s. "
                    f"{tune_summary(res)}",
                    file=out,
                )
            elif res is not None:
                print(f"{arm.capitalize()} arm — searched in {res.seconds:.1f} s. {tune_summary(res)}", file=out)
        skills = train(ctl, arms)
        elapsed = time.perf_counter() - t0  # Suggest, learning and judging
        verdicts = ctl.training.verdicts()
        touching = ctl.scene.contact_reason()  # what the skill would touch, with the objects of the session's scene
    print(report(session, skills, elapsed), file=out)
    if touching:
        print(f"\nWhat the skill would touch: {touching} The studio does not run it on the robot.", file=out)
    for arm in skills:
        v = verdicts.get(arm)
        lines = verdict_words(v.verdict, cli_remedies(session.name, auto)) if v and v.verdict else ()
        if lines:
            print(f"\nHow good is the {arm} arm's skill?", file=out)
            for line in lines:
                print(f"  {line}", file=out)
    return 0


def _fmt(x: float, spec: str = ".3g") -> str:
    try:
        return format(float(x), spec)
    except (TypeError, ValueError):
        return "—"


def report(session: Session, skills: Mapping[Arm, Skill], elapsed: float | None = None) -> str:
    """The plain-text learning report: per demo samples and key-points, k, log-likelihood, reference, quality."""
    lines = [
        f'Session "{session.name}": {count_words(len(session.recordings), "demonstration")}, learned '
        + ", ".join(skills)
    ]
    if elapsed is not None:
        lines[0] += f" in {elapsed:.1f} s"
    for arm, sk in skills.items():
        lines += _arm_report(session, arm, sk)
    lines.append("")
    lines.append(f"Saved into the session ({session.path}).")
    return "\n".join(lines)


def _arm_report(session: Session, arm: Arm, sk: Skill) -> list[str]:
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


def _distances_to_demos(path: np.ndarray, recordings: list[Recording], arm: Arm) -> list[float]:
    """How far the generalized path stays from each demonstration (mean nearest distance, m)."""
    if not recordings:
        return []
    from studio.core.kinematics import Baxter  # pinocchio: loaded only for a report

    b = Baxter.load()
    dists = []
    p = np.asarray(path)[:: max(1, len(path) // 2000)]
    for r in recordings:
        pos, _ = b.fk_batch(arm, r.arm_q(arm)[:: max(1, len(r) // 2000)])
        # a few hundred path points at a time: the whole (path × demo) difference array is ~100 MB
        d = np.concatenate(
            [np.sqrt(((c[:, None, :] - pos[None, :, :]) ** 2).sum(-1)).min(axis=1) for c in np.array_split(p, 8)]
        )
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
    store.path_of(args.session)  # the session's name is checked before any file is read
    for f in args.files:
        try:
            r = read_csv(f, arms=arms)
            check_demo_name(r.name)  # the demonstration's name comes from the file's: checked before creating
            recs.append((Path(f), r))
        except StudioError as exc:
            failed.append(f"  {f}: {exc}")
    if recs:
        created = not store.exists(args.session)
        session = store.create(args.session, arms=arms) if created else store.open(args.session)
        added = 0
        for f, r in recs:
            try:
                i = session.add_recording(r)
            except StudioError as exc:  # this file is named; the others are still imported
                failed.append(f"  {f}: {exc}")
                continue
            added += 1
            if created and added == 1:
                print(f'Created session "{session.name}".', file=out)
            rr = session.recordings[i]
            print(f'Imported {f.name} as "{rr.name}": {len(rr)} samples, {rr.duration:.1f} s.', file=out)
        if created and not added:  # the session was made for these files only
            store.delete(session.name)
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
            with headless(tmp_store, session) as ctl:
                skills = train(ctl)
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
    "export_csv",
    "headless",
    "import_csv",
    "learn",
    "make_examples",
    "record_plan",
    "report",
    "train",
]
