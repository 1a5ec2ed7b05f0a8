"""The session folder on disk, treated as someone else may have left it: links, special files, leftovers.

:func:`read_capped` reads only a regular file, at most so many bytes (a link to ``/dev/zero`` or a FIFO never
hangs the studio); :func:`linked_folder` finds a session folder that is a link; :func:`changing` holds an
exclusive ``flock`` while files change; :func:`clean_leftovers` cleans what a kill -9 left (unlisted demos go to
``recovered/``) only when no one holds it; :func:`temporary_folder` holds the store's own temporary folders."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import stat
from collections.abc import Iterable, Iterator
from pathlib import Path

from studio.core.errors import SessionFormatError
from studio.storage.format import (
    DEMO_DIR,
    DEMO_FILE_RE,
    RECORDING_DIR,
    RECOVERED_DIR,
    SKILL_DIR,
    SKILL_FILE_RE,
    damaged,
)

#: The folders of a session; none may be a link.
FOLDERS = (DEMO_DIR, SKILL_DIR, RECORDING_DIR, RECOVERED_DIR)
TMP_PREFIX = ".tmp-"
#: The store's temporary folders (in the sessions folder): ``.tmp-import-*``, ``.tmp-copy-*``.
TMP_FOLDER_KINDS = ("import", "copy")


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


def clean_leftovers(path: Path, listed: Iterable[str]) -> tuple[list[str], list[str]]:
    """Clean what interrupted saves left in session folder ``path``; returns (removed, moved to ``recovered/``),
    relative paths.

    Temporary files (``.tmp-*``) in the session, ``demos`` and ``skills`` folders and skill files that ``listed``
    (the manifest's files) does not name are removed; demo files it does not name are moved to ``recovered/``
    (a manifest put back from a backup lists fewer than the folder holds: they are never deleted). Nothing
    happens while another process or thread is changing the session (:func:`changing`).
    """
    keep = set(listed)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return [], []
    removed: list[str] = []
    recovered: list[str] = []
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return [], []  # someone is saving right now; the next open cleans
        for sub in ("", DEMO_DIR, SKILL_DIR):
            if sub and linked_folder(path, (sub,)) is not None:
                continue
            folder = path / sub if sub else path
            try:
                entries = list(os.scandir(folder))
            except OSError:
                continue
            for e in entries:
                rel = f"{sub}/{e.name}" if sub else e.name
                if rel in keep:
                    continue
                if DEMO_FILE_RE.fullmatch(rel):
                    moved = _recover(path, e)
                    if moved is not None:
                        recovered.append(moved)
                elif (e.name.startswith(TMP_PREFIX) and not e.is_dir(follow_symlinks=False)) or SKILL_FILE_RE.fullmatch(
                    rel
                ):
                    with contextlib.suppress(OSError):
                        os.unlink(e.path)
                        removed.append(rel)
    finally:
        os.close(fd)
    return sorted(removed), sorted(recovered)


def _recover(path: Path, entry: os.DirEntry[str]) -> str | None:
    """Move the unlisted demo file ``entry`` into ``recovered/`` under a free name (an identical copy already
    there is enough); its new relative path, or None when it stays where it is."""
    if linked_folder(path, (RECOVERED_DIR,)) is not None or entry.is_symlink():
        return None
    folder = path / RECOVERED_DIR
    stem, ext = os.path.splitext(entry.name)
    try:
        folder.mkdir(exist_ok=True)
        for i in range(1, 1000):
            target = folder / (entry.name if i == 1 else f"{stem}-{i}{ext}")
            if not target.exists():
                os.rename(entry.path, target)  # the same folder tree: never a copy, never half a file
                return f"{RECOVERED_DIR}/{target.name}"
            if _same_file_content(Path(entry.path), target):
                os.unlink(entry.path)
                return f"{RECOVERED_DIR}/{target.name}"
    except OSError:
        pass
    return None


def _same_file_content(a: Path, b: Path) -> bool:
    import filecmp

    try:
        return filecmp.cmp(a, b, shallow=False)
    except OSError:
        return False


@contextlib.contextmanager
def temporary_folder(root: Path, kind: str) -> Iterator[Path]:
    """A new folder ``<root>/.tmp-<kind>-<random>`` held (``flock``) while in use, removed afterwards."""
    import shutil
    import uuid

    assert kind in TMP_FOLDER_KINDS
    tmp = root / f"{TMP_PREFIX}{kind}-{uuid.uuid4().hex[:8]}"
    tmp.mkdir(parents=True)
    fd = os.open(tmp, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield tmp
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        os.close(fd)


def clean_temporary_folders(root: Path) -> list[str]:
    """Remove the store's temporary folders a killed studio left in ``root`` (none that another holds)."""
    import shutil

    removed: list[str] = []
    try:
        entries = list(os.scandir(root))
    except OSError:
        return removed
    for e in entries:
        if not any(e.name.startswith(f"{TMP_PREFIX}{k}-") for k in TMP_FOLDER_KINDS):
            continue
        if not e.is_dir(follow_symlinks=False):
            continue
        try:
            fd = os.open(e.path, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue  # in use by another studio
        try:
            shutil.rmtree(e.path, ignore_errors=True)
            removed.append(e.name)
        finally:
            os.close(fd)
    return removed


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
