"""Training: learn the skill of every taught arm on the work thread, then judge it (the verdict in plain words
and how well each demonstration fits), and answer what the panels show about the learned skill. The learning
and the judging are the core's (:mod:`studio.core.learn`); this part schedules them and keeps the session."""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from studio.controller.context import Context
from studio.controller.events import Topic
from studio.controller.learning import ShownDemos
from studio.controller.placed import rules_of
from studio.core.errors import Cancelled, NotEnoughData, StudioError
from studio.core.frames import ObjectAt
from studio.core.learn import TaughtObjects
from studio.core.learn_settings import LearnSettings
from studio.core.quality import DemoFit, Verdict
from studio.core.segment_view import SegmentFit
from studio.core.segments import FrameChoice
from studio.core.thresholds import ThresholdSettings
from studio.core.types import FRAMES, Arm, Demo, Generalization, KeypointParams, Recording, Skill
from studio.storage import ReadOnly
from studio.words.controls import Control
from studio.world.relative import objects_now


@dataclass(frozen=True)
class UsedDemo:
    """A demonstration a skill was learned from: its name then, and its index and Demo now (None when it was
    renamed or deleted since)."""

    name: str
    index: int | None
    demo: Demo | None


@dataclass(frozen=True)
class SkillVerdict:
    """The judgement of one arm's skill: the verdict (headline and bullets), how well each demonstration fits,
    or ``message`` when it could not be judged (then ``verdict`` is None)."""

    skill: Skill
    verdict: Verdict | None
    fits: tuple[DemoFit, ...] = ()
    message: str = ""
    #: a skill that follows the objects: how closely each stretch follows the demonstrations in its frame
    segments: tuple[SegmentFit, ...] = ()
    #: ... and how the frame of each grasp and release was chosen (by the task's meaning, or the demonstrations)
    choices: tuple[FrameChoice, ...] = ()


class DemoSource(ShownDemos, Protocol):
    """The demonstrations learning reads (:class:`~studio.controller.demos.Demos`)."""

    def demo_of(self, rec: Recording, arm: Arm) -> Demo: ...


class Settings(Protocol):
    """The thresholds and k a skill is learned with (:class:`~studio.controller.learning.KeypointTuning`)."""

    @property
    def k(self) -> int | None: ...
    def settings(self) -> ThresholdSettings: ...
    def params(self, arm: Arm | None = None, settings: ThresholdSettings | None = None) -> KeypointParams: ...
    def persist(self, force: bool = False) -> None: ...


