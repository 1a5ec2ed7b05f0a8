"""Key-points panel: the paper's fourteen thresholds ε1–ε14 as sliders, live key-points and k-means centroids."""

from __future__ import annotations

import html
import math
import threading
from collections.abc import Callable
from dataclasses import fields

import numpy as np
import viser

from studio.controller import Controller, KeypointView, Layer, Topic
from studio.core.types import ARMS, KeypointParams

#: (field, plain label, unit, min, max, step, hint) — labels say what the threshold does, then the symbol.
POSITION_SLIDERS: tuple[tuple[str, str, str, float, float, float, str], ...] = (
    (
        "eps1",
        "Corner sharpness",
        "rad",
        math.pi,
        2 * math.pi,
        0.01,
        "Higher keeps only sharp corners of the hand's path as key-points (π: every bend counts).",
    ),
    (
        "eps2",
        "Pause speed",
        "m/s",
        0.0,
        0.1,
        0.001,
        "Below this speed the hand counts as pausing; a pause can become a key-point.",
    ),
    ("eps3", "Pause wait", "s", 0.0, 5.0, 0.05, "A pause only counts this long after the previous key-point."),
    ("eps4", "Pause distance", "m", 0.0, 0.3, 0.005, "A pause only counts this far from the previous key-point."),
    (
        "eps5",
        "Travel distance",
        "m",
        0.0,
        0.6,
        0.005,
        "Moving this far from the previous key-point makes a new key-point.",
    ),
    ("eps6", "Travel wait", "s", 0.0, 5.0, 0.05, "…but not sooner than this after the previous key-point."),
    ("eps7", "Travel radius", "m", 0.0, 0.6, 0.005, "…and only if the hand stayed within this radius until then."),
)
ORIENTATION_SLIDERS: tuple[tuple[str, str, str, float, float, float, str], ...] = (
    (
        "eps8",
        "Turn corner sharpness",
        "rad",
        math.pi,
        2 * math.pi,
        0.01,
        "Higher keeps only sudden changes in how the hand turns as key-points.",
    ),
    (
        "eps9",
        "Turn pause speed",
        "rad/s",
        0.0,
        0.5,
        0.005,
        "Below this turning speed the hand counts as holding its angle.",
    ),
    (
        "eps10",
        "Turn pause wait",
        "s",
        0.0,
        5.0,
        0.05,
        "A turning pause only counts this long after the previous key-point.",
    ),
    (
        "eps11",
        "Turn pause angle",
        "rad",
        0.0,
        1.5,
        0.01,
        "A turning pause only counts this far (in angle) from the previous key-point.",
    ),
    (
        "eps12",
        "Turn amount",
        "rad",
        0.0,
        2.0,
        0.01,
        "Turning this much from the previous key-point makes a new key-point.",
    ),
    ("eps13", "Turn wait", "s", 0.0, 5.0, 0.05, "…but not sooner than this after the previous key-point."),
    (
        "eps14",
        "Turn range",
        "rad",
        0.0,
        2.0,
        0.01,
        "…and only if the hand's angle stayed within this range until then.",
    ),
)
SYMBOL = {f"eps{i}": f"ε{i}" for i in range(1, 15)}
CENTROID_COLOR = (220, 20, 20)
#: A centroid's number is left out when a shown number is closer than this (m): numbers never pile up.
LABEL_GAP = 0.035
#: Range of the k slider; a session may hold a k outside it (set in code): the slider shows the nearest end.
K_MIN, K_MAX, K_DEFAULT = 2, 40, 12


def _k_shown(k: int | None) -> int:
    return K_DEFAULT if k is None else min(max(int(k), K_MIN), K_MAX)


def slider_label(name: str, words: str) -> str:
    return f"{words} ({SYMBOL[name]})"


