"""The session folder on disk, treated as someone else may have left it: links, special files, leftovers.

:func:`read_capped` reads only a regular file, at most so many bytes (a link to ``/dev/zero`` or a FIFO never
hangs the studio); :func:`linked_folder` finds a session folder that is a link; :func:`changing` holds an
exclusive ``flock`` while files change, and :func:`clean_leftovers` removes what a kill -9 left only when no
one holds it."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import stat
from collections.abc import Iterable, Iterator
from pathlib import Path

from studio.core.errors import SessionFormatError
from studio.storage.format import DEMO_DIR, DEMO_FILE_RE, RECORDING_DIR, SKILL_DIR, SKILL_FILE_RE, damaged

#: The folders of a session; none may be a link.
FOLDERS = (DEMO_DIR, SKILL_DIR, RECORDING_DIR)
TMP_PREFIX = ".tmp-"


def read_capped(path: Path, limit: int, *, session: str, rel: str) -> bytes:
    """The bytes of session file ``path`` if it is a regular file of at most ``limit`` bytes.

    Raises:
        SessionFormatError: missing, a link, not a regular file, too large, or unreadable (named ``rel``).
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError as exc:
        raise damaged(session, rel, "is missing") from exc
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise damaged(session, rel, "is a link to another file, which the studio does not follow") from exc
        raise damaged(session, rel, f"cannot be read ({exc.strerror})") from exc
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise damaged(session, rel, "is not a regular file")
        if st.st_size > limit:
            raise damaged(session, rel, f"is absurdly large ({st.st_size:,} bytes)")
        chunks: list[bytes] = []
        got = 0
        while got <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - got))
            if not chunk:
                break
            chunks.append(chunk)
            got += len(chunk)
        if got > limit:
            raise damaged(session, rel, "grew while it was read")
        return b"".join(chunks)
    except OSError as exc:
        raise damaged(session, rel, f"cannot be read ({exc.strerror})") from exc
    finally:
        os.close(fd)


def linked_folder(path: Path, folders: Iterable[str] = FOLDERS) -> tuple[str, str] | None:
    """(folder, problem) for the first of ``folders`` inside ``path`` that is a link or not a folder, else None."""
    for sub in folders:
        try:
            st = os.lstat(path / sub)
        except FileNotFoundError:
            continue
        except OSError as exc:
            return sub, f"cannot be read ({exc.strerror})"
        if stat.S_ISLNK(st.st_mode):
            return sub, "is a link to another folder; the studio works only inside the session's own folder"
        if not stat.S_ISDIR(st.st_mode):
            return sub, "is not a folder"
    return None


def check_session_folder(path: Path, session: str) -> None:
    """Refuse a session folder that is itself a link, or holds a linked folder (:class:`SessionFormatError`)."""
    if path.is_symlink():
        raise SessionFormatError(
            f'The session "{session}" is a link to another folder; the studio opens only folders that are inside '
            "its sessions folder. Move the session's folder there instead.",
            session=session,
        )
    bad = linked_folder(path)
    if bad is not None:
        raise _folder_error(session, *bad, "It was not opened; your files are untouched.")


@contextlib.contextmanager
def changing(path: Path) -> Iterator[None]:
    """Hold session folder ``path`` while its files change (waits for another process changing it)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError:
        yield  # no folder yet (or unreadable): the write itself will say what is wrong
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def clean_leftovers(path: Path, listed: Iterable[str]) -> list[str]:
    """Remove what interrupted saves left in session folder ``path``; returns what was removed (relative paths).

    Leftovers are temporary files (``.tmp-*``) in the session, ``demos`` and ``skills`` folders, and demo or
    skill files that ``listed`` (the manifest's files) does not name. Nothing is removed while another process
    or thread is changing the session (:func:`changing`): its temporary and new files are still being written.
    """
    keep = set(listed)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return []
    removed: list[str] = []
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return []  # someone is saving right now; the next open cleans
        for sub in ("", DEMO_DIR, SKILL_DIR):
            folder = path / sub if sub else path
            if sub and linked_folder(path, (sub,)) is not None:
                continue
            try:
                entries = list(os.scandir(folder))
            except OSError:
                continue
            for e in entries:
                rel = f"{sub}/{e.name}" if sub else e.name
                temporary = e.name.startswith(TMP_PREFIX) and not e.is_dir(follow_symlinks=False)
                orphan = bool(DEMO_FILE_RE.fullmatch(rel) or SKILL_FILE_RE.fullmatch(rel)) and rel not in keep
                if temporary or orphan:
                    with contextlib.suppress(OSError):
                        os.unlink(e.path)
                        removed.append(rel)
    finally:
        os.close(fd)
    return sorted(removed)


def check_changeable(path: Path, session: str) -> SessionFormatError | None:
    """The error to raise before changing a session whose folders became links since it was opened, or None."""
    bad = linked_folder(path)
    return None if bad is None else _folder_error(session, *bad, "Nothing was changed.")


def _folder_error(session: str, folder: str, problem: str, after: str) -> SessionFormatError:
    return SessionFormatError(
        f'The folder "{folder}" of session "{session}" {problem}. {after}',
        session=session,
        file=folder,
        problem=problem,
    )
