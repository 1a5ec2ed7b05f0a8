"""The fourteen ε sliders (in the "All thresholds" folder of the Key-points tab): units a person reads, which
values are automatic and which are the teacher's, back to automatic. Presentation only: values are stored in SI
units (m, s, rad) by the controller; here they are shown in cm, degrees and seconds."""

from __future__ import annotations

import html
import math
from collections.abc import Callable
from dataclasses import dataclass

import viser

from studio.controller import Controller
from studio.core.types import KeypointParams

DEG = 180.0 / math.pi
#: What the folder holds, in one sentence (the paper's names are in each slider's hint).
ABOUT = (
    '<div class="thresholds-about" style="font-size:0.85em;color:#555">Advanced: the fourteen thresholds of the '
    "paper (ε1–ε14). Detail and Suggest set them for you; move one only to try it.</div>"
)


@dataclass(frozen=True)
class SliderSpec:
    """One threshold as a slider: shown value = stored value × ``factor`` in ``unit``.

    ``scaled``: the range follows the size of the demonstrations (distances), else ``lo``…``hi`` as given.
    """

    name: str
    words: str
    unit: str
    factor: float
    lo: float
    hi: float
    step: float
    hint: str
    scaled: bool = False

    @property
    def symbol(self) -> str:
        return f"ε{self.name[3:]}"

    def label(self, yours: bool = False) -> str:
        """ "Travel distance, cm", with "· yours" when the teacher set it (the paper's ε is in the hint)."""
        return f"{self.words}, {self.unit}{' · yours' if yours else ''}"


POSITION: tuple[SliderSpec, ...] = (
    SliderSpec(
        "eps1", "Corner sharpness", "°", DEG, 180.0, 360.0, 1.0,
        "How sharp a corner of the hand's path must be to become a key-point, as the angle between the way in and "
        "the way out: 180° is a straight line (every bend counts), towards 360° only sharp turns and reversals.",
    ),
    SliderSpec(
        "eps2", "Pause speed", "cm/s", 100.0, 0.0, 10.0, 0.1,
        "Below this speed the hand counts as pausing; a pause can become a key-point.",
    ),
    SliderSpec("eps3", "Pause wait", "s", 1.0, 0.0, 5.0, 0.05, "A pause only counts this long after the last one."),
    SliderSpec(
        "eps4", "Pause distance", "cm", 100.0, 0.0, 30.0, 0.1,
        "A pause only counts this far from the last key-point.", scaled=True,
    ),
    SliderSpec(
        "eps5", "Travel distance", "cm", 100.0, 0.0, 60.0, 0.5,
        "Moving this far from the last key-point makes a new key-point.", scaled=True,
    ),
    SliderSpec("eps6", "Travel wait", "s", 1.0, 0.0, 5.0, 0.05, "…but not sooner than this after the last key-point."),
    SliderSpec(
        "eps7", "Travel radius", "cm", 100.0, 0.0, 60.0, 0.5,
        "…and only if the hand stayed within this radius until then.", scaled=True,
    ),
)  # fmt: skip
ORIENTATION: tuple[SliderSpec, ...] = (
    SliderSpec(
        "eps8", "Turn corner sharpness", "°", DEG, 180.0, 360.0, 1.0,
        "Higher keeps only sudden changes in how the hand turns as key-points.",
    ),
    SliderSpec(
        "eps9", "Turn pause speed", "°/s", DEG, 0.0, 30.0, 0.5,
        "Below this turning speed the hand counts as holding its angle.",
    ),
    SliderSpec(
        "eps10", "Turn pause wait", "s", 1.0, 0.0, 5.0, 0.05,
        "A turning pause only counts this long after the last key-point.",
    ),
    SliderSpec(
        "eps11", "Turn pause angle", "°", DEG, 0.0, 90.0, 0.5,
        "A turning pause only counts this far (in angle) from the last key-point.",
    ),
    SliderSpec(
        "eps12", "Turn amount", "°", DEG, 0.0, 120.0, 0.5,
        "Turning this much from the last key-point makes a new key-point.",
    ),
    SliderSpec("eps13", "Turn wait", "s", 1.0, 0.0, 5.0, 0.05, "…but not sooner than this after the last key-point."),
    SliderSpec(
        "eps14", "Turn range", "°", DEG, 0.0, 120.0, 0.5,
        "…and only if the hand's angle stayed within this range until then.",
    ),
)  # fmt: skip
SPECS: dict[str, SliderSpec] = {s.name: s for s in POSITION + ORIENTATION}
_NICE = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)


