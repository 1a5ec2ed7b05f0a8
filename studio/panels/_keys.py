"""Keyboard teaching: a script every tab runs that turns a key press into a click on the on-screen button that
shows that key, so a key does exactly what its button does (docs/decisions/071); Shift, or a key held a second,
clicks its 5 cm button (docs/decisions/092).

A key counts only while its button is on screen (the Teach step), never while typing in a box, and then does not
also move viser's camera (which uses some of the same letters)."""

from __future__ import annotations

import json
from collections.abc import Mapping

import viser

from studio import viser_adapter

#: A held key: its button at most every :data:`TAP_EVERY_S` for the first :data:`FAST_AFTER_S`, then its big
#: step's button (Shift's) at most every :data:`BIG_EVERY_S`; with Shift, the big step's from the start.
FAST_AFTER_S = 1.0
TAP_EVERY_S = 0.09
BIG_EVERY_S = 0.25

_KEYS_JS = """
(() => {
  const cfg = %s;
  if (window.__studioKeys) { Object.assign(window.__studioKeys, cfg); return; }
  const st = window.__studioKeys = Object.assign({last: 0, down: {}}, cfg);
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
    const plain = st.keys[e.code], big = st.keys['Shift+' + e.code];
    if (!plain && !big) return;
    const now = performance.now();
    if (!e.repeat || !(e.code in st.down)) st.down[e.code] = now;
    // the page knows how long the key is held, whatever the rate its repeats arrive at
    const useBig = big && (e.shiftKey || (e.repeat && now - st.down[e.code] >= st.fastAfterMs));
    const b = button(useBig ? big : (plain || big));
    if (!b) return;
    e.preventDefault();
    e.stopPropagation();
    if (e.repeat && now - st.last < (useBig ? st.bigEveryMs : st.tapEveryMs)) return;
    st.last = now;
    b.click();
  }, true);
  window.addEventListener('keyup', (e) => { delete st.down[e.code]; }, true);
  window.addEventListener('blur', () => { st.down = {}; });
})();
"""


def install_keys(server: viser.ViserServer, keys: Mapping[str, str]) -> None:
    """Send the key script to every tab, now and later. ``keys``: a key's ``KeyboardEvent.code`` (e.g. "KeyW"),
    or "Shift+" and the code, → the exact label of the button it presses (Shift falls back to the plain key's)."""
    cfg = {
        "keys": dict(keys),
        "fastAfterMs": FAST_AFTER_S * 1000,
        "tapEveryMs": TAP_EVERY_S * 1000,
        "bigEveryMs": BIG_EVERY_S * 1000,
    }
    viser_adapter.run_javascript(server, _KEYS_JS % json.dumps(cfg, ensure_ascii=False))
