"""Skills that follow the objects: each demonstration split at its grasps and releases, each stretch learned by
the paper's pipeline in the frame of the object it acts on (:mod:`studio.core.frames`).

:func:`plan` reads the frames from the demonstrations' contacts (a grasp in the grasped object's frame; a
release in its target's frame unless the demonstrations clearly agree better in another: decision 085).
:func:`learn_relative` learns the segments and returns a :class:`Skill` placed where the objects are now;
:func:`place_skill` moves it when they move (docs/decisions/080)."""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from studio.core import alignment
from studio.core.errors import InvalidInput, NotEnoughData
from studio.core.frames import (
    CONTRADICT_M,
    DECIDE_M,
    ROBOT,
    ROUND_KINDS,
    YAW_M_PER_RAD,
    Border,
    DemoObjects,
    ObjectAt,
    ObjectFrames,
    Region,
    Segment,
    adapt,
    border_frames,
    frame_of,
    to_local,
    to_world,
    turn,
)
from studio.core.kinematics import Baxter
from studio.core.learn_settings import LearnSettings
from studio.core.types import Arm, Demo, Generalization, KeypointParams, Skill

_DEFAULT = LearnSettings()
#: Frames whose landing spreads differ by less than this (m) are equally good: the more specific one is kept.
TIE_M = 0.005
#: The demonstrations' spread below this (m) is noise (it keeps the weights from trusting 3 demos too much).
SIGMA_FLOOR_M = 0.01
#: Samples per second of a segment's path.
RATE_HZ = 100.0
_ALIGN_HZ = 25.0


