"""Only the studio's own page may drive the studio: host, origin, a per-launch key bound to a per-launch path,
the page's address and Content-Security-Policy, upload and message limits (``docs/decisions/016`` and ``050``)."""

from studio.security.access import NEEDS_KEY_TEXT, ODD_ADDRESS_TEXT, REFUSED_TEXT, Access, Verdict
from studio.security.addresses import KEY_PARAM, WILDCARD_HOSTS, host_name, is_loopback, new_key
from studio.security.uploads import MAX_MESSAGE_BYTES, MAX_UPLOAD_BYTES, UPLOAD_IDLE_S, UploadLimit

__all__ = [
    "KEY_PARAM",
    "MAX_MESSAGE_BYTES",
    "MAX_UPLOAD_BYTES",
    "NEEDS_KEY_TEXT",
    "ODD_ADDRESS_TEXT",
    "REFUSED_TEXT",
    "UPLOAD_IDLE_S",
    "WILDCARD_HOSTS",
    "Access",
    "UploadLimit",
    "Verdict",
    "host_name",
    "is_loopback",
    "new_key",
]
