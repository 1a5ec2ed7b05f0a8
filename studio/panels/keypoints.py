"""Key-points panel: Detail (fewer ↔ more key-points) for newcomers, Suggest thresholds, the fourteen thresholds
ε1–ε14 in an "All thresholds" folder, k; in the scene the live key-points, k-means centroids and the live learned
path (thin, dashed, drawn with the Key-points layer)."""

from __future__ import annotations

import html
import math
import threading

import numpy as np
import viser

from studio.controller import Controller, KeypointView, Layer, LivePath, Step, Topic
from studio.core.thresholds import DETAIL_MAX, DETAIL_MIN
from studio.core.types import ARMS, Arm
from studio.panels._charts import dashes
from studio.panels._sliders import SPECS, ThresholdSliders
from studio.panels._suggest import SuggestControls

CENTROID_COLOR = (220, 20, 20)
#: A centroid's number is left out when a shown number is closer than this (m): numbers never pile up.
LABEL_GAP = 0.035
#: At most this many centroid numbers per arm (spread along the path); the markers themselves are all drawn.
MAX_LABELS = 12
LIVE_PATH_COLOR = (0, 200, 230)  # the learned path's cyan (Preview draws it thick and solid)
#: Range of the k slider; a session may hold a k outside it (set in code): the slider shows the nearest end.
K_MIN, K_MAX, K_DEFAULT = 2, 40, 12


def _k_shown(k: int | None) -> int:
    return K_DEFAULT if k is None else min(max(int(k), K_MIN), K_MAX)


def slider_label(name: str, words: str = "") -> str:
    """The label of threshold ``name``'s slider while it is automatic (e.g. "Travel distance, cm (ε5)")."""
    return SPECS[name].label()


