"""Only the studio's own page may drive the studio: origin, host, a per-launch key, and upload limits.

Why: viser serves the page and its websocket on one port and, left alone, accepts any websocket. Any web
page open in the teacher's browser (or any program on the computer) could connect, receive the whole GUI,
press buttons (delete demonstrations, move the robot) and download the session.

What is checked, on every HTTP request and every websocket upgrade, before viser sees it:

* **Host** must name this studio: ``127.0.0.1``, ``localhost`` or ``[::1]`` (or the address given with
  ``--host``) with the studio's port. This stops DNS rebinding (``evil.example`` resolving to 127.0.0.1).
  When listening on every interface (``0.0.0.0``) any name is accepted and the key does the work.
* **Origin**, when present (browsers always send it with a websocket), must be the page's own origin
  ``http://<Host>``. A page served from elsewhere, even from another port of this computer (which the browser
  counts as the same *site* and so sends it the studio's cookie), is refused.
* **The key**: a random secret made at each start (:func:`secrets.token_urlsafe`), in the address the studio
  prints (``http://127.0.0.1:8080/?key=...``). Opening that address answers with a redirect to the same page
  without the key and a cookie ``studio-key-<port>`` (``HttpOnly; SameSite=Strict``), so reloads work and the
  key does not stay in the address bar. A websocket needs the cookie, or ``?key=`` in its own address (for
  programs, which send no Origin). ``--no-key`` turns the key off, on this computer only: listening beyond
  it without the key is refused (:class:`StudioError`).
* **No other server**: a page address with viser's ``websocket=`` or ``playbackPath=`` parameter (the page
  would connect to, or replay from, another server, whose HTML would then run as the studio's page) is
  refused.

A refused request gets HTTP 403 with a short plain-text explanation (what to open instead); nothing of the
studio is sent, no websocket is opened and no callback runs. Accepted pages also carry headers that keep
other sites from framing them (``frame-ancestors 'self'``) or seeing the address (``no-referrer``).

Uploads are capped at the server. viser's browser client sends a file as one ``FileTransferStartUpload``
(declared size) and 512 KiB ``FileTransferPart`` messages; viser buffers every part in memory until the file
is complete, with no limit. Here the declared size is checked first (:data:`MAX_UPLOAD_BYTES` for all
uploads in flight together), so the parts of a refused upload are dropped as they arrive and never
buffered; parts beyond the declared size end the upload. The browser gets a notification in plain words,
its progress notice is closed and its upload button released. A single websocket message may be at most
:data:`MAX_MESSAGE_BYTES` (viser allows 50 MiB): websockets refuses a longer frame from its header, before
reading it, and closes that connection (code 1009).

Where this hooks into viser, and why there (viser 1.1.1 with websockets 16):

* ``viser.infra.WebsockServer._background_worker`` (a thread started by ``ViserServer.__init__``, which
  waits until the port is bound) calls ``websockets.asyncio.server.serve(ws_handler, host, port,
  max_size=50 MiB, process_request=viser_http_server, ...)``. ``process_request`` is called for every
  request on the port: page loads (viser answers them with its bundled client) and websocket upgrades
  (viser returns None: accept). It is the narrowest point that sees the headers of both, before a websocket
  exists, before any GUI is sent and before any callback can run, and where a refusal is a plain HTTP 403.
  :meth:`Access.start_viser` therefore swaps ``websockets.asyncio.server.serve`` for a wrapper *only while
  the studio's ViserServer is being built* (under a lock), and puts the original back as soon as the server
  listens: the wrapper wraps viser's ``process_request`` with :meth:`Access.check` and sets ``max_size``.
  No other websockets server in the process is affected. (viser's own banner, which shows the address
  without the key, is silenced for that moment: the studio prints the address to open.)
* Every incoming websocket message is dispatched by ``WebsockServer._handle_incoming_message(client_id,
  message)``, looked up on the server instance for each message; :class:`UploadLimit` wraps it on this one
  instance to check uploads before viser's ``GuiApi`` buffers them.
* If a viser upgrade moves either point, :meth:`Access.start_viser` stops the server and raises
  :class:`StudioError` (the studio refuses to run unprotected), and
  ``tests/test_security.py::test_the_guard_sits_where_viser_serves`` fails.

Modules: ``addresses`` (hosts, keys, cookies in requests), ``access`` (:class:`Access`: the decision and the
hook into viser), ``uploads`` (:class:`UploadLimit`: upload and message size caps).
"""

from studio.security.access import NEEDS_KEY_TEXT, REFUSED_TEXT, Access, Verdict
from studio.security.addresses import (
    FOREIGN_SOURCE_PARAMS,
    KEY_PARAM,
    LOOPBACK_HOSTS,
    WILDCARD_HOSTS,
    is_loopback,
    new_key,
)
from studio.security.uploads import MAX_MESSAGE_BYTES, MAX_UPLOAD_BYTES, UPLOAD_IDLE_S, UploadLimit

__all__ = [
    "FOREIGN_SOURCE_PARAMS",
    "KEY_PARAM",
    "LOOPBACK_HOSTS",
    "MAX_MESSAGE_BYTES",
    "MAX_UPLOAD_BYTES",
    "NEEDS_KEY_TEXT",
    "REFUSED_TEXT",
    "UPLOAD_IDLE_S",
    "WILDCARD_HOSTS",
    "Access",
    "UploadLimit",
    "Verdict",
    "is_loopback",
    "new_key",
]
