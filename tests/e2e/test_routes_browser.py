"""Browser walk of issue 22's routes: four demonstrations, two each way around an obstacle; training says the
two ways and which one was learned, never a path between them; the Way chooser learns the other one; the live
path on the Key-points step says it too. Screenshots in test-artifacts/."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import expect

from studio.core.kinematics import Baxter
from studio.core.pipeline import demo_from_recording
from studio.core.routes import find_routes
from studio.core.types import Recording
from studio.shapes import joint_angles, route_demos
from studio.storage import SessionStore
from tests.e2e import ui

pytestmark = pytest.mark.e2e


def two_ways(root: Path) -> tuple[int, ...]:
    """A session "two-ways": 4 strokes of 15 cm drawn with the left arm, on the robot's left or right of an
    obstacle (recorded joints by IK of the human-like teacher's strokes). Returns each demo's way (0 = left)."""
    demos, ways = route_demos(2, 0.15, 2.0, 4, seed=3)
    b = Baxter.load()
    right = np.asarray(b.neutral("right"))
    s = SessionStore(root).create("two-ways")
    for d in demos:
        q = np.column_stack([joint_angles(d, "left", baxter=b), np.tile(right, (len(d), 1))])
        grip = np.column_stack([d.gripper, np.full(len(d), 100.0)])
        s.add_recording(Recording(np.asarray(d.t), q, grip, ("left",), d.name))
    found = find_routes([demo_from_recording(r, "left", b) for r in s.recordings])
    assert sorted(r.demos for r in found.routes) == sorted(
        tuple(i for i, w in enumerate(ways) if w == k) for k in (0, 1)
    ), "the recorded strokes go two ways"
    return ways


def test_two_ways_are_named_and_the_other_way_can_be_chosen(browser, studio_factory, shots, tmp_path) -> None:
    root = tmp_path / "sessions"
    root.mkdir()
    ways = two_ways(root)
    left = ", ".join(f"demo {i + 1}" for i, w in enumerate(ways) if w == 0)
    right = ", ".join(f"demo {i + 1}" for i, w in enumerate(ways) if w == 1)
    server = studio_factory("two-ways", sessions_dir=root)
    page = ui.open_studio(browser, server.url)

    # The live path on the Key-points step says which way it follows.
    ui.tab(page, "Key-points")
    expect(page.locator(".live-path").first).to_contain_text("Your demonstrations go two ways", timeout=60_000)
    expect(page.locator(".live-path").first).to_contain_text(f"on the robot's left: {left}")
    shots(page, "key-points: the live path says the two ways")

    # Training learns one way and says so, with the other to choose.
    ui.tab(page, "Train")
    page.get_by_role("button", name="Train").click()
    ui.wait_text(page, r"^Trained\.", timeout=120)
    verdict = page.locator(".verdict[data-level]").first
    sides = [f"on the robot's left: {left}", f"on the robot's right: {right}"]
    if ways[0] == 1:  # the ways are listed in the order of their first demonstration
        sides.reverse()
    words = f"Your demonstrations go two ways ({'; '.join(sides)})."
    expect(verdict).to_contain_text(words, timeout=120_000)
    n_left, n_right = sum(w == 0 for w in ways), sum(w == 1 for w in ways)
    first = "left" if n_left > n_right or (n_left == n_right and ways[0] == 0) else "right"  # a tie: demo 1's way
    expect(verdict).to_contain_text(f"I learned the way on the robot's {first}, never a path between them")
    expect(page.locator("tr.fit-row")).to_have_count(2)  # learned from the two demonstrations of that way
    shots(page, f"trained: two ways, the {first} one learned")

    # The Way chooser learns the other way at once.
    other = "right" if first == "left" else "left"
    ui.choose(page, "Way", f"on the robot's {other}: {right if other == 'right' else left}")
    expect(verdict).to_contain_text(f"I learned the way on the robot's {other}", timeout=120_000)
    expect(page.locator("tr.fit-row")).to_have_count(2)
    names = page.locator("tr.fit-row td:first-child").all_inner_texts()
    assert ", ".join(names) == (right if other == "right" else left)
    shots(page, f"the {other} way chosen and learned")
    assert re.search(r"^(Good|Fair|Poor): ", page.locator(".verdict-head").first.inner_text())
    page.close()
