"""Session archives (.zip) for download and upload: export what loads, import only what validates.

An uploaded archive is someone else's file: its directory, then its manifest, then the sizes it declares
(against the manifest, the free disk and a multiple of the upload) are checked before anything is unpacked;
then only the listed files are unpacked into a temporary folder, loaded with full validation and moved into
place. On any problem nothing is added (docs/decisions/024)."""

from __future__ import annotations

import io
import json
import os
import shutil
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path

from studio.core.errors import SessionFormatError
from studio.storage.format import (
    ARCHIVE_DISK_FLOOR,
    ARCHIVE_DISK_PER_BYTE,
    ARCHIVE_MEMORY_FLOOR,
    ARCHIVE_MEMORY_PER_BYTE,
    DEMO_BYTES_PER_SAMPLE,
    DEMO_FILE_RE,
    MANIFEST,
    MAX_DEMO_BYTES,
    MAX_DEMOS,
    MAX_MANIFEST_BYTES,
    MAX_SKILL_BYTES,
    SKILL_FILE_RE,
    sanitize_name,
    what_went_wrong,
)
from studio.storage.fs import temporary_folder
from studio.storage.limits import check_disk, size_text, write_failed
from studio.storage.loading import demos_bytes, load_session, skills_bytes
from studio.storage.manifest import Manifest
from studio.storage.session import Session

_NOTHING = "Nothing was imported."


def export_zip(session: Session, manifest: bytes | None = None) -> bytes:
    """The session's manifest (``manifest``, or its file), demos and skills as a zip archive (one folder named
    after the session)."""
    name = session.name
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
        if manifest is None:
            zf.write(session.path / MANIFEST, f"{name}/{MANIFEST}")
        else:
            zf.writestr(f"{name}/{MANIFEST}", manifest)
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
        or info.flag_bits & 0x1  # encrypted
        or info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED)  # bzip2/lzma: unbounded chunks
        or not (
            rel == MANIFEST
            or DEMO_FILE_RE.fullmatch(rel)
            or SKILL_FILE_RE.fullmatch(rel)
            or (info.is_dir() and rel.rstrip("/") in ("", "demos", "skills"))
        )
    )


def _checked_entries(zf: zipfile.ZipFile) -> tuple[str, dict[str, zipfile.ZipInfo]]:
    """The archive's one top folder and its files by path inside it, once every entry was found safe."""
    infos = zf.infolist()
    if not infos or len(infos) > MAX_DEMOS + 10:
        raise SessionFormatError(f"The archive does not look like a Teaching Studio session. {_NOTHING}")
    tops = {i.filename.split("/", 1)[0] for i in infos}
    if len(tops) != 1:
        raise SessionFormatError(f"The archive must hold exactly one session folder. {_NOTHING}")
    top = tops.pop()
    files: dict[str, zipfile.ZipInfo] = {}
    for i in infos:
        if not _safe_entry(i, top) or i.filename[len(top) + 1 :] in files:
            shown = json.dumps(i.filename, ensure_ascii=False)  # a newline or control character shows as such
            raise SessionFormatError(f"The archive contains an unexpected or unsafe entry {shown}. {_NOTHING}")
        if not i.is_dir():
            files[i.filename[len(top) + 1 :]] = i
    return top, files


def _manifest(zf: zipfile.ZipFile, files: dict[str, zipfile.ZipInfo], session: str, label: str) -> Manifest:
    """The archive's manifest, read and validated before anything else is unpacked."""
    info = files.get(MANIFEST)
    if info is None:
        raise SessionFormatError(f"{label} holds no session description ({MANIFEST}). {_NOTHING}")
    if info.file_size > MAX_MANIFEST_BYTES:
        raise SessionFormatError(
            f"{label} cannot be imported: its {MANIFEST} is too large ({size_text(info.file_size)}). {_NOTHING}"
        )
    try:
        raw = zf.read(info)
    except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError, ValueError) as exc:
        raise SessionFormatError(
            f'{label} is damaged (the file "{info.filename}" inside it cannot be read). {_NOTHING}'
        ) from exc
    try:
        return Manifest.from_json(raw, session)
    except SessionFormatError as exc:
        raise SessionFormatError(f"{label} cannot be imported. {what_went_wrong(exc)} {_NOTHING}") from exc


