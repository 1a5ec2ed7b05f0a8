"""Which demonstrations go which way (core/routes.py), and a skill learned from one way only."""

from __future__ import annotations

import numpy as np
import pytest

from studio.core.errors import InvalidInput
from studio.core.learn_settings import LearnSettings
from studio.core.pipeline import learn_skill
from studio.core.routes import find_routes
from studio.core.types import Skill
from studio.shapes import ShapeSpec, route_demos, shape_demo, shape_demos
from studio.words import routes_words


def groups(ways: tuple[int, ...]) -> list[tuple[int, ...]]:
    return sorted(tuple(i for i, w in enumerate(ways) if w == k) for k in sorted(set(ways)))


@pytest.mark.parametrize(("n_routes", "size", "n"), [(2, 0.15, 3), (2, 0.6, 7), (3, 0.6, 3), (3, 0.15, 7)])
def test_the_ways_are_found(n_routes, size, n):
    demos, ways = route_demos(n_routes, size, 2.0, n, seed=41)
    assert sorted(r.demos for r in find_routes(demos).routes) == groups(ways)


@pytest.mark.parametrize("style", ["careful", "loose"])
def test_one_way_is_not_split(style):
    for shape in ("circle", "zigzag", "wave"):
        assert not find_routes(shape_demos(ShapeSpec(shape, 0.15, 2.0, style=style), 7))


def test_an_odd_demonstration_is_not_a_way():
    odd = [*shape_demos(ShapeSpec("circle", 0.15, 2.0), 3), shape_demo(ShapeSpec("figure-eight", 0.15, 2.0), 9)]
    assert not find_routes(odd)


def test_the_skill_learns_one_way_and_keeps_the_others():
    demos, ways = route_demos(2, 0.15, 2.0, 5, seed=7)
    sk = learn_skill(list(demos))
    mine = [i for i, w in enumerate(ways) if w == ways[0]] if ways.count(ways[0]) >= 3 else None
    assert len(sk.routes) == 2 and sorted(len(r.demos) for r in sk.routes) == [2, 3]
    assert len(sk.routes[sk.route].demos) == 3 and sk.demo_names == sk.routes[sk.route].demos
    assert mine is None or list(sk.demo_names) == [f"demo {i + 1}" for i in mine]
    # the learned path stays on its way: nearer every one of its demos than any demo of the other way
    named = {d.name: d for d in demos}
    other = sk.routes[1 - sk.route].demos
    near = max(
        np.min(np.linalg.norm(named[n].position[:, None] - sk.trajectory.position[None, ::20], axis=2), axis=0).mean()
        for n in sk.demo_names
    )
    far = min(
        np.min(np.linalg.norm(named[n].position[:, None] - sk.trajectory.position[None, ::20], axis=2), axis=0).mean()
        for n in other
    )
    assert near < 0.25 * far
    again = learn_skill(list(demos), LearnSettings(route=1 - sk.route))
    assert again.demo_names == sk.routes[1 - sk.route].demos and again.route == 1 - sk.route
    back = Skill.from_arrays(sk.to_arrays())
    assert back.routes == sk.routes and back.route == sk.route and back.route_where == pytest.approx(sk.route_where)
    words = routes_words(sk.routes, sk.route)
    assert words.startswith("Your demonstrations go two ways (on the robot's ") and "I learned the way on" in words
    assert "on the robot's left: " in words and "on the robot's right: " in words
    with pytest.raises(InvalidInput, match="choose one of them"):
        learn_skill(list(demos), LearnSettings(route=2))
    with pytest.raises(InvalidInput, match="all go the same way"):
        learn_skill(list(shape_demos(ShapeSpec("circle", 0.15, 2.0), 3)), LearnSettings(route=1))
