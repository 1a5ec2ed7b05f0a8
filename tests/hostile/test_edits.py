"""Issue 21 §7: edits that two tabs, a long training or a hostile name could turn against the teacher.

Two tabs' Delete presses, a demonstration deleted while the skill trains, names with invisible characters or
megabytes long, and ``studio import-csv`` refused for its file's name. The websocket tests start a real studio
(viser server on a free 127.0.0.1 port); the others drive a controller without a server.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from studio.app import Studio, build_app
from studio.controller import Controller
from studio.core.errors import StudioError
from studio.csv_io import export_recording_csv
from studio.robot_backend.simulated import SimulatedBaxter
from studio.storage import SessionStore
from tests.conftest import RecordingNotifier, free_port, wait_for
from tests.hostile.builders import make_rec
from tests.viser_client import ViserClient


@pytest.fixture
def app(sessions: Path) -> Iterator[Studio]:
    a = build_app(port=free_port(), session="stack-cup", sessions_dir=sessions)
    yield a
    a.stop()


@pytest.fixture
def ctl(sessions: Path) -> Iterator[Controller]:
    c = Controller(
        store=SessionStore(sessions), session="stack-cup", backend=SimulatedBaxter(), notifier=RecordingNotifier()
    )
    c.start()
    yield c
    c.close()
    c.shutdown()


def tab(app: Studio) -> ViserClient:
    c = ViserClient(f"ws://127.0.0.1:{app.port}/?key={app.access.key}")
    c.wait_gui("Demo action")
    return c


def asked(c: ViserClient) -> int:
    return sum("Delete for good?" in str(n) for n in c.notifications())


def test_two_tabs_delete_presses_never_confirm_each_other(app: Studio) -> None:
    """Today: one tab's Delete asked, another tab's Delete then deleted (the question was shared)."""
    ctl = app.controller
    told = RecordingNotifier(then=ctl.notifier)
    ctl.notifier = told
    names = ctl.demos.names()
    a, b = tab(app), tab(app)

    def said() -> list[str]:
        return [t for t in told.titles() if t in ("Delete for good?", "Demonstration deleted")]

    try:
        a.set_value("Demo action", "Delete")
        assert wait_for(lambda: len(said()) == 1)
        b.set_value("Demo action", "Delete")
        assert wait_for(lambda: len(said()) == 2)
        assert said() == ["Delete for good?", "Delete for good?"], said()  # the second tab was asked too
        assert ctl.demos.names() == names
        assert a.wait_for(lambda _m: asked(a) == 1) and asked(a) == 1  # each tab sees its own question
        a.set_value("Demo action", "Delete")  # the first tab's own second press deletes
        assert wait_for(lambda: len(said()) == 3) and said()[-1] == "Demonstration deleted"
        assert ctl.demos.names() == names[:-1]
        assert wait_for(lambda: app.panels.demos.demo_pick.value == names[-2])  # the list shows the change
        b.set_value("Demo action", "Delete")  # asked about a demonstration that is gone: asks again, deletes nothing
        assert wait_for(lambda: len(said()) == 4) and said()[-1] == "Delete for good?"
        assert ctl.demos.names() == names[:-1]
    finally:
        a.close()
        b.close()


def test_a_demo_deleted_while_training_leaves_the_skill_marked_stale(ctl: Controller, sessions: Path) -> None:
    """Today: the skill was saved marked fresh, listing the deleted demonstration."""
    gate = threading.Event()
    ctl.ctx.submit(lambda: gate.wait(60))  # the work thread is busy: training waits behind it
    future = ctl.training.train()
    deleted = ctl.demos.names()[-1]
    ctl.demos.delete(len(ctl.demos.names()) - 1)
    gate.set()
    assert future.result(timeout=300) is not None
    assert ctl.session.skills and ctl.session.skills_stale
    reopened = SessionStore(sessions).open("stack-cup")
    assert reopened.skills_stale and deleted not in reopened.demo_names
    assert any("changed or deleted while it trained" in body for _, _, body in ctl.notifier.notes)  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    "name",
    ["evil\u202etxt.exe", "demo\u200b 1", "a\u2066b\u2069", "line\u2028break", "\ufeffdemo"],
    ids=["rtl-override", "zero-width-space", "isolate", "line-separator", "bom"],
)
def test_a_name_with_invisible_characters_is_refused(ctl: Controller, name: str) -> None:
    before = ctl.demos.names()
    with pytest.raises(StudioError, match="invisible characters"):
        ctl.demos.rename(0, name)
    with pytest.raises(StudioError, match="invisible characters"):
        ctl.session.add_recording(make_rec(name=name))
    assert ctl.demos.names() == before
    ctl.demos.rename(0, "Grüße, première (1)")  # letters of any language are fine
    assert ctl.demos.names()[0] == "Grüße, première (1)"


def test_a_3_mb_name_is_never_echoed_whole(ctl: Controller, caplog: pytest.LogCaptureFixture) -> None:
    huge = "x" * 3_000_000
    for act in (lambda: ctl.demos.rename(0, huge), lambda: ctl.sessions.new(huge), lambda: ctl.sessions.open(huge)):
        with pytest.raises(StudioError) as err:
            act()
        assert len(str(err.value)) < 400, str(err.value)[:200]
    assert "x" * 100 not in caplog.text


def test_import_csv_refused_for_its_file_name_creates_no_session(tmp_path: Path) -> None:
    """Today: a file whose name cannot name a demonstration was refused, but the session was created empty."""
    from argparse import Namespace

    from studio import commands

    sessions = tmp_path / "sessions"
    bad = tmp_path / "a\tname.csv"  # a tab cannot be in a demonstration's name
    export_recording_csv(make_rec(n=400), bad)
    assert commands.import_csv(Namespace(files=[bad], session="fresh", arm="left", sessions_dir=sessions)) == 1
    assert not SessionStore(sessions).exists("fresh")
    good = tmp_path / "good.csv"
    export_recording_csv(make_rec(n=400), good)
    assert commands.import_csv(Namespace(files=[bad, good], session="fresh", arm="left", sessions_dir=sessions)) == 1
    assert SessionStore(sessions).open("fresh").demo_names == ["good"]
    assert np.isfinite(SessionStore(sessions).open("fresh").recordings[0].t).all()