class Training:
    """Learns the skill of every taught arm on the work thread and judges it; answers what the panels show.

    The open session cannot change while it trains; another session is judged when it has skills.
    """

    def __init__(self, ctx: Context, demos: DemoSource, tuning: Settings) -> None:
        self.ctx = ctx
        self.demos = demos
        self.tuning = tuning
        self.busy = False
        self.judging = False
        #: The newest judgement under way or done (training starts one when it finishes).
        self.judgement: Future[None] | None = None
        self._verdicts: dict[Arm, SkillVerdict] = {}
        self._routes: dict[Arm, int] = {}
        ctx.on_leave(self._check_leave)
        ctx.events.on(Topic.SESSION, self._on_session)

    def skills(self) -> dict[Arm, Skill]:
        return dict(self.ctx.session.skills)

    # -- generalisation mode -------------------------------------------------------------------------------
    @property
    def generalization(self) -> Generalization:
        """The mode the next training uses ("aligned-mean", the default, or "paper")."""
        return self.ctx.session.generalization

    def set_generalization(self, mode: Generalization | str) -> None:
        mode = Generalization.of(mode)
        with self.ctx.lock:
            if mode == self.ctx.session.generalization:
                return
            self.ctx.session.set_params(mode=mode)
        self.ctx.emit(Topic.TRAINING)

    @property
    def frames(self) -> str:
        """Where the next training keeps the skill's path: "objects" (it follows them) or "robot" (the paper)."""
        return self.ctx.session.frames

    def set_frames(self, frames: str) -> None:
        if frames not in FRAMES:
            raise StudioError(f'Unknown way to place the skill "{frames}".')
        with self.ctx.lock:
            if frames == self.ctx.session.frames:
                return
            self.ctx.session.set_params(mode=frames)
        self.ctx.emit(Topic.TRAINING)

    def _check_leave(self, doing: str) -> None:
        if self.busy:
            raise StudioError(f"Wait for the training to finish before {doing}.")

    # -- which way, when the demonstrations go several ways ---------------------------------------------------
    def chosen_route(self, arm: Arm) -> int | None:
        """The way the teacher chose for ``arm`` (index into its skill's ``routes``), or None for the default."""
        return self._routes.get(arm)

    def set_route(self, arm: Arm, route: int) -> Future[dict[Arm, Skill] | None]:
        """Learn ``arm``'s skill from the demonstrations of another way (see :attr:`Skill.routes`), at once."""
        sk = self.ctx.session.skills.get(arm)
        if sk is None or not 0 <= int(route) < len(sk.routes):
            raise StudioError("Your demonstrations go only one way: there is no other way to choose.")
        with self.ctx.lock:
            self._routes[arm] = int(route)
        return self.train()

    # -- training ------------------------------------------------------------------------------------------
    def train(self, arms: Sequence[Arm] | None = None) -> Future[dict[Arm, Skill] | None]:
        """Learn the skill of every taught arm (or of ``arms``) from the shown demos on the work thread, then
        judge it."""
        from studio.core.learn import learn

        with self.ctx.lock:
            if self.busy:
                raise StudioError("Training is already running; wait for it to finish.")
            if self.ctx.session.read_only:  # its skill could not be kept: say so before the work
                raise ReadOnly(self.ctx.session.name)
            per_arm = {arm: self.demos.for_arm(arm) for arm in (self.ctx.arms if arms is None else arms)}
            for arm, demos in per_arm.items():
                if len(demos) < 2:
                    raise NotEnoughData(
                        f"The {arm} arm needs at least two shown demonstrations to learn from "
                        f"(it has {len(demos)}). Record more, or show hidden ones."
                    )
            thresholds, k = self.tuning.settings(), self.tuning.k
            params = {arm: self.tuning.params(arm, thresholds) for arm in per_arm}
            session = self.ctx.session  # the skill belongs to the session it was learned from
            frames = session.frames
            settings = {
                arm: LearnSettings(
                    params=params[arm],
                    n_clusters=k,
                    generalization=session.generalization,
                    frames=frames,
                    route=self._routes.get(arm),
                )
                for arm in per_arm
            }
            used = [session.recordings[i] for demos in per_arm.values() for i, _ in demos]
            self.busy = True
        self.ctx.emit(Topic.TRAINING)
        now = tuple(objects_now(session.objects.scene))
        objects = {
            arm: self._taught(arm, [i for i, _ in demos], now) if frames == "objects" else None
            for arm, demos in per_arm.items()
        }

        def job() -> dict[Arm, Skill]:
            out: dict[Arm, Skill] = {}
            for arm, demos in per_arm.items():
                learned = learn(
                    [d for _, d in demos],
                    objects[arm],
                    settings[arm],
                    arm=arm,
                    baxter=self.ctx.baxter,
                    caches=self.ctx.caches,
                )
                if learned.note:
                    self.ctx.notify("The skill follows fixed places", learned.note, kind="info")
                out[arm] = learned.skill
            return out

        def done(skills: dict[Arm, Skill]) -> None:
            names = {arm: [d.name for _, d in per_arm[arm]] for arm in skills}
            first: KeypointParams | None = next(iter(params.values()), None)
            with self.ctx.lock:
                # A demonstration deleted, trimmed or renamed while it trained: the skill is kept, marked stale.
                changed = any(all(r is not kept for kept in session.recordings) for r in used)
                session.set_skills(skills, params=first, demos=names, stale=changed)
                current = session is self.ctx.session
                if current:
                    self._verdicts = {}
                self.busy = False  # only now: sessions cannot be switched while training
            self.ctx.emit(Topic.TRAINING)
            if not current:
                self.ctx.notify(
                    "Training finished", f'The skill was learned for session "{session.name}".', kind="info"
                )
                return
            self.tuning.persist(force=True)  # the current settings again (the skill's values replaced them)
            self.ctx.emit(Topic.SKILL)  # the player unloads the preview of the previous skill
            if changed:
                self.ctx.notify(
                    "Training finished",
                    "The robot learned the skill, but a demonstration was changed or deleted while it trained: "
                    f"{self.ctx.say(Control.TRAIN)} again to learn from the demonstrations as they are now.",
                    kind="warning",
                )
            else:
                said = f"The robot learned the skill: {self.ctx.say(Control.PREVIEW)} to watch it."
                self.ctx.notify("Training finished", said, kind="success")
            self.judge()

        fut = self.ctx.submit(job, done=done, title="Training failed")
        fut.add_done_callback(lambda f: self._finished())
        return fut

    def _taught(self, arm: Arm, indices: list[int], now: tuple[ObjectAt, ...] | None = None) -> TaughtObjects:
        """The objects and ``arm``'s contacts of the demonstrations ``indices`` (each contact at its moment in the
        demonstration as taught), or why the skill cannot follow them; ``now``: where the objects stand now."""
        objs = self.demos.objects_of(arm, indices)
        if isinstance(objs, str):
            return TaughtObjects(why_not=objs)
        return TaughtObjects(tuple(objs), rules=rules_of(self.ctx.session, objs, indices), now=now)

    def _finished(self) -> None:
        if self.busy:  # the job failed: done() never ran
            self.busy = False
            self.ctx.emit(Topic.TRAINING)

    # -- the verdict ---------------------------------------------------------------------------------------
    def verdicts(self) -> dict[Arm, SkillVerdict]:
        """arm -> the judgement of its current skill (only once judged; see :attr:`judging`)."""
        with self.ctx.lock:
            skills = self.ctx.session.skills
            return {arm: v for arm, v in self._verdicts.items() if skills.get(arm) is v.skill}

    def judge(self) -> Future[None]:
        """Judge every skill of the open session on the work thread (held-out fidelity, the verdict and the
        per-demo fit); :attr:`Topic.VERDICT` is emitted when it starts and when it is done."""
        session = self.ctx.session
        skills = dict(session.skills)
        with self.ctx.lock:
            self.judging = bool(skills)
        self.ctx.emit(Topic.VERDICT)
        settings = LearnSettings(n_clusters=session.n_clusters)

        def job() -> None:
            out = {arm: self._judge_one(arm, skill, settings) for arm, skill in skills.items()}  # may be Cancelled
            with self.ctx.lock:
                if session is self.ctx.session:
                    self._verdicts.update(out)

        def finished(_: Future[None]) -> None:
            with self.ctx.lock:
                self.judging = False
            self.ctx.emit(Topic.VERDICT)

        fut = self.ctx.submit(job, title="Could not judge the skill")
        fut.add_done_callback(finished)
        self.judgement = fut
        return fut

    def _judge_one(self, arm: Arm, skill: Skill, settings: LearnSettings) -> SkillVerdict:
        from studio.core.learn import judge

        used = self.skill_demos(arm)
        demos = [u.demo for u in used if u.demo is not None]  # as taught
        if len(demos) != len(used) or not demos:
            return SkillVerdict(
                skill,
                None,
                message="Some demonstrations this skill learned from were renamed or deleted since: train again "
                "to see how good it is.",
            )
        indices = [u.index for u in used if u.index is not None]
        if any(len(k) and int(np.max(k)) >= len(d) for k, d in zip(skill.keypoints, demos, strict=False)):
            return SkillVerdict(
                skill, None, message="Demonstrations were trimmed since this skill was learned: train again."
            )
        if self.ctx.stopping.is_set():
            raise Cancelled
        objects = self._taught(arm, indices) if skill.frames is not None else None
        j = judge(
            skill,
            demos,
            objects,
            settings,
            arm=arm,
            baxter=self.ctx.baxter,
            caches=self.ctx.caches,
            stopping=self.ctx.stopping.is_set,
        )
        return SkillVerdict(skill, j.verdict, j.fits, segments=j.segments, choices=j.choices)

    def _on_session(self) -> None:
        with self.ctx.lock:
            self._verdicts = {}
            self._routes = {}
            has_skills = bool(self.ctx.session.skills)
        if has_skills:
            self.judge()

    # -- what the panels show ------------------------------------------------------------------------------
    def skill_demo_names(self, arm: Arm) -> list[str]:
        """Names of the demonstrations the current skill of ``arm`` was learned from, in the skill's order
        (the order of its log-likelihoods and key-points), as they were called then."""
        sk = self.ctx.session.skills.get(arm)
        if sk is None:
            return []
        info = self.ctx.session.skill_info.get(arm)
        return [str(n) for n in (sk.demo_names or (info.demos if info is not None else ()))]

    def skill_demos(self, arm: Arm) -> list[UsedDemo]:
        """Every demonstration the current skill of ``arm`` was learned from, in the skill's order."""
        by_name = {r.name: (i, r) for i, r in enumerate(self.ctx.session.recordings)}
        out: list[UsedDemo] = []
        for nm in self.skill_demo_names(arm):
            hit = by_name.get(nm)
            if hit is not None and arm in hit[1].arms:
                out.append(UsedDemo(nm, hit[0], self.demos.demo_of(hit[1], arm)))
            else:
                out.append(UsedDemo(nm, None, None))
        return out

    def ik_failures(self, arm: Arm) -> np.ndarray:
        """(n, 3) positions of the learned path the arm cannot reach exactly."""
        sk = self.ctx.session.skills.get(arm)
        jt = sk.joint_trajectory if sk is not None else None
        if sk is None or jt is None:
            return np.zeros((0, 3))
        bad = ~np.asarray(jt.converged, dtype=bool)
        if not bad.any():
            return np.zeros((0, 3))
        tr = sk.trajectory
        pos = np.column_stack([np.interp(jt.t, tr.t, tr.position[:, c]) for c in range(3)])
        return pos[bad]
