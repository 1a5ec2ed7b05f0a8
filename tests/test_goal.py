"""The task's goal as data (studio/world/goal.py): what each set-up declares, what the demonstrations show (onto an
object, back where it started, a spot on the table), the goal a session is judged by when one take missed the
target, the goals the teacher may choose instead, and the goal kept with the scene."""

from __future__ import annotations

import pytest

from studio.core.errors import SessionFormatError
from studio.teacher import Place, Places, recording_from_plan, teach
from studio.world import START, TABLE, Placement, Scene, declared, preset, read_goal, session_goal, simulate
from studio.world.goal import alternatives


def events(task: str, seeds, places=None, scene: Scene | None = None, once: bool = True):
    """The object events of the scripted teacher's takes (``places`` per take: where its hand acts)."""
    scene = scene or preset(task)
    out = []
    for i, s in enumerate(seeds):
        pl = places[i] if places is not None else Places()
        rec = recording_from_plan(teach(task, s, places=pl, once=once))
        out.append(simulate(rec.t, rec.q, rec.gripper, scene).events)
    return out


def test_each_set_up_declares_its_goal_in_terms_of_objects() -> None:
    assert preset("pick-place").goal == (Placement("block", "pad"),)
    assert preset("stack-cup").goal == (Placement("cup", "bottom cup"),)
    both = preset("stack-cup", ("left", "right"))
    assert both.goal == (Placement("cup (left)", "bottom cup (left)"), Placement("cup (right)", "bottom cup (right)"))
    assert preset("empty table").goal == () == declared("empty table", ["block", "pad"])
    assert declared("pick-place", ["block"]) == ()  # no pad: nothing to put it on


def test_the_goal_is_kept_with_the_scene() -> None:
    scene = preset("pick-place")
    assert Scene.from_dict(scene.to_dict()) == scene
    raw = scene.to_dict()
    del raw["goal"]  # saved before goals were kept: the set-up's goal
    assert Scene.from_dict(raw).goal == (Placement("block", "pad"),)
    mine = scene.with_goal((Placement("block", TABLE, (0.7, 0.2, -0.07, 0.0)),))
    assert Scene.from_dict(mine.to_dict()).goal == mine.goal
    assert scene.move("block", (0.7, 0.3, 0.0)).goal == scene.goal
    assert scene.remove("pad").goal == ()  # a goal never names an object that is gone
    with pytest.raises(ValueError, match="not on the table"):
        scene.with_goal((Placement("block", "cup"),))
    raw["goal"] = [{"object": "block"}]
    with pytest.raises(SessionFormatError, match="damaged"):
        Scene.from_dict(raw)


def test_the_goal_is_read_from_the_demonstrations_of_the_teachers_own_table() -> None:
    own = Scene("", preset("pick-place").table, preset("pick-place").objects)  # the same objects, no set-up goal
    goal = read_goal(events("pick-place", (1, 2)))
    assert goal.source == "demonstrations" and [(p.object, p.onto) for p in goal.placements] == [("block", "pad")]
    spot = goal.placements[0].spot
    assert spot is not None and abs(spot[0]) < 0.01 and abs(spot[1]) < 0.01  # near the pad's centre
    assert session_goal(own.preset, own.goal, own.names(), events("pick-place", (1, 2))) == goal
    there_and_back = read_goal(events("pick-place", (1, 2), once=False))
    assert [p.onto for p in there_and_back.placements] == ["pad", START]
    # Put down on the table 8 cm beside the pad, at one place: a spot on the table (a fixed place).
    beside = [Places(put=Place(0.0, 0.1, 0.0))] * 2
    table = read_goal(events("pick-place", (1, 2), beside))
    assert [p.onto for p in table.placements] == [TABLE] and table.placements[0].spot is not None


def test_a_spot_relative_to_where_the_block_stood_when_the_demonstrations_show_it() -> None:
    """The block put down 10 cm to its left each time, from three different places: measured from where it
    started, not a fixed spot (the demonstrations clearly agree better that way)."""
    starts = [Place(0.0, 0.0, 0.0), Place(-0.08, -0.06, 0.0), Place(0.06, -0.1, 0.0)]
    hand = [Places(pick=p, put=Place(p.dx + 0.0, p.dy - 0.13, 0.0)) for p in starts]
    evs = []
    for i, (p, h) in enumerate(zip(starts, hand, strict=True)):
        scene = Scene("", preset("pick-place").table, preset("pick-place", places=Places(pick=p)).objects[1:])
        evs += events("pick-place", (i + 1,), [h], scene)
    (placement,) = read_goal(evs).placements
    assert (
        placement.onto == START
        and placement.spot is not None
        and abs(placement.spot[0] ** 2 + placement.spot[1] ** 2) > 0.05**2
    )


def test_one_take_that_missed_the_pad_does_not_move_the_goal() -> None:
    """Two takes put the block on the pad, one let it go 7 cm from the pad's centre (on the table): the set-up's
    goal is the pad, and its spot on the pad is where the two takes on it put it."""
    scene = preset("pick-place")
    sloppy = [Places(), Places(put=Place(0.07, 0.0, 0.0)), Places()]
    evs = events("pick-place", (1, 2, 3), sloppy)
    ons = [next(e for e in ev if e.kind == "release").pose("block").on for ev in evs]
    assert ons == ["pad", "table", "pad"]
    goal = session_goal(scene.preset, scene.goal, scene.names(), evs)
    assert goal.source == "set-up" and [(p.object, p.onto) for p in goal.placements] == [("block", "pad")]
    assert goal.differs == ()
    spot = goal.placements[0].spot
    assert spot is not None and spot[0] ** 2 + spot[1] ** 2 < 0.01**2
    assert [p.onto for p in read_goal(evs).placements] == ["pad"]  # two of three: the demonstrations say so too
    # No take put it on the pad: the set-up's goal stays, and says the demonstrations did not do it.
    off = events("pick-place", (1, 2), [Places(put=Place(0.0, 0.12, 0.0))] * 2)
    goal = session_goal(scene.preset, scene.goal, scene.names(), off)
    assert [p.onto for p in goal.placements] == ["pad"] and goal.differs == (Placement("block", "pad"),)


def test_the_set_ups_goal_is_matched_to_the_release_that_does_it() -> None:
    """The scripted teacher brings the block back: the pad is the first release, where it started the second."""
    scene = preset("pick-place")
    goal = session_goal(scene.preset, scene.goal, scene.names(), events("pick-place", (1, 2), once=False))
    assert [p.onto for p in goal.placements] == ["pad", START]


def test_the_goals_the_teacher_may_choose_instead() -> None:
    scene = preset("pick-place")
    goal = session_goal(scene.preset, scene.goal, scene.names(), events("pick-place", (1, 2)))
    kinds = {o.name: o.kind for o in scene.objects}
    other = alternatives(goal, scene.names(), kinds)
    assert [g[-1].onto for g in other] == [START, TABLE]  # never onto itself, nor onto the pad it is already on
    confirmed = scene.with_goal(other[0])
    chosen = session_goal(confirmed.preset, confirmed.goal, confirmed.names(), events("pick-place", (1, 2)))
    assert chosen.source == "you" and chosen.placements == other[0]
    assert chosen.differs == (Placement("block", START),)  # no take brought it back
