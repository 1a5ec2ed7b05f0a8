"""Keyboard teaching: a script every tab runs that turns a key press into a click on the on-screen button that
shows that key, so a key does exactly what its button does (docs/decisions/071).

A key counts only while its button is on screen (the Teach step), never while typing in a box, and then does not
also move viser's camera (which uses some of the same letters)."""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping

import viser

log = logging.getLogger(__name__)

_KEYS_JS = """
(() => {
  const keys = %s;
  if (window.__studioKeys) { window.__studioKeys.keys = keys; return; }
  const st = window.__studioKeys = {keys, last: 0};
  const typing = (t) => t && (t.tagName === 'INPUT' || t.tagName === 'TEXTAREA' || t.tagName === 'SELECT' ||
    t.isContentEditable);
  const button = (label) => {
    for (const b of document.querySelectorAll('button')) {
      if (b.textContent.trim() === label && b.offsetParent !== null && !b.disabled) return b;
    }
    return null;
  };
  window.addEventListener('keydown', (e) => {
    if (e.ctrlKey || e.metaKey || e.altKey || typing(e.target)) return;
    const shifted = e.shiftKey ? st.keys['Shift+' + e.code] : undefined;
    const label = shifted || st.keys[e.code];
    if (!label) return;
    const b = button(label);
    if (!b) return;
    e.preventDefault();
    e.stopPropagation();
    const now = performance.now();
    if (e.repeat && now - st.last < 90) return;
    st.last = now;
    b.click();
  }, true);
})();
"""


def install_keys(server: viser.ViserServer, keys: Mapping[str, str]) -> None:
    """Send the key script to every tab, now and later. ``keys``: a key's ``KeyboardEvent.code`` (e.g. "KeyW"),
    or "Shift+" and the code, → the exact label of the button it presses (Shift falls back to the plain key's).
    Uses viser's message queue (an internal): if a viser upgrade moved it, the buttons still work and the
    studio's log says the keys do not."""
    try:
        from viser import _messages

        source = _KEYS_JS % json.dumps(dict(keys), ensure_ascii=False)
        server.gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=source))
    except (AttributeError, ImportError, TypeError):
        log.warning("viser changed: the teaching keys are off (the buttons on screen still work)")