def minjerk(u: np.ndarray) -> np.ndarray:
    """The minimum-jerk blend 0 → 1 over ``u`` in 0…1."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10 - 15 * u + 6 * u * u)


@dataclass(frozen=True)
class FrameChoice:
    """How the frame of one border was chosen (facts for the Train step's words).

    Attributes:
        kind, object: the border ("grasp" or "release" of ``object``).
        role: the frame it follows ("object:<name>", "start:<name>" or "robot").
        rule: the frame its meaning gives (the grasped object; for a release, the goal's target), "" without one.
        told: the demonstrations could tell the frames apart (the objects stood in different places relative to
            each other); when not, ``role`` is ``rule``.
        against: they agree clearly better in another frame than in ``rule``: ``role`` follows them.
    """

    kind: str
    object: str
    role: str
    rule: str = ""
    told: bool = True
    against: bool = False


def plan(objects: Sequence[DemoObjects], rules: Mapping[int, str] | None = None) -> tuple[tuple[Border, ...], str]:
    """The borders (grasps and releases with their frames) the demonstrations share, or () and why not.

    ``rules``: contact index -> the frame a release follows by its meaning (the goal's target:
    "object:<name>", "start:<name>" or "robot"); without one, the object most demonstrations put it on.
    """
    borders, _, why = choose_frames(objects, rules)
    return borders, why


def choose_frames(
    objects: Sequence[DemoObjects], rules: Mapping[int, str] | None = None
) -> tuple[tuple[Border, ...], tuple[FrameChoice, ...], str]:
    """:func:`plan` with how each border's frame was chosen (:class:`FrameChoice`)."""
    if not objects:
        return (), (), "There are no demonstrations with objects."
    seqs = [tuple((c.kind, c.object) for c in o.contacts) for o in objects]
    if not seqs[0]:
        return (), (), "Your demonstrations do not pick up any object, so the skill follows fixed places."
    if any(s != seqs[0] for s in seqs):
        return (
            (),
            (),
            (
                "Your demonstrations do not all pick up and put down the same objects in the same order, "
                "so the skill follows fixed places."
            ),
        )
    borders, choices = [], []
    for k, (kind, name) in enumerate(seqs[0]):
        if kind == "grasp":
            role = f"object:{name}"
            borders.append(Border("grasp", name, role))
            choices.append(FrameChoice("grasp", name, role, role, _moved(objects, k, f"start:{name}", ROBOT)))
        else:
            border, choice = _release(objects, k, name, (rules or {}).get(k))
            borders.append(border)
            choices.append(choice)
    return tuple(borders), tuple(choices), ""


def _release(objects: Sequence[DemoObjects], k: int, name: str, rule: str | None) -> tuple[Border, FrameChoice]:
    """A release's frame. Its meaning (``rule``, by default the object most demonstrations put it on) decides
    unless the demonstrations can tell the frames apart and clearly agree better in another one (the object
    it landed on, where it came from, or the robot); without a meaning, where they agree best (ties to the more
    specific frame). Where it lands is measured over the demonstrations that put it onto the frame's object."""
    landed = [o.contacts[k].pose(name) for o in objects]
    if any(p is None for p in landed):
        return Border("release", name, ROBOT, on=None), FrameChoice("release", name, ROBOT, rule or "")
    poses = [p for p in landed if p is not None]
    on_objects = [p.on for p in poses if p.on is not None and p.on not in ("table", "floor", "hand")]
    if rule is None and on_objects:
        top, n = Counter(on_objects).most_common(1)[0]
        rule = f"object:{top}" if 2 * n > len(poses) else None
    candidates = [f"object:{o}" for o in dict.fromkeys(on_objects)] + [f"start:{name}", ROBOT]
    if rule is not None and rule not in candidates:
        candidates.insert(0, rule)
    spreads = {r: s for r in candidates if (s := _spread(objects, k, name, r, poses[0].kind)) is not None}
    if rule is None or rule not in spreads:
        plain = [r for r in candidates if r in spreads and (not r.startswith("object:") or _all_on(poses, r))]
        best = min(spreads[r] for r in plain)
        role = next(r for r in plain if spreads[r] <= best + TIE_M)
        choice = FrameChoice("release", name, role, rule or "")
    else:
        told = [r for r in spreads if r != rule and _moved(objects, k, rule, r)]
        better = [r for r in told if spreads[r] + CONTRADICT_M < spreads[rule]]
        role = min(better, key=lambda r: spreads[r]) if better else rule
        choice = FrameChoice("release", name, role, rule, bool(told), bool(better))
    local = _landed_in(objects, k, name, role)
    assert local is not None
    target = role.partition(":")[2] if role.startswith("object:") else None
    on_it = [i for i, p in enumerate(poses) if target is not None and p.on == target]
    rows = local[on_it] if on_it else local
    mean = rows.mean(axis=0)
    mean[3] = float(np.angle(np.mean(np.exp(1j * rows[:, 3]))))
    on = target if target is not None else poses[0].on
    landed_at = (float(mean[0]), float(mean[1]), float(mean[2]), float(mean[3]))
    return Border("release", name, role, landed_at, on), choice


def _all_on(poses: Sequence[ObjectAt], role: str) -> bool:
    return all(p.on == role.partition(":")[2] for p in poses)


def _spread(objects: Sequence[DemoObjects], k: int, name: str, role: str, kind: str) -> float | None:
    """How far apart the demonstrations left object ``name`` at contact ``k`` in frame ``role`` (m, headings
    counted as :data:`YAW_M_PER_RAD`; None when a demonstration lacks that frame)."""
    local = _landed_in(objects, k, name, role)
    if local is None:
        return None
    d = np.linalg.norm(local[:, :3] - local[:, :3].mean(axis=0), axis=1)
    yaw = 0.0 if kind in ROUND_KINDS else float(np.max(np.abs(_yaw_dev(local[:, 3]))))
    return float(d.max()) + YAW_M_PER_RAD * yaw


def _moved(objects: Sequence[DemoObjects], k: int, a: str, b: str) -> bool:
    """Whether frames ``a`` and ``b`` at contact ``k`` stood in places relative to each other that differ by at
    least :data:`DECIDE_M` over the demonstrations (then the demonstrations can tell them apart)."""
    rows = []
    for o in objects:
        fa, fb = frame_at_contact(o, k, a), frame_at_contact(o, k, b)
        if fa is None or fb is None:
            return False
        rows.append([*to_local(fa, fb[:3]), fb[3] - fa[3]])
    r = np.array(rows)
    d = np.linalg.norm(r[:, :3] - r[:, :3].mean(axis=0), axis=1)
    return float(d.max()) + YAW_M_PER_RAD * float(np.max(np.abs(_yaw_dev(r[:, 3])))) >= DECIDE_M


def _yaw_dev(y: np.ndarray) -> np.ndarray:
    m = np.angle(np.mean(np.exp(1j * y)))
    return np.angle(np.exp(1j * (y - m)))


def frame_at_contact(o: DemoObjects, k: int, role: str) -> np.ndarray | None:
    """The frame ``role`` names at contact ``k`` of one demonstration (the objects just after it)."""
    if role == ROBOT:
        return np.zeros(4)
    kind, _, name = role.partition(":")
    if kind == "start":
        p = o.start_pose(name)
    else:  # the object as it is at the contact (before a grasp moves it, it is where it stood)
        p = o.contacts[k].pose(name)
    return None if p is None else frame_of(p)


def _landed_in(objects: Sequence[DemoObjects], k: int, name: str, role: str) -> np.ndarray | None:
    rows = []
    for o in objects:
        f, p = frame_at_contact(o, k, role), o.contacts[k].pose(name)
        if f is None or p is None:
            return None
        rows.append([*to_local(f, np.asarray(p.position)), p.yaw - f[3]])
    return np.array(rows)


def regions(objects: Sequence[DemoObjects], borders: Sequence[Border]) -> tuple[Region, ...]:
    """Where the demonstrations had each object the skill's frames name (at their start)."""
    names: list[str] = []
    for b in borders:
        for n in (b.object, b.role.partition(":")[2]):
            if n and n not in names:
                names.append(n)
    out = []
    for n in names:
        starts = [o.start_pose(n) for o in objects]
        if any(s is None for s in starts):
            continue
        rows = np.array([[s.position[0], s.position[1], s.yaw] for s in starts if s is not None])
        out.append(Region(n, next(s.kind for s in starts if s is not None), rows))
    return tuple(out)


# -- learning ------------------------------------------------------------------------------------------------


def contact_cuts(demo: Demo, objects: DemoObjects) -> list[int]:
    """Sample indices of the borders in ``demo`` (first and last sample included)."""
    t = np.asarray(demo.t) - demo.t[0]
    cut = [int(np.clip(np.searchsorted(t, c.t), 1, len(t) - 2)) for c in objects.contacts]
    idx = [0, *cut, len(t) - 1]
    if any(b <= a for a, b in itertools.pairwise(idx)):
        raise NotEnoughData(f"{demo.name}: a grasp and a release are too close together to learn from.")
    return idx


def in_frame(demo: Demo, i0: int, i1: int, f: np.ndarray) -> Demo:
    """Samples ``i0``…``i1`` of ``demo`` in frame ``f``, their time from ``i0``."""
    sl = slice(i0, i1 + 1)
    t = np.asarray(demo.t[sl]) - demo.t[i0]
    return Demo(t, to_local(f, demo.position[sl]), turn(demo.orientation[sl], -f[3]), demo.gripper[sl], name=demo.name)


def _resampled(traj: Demo) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    t0 = np.asarray(traj.t) - traj.t[0]
    n = max(2, math.ceil(t0[-1] * RATE_HZ) + 1)
    t = np.linspace(0.0, t0[-1], n)
    pos = np.column_stack([np.interp(t, t0, traj.position[:, c]) for c in range(3)])
    q = np.column_stack([np.interp(t, t0, traj.orientation[:, c]) for c in range(4)])
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    g = np.asarray(traj.gripper)[np.clip(np.searchsorted(t0, t + 1e-9, side="right") - 1, 0, len(t0) - 1)]
    return t, pos, q, g


def _statistics(
    t: np.ndarray, path: np.ndarray, parts: Sequence[tuple[Demo, Demo]]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The demonstrations aligned to the learned path (DTW on positions in the path's frame): their mean
    position and orientation at each instant in the path's frame and the other one, and their spreads (m²)."""
    grid = alignment.time_grid(0.0, float(t[-1]), _ALIGN_HZ)
    ref = alignment.resample(t, path, grid)
    P, O, QP, QO = [], [], [], []
    for mine, other in parts:
        dg = alignment.time_grid(0.0, float(mine.t[-1]), _ALIGN_HZ)
        _, wp = alignment.dtw(ref, alignment.resample(mine.t, mine.position, dg))
        when = alignment.time_map(wp[:, ::-1], dg, grid)  # for each instant of the path, the demo's time
        when = np.interp(t, grid, np.maximum.accumulate(when))
        P.append(np.column_stack([np.interp(when, mine.t, mine.position[:, c]) for c in range(3)]))
        O.append(np.column_stack([np.interp(when, other.t, other.position[:, c]) for c in range(3)]))
        QP.append(np.column_stack([np.interp(when, mine.t, mine.orientation[:, c]) for c in range(4)]))
        QO.append(np.column_stack([np.interp(when, other.t, other.orientation[:, c]) for c in range(4)]))
    mp, mo = np.mean(P, axis=0), np.mean(O, axis=0)
    vp = np.mean([np.sum((p - mp) ** 2, axis=1) for p in P], axis=0)
    vo = np.mean([np.sum((o - mo) ** 2, axis=1) for o in O], axis=0)
    return mp, mo, _mean_quat(QP), _mean_quat(QO), vp, vo


def _mean_quat(qs: list[np.ndarray]) -> np.ndarray:
    acc = np.zeros_like(qs[0])
    for q in qs:
        acc += q * np.where(np.einsum("ij,ij->i", q, qs[0]) < 0, -1.0, 1.0)[:, None]
    return acc / np.linalg.norm(acc, axis=1, keepdims=True)


def path_roles(roles: tuple[str, str]) -> tuple[str, str]:
    """(the frame a segment from ``roles[0]`` to ``roles[1]`` is learned in, the other one): the end's, unless
    the segment ends free (the robot's frame), then the start's."""
    start_role, end_role = roles
    path_role = end_role if end_role != ROBOT else start_role
    return path_role, (start_role if path_role == end_role else end_role)


def segment_frames(o: DemoObjects, k: int, roles: tuple[str, str]) -> tuple[np.ndarray, np.ndarray]:
    """(the path's frame, the other frame) of segment ``k`` in one demonstration (a start frame as the objects
    were at the border before it, an end frame as at the border after it)."""
    path_role, other_role = path_roles(roles)
    out = []
    for role in (path_role, other_role):
        f = np.zeros(4) if role == ROBOT else frame_at_contact(o, k if role == roles[1] else k - 1, role)
        if f is None:
            raise InvalidInput("An object the skill acts on is missing from a demonstration.")
        out.append(f)
    return out[0], out[1]


def _learn_segment(
    k: int,
    demos: Sequence[Demo],
    objects: Sequence[DemoObjects],
    cuts: Sequence[list[int]],
    roles: tuple[str, str],
    params: KeypointParams,
    settings: LearnSettings,
) -> tuple[Segment, Skill]:
    from studio.core.pipeline import learn_skill
    from studio.core.thresholds import auto_params

    start_role, end_role = roles
    path_role, other_role = path_roles(roles)
    parts = []
    for d, o, c in zip(demos, objects, cuts, strict=True):
        fp, fo = segment_frames(o, k, roles)
        parts.append((in_frame(d, c[k], c[k + 1], fp), in_frame(d, c[k], c[k + 1], fo)))
    seg_demos = [p[0] for p in parts]
    # each stretch keeps every demo (one way) and finds its own k; only the thresholds, seed and mode carry over
    part = LearnSettings(params=params, seed=settings.seed, generalization=settings.generalization, split_routes=False)
    try:
        sk = learn_skill(seg_demos, part)
    except NotEnoughData:
        sk = learn_skill(seg_demos, dataclasses.replace(part, params=auto_params(seg_demos)))
    t, pos, q, g = _resampled(sk.trajectory)
    mp, mo, qp, qo, vp, vo = _statistics(t, pos, parts)
    pi_end = minjerk(t / max(t[-1], 1e-9))
    floor = SIGMA_FLOOR_M**2
    if other_role == path_role:
        w = np.ones_like(t)
    else:
        v_end, v_start = (vp, vo) if path_role == end_role else (vo, vp)
        a, b = pi_end / (v_end + floor), (1.0 - pi_end) / (v_start + floor)
        w_end = a / np.maximum(a + b, 1e-300)
        w = w_end if path_role == end_role else 1.0 - w_end
    seg = Segment(start_role, end_role, path_role, t, pos, q, g, mp, mo, qp, qo, w)
    return seg, sk


def learn_relative(
    demos: Sequence[Demo],
    objects: Sequence[DemoObjects],
    settings: LearnSettings = _DEFAULT,
    *,
    now: Sequence[ObjectAt] | None = None,
    arm: Arm | None = None,
    baxter: Baxter | None = None,
    rules: Mapping[int, str] | None = None,
) -> Skill:
    """Learn a skill that follows the objects (module docstring).

    Args:
        demos: one arm's demonstrations; objects: their objects and that arm's contacts, in the same order.
        settings: the thresholds (default automatic for all the demos; a segment they find too few key-points in
            gets its own), seed and mode; each segment finds its own k.
        now: where the objects are now (default: as at the first demonstration's start).
        arm: when given, the path placed ``now`` gets its joint trajectory (whole-path IK).
        rules: the frame each release follows by its meaning (:func:`plan`).

    Raises:
        InvalidInput: the demonstrations share no grasps and releases (the message says why).
    """
    demos, objects = list(demos), list(objects)
    if len(demos) != len(objects) or not demos:
        raise InvalidInput("Give the objects of every demonstration.")
    borders, why = plan(objects, rules)
    if not borders:
        raise InvalidInput(why)
    params = settings.thresholds(demos)
    cuts = [contact_cuts(d, o) for d, o in zip(demos, objects, strict=True)]
    roles = [ROBOT, *(b.role for b in borders), ROBOT]
    segs, parts = [], []
    for k in range(len(borders) + 1):
        seg, sk = _learn_segment(k, demos, objects, cuts, (roles[k], roles[k + 1]), params, settings)
        segs.append(seg)
        parts.append(sk)
    frames = ObjectFrames(borders, tuple(segs), regions(objects, borders))
    skill = _combine(parts, cuts, frames, params, settings.generalization, tuple(d.name for d in demos))
    here = list(now) if now is not None else list(objects[0].start)
    seed_q = demos[0].q[0] if demos[0].q is not None else None
    return place_skill(skill, here, arm=arm, baxter=baxter, q_seed=seed_q)


def _combine(
    parts: Sequence[Skill],
    cuts: Sequence[list[int]],
    frames: ObjectFrames,
    params: KeypointParams,
    generalization: str,
    names: tuple[str, ...],
) -> Skill:
    """One :class:`Skill` of the segments' models: key-points per whole demonstration, the clusters and states
    numbered on, block-diagonal HMM; centroids and path points stay in their segment's frame (``frames``)."""
    n = len(cuts)
    kps: list[list[np.ndarray]] = [[] for _ in range(n)]
    labels: list[list[np.ndarray]] = [[] for _ in range(n)]
    paths: list[list[np.ndarray]] = [[] for _ in range(n)]
    cents, ctimes, states, zeros, pts, ptimes, pstates = [], [], [], [], [], [], []
    seg_of_c, seg_of_p = [], []
    k_off, t_off = 0, 0.0
    for s, sk in enumerate(parts):
        for d in range(n):
            kp = np.asarray(sk.keypoints[d]) + cuts[d][s]
            keep = np.ones(len(kp), bool) if s == 0 else kp > cuts[d][s]
            kps[d].append(kp[keep])
            labels[d].append(np.asarray(sk.labels[d])[keep] + k_off)
            paths[d].append(np.asarray(sk.paths[d])[keep] + k_off)
        cents.append(sk.centroids)
        ctimes.append(sk.centroid_times + t_off)
        states.append(np.asarray(sk.states) + k_off)
        zeros.append(np.asarray(sk.zero_points) + k_off)
        pts.append(sk.path_points)
        ptimes.append(sk.path_times + t_off)
        pstates.append(np.asarray(sk.path_states) + k_off)
        seg_of_c += [s] * sk.n_clusters
        seg_of_p += [s] * len(sk.path_points)
        k_off += sk.n_clusters
        t_off += frames.segments[s].duration
    K = k_off
    A, B = np.zeros((K, K)), np.zeros((K, K))
    start = np.zeros(K)
    start[: parts[0].n_clusters] = parts[0].startprob
    o = 0
    for sk in parts:
        m = sk.n_clusters
        A[o : o + m, o : o + m] = sk.transmat
        B[o : o + m, o : o + m] = sk.emissionprob
        o += m
    frames = dataclasses.replace(
        frames,
        local_centroids=np.vstack(cents),
        centroid_segment=np.array(seg_of_c, dtype=np.int64),
        local_points=np.vstack(pts),
        point_segment=np.array(seg_of_p, dtype=np.int64),
    )
    return Skill(
        trajectory=parts[0].trajectory,
        keypoints=[np.concatenate(x) for x in kps],
        labels=[np.concatenate(x) for x in labels],
        centroids=np.vstack(cents),
        centroid_times=np.concatenate(ctimes),
        states=np.concatenate(states),
        paths=[np.concatenate(x) for x in paths],
        reference=parts[0].reference,
        zero_points=np.concatenate(zeros),
        startprob=start,
        transmat=A,
        emissionprob=B,
        loglik=np.sum([sk.loglik for sk in parts], axis=0),
        path_times=np.concatenate(ptimes),
        path_points=np.vstack(pts),
        path_states=np.concatenate(pstates),
        params=params,
        spline_through=parts[0].spline_through,
        demo_names=names,
        generalization=Generalization.of(generalization),
        frames=frames,
    )


def _to_world8(x: np.ndarray, seg: np.ndarray, F: np.ndarray, frames: ObjectFrames) -> np.ndarray:
    """8-D points (x, y, z, quaternion, gripper) of the segments' frames placed in frames ``F``."""
    out = np.array(x, dtype=np.float64)
    for s, sg in enumerate(frames.segments):
        m = seg == s
        if not m.any():
            continue
        f = F[s] if sg.path_role == sg.start_role else F[s + 1]
        out[m, :3] = to_world(f, x[m, :3])
        out[m, 3:7] = turn(x[m, 3:7], f[3])
    return out


def place_skill(
    skill: Skill,
    now: Sequence[ObjectAt],
    *,
    arm: Arm | None = None,
    baxter: Baxter | None = None,
    q_seed: np.ndarray | None = None,
) -> Skill:
    """``skill`` (learned with objects) with its path rebuilt where the objects are ``now``; with ``arm`` also
    its joint trajectory (whole-path IK, seeded by ``q_seed`` or the skill's own first joints)."""
    from studio.core.execution import joint_trajectory

    fr = skill.frames
    if fr is None:
        raise InvalidInput("This skill follows fixed places; it cannot be moved with the objects.")
    path = adapt(fr, now, RATE_HZ)
    traj = Demo(path.t, path.position, path.orientation, path.gripper, name="learned skill")
    F = border_frames(fr, now)
    jt = None
    arm = arm or skill.arm
    if arm is not None:
        b = baxter or Baxter.load()
        if q_seed is None:
            old = skill.joint_trajectory
            q_seed = old.q[0] if old is not None else b.neutral(arm)
        jt = joint_trajectory(traj, arm, np.asarray(q_seed), b)
    return dataclasses.replace(
        skill,
        trajectory=traj,
        joint_trajectory=jt,
        arm=arm,
        centroids=_to_world8(fr.local_centroids, fr.centroid_segment, F, fr),
        path_points=_to_world8(fr.local_points, fr.point_segment, F, fr),
    )