def scaled_range(size_m: float, value_shown: float) -> tuple[float, float]:
    """(max, step) in cm for a distance slider: up to the demos' size (at least 2 cm), about 100 steps."""
    hi = max(2.0, 100.0 * size_m, 1.2 * value_shown)
    step = next((s for s in _NICE if hi / s <= 150), _NICE[-1])
    return math.ceil(hi / step) * step, step


def _digits(step: float) -> int:
    """Decimals a slider with this step shows (0.05 → 2, 0.5 → 1, 1 → 0)."""
    return max(0, -math.floor(math.log10(step) + 1e-9))


class ThresholdSliders:
    """The "All thresholds" folder: a line with the current key-point counts and whose values are whose, the
    position and orientation sliders, and "back to automatic" for one or all."""

    def __init__(
        self, ctl: Controller, gui: viser.GuiApi, counts_line: Callable[[], str], touched: Callable[[], None]
    ) -> None:
        self.ctl = ctl
        self.counts_line = counts_line
        self.touched = touched  # the teacher works on the thresholds (the scene shows the key-points)
        self.sliders: dict[str, viser.GuiSliderHandle[float]] = {}
        self.lines: list[viser.GuiHtmlHandle] = []
        self._scale = 0.0
        self._pushed: dict[str, float] = {}  # the value each slider was last given by the studio
        settings = ctl.keypoints.settings()
        params = ctl.keypoints.params()
        with gui.add_folder("All thresholds", expand_by_default=False):
            self.whose = gui.add_html("")
            self.about = gui.add_html(ABOUT)
            for title, group in (("Position", POSITION), ("Orientation", ORIENTATION)):
                with gui.add_folder(title, expand_by_default=title.startswith("Position")):
                    self.lines.append(gui.add_html(""))  # the counts, right above the sliders being moved
                    for spec in group:
                        v = float(getattr(params, spec.name)) * spec.factor
                        s = gui.add_slider(
                            spec.label(not settings.is_auto(spec.name)),
                            min=spec.lo,
                            max=spec.hi,
                            step=spec.step,
                            initial_value=min(max(v, spec.lo), spec.hi),
                            hint=f"{spec.hint} ({spec.symbol} in the paper.)",
                        )
                        s.precision = _digits(spec.step)
                        self._pushed[spec.name] = float(s.value)
                        s.on_update(self._make_cb(spec))
                        self.sliders[spec.name] = s
            self.yours = gui.add_dropdown(
                "Your values", options=("none",), initial_value="none",
                hint="The thresholds you set yourself; the others follow your demonstrations.",
            )  # fmt: skip
            self.make_auto = gui.add_button(
                "Make it automatic", icon=viser.Icon.WAND, hint="This threshold follows your demonstrations again."
            )
            self.all_auto = gui.add_button(
                "All automatic", icon=viser.Icon.REFRESH, hint="Every threshold follows your demonstrations again."
            )
        self.make_auto.on_click(ctl.guarded("Could not make the threshold automatic")(self._on_make_auto))
        all_auto = ctl.guarded("Could not make the thresholds automatic")(lambda _: ctl.keypoints.all_auto())
        self.all_auto.on_click(all_auto)
        self.sync(every=True)

    def _make_cb(self, spec: SliderSpec) -> Callable[[viser.GuiEvent], None]:
        def cb(event: viser.GuiEvent) -> None:
            if event.client is None:
                return
            value = float(self.sliders[spec.name].value) / spec.factor
            if spec.name in ("eps1", "eps8"):
                value = min(max(value, math.pi), 2 * math.pi)
            first = self.ctl.keypoints.settings().is_auto(spec.name)
            self.ctl.keypoints.set_param(spec.name, value)
            self._pushed[spec.name] = float(self.sliders[spec.name].value)  # the studio holds this value now
            self.touched()
            if first:  # it is the teacher's from now on
                self.sliders[spec.name].label = spec.label(True)
                self._sync_whose()

        return self.ctl.guarded("Could not change the threshold")(cb)

    def _on_make_auto(self, event: viser.GuiEvent) -> None:
        name = next((s.name for s in SPECS.values() if s.label() == self.yours.value), None)
        if name is None:
            raise ValueError("Choose one of your values first.")
        self.ctl.keypoints.set_auto(name)

    # -- showing the state ---------------------------------------------------------------------------------
    def sync(self, every: bool = False, params: KeypointParams | None = None) -> None:
        """Show the current values: every slider (``every``, after Detail, Suggest, undo, a session), or only
        the automatic ones (a new key-point view: the automatic values follow the demonstrations)."""
        settings = self.ctl.keypoints.settings()
        params = params or self.ctl.keypoints.params()
        arm = self.ctl.keypoints.shown_arm()
        stats = self.ctl.keypoints.stats(arm) if arm else None
        size = stats.size if stats is not None else 0.6
        rescale = abs(size - self._scale) > 1e-9
        self._scale = size
        for name, s in self.sliders.items():
            spec, auto = SPECS[name], settings.is_auto(name)
            v = float(getattr(params, name)) * spec.factor
            if spec.scaled and rescale:
                hi, step = scaled_range(size, v)
                s.max, s.step, s.precision = hi, step, _digits(step)
            if every or auto:
                if not every and abs(float(s.value) - self._pushed.get(name, float(s.value))) > 1e-9:
                    continue  # the teacher has just moved it: their value is on its way to the controller
                v = round(min(max(v, s.min), s.max), _digits(s.step) + 1)  # what the box can show
                if abs(float(s.value) - v) > 1e-9:
                    s.value = v
                self._pushed[name] = float(s.value)
                if s.label != spec.label(not auto):
                    s.label = spec.label(not auto)
        self._sync_whose()

    def _sync_whose(self) -> None:
        content = self._whose_html()
        if content == self.whose.content:  # nothing changed: send nothing (this runs after every view)
            return
        settings = self.ctl.keypoints.settings()
        mine = [SPECS[n].label() for n in SPECS if not settings.is_auto(n)]
        self.yours.options = tuple(mine) or ("none",)
        self.yours.value = mine[0] if mine else "none"
        self.make_auto.disabled = not mine
        self.whose.content = content

    def _whose_html(self) -> str:
        settings = self.ctl.keypoints.settings()
        mine = [SPECS[n] for n in SPECS if not settings.is_auto(n)]
        if not mine:
            text = "Every threshold follows your demonstrations (automatic)."
        else:
            text = (
                "Yours: " + ", ".join(html.escape(f"{s.words} ({s.symbol})") for s in mine) + ". The others follow "
                "your demonstrations."
            )
        arm, arms = self.ctl.keypoints.shown_arm(), self.ctl.teaching.selected_arms
        if arm is not None and len(arms) > 1:  # one set of sliders: automatic values differ per arm
            text += f" Values shown for the {arm} arm's demonstrations; each arm's automatic ones follow its own."
        return f'<div class="kp-whose" data-yours="{len(mine)}" style="font-size:0.85em">{text}</div>'

    def show_counts(self) -> None:
        line = self.counts_line()
        for h in self.lines:
            h.content = line
