"""Sessions panel: new / open / save / duplicate, replay a demo, zip download and upload, Baxter SDK CSV export."""

from __future__ import annotations

from typing import TYPE_CHECKING

import viser

if TYPE_CHECKING:
    from studio.app import Studio


class SessionsPanel:
    def __init__(self, app: Studio, gui: viser.GuiApi) -> None:
        self.app = app
        self.current = gui.add_markdown(self._current_text())
        with gui.add_folder("Session"):
            names = app.session_names()
            self.pick = gui.add_dropdown(
                "Open session", options=names or [app.session.name], initial_value=app.session.name
            )
            self.name = gui.add_text(
                "New name", initial_value="", hint="Name for a new session or for a copy of this one."
            )
            self.actions = gui.add_button_group("Session action", options=("Open", "New", "Save", "Duplicate"))
        with gui.add_folder("Replay a demonstration"):
            self.replay_pick = gui.add_dropdown("Demonstration", options=app.demo_names() or ["(none)"])
            self.replay_controls = gui.add_button_group("Replay", options=("Play", "Pause", "Stop"))
            self.replay_time = gui.add_slider(
                "Replay time (s)",
                min=0.0,
                max=1.0,
                step=0.01,
                initial_value=0.0,
                disabled=app.playback_kind() != "replay",
                hint="Press Play first, then move to any moment of the demonstration.",
            )
        with gui.add_folder("Files"):
            self.download = gui.add_button("Download session (.zip)", icon=viser.Icon.DOWNLOAD)
            self.upload = gui.add_upload_button(
                "Upload session (.zip)",
                icon=viser.Icon.UPLOAD,
                mime_type=".zip,application/zip",
                disabled=app.recorder is not None,
                hint="Add a downloaded session and open it (not while recording or training).",
            )
            self.export = gui.add_button(
                "Export joint trajectory (Baxter SDK CSV)",
                icon=viser.Icon.FILE_EXPORT,
                disabled=not app.skills(),
                hint="The learned skill as a file the Baxter SDK can play back (train first).",
            )
        self._last_sync = 0.0

        self.actions.on_click(app.guarded("The session action did not work")(self._on_action))
        self.replay_controls.on_click(app.guarded("Could not replay the demonstration")(self._on_replay))
        self.replay_time.on_update(app.guarded("Could not move the replay")(self._on_replay_time))
        self.download.on_click(app.guarded("Could not prepare the download")(self._on_download))
        self.upload.on_upload(app.guarded("The upload did not work")(self._on_upload))
        self.export.on_click(app.guarded("Could not export the trajectory")(self._on_export))
        app.events.on("session", self.refresh)
        app.events.on("sessions", self.refresh)
        app.events.on("demos", self.refresh)
        # Buttons that cannot act now are disabled (the actions still refuse in plain words if raced).
        app.events.on("session", self._sync_enabled)
        app.events.on("skill", self._sync_enabled)
        app.events.on("recording", self._sync_enabled)
        app.events.on("training", self._sync_enabled)
        app.events.on("playback", self._sync_enabled)

    def _sync_enabled(self) -> None:
        with self.app.server.atomic():
            self.export.disabled = not self.app.skills()
            self.upload.disabled = self.app.recorder is not None or self.app.training
            self.replay_time.disabled = self.app.playback_kind() != "replay"

    def _current_text(self) -> str:
        s = self.app.session
        return f"Open session: **{s.name}** · {len(s.recordings)} demonstrations"

    def refresh(self) -> None:
        names = self.app.session_names()
        demos = self.app.demo_names() or ["(none)"]
        with self.app.server.atomic():
            self.current.content = self._current_text()
            self.pick.options = names or [self.app.session.name]
            self.pick.value = self.app.session.name
            cur = self.replay_pick.value
            self.replay_pick.options = demos
            if cur not in demos:
                self.replay_pick.value = demos[0]

    def _on_action(self, event: viser.GuiEvent) -> None:
        action = event.target.value
        if action == "Open":
            self.app.open_session(self.pick.value)
        elif action == "New":
            self.app.new_session(self.name.value)
        elif action == "Save":
            self.app.save_session()
        elif action == "Duplicate":
            self.app.duplicate_session(self.name.value)

    def _on_replay(self, event: viser.GuiEvent) -> None:
        action = event.target.value
        if action == "Play":
            names = self.app.demo_names()
            if self.replay_pick.value not in names:
                raise _err("Choose a demonstration to replay first.")
            dur = self.app.replay_demo(names.index(self.replay_pick.value))
            self.replay_time.max = round(max(dur, 0.01), 2)
        elif action == "Pause":
            self.app.replay_pause()
        else:
            self.app.replay_stop()

    def _on_replay_time(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.app.replay_seek(float(self.replay_time.value))

    def _on_download(self, event: viser.GuiEvent) -> None:
        name, data = self.app.session_zip()
        target = event.client
        if target is None:
            raise _err("Could not find the browser tab to send the file to.")
        target.send_file_download(name, data, save_immediately=True)

    def _on_upload(self, event: viser.GuiEvent) -> None:
        f = self.upload.value
        self.app.import_session_zip(f.name, f.content)

    def _on_export(self, event: viser.GuiEvent) -> None:
        name, data = self.app.joint_trajectory_csv()
        if event.client is None:
            raise _err("Could not find the browser tab to send the file to.")
        event.client.send_file_download(name, data, save_immediately=True)

    def tick(self, now: float) -> None:
        pos = self.app.replay_position()
        if pos is not None and now - self._last_sync > 0.1:
            self._last_sync = now
            self.replay_time.value = round(min(pos, self.replay_time.max), 2)


def _err(msg: str) -> Exception:
    from studio.core.errors import InvalidInput

    return InvalidInput(msg)