def _listed(m: Manifest, files: dict[str, zipfile.ZipInfo], label: str, upload: int) -> list[zipfile.ZipInfo]:
    """The entries the manifest lists, each within what the manifest allows it; the unpacked total bounded."""
    caps = {d.file: d.samples * DEMO_BYTES_PER_SAMPLE + 65536 for d in m.demos}
    caps.update({s.file: MAX_SKILL_BYTES + 65536 for s in m.skills.values()})
    out = [files[MANIFEST]]
    for rel, cap in caps.items():
        info = files.get(rel)
        if info is None:
            continue  # loading says it is missing
        if info.file_size > cap:
            raise SessionFormatError(
                f'{label} cannot be imported: the file "{rel}" inside it is too large ({size_text(info.file_size)} '
                f"where its session description allows {size_text(cap)}). {_NOTHING}"
            )
        out.append(info)
    total = sum(i.file_size for i in out)
    budget = max(ARCHIVE_DISK_FLOOR, ARCHIVE_DISK_PER_BYTE * upload)
    if total > budget:
        raise SessionFormatError(
            f"{label} cannot be imported: it would unpack to {size_text(total)} from {size_text(upload)}, far more "
            f"than a session archive holds (at most {ARCHIVE_DISK_PER_BYTE} times its size). {_NOTHING}"
        )
    return out


def _check_memory(m: Manifest, label: str, upload: int, skills: int = 0) -> None:
    """Refuse an upload whose session would take more memory than an archive of its size should hold."""
    too_big = [d for d in m.demos if d.samples * DEMO_BYTES_PER_SAMPLE > MAX_DEMO_BYTES]
    if too_big:
        d = too_big[0]
        raise SessionFormatError(
            f'{label} cannot be imported: its demonstration "{d.name}" is too large to open ({d.samples:,} samples '
            f"would take {size_text(d.samples * DEMO_BYTES_PER_SAMPLE)} of memory; the limit is "
            f"{size_text(MAX_DEMO_BYTES)}). {_NOTHING}"
        )
    need = demos_bytes(m) + skills
    budget = max(ARCHIVE_MEMORY_FLOOR, ARCHIVE_MEMORY_PER_BYTE * upload)
    if need > budget:
        raise SessionFormatError(
            f"{label} cannot be imported: its {size_text(upload)} would take {size_text(need)} of memory once "
            f"opened. Uploads may take at most {ARCHIVE_MEMORY_PER_BYTE} times their size (or "
            f"{size_text(ARCHIVE_MEMORY_FLOOR)}), so that a small file cannot take the computer's memory. To bring "
            f"in a session this large, copy its folder into the sessions folder instead. {_NOTHING}"
        )


def _unpack(zf: zipfile.ZipFile, infos: list[zipfile.ZipInfo], top: str, dest: Path, label: str) -> None:
    for i in infos:
        target = dest / i.filename[len(top) + 1 :]
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            with zf.open(i) as src, open(target, "wb") as out:
                shutil.copyfileobj(src, out, 1 << 20)  # zipfile never yields more than the declared size
        except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError, ValueError) as exc:
            raise SessionFormatError(
                f'{label} is damaged (the file "{i.filename}" inside it cannot be read). {_NOTHING}'
            ) from exc
        except OSError as exc:
            raise write_failed(target, exc, doing="imported", subject=label, after=_NOTHING) from exc


def import_zip(root: Path, data: bytes, final_name: Callable[[str], str], *, archive: str | None = None) -> str:
    """Check, unpack, validate and add the session archive ``data`` under ``root``; returns the session's name.

    Args:
        final_name: turns the archive's (sanitised) folder name into the name the session gets (a free one).
        archive: the uploaded file's name, for messages.

    Raises:
        SessionFormatError: the archive is damaged, hostile, or not a session (nothing was added).
        StorageError: the disk has no room for it (nothing was added).
    """
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, EOFError) as exc:
        raise SessionFormatError(f"The uploaded file is not a session archive (.zip). {_NOTHING}") from exc
    with zf:
        top, files = _checked_entries(zf)
        label = f'The archive "{archive}"' if archive else f'The archive of session "{top}"'
        m = _manifest(zf, files, sanitize_name(top), label)
        infos = _listed(m, files, label, len(data))
        _check_memory(m, label, len(data))
        check_disk(root, sum(i.file_size for i in infos), label)
        root.mkdir(parents=True, exist_ok=True)
        try:
            with temporary_folder(root, "import") as tmp_root:  # held: a studio starting meanwhile leaves it
                tmp = tmp_root / sanitize_name(top)  # messages from loading name the session, not the folder
                tmp.mkdir()
                _unpack(zf, infos, top, tmp, label)
                _check_memory(m, label, len(data), skills_bytes(tmp, m))  # skills: from their headers, unpacked
                try:
                    s = load_session(tmp)
                except SessionFormatError as exc:
                    raise SessionFormatError(f"{label} cannot be imported. {what_went_wrong(exc)} {_NOTHING}") from exc
                final = final_name(sanitize_name(top))
                s.name = final
                s._write_manifest()
                os.rename(tmp, root / final)
        except OSError as exc:
            raise write_failed(root, exc, doing="imported", subject=label, after=_NOTHING) from exc
    return final
