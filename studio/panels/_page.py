"""Page behaviour the GUI library does not offer, installed once per server as a small script every tab runs.

Arrow keys stay in the control that has the focus (viser's camera would also orbit on them; why:
docs/decisions/018), every control's hint is also the ``title`` of its label and closes when its control is
pressed, the tab is called "Teaching Studio" and viser's developer settings button is hidden. The script is sent as
viser's ``RunJavascriptMessage``, which viser replays to every tab that connects later."""

from __future__ import annotations

import json

import viser

from studio import viser_adapter

_GUARD_JS = """
(() => {
  if (window.__studioPage) return;
  window.__studioPage = {hints: {}};
  const TITLE = "Teaching Studio";
  const inControl = (t) => t && t.closest &&
    t.closest('[role=slider], input, textarea, select, button, [role=button], [role=option]');
  const stop = (e) => { if (e.key && e.key.startsWith('Arrow') && inControl(e.target)) e.stopPropagation(); };
  const attach = () => {
    // The tab is the studio's, not the GUI library's; its developer settings are not for the teacher.
    const title = () => { if (document.title !== TITLE) document.title = TITLE; };
    title();
    new MutationObserver(title).observe(document.head, {subtree: true, childList: true, characterData: true});
    const css = document.createElement('style');
    css.textContent = '[data-dock-header] button:has(.tabler-icon-adjustments) { display: none !important; }' +
      ' [role=tooltip] { pointer-events: none; }' +
      ' body.studio-pressed [role=tooltip] { display: none !important; }';
    document.head.appendChild(css);
    // A hint closes when its control is pressed and stays closed until the pointer goes to another control.
    let pressed = null;
    const row = (t) => (t && t.closest && t.closest('.mantine-Flex-root')) || (t && t.parentElement) || t;
    document.addEventListener('pointerdown', (e) => {
      pressed = row(e.target);
      document.body.classList.add('studio-pressed');
    }, true);
    document.addEventListener('pointerover', (e) => {
      if (pressed && !pressed.contains(e.target)) {
        pressed = null;
        document.body.classList.remove('studio-pressed');
      }
    }, true);
    document.body.addEventListener('keydown', stop);
    document.body.addEventListener('keyup', stop);
    const label = () => {
      const hints = window.__studioPage.hints;
      for (const [uuid, hint] of Object.entries(hints)) {
        const el = document.querySelector('label[for="' + uuid + '"]');
        if (el && el.title !== hint) el.title = hint;
      }
    };
    let queued = false;
    new MutationObserver(() => {
      if (queued) return;
      queued = true;
      setTimeout(() => { queued = false; label(); }, 200);
    }).observe(document.body, {subtree: true, childList: true});
    label();
  };
  if (document.body) attach(); else document.addEventListener('DOMContentLoaded', attach);
})();
"""


def install(server: viser.ViserServer) -> None:
    """Send the script (arrow keys; the hints of every control built so far on its label) to every tab, now and
    later. Call once, after the panels are built."""
    hints: dict[str, str] = {}
    for uid, handle in viser_adapter.controls(server).items():
        hint = getattr(handle, "hint", None)
        if isinstance(hint, str) and hint:
            hints[uid] = hint
    viser_adapter.run_javascript(server, _GUARD_JS)
    viser_adapter.run_javascript(
        server, f"Object.assign(window.__studioPage.hints, {json.dumps(hints, ensure_ascii=False)});"
    )