class KeypointsPanel:
    """Counts and the live path's figure, Detail, Suggest, every threshold, k; draws the controller's key-point
    view and live path whenever they are new, shown or hidden with the Key-points and Cluster centres layers."""

    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        self.scene = server.scene
        gui = server.gui
        self.counts = gui.add_html(counts_html(None))
        self.live_text = gui.add_html(live_html(self.ctl.live.paths))
        self.detail = gui.add_slider(
            "Detail: fewer ↔ more key-points",
            min=DETAIL_MIN,
            max=DETAIL_MAX,
            step=0.5,
            initial_value=ctl.keypoints.settings().detail,
            hint="Moves the automatic thresholds together: left for fewer key-points (a smoother, simpler skill), "
            "right for more (closer to every turn of your demonstrations). Values you set yourself stay.",
        )
        self.suggest = SuggestControls(ctl, gui)
        self.thresholds = ThresholdSliders(ctl, gui, lambda: counts_line(ctl.keypoints.view), self._touched)
        self.sliders = self.thresholds.sliders
        k = ctl.keypoints.k
        with gui.add_folder("Clusters", expand_by_default=False):
            self.k_auto = gui.add_checkbox(
                "Choose the number of clusters automatically",
                initial_value=k is None,
                hint="Untick to set k, the number of k-means clusters (= HMM states), yourself.",
            )
            self.k = gui.add_slider(
                "Clusters (k)", min=K_MIN, max=K_MAX, step=1, initial_value=_k_shown(k), disabled=k is None
            )
        self.reset = gui.add_button(
            "Everything automatic",
            icon=viser.Icon.REFRESH,
            hint="Detail back to the middle, every threshold and the number of clusters automatic.",
        )
        self.detail.on_update(ctl.guarded("Could not change the detail")(self._on_detail))
        self.k_auto.on_update(ctl.guarded("Could not change the number of clusters")(self._on_k))
        self.k.on_update(ctl.guarded("Could not change the number of clusters")(self._on_k))
        self.reset.on_click(ctl.guarded("Could not reset the thresholds")(lambda _: ctl.keypoints.reset()))

        # Scene: one point cloud per (demo, arm) for key-points, one for the centroids, a pool of labels, and one
        # dashed line per arm for the live path.
        self._kp_nodes: dict[str, viser.PointCloudHandle] = {}
        self._labels: list[viser.LabelHandle] = []
        self._label_wanted: list[bool] = []  # label i has a centroid and room to be read
        self._centroid_nodes: dict[str, viser.PointCloudHandle] = {}
        self._live_nodes: dict[str, viser.LineSegmentsHandle] = {}
        self._n_labels = 0
        self._pending: KeypointView | None = None  # a view whose markers wait for its live path
        self._closed = False
        self._draw_lock = threading.RLock()  # drawing and the view's show/hide, one at a time
        ctl.events.on(Topic.SESSION, self._sync_all)
        ctl.events.on(Topic.THRESHOLDS, self._sync_all)
        ctl.events.on(Topic.KEYPOINTS, self._on_view)
        ctl.events.on(Topic.LIVE_PATH, self._on_live)
        ctl.events.on(Topic.VIEW, self._apply_view)
        if ctl.keypoints.view is not None:  # computed before this panel existed
            self.draw(ctl.keypoints.view)
        ctl.keypoints.request()

    # -- callbacks ---------------------------------------------------------------------------------------
    def _touched(self) -> None:
        """The teacher works on the thresholds: the scene shows the Key-points step (their own "Show" choices
        stay while they are in it)."""
        if self.ctl.view.step != Step.KEYPOINTS:
            self.ctl.view.set_step(Step.KEYPOINTS)

    def _on_detail(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.ctl.keypoints.set_detail(float(self.detail.value))
        self._touched()

    def _on_k(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.k.disabled = bool(self.k_auto.value)
        self.ctl.keypoints.set_k(None if self.k_auto.value else int(self.k.value))
        self._touched()

    def _sync_all(self) -> None:
        """Settings changed other than by one slider (Detail, automatic again, Suggest, undo, session)."""
        with self.server.atomic():
            self.detail.value = self.ctl.keypoints.settings().detail
            self.thresholds.sync(every=True)
            self._sync_k(self.ctl.keypoints.view)

    def _sync_k(self, view: KeypointView | None) -> None:
        k = self.ctl.keypoints.k
        if self.k_auto.value != (k is None):
            self.k_auto.value = k is None
        if self.k.disabled != (k is None):
            self.k.disabled = k is None
        shown = _k_shown(k) if k is not None else None
        if k is None and view is not None and view.k:  # automatic: show the k in use, not a stale number
            shown = _k_shown(next(iter(view.k.values())))
        if shown is not None and self.k.value != shown:
            self.k.value = shown

    # -- drawing -----------------------------------------------------------------------------------------
    def _on_view(self) -> None:
        """A new key-point view: the counts and values at once; the markers with the live path computed next
        (one scene update per step: without a GPU a second update would wait for the first one's frame,
        docs/decisions/018), or at once when no live path follows."""
        view = self.ctl.keypoints.view
        if view is None:
            return
        with self._draw_lock:
            if self._closed:
                return
            with self.server.atomic():
                self._draw_words(view)
            if self.ctl.live.wanted():
                self._pending = view
                return
            self._pending = None
            with self.server.atomic():
                self._draw_markers(view)

    def draw(self, view: KeypointView) -> None:
        """Key-points, centroids with their numbers, the counts and the automatic values, in one atomic update."""
        with self._draw_lock:  # one drawing at a time: the scene nodes and the label pool are shared
            if self._closed:  # the studio is stopping: the server may already be gone
                return
            with self.server.atomic():
                self._draw_markers(view)
                self._draw_words(view)

    def _draw_markers(self, view: KeypointView) -> None:
        self._draw_keypoints(view)
        self._draw_centroids(view)

    def _draw_words(self, view: KeypointView) -> None:
        self.counts.content = counts_html(view)
        self.thresholds.show_counts()
        arm = self.ctl.keypoints.shown_arm()
        if arm in view.params and view.settings == self.ctl.keypoints.settings():  # a stale view: the next one shows
            self.thresholds.sync(params=view.params[arm])
        self._sync_k(view)

    def _draw_keypoints(self, view: KeypointView) -> None:
        seen: set[str] = set()
        shown = self.ctl.view.shown(Layer.KEYPOINTS)
        for item in view.demos:
            key = f"/keypoints/{item.arm}/demo{item.index}"
            seen.add(key)
            pts = (item.points if len(item.points) else np.zeros((0, 3))).astype(np.float32)
            node = self._kp_nodes.get(key)
            if node is not None:  # moved in place (a single colour: any number of points)
                node.points = pts
                continue
            self._kp_nodes[key] = self.scene.add_point_cloud(
                key, points=pts, colors=item.color, point_size=0.012, point_shape="circle", visible=shown
            )
        for key in list(self._kp_nodes):
            if key not in seen:
                self._kp_nodes.pop(key).remove()

    def _draw_centroids(self, view: KeypointView) -> None:
        n_labels = 0
        shown = self.ctl.view.shown(Layer.CENTROIDS)
        for arm in ARMS:
            c = view.centroids.get(arm)
            key = f"/keypoints/{arm}/centroids"
            if c is None or not len(c):
                node = self._centroid_nodes.pop(key, None)
                if node is not None:
                    node.remove()
                continue
            pts = c[:, :3].astype(np.float32)
            if key in self._centroid_nodes:
                self._centroid_nodes[key].points = pts
            else:
                self._centroid_nodes[key] = self.scene.add_point_cloud(
                    key, points=pts, colors=CENTROID_COLOR, point_size=0.028, point_shape="circle", visible=shown
                )
            room = spaced(pts, LABEL_GAP)
            for j, p in enumerate(pts):
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
                lab.visible = shown and room[j]
                n_labels += 1
        for k in range(n_labels, len(self._labels)):
            self._label_wanted[k] = False
            self._labels[k].visible = False
        self._n_labels = n_labels

    def _on_live(self) -> None:
        """A new live path: redraw it dashed, with its figure and the key-points it was learned from, in one
        atomic update."""
        paths = self.ctl.live.paths
        with self._draw_lock:
            if self._closed:
                return
            shown = self.ctl.view.shown(Layer.KEYPOINTS)
            pending, self._pending = self._pending, None
            with self.server.atomic():
                if pending is not None:
                    self._draw_markers(pending)
                for arm in ARMS:
                    key = f"/keypoints/{arm}/live-path"
                    p = paths.get(arm)
                    segs = dashes(p.position, 60) if p is not None and len(p.position) > 1 else None
                    node = self._live_nodes.get(key)
                    if segs is None or not len(segs):
                        if node is not None:
                            node.visible = False
                        continue
                    if node is not None and node.points.shape == segs.shape:
                        node.points = segs
                        node.visible = shown
                    else:
                        if node is not None:
                            node.remove()
                        self._live_nodes[key] = self.scene.add_line_segments(
                            key, segs, colors=LIVE_PATH_COLOR, thickness=3.0, thickness_units="screen", visible=shown
                        )
                self.live_text.content = live_html(self.ctl.live.paths)

    def _apply_view(self) -> None:
        """Show or hide this panel's scene nodes as the Key-points and Cluster centres layers say."""
        kp, cent = self.ctl.view.shown(Layer.KEYPOINTS), self.ctl.view.shown(Layer.CENTROIDS)
        with self._draw_lock:
            if self._closed:
                return
            pending, self._pending = self._pending, None
            with self.server.atomic():
                if pending is not None:  # its live path will not come now: draw what is waiting
                    self._draw_markers(pending)
                for node in self._kp_nodes.values():
                    node.visible = kp
                for key, line in self._live_nodes.items():
                    arm = key.split("/")[2]
                    line.visible = kp and arm in self.ctl.live.paths and len(self.ctl.live.paths[arm].position) > 1
                for node in self._centroid_nodes.values():
                    node.visible = cent
                for lab, wanted in zip(self._labels[: self._n_labels], self._label_wanted, strict=False):
                    lab.visible = cent and wanted  # numbers never pile up (spaced)

    def close(self) -> None:
        self._closed = True


def live_html(paths: dict[Arm, LivePath]) -> str:
    """The live path's figure in words (class ``live-path``, ``data-version``: the key-point view it shows)."""
    if not paths:
        return '<div class="live-path" data-version="-1" style="font-size:0.85em"></div>'
    rows = []
    for arm, p in paths.items():
        who = f"{arm.capitalize()} arm: " if len(paths) > 1 else ""
        mark = ""
        if not p.message and math.isfinite(p.g_over_r):  # G/R: against how far the demos are from each other
            if p.g_over_r <= 0.6:
                mark = " That is closer than your demonstrations are to each other."
            elif p.g_over_r > 1.0:
                mark = " That is farther than they are from each other: try more detail."
        rows.append(f"{who}{html.escape(p.words)}{mark}")
    version = max(p.version for p in paths.values())
    return (
        f'<div class="live-path" data-version="{version}" style="font-size:0.85em">'
        '<span style="color:rgb(0,200,230);font-weight:700">- - -</span> ' + "<br>".join(rows) + "</div>"
    )


def counts_line(view: KeypointView | None) -> str:
    """One line of key-point counts and k, shown right above the sliders being moved."""
    if view is None:
        return ""
    parts = [f"{html.escape(d.name)}: {d.count}" for d in view.demos]
    ks = ", ".join(str(k) for k in view.k.values())
    return (
        '<div class="kp-line" style="font-size:0.8em;color:#555">Key-points now — '
        + " · ".join(parts)
        + (f" — {ks} clusters" if ks else "")
        + "</div>"
    )


def counts_html(view: KeypointView | None) -> str:
    """Key-points per demo (class ``kp-count``, ``data-count``), clusters per arm, messages."""
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
    if view.in_frames:
        rows.append(
            '<div class="kp-frames" style="color:#555">Drawn as the skill learns them: each stretch between a grasp '
            "and a release relative to the object it acts on, with the objects where they are now.</div>"
        )
    for msg in view.messages:
        rows.append(f'<div class="kp-msg" style="color:#b45309">{html.escape(msg)}</div>')
    return '<div class="kp-counts" style="font-size:0.85em">' + "".join(rows) + "</div>"


def spaced(points: np.ndarray, gap: float, most: int = MAX_LABELS) -> list[bool]:
    """Which points get a label: no two labels closer than ``gap`` (in order: the first wins), and at most
    ``most`` of them (the gap widens until so few are left): numbers never pile up, whatever the zoom."""
    pts = np.asarray(points, dtype=float)
    while True:
        kept: list[np.ndarray] = []
        out = []
        for p in pts:
            ok = all(float(np.linalg.norm(p - k)) >= gap for k in kept)
            if ok:
                kept.append(p)
            out.append(ok)
        if len(kept) <= most:
            return out
        gap *= 1.25
