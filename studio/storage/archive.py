"""Session archives (.zip) for download and upload: export what loads, import only what validates.

An uploaded archive is checked (one session folder, safe member names, declared sizes), unpacked into a
temporary folder, loaded with full validation, and only then moved into place; on any problem nothing is
added and the message names the archive and the problem.
"""

from __future__ import annotations

import io
import os
import shutil
import uuid
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path

from studio.core.errors import SessionFormatError
from studio.storage.format import (
    DEMO_FILE_RE,
    MANIFEST,
    MAX_DEMOS,
    MAX_ZIP_BYTES,
    SKILL_FILE_RE,
    sanitize_name,
    what_went_wrong,
)
from studio.storage.session import Session, load_session

_NOTHING = "Nothing was imported."


def export_zip(session: Session) -> bytes:
    """The session's manifest, demos and skills as a zip archive (one folder named after the session)."""
    name = session.name
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
        zf.write(session.path / MANIFEST, f"{name}/{MANIFEST}")
        for rel in session.demo_files:
            zf.write(session.path / rel, f"{name}/{rel}")
        for info in session.skill_info.values():
            zf.write(session.path / info.file, f"{name}/{info.file}")
    return buf.getvalue()


def _safe_entry(info: zipfile.ZipInfo, top: str) -> bool:
    fn = info.filename
    rel = fn[len(top) + 1 :]
    mode = (info.external_attr >> 16) & 0o170000
    return not (
        fn.startswith("/")
        or "\\" in fn
        or ".." in fn.split("/")
        or mode == 0o120000
        or not (rel == MANIFEST or DEMO_FILE_RE.match(rel) or SKILL_FILE_RE.match(rel) or info.is_dir())
    )


def _checked_entries(zf: zipfile.ZipFile) -> tuple[str, list[zipfile.ZipInfo]]:
    """The archive's one top folder and its entries, once every entry was found safe."""
    infos = zf.infolist()
    if not infos or len(infos) > MAX_DEMOS + 10:
        raise SessionFormatError(f"The archive does not look like a Teaching Studio session. {_NOTHING}")
    tops = {i.filename.split("/", 1)[0] for i in infos}
    if len(tops) != 1:
        raise SessionFormatError(f"The archive must hold exactly one session folder. {_NOTHING}")
    top = tops.pop()
    for i in infos:
        if not _safe_entry(i, top):
            raise SessionFormatError(f'The archive contains an unexpected or unsafe entry "{i.filename}". {_NOTHING}')
    if sum(i.file_size for i in infos) > MAX_ZIP_BYTES:
        raise SessionFormatError(f"The archive is absurdly large once unpacked. {_NOTHING}")
    return top, infos


def _unpack(zf: zipfile.ZipFile, top: str, infos: list[zipfile.ZipInfo], dest: Path, label: str) -> None:
    for i in infos:
        if i.is_dir():
            continue
        target = dest / i.filename[len(top) + 1 :]
        target.parent.mkdir(parents=True, exist_ok=True)
        try:
            with zf.open(i) as src, open(target, "wb") as out:
                shutil.copyfileobj(src, out)
        except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError) as exc:
            raise SessionFormatError(
                f'{label} is damaged (the file "{i.filename}" inside it cannot be read). {_NOTHING}'
            ) from exc


def import_zip(root: Path, data: bytes, final_name: Callable[[str], str], *, archive: str | None = None) -> str:
    """Unpack, validate and add the session archive ``data`` under ``root``; returns the session's name.

    Args:
        final_name: turns the archive's (sanitised) folder name into the name the session gets (a free one).
        archive: the uploaded file's name, for messages.
    """
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile as exc:
        raise SessionFormatError(f"The uploaded file is not a session archive (.zip). {_NOTHING}") from exc
    with zf:
        top, infos = _checked_entries(zf)
        label = f'The archive "{archive}"' if archive else f'The archive of session "{top}"'
        root.mkdir(parents=True, exist_ok=True)
        tmp_root = root / f".tmp-import-{uuid.uuid4().hex[:8]}"
        tmp = tmp_root / sanitize_name(top)  # messages from loading name the session, not the temporary folder
        tmp.mkdir(parents=True)
        try:
            _unpack(zf, top, infos, tmp, label)
            try:
                s = load_session(tmp)
            except SessionFormatError as exc:
                raise SessionFormatError(f"{label} cannot be imported. {what_went_wrong(exc)} {_NOTHING}") from exc
            final = final_name(sanitize_name(top))
            s.name = final
            s._write_manifest()
            os.rename(tmp, root / final)
        finally:
            if tmp_root.exists():
                shutil.rmtree(tmp_root, ignore_errors=True)
    return final