class KeypointsPanel:
    """ε sliders in two groups, k override, reset; draws the controller's key-point view whenever it is new."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        self.scene = server.scene
        gui = server.gui
        self.sliders: dict[str, viser.GuiSliderHandle[float]] = {}
        params = ctl.keypoints.params()
        self.counts = gui.add_html(self._counts_html(None))
        for title, group in (("Position (ε1–ε7)", POSITION_SLIDERS), ("Orientation (ε8–ε14)", ORIENTATION_SLIDERS)):
            with gui.add_folder(title, expand_by_default=title.startswith("Position")):
                for name, words, unit, lo, hi, step, hint in group:
                    v = float(getattr(params, name))
                    s = gui.add_slider(
                        slider_label(name, words),
                        min=round(lo, 4),
                        max=round(hi, 4),
                        step=step,
                        initial_value=min(max(v, lo), hi),
                        hint=f"{hint} Unit: {unit}.",
                    )
                    s.on_update(self._make_cb(name))
                    self.sliders[name] = s
        k = ctl.keypoints.k
        with gui.add_folder("Clusters"):
            self.k_auto = gui.add_checkbox(
                "Choose the number of clusters automatically",
                initial_value=k is None,
                hint="Untick to set k, the number of k-means clusters (= HMM states), yourself.",
            )
            self.k = gui.add_slider(
                "Clusters (k)", min=K_MIN, max=K_MAX, step=1, initial_value=_k_shown(k), disabled=k is None
            )
            self.reset = gui.add_button(
                "Reset to defaults", icon=viser.Icon.REFRESH, hint="Put every threshold back to its default value."
            )

        self.k_auto.on_update(ctl.guarded("Could not change the number of clusters")(self._on_k))
        self.k.on_update(ctl.guarded("Could not change the number of clusters")(self._on_k))
        self.reset.on_click(ctl.guarded("Could not reset the thresholds")(self._on_reset))

        # Scene: one point cloud per (demo, arm) for key-points, one for the centroids, a pool of labels.
        self._kp_nodes: dict[str, viser.PointCloudHandle] = {}
        self._labels: list[viser.LabelHandle] = []
        self._label_wanted: list[bool] = []  # label i has a centroid and room to be read
        self._centroid_nodes: dict[str, viser.PointCloudHandle] = {}
        self._closed = False
        self._draw_lock = threading.RLock()  # drawing and the view's show/hide, one at a time
        ctl.events.on(Topic.SESSION, self._sync_sliders)
        ctl.events.on(Topic.KEYPOINTS, self._on_view)
        ctl.events.on(Topic.VIEW, self._apply_view)
        if ctl.keypoints.view is not None:  # computed before this panel existed
            self.draw(ctl.keypoints.view)
        ctl.keypoints.request()

    # -- callbacks ---------------------------------------------------------------------------------------
    def _make_cb(self, name: str) -> Callable[[viser.GuiEvent], None]:
        def cb(event: viser.GuiEvent) -> None:
            if event.client is None:
                return
            self.ctl.keypoints.set_param(name, float(self.sliders[name].value))

        return self.ctl.guarded("Could not change the threshold")(cb)

    def _on_k(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.k.disabled = bool(self.k_auto.value)
        self.ctl.keypoints.set_k(None if self.k_auto.value else int(self.k.value))

    def _on_reset(self, event: viser.GuiEvent) -> None:
        self.ctl.keypoints.reset()
        self._sync_sliders()

    def _sync_sliders(self) -> None:
        params, k = self.ctl.keypoints.params(), self.ctl.keypoints.k
        with self.server.atomic():
            for f in fields(KeypointParams):
                s = self.sliders[f.name]
                s.value = min(max(float(getattr(params, f.name)), s.min), s.max)
            self.k_auto.value = k is None
            self.k.disabled = k is None
            if k is not None:
                self.k.value = _k_shown(k)

    # -- drawing -----------------------------------------------------------------------------------------
    def _on_view(self) -> None:
        view = self.ctl.keypoints.view
        if view is not None:
            self.draw(view)

    def draw(self, view: KeypointView) -> None:
        """Key-points, centroids with their numbers, and the counts, in one atomic update of the scene."""
        with self._draw_lock:  # one drawing at a time: the scene nodes and the label pool are shared
            if self._closed:  # the studio is stopping: the server may already be gone
                return
            with self.server.atomic():
                self._draw_keypoints(view)
                self._draw_centroids(view)
                self.counts.content = self._counts_html(view)
                self._apply_view()

    def _apply_view(self) -> None:
        """Key-points and cluster centres (with their numbers) follow the step's "Show" layers."""
        kp, centres = self.ctl.view.shown(Layer.KEYPOINTS), self.ctl.view.shown(Layer.CENTROIDS)
        with self._draw_lock, self.server.atomic():
            for node in self._kp_nodes.values():
                node.visible = kp
            for c in self._centroid_nodes.values():
                c.visible = centres
            for lab, wanted in zip(self._labels, self._label_wanted, strict=True):
                lab.visible = centres and wanted

    def _draw_keypoints(self, view: KeypointView) -> None:
        seen: set[str] = set()
        for item in view.demos:
            key = f"/keypoints/{item.arm}/demo{item.index}"
            seen.add(key)
            pts = item.points if len(item.points) else np.zeros((0, 3))
            node = self._kp_nodes.get(key)
            if node is not None and len(pts) and len(node.points) == len(pts):
                node.points = pts.astype(np.float32)
                continue
            if node is not None:
                node.remove()
            self._kp_nodes[key] = self.scene.add_point_cloud(
                key, points=pts.astype(np.float32), colors=item.color, point_size=0.012, point_shape="circle"
            )
        for key in list(self._kp_nodes):
            if key not in seen:
                self._kp_nodes.pop(key).remove()

    def _draw_centroids(self, view: KeypointView) -> None:
        n_labels = 0
        for arm in ARMS:
            c = view.centroids.get(arm)
            key = f"/keypoints/{arm}/centroids"
            node = self._centroid_nodes.pop(key, None)
            if node is not None:
                node.remove()
            if c is None or not len(c):
                continue
            self._centroid_nodes[key] = self.scene.add_point_cloud(
                key, points=c[:, :3].astype(np.float32), colors=CENTROID_COLOR, point_size=0.028, point_shape="circle"
            )
            room = spaced(c[:, :3], LABEL_GAP)
            for j, p in enumerate(c[:, :3]):
                if n_labels >= len(self._labels):
                    self._labels.append(
                        self.scene.add_label(
                            f"/keypoints/labels/{n_labels}", str(j), font_size_mode="screen", font_screen_scale=0.7
                        )
                    )
                    self._label_wanted.append(False)
                lab = self._labels[n_labels]
                lab.text = str(j)
                lab.position = (float(p[0]), float(p[1]), float(p[2]) + 0.035)
                self._label_wanted[n_labels] = room[j]
                n_labels += 1
        for k in range(n_labels, len(self._labels)):
            self._label_wanted[k] = False

    def _counts_html(self, view: KeypointView | None) -> str:
        if view is None:
            return '<div class="kp-counts" style="font-size:0.85em">Finding key-points…</div>'
        rows = []
        for item in view.demos:
            rows.append(
                f'<div class="kp-count" data-demo="{item.index}" data-arm="{item.arm}" data-count="{item.count}">'
                f'<span style="display:inline-block;width:10px;height:10px;border-radius:5px;'
                f'background:rgb{item.color}"></span> {html.escape(item.name)} ({item.arm}): '
                f"<b>{item.count}</b> key-points</div>"
            )
        if not rows:
            rows.append("<div>No demonstrations to look at yet.</div>")
        for arm, k in view.k.items():
            rows.append(
                f'<div class="kp-k" data-arm="{arm}" data-k="{k}">Clusters ({arm} arm): <b>{k}</b> '
                "(large red markers, numbered)</div>"
            )
        for msg in view.messages:
            rows.append(f'<div class="kp-msg" style="color:#b45309">{html.escape(msg)}</div>')
        return '<div class="kp-counts" style="font-size:0.85em">' + "".join(rows) + "</div>"

    def close(self) -> None:
        self._closed = True


def spaced(points: np.ndarray, gap: float) -> list[bool]:
    """Which points get a label so that no two labels are closer than ``gap`` (in order: the first wins)."""
    kept: list[np.ndarray] = []
    out = []
    for p in np.asarray(points, dtype=float):
        ok = all(float(np.linalg.norm(p - k)) >= gap for k in kept)
        if ok:
            kept.append(p)
        out.append(ok)
    return out
