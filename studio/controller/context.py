"""What every part of the controller shares: the open session and its taught arms, one lock, the events,
notifications, the pose the scene draws, what learning reuses, the checks before the session changes, one work
thread for heavy jobs and the helper threads they spread tasks over. Failures become plain-words notifications;
the studio keeps running."""

from __future__ import annotations

import functools
import logging
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Literal, ParamSpec, Protocol, TypeVar

from studio.controller.events import Events, Topic
from studio.controller.pose import Display
from studio.core.arms import normalize_arms
from studio.core.caches import LearningCaches
from studio.core.errors import Cancelled, InvalidInput, StudioError
from studio.core.kinematics import Baxter
from studio.core.types import Arm
from studio.storage import Session, SessionStore
from studio.words.controls import STUDIO_CONTROLS, Control, Controls, say

log = logging.getLogger(__name__)

P = ParamSpec("P")
R = TypeVar("R")
Kind = Literal["error", "warning", "info", "success"]
#: Helper threads (both cores of the target machine; docs/decisions/030 says why threads).
HELPERS = 2


class Notifier(Protocol):
    """Tells the person something in plain words (the app shows it in the browser tabs).

    ``client`` is the tab to tell (an opaque handle from the GUI event), or None for every tab.
    """

    def notify(self, title: str, body: str, *, kind: Kind = "error", client: object | None = None) -> None: ...


class LogNotifier:
    """Notifications without a GUI: logged (tests and headless use)."""

    def notify(self, title: str, body: str, *, kind: Kind = "error", client: object | None = None) -> None:
        if kind in ("error", "warning"):
            log.warning("%s: %s", title, body)
        else:
            log.info("%s: %s", title, body)


class Context:
    """Shared by the parts of the :class:`~studio.controller.Controller`.

    Attributes:
        store: the sessions on disk; ``session`` is the open one (switched only by the session actions).
        baxter: the kinematic model (FK/IK).
        notifier: where notifications go (replaceable, e.g. by a test that records them).
        events: the topics the views subscribe to.
        lock: guards the state the parts share (session switches, the recorder, training).
        display: which robot pose the scene draws (the live robot, or a replay's or preview's).
        helpers: the threads a job on the work thread spreads its tasks over (Suggest's candidates).
        headless: a failed job on the work thread stays in its future (the caller raises it) instead of
            becoming a notification.
        stopping: set by :meth:`shutdown`: a job that can stop early (the verdict) stops (raises
            :class:`~studio.core.errors.Cancelled`, its future's result is None).
        controls: how the audience reaches a :class:`~studio.words.controls.Control` its sentences point to.
    """

    def __init__(
        self,
        store: SessionStore,
        session: Session,
        baxter: Baxter,
        notifier: Notifier,
        *,
        headless: bool = False,
        controls: Controls = STUDIO_CONTROLS,
    ) -> None:
        self.store = store
        self.controls = controls
        self.session = session
        self.baxter = baxter
        self.notifier = notifier
        self.events = Events()
        self.lock = threading.RLock()
        self.display = Display()
        #: what learning reuses across calls (key-point series, DTW maps, ways): the sliders, the live path and
        #: training share it
        self.caches = LearningCaches()
        self.headless = headless
        self._leaving: list[Callable[[str], None]] = []
        self._work = ThreadPoolExecutor(max_workers=1, thread_name_prefix="studio-work")
        self.helpers = ThreadPoolExecutor(max_workers=HELPERS, thread_name_prefix="studio-helper")
        self.stopping = threading.Event()

    @property
    def arms(self) -> tuple[Arm, ...]:
        """The arm(s) taught in the open session."""
        return taught_arms(self.session)

    def on_leave(self, check: Callable[[str], None]) -> None:
        """Call ``check(doing)`` before the open session is changed (``doing``: "opening another session", …):
        it refuses in plain words (raises :class:`StudioError`) or keeps what belongs to the session being left."""
        self._leaving.append(check)

    def leave(self, doing: str) -> None:
        """Run the checks of :meth:`on_leave` (the first refusal propagates)."""
        for check in list(self._leaving):
            check(doing)

    def notify(self, title: str, body: str, *, kind: Kind = "error", client: object | None = None) -> None:
        self.notifier.notify(title, body, kind=kind, client=client)

    def say(self, control: Control, *, first: bool = False) -> str:
        """How this audience reaches ``control`` (its phrase in :attr:`controls`; capitalised with ``first``)."""
        return say(self.controls, control, first=first)

    def emit(self, topic: Topic) -> None:
        self.events.emit(topic)

    def report(self, exc: BaseException, *, title: str = "That did not work", client: object | None = None) -> None:
        """A failure as a notification: a :class:`StudioError`'s own words, anything else logged with its
        traceback and told in general words."""
        if isinstance(exc, StudioError):
            self.notify(title, str(exc), client=client)
            return
        log.error("%s", title, exc_info=exc)
        self.notify(
            title,
            f"Something unexpected went wrong ({type(exc).__name__}: {exc}). Your work is kept; you can try again.",
            client=client,
        )

    def guarded(self, title: str = "That did not work") -> Callable[[Callable[P, R]], Callable[P, R | None]]:
        """Decorator for GUI callbacks: any failure becomes a notification (to the tab of the event, when the
        first argument is a GUI event with a ``client``); the studio keeps running."""

        def deco(fn: Callable[P, R]) -> Callable[P, R | None]:
            @functools.wraps(fn)
            def wrapper(*args: P.args, **kwargs: P.kwargs) -> R | None:
                try:
                    return fn(*args, **kwargs)
                except Exception as exc:
                    client = getattr(args[0], "client", None) if args else None  # viser's GuiEvent
                    self.report(exc, title=title, client=client)
                    return None

            return wrapper

        return deco

    def submit(
        self,
        job: Callable[[], R],
        *,
        done: Callable[[R], None] | None = None,
        title: str = "That did not work",
    ) -> Future[R | None]:
        """Run ``job`` on the work thread (one job at a time); ``done(result)`` runs there too. A failure is a
        notification and the future's result is None (:attr:`headless`: the future holds the failure)."""

        def run() -> R | None:
            try:
                result = job()
                if done is not None:
                    done(result)
                return result
            except Cancelled:
                return None
            except Exception as exc:
                if self.headless:
                    raise
                self.report(exc, title=title)
                return None

        return self._work.submit(run)

    def shutdown(self) -> None:
        """Drop queued work; a running job finishes on its own, or stops early where it can (:attr:`stopping`)."""
        self.stopping.set()
        self._work.shutdown(wait=False, cancel_futures=True)
        self.helpers.shutdown(wait=False, cancel_futures=True)


def taught_arms(session: Session) -> tuple[Arm, ...]:
    """The arm(s) ``session`` teaches ("left" when it names none that is valid)."""
    try:
        return normalize_arms(tuple(session.arms))
    except InvalidInput:
        return ("left",)
