"""Sessions panel: new / open / save / duplicate, replay a demo, zip download and upload, Baxter SDK CSV export."""

from __future__ import annotations

import viser

from studio import viser_adapter
from studio.controller import REPLAY, SCENE_PRESETS, Controller, Topic
from studio.core.errors import InvalidInput
from studio.panels._choice import kept_choice
from studio.words import count_words

EXPORT_WHY = "*Train first: the export is the learned skill.*"


class SessionsPanel:
    def __init__(self, ctl: Controller, server: viser.ViserServer) -> None:
        self.ctl = ctl
        self.server = server
        gui = server.gui
        self.current = gui.add_markdown(self._current_text())
        with gui.add_folder("Session"):
            names = ctl.sessions.names()
            self.pick = gui.add_dropdown(
                "Open session",
                options=names or [ctl.session.name],
                initial_value=ctl.session.name,
                hint="Choose a session, then press Open. The session that is open is named above.",
            )
            self.name = gui.add_text(
                "New name", initial_value="", hint="Name for a new session or for a copy of this one."
            )
            self.new_scene = gui.add_dropdown(
                "New session's table",
                options=SCENE_PRESETS,
                initial_value=SCENE_PRESETS[0],
                hint="The objects a new session starts with (you can add, move and remove them in Teach).",
            )
            self.actions = gui.add_button_group("Session action", options=("Open", "New", "Save", "Duplicate"))
        with gui.add_folder("Replay a demonstration"):
            self.replay_pick = gui.add_dropdown("Demonstration", options=ctl.demos.names() or ["(none)"])
            self._listed = list(self.replay_pick.options)  # what the replay's list offered before its last redraw
            self.replay_controls = gui.add_button_group("Replay", options=("Play", "Pause", "Stop"))
            self.replay_time = gui.add_slider(
                "Replay time (s)",
                min=0.0,
                max=1.0,
                step=0.01,
                initial_value=0.0,
                disabled=ctl.playback.kind != REPLAY,
                hint="Press Play first, then move to any moment of the demonstration.",
            )
        with gui.add_folder("Files"):
            self.download = gui.add_button("Download session (.zip)", icon=viser.Icon.DOWNLOAD)
            self.upload = gui.add_upload_button(
                "Upload session (.zip)",
                icon=viser.Icon.UPLOAD,
                mime_type=".zip,application/zip",
                disabled=ctl.teaching.recording,
                hint="Add a downloaded session and open it (not while recording or training).",
            )
            self.export = gui.add_button(
                "Export joint trajectory (Baxter SDK CSV)",
                icon=viser.Icon.FILE_EXPORT,
                disabled=not ctl.training.skills(),
                hint="The learned skill as a file the Baxter SDK can play back (train first).",
            )
            self.export_why = gui.add_markdown(EXPORT_WHY, visible=not ctl.training.skills())
        self._last_sync = 0.0

        self.actions.on_click(ctl.guarded("The session action did not work")(self._on_action))
        self.replay_controls.on_click(ctl.guarded("Could not replay the demonstration")(self._on_replay))
        self.replay_time.on_update(ctl.guarded("Could not move the replay")(self._on_replay_time))
        self.download.on_click(ctl.guarded("Could not prepare the download")(self._on_download))
        self.upload.on_upload(ctl.guarded("The upload did not work")(self._on_upload))
        self.export.on_click(ctl.guarded("Could not export the trajectory")(self._on_export))
        for topic in (Topic.SESSION, Topic.SESSIONS, Topic.DEMOS):
            ctl.events.on(topic, self.refresh)
        ctl.events.on(Topic.SESSION, self._on_session)
        # Buttons that cannot act now are disabled (the actions still refuse in plain words if raced).
        for topic in (Topic.SESSION, Topic.SKILL, Topic.RECORDING, Topic.TRAINING, Topic.PLAYBACK):
            ctl.events.on(topic, self._sync_enabled)

    def _sync_enabled(self) -> None:
        ctl = self.ctl
        with self.server.atomic():
            self.export.disabled = not ctl.training.skills()
            self.export_why.visible = not ctl.training.skills()
            self.upload.disabled = ctl.teaching.recording or ctl.training.busy
            self.replay_time.disabled = ctl.playback.kind != REPLAY

    def _current_text(self) -> str:
        s = self.ctl.session
        kept = " · an example, kept as it is (Duplicate it to change it)" if s.read_only else ""
        return f"Open session: **{s.name}** · {count_words(len(s.recordings), 'demonstration')}{kept}"

    def refresh(self) -> None:
        names = self.ctl.sessions.names()
        demos = self.ctl.demos.names() or ["(none)"]
        with self.server.atomic():
            self.current.content = self._current_text()
            self.pick.options = names or [self.ctl.session.name]
            self.pick.value = self.ctl.session.name
            cur = self.replay_pick.value
            self.replay_pick.options = demos
            if cur not in demos:  # a renamed demonstration stays chosen; else the first one
                self.replay_pick.value = kept_choice(self._listed, cur, demos, 0)
            self._listed = list(demos)

    def _on_session(self) -> None:
        """Another session is open: the replay starts over on its first demonstration."""
        demos = self.ctl.demos.names()
        with self.server.atomic():
            self.replay_pick.options = demos or ["(none)"]
            self.replay_pick.value = demos[0] if demos else "(none)"
            self._listed = list(self.replay_pick.options)
            self.replay_time.max = round(max(self.ctl.demos.duration(0), 0.01), 2) if demos else 1.0
            self.replay_time.value = 0.0

    def _on_action(self, event: viser.GuiEvent) -> None:
        try:
            self._do(event.target.value)
        finally:  # refused or done: the box names the session that is open
            self.pick.value = self.ctl.session.name

    def _do(self, action: str) -> None:
        sessions = self.ctl.sessions
        if action == "Open":
            sessions.open(self.pick.value)
        elif action == "New":
            sessions.new(self.name.value, scene=self.new_scene.value)
            self.name.value = ""  # the next new name starts empty, never the last one
        elif action == "Save":
            sessions.save()
        elif action == "Duplicate":
            sessions.duplicate(self.name.value)
            self.name.value = ""

    def _on_replay(self, event: viser.GuiEvent) -> None:
        action = event.target.value
        if action == "Play":
            names = self.ctl.demos.names()
            if self.replay_pick.value not in names:
                raise InvalidInput("Choose a demonstration to replay first.")
            dur = self.ctl.playback.play_demo(names.index(self.replay_pick.value))
            self.replay_time.max = round(max(dur, 0.01), 2)
        elif action == "Pause":
            self.ctl.playback.pause(REPLAY)
        else:
            self.ctl.playback.stop(REPLAY)

    def _on_replay_time(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.ctl.playback.seek(REPLAY, float(self.replay_time.value))

    def _on_download(self, event: viser.GuiEvent) -> None:
        name, data = self.ctl.sessions.zip()
        if event.client is None:
            raise InvalidInput("Could not find the browser tab to send the file to.")
        event.client.send_file_download(name, data, save_immediately=True)

    def _on_upload(self, event: viser.GuiEvent) -> None:
        f = self.upload.value
        # viser keeps the last file as the button's value (up to the 512 MB cap): imported or refused, let it go
        viser_adapter.set_value_quietly(self.upload, type(f)("", b""))
        self.ctl.sessions.import_zip(f.name, f.content)

    def _on_export(self, event: viser.GuiEvent) -> None:
        name, data = self.ctl.sessions.trajectory_csv()
        if event.client is None:
            raise InvalidInput("Could not find the browser tab to send the file to.")
        event.client.send_file_download(name, data, save_immediately=True)

    def tick(self, now: float) -> None:
        pos = self.ctl.playback.position(REPLAY)
        if pos is not None and now - self._last_sync > 0.1:
            self._last_sync = now
            self.replay_time.value = round(min(pos, self.replay_time.max), 2)
