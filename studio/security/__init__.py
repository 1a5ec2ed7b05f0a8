"""Only the studio's own page may drive the studio: Host and Origin checks, a per-launch key, upload caps.

Every HTTP request and websocket upgrade is checked before viser sees it; a refused one gets HTTP 403 with a
plain explanation and nothing of the studio. Modules: ``addresses`` (hosts, keys, cookies in requests),
``access`` (:class:`Access`: the decision and the hook into viser), ``uploads`` (:class:`UploadLimit`: upload
and message size caps). What is checked and why it hooks where it does: ``docs/decisions/016-who-may-connect.md``."""

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
