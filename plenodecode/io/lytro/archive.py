"""Lytro calibration archives read in place: the Illum backup ``caldata-<serial>.tar`` and F01 ``data.C.0..N``.

``formats.md`` §1-3.  Neither archive is extracted: a white image inside one is named by an
*archive member path* ``ARCHIVE::MEMBER`` (:class:`MemberPath`), e.g.
``caldata-B5143909630.tar::B5143909630/MOD_0000.RAW`` or ``data.C.0::T1CALIB/MOD_0000.RAW``, and
:func:`read_member_raw` reads such a ``MOD_NNNN.RAW`` with its ``.TXT`` sidecar from the archive.

* **Illum** ``caldata-<serial>.tar`` (the camera's "pairing data"): a ``<serial>/`` or ``unitdata/``
  folder holding ``cal_file_manifest.json``, ``MOD_NNNN.RAW`` + ``.TXT`` pairs and ``*.GCT`` files.
  Read with :mod:`tarfile` (any compression it knows).
* **F01** ``data.C.0``, ``data.C.1``, ...: each volume is a Lytro container whose table of contents is
  ``{"files": [{"name": "C:\\T1CALIB\\MOD_0000.RAW", "dataRef": "sha1-..."}, ...], "nextFile": "data.C.1"}``,
  one LFC section per file; the chain is followed from the first volume through ``nextFile``.  Member
  names drop the drive and use ``/`` (``T1CALIB/MOD_0000.RAW``).

``cal_file_manifest.json`` (``calibrationFiles[i].{name, hash}``) links each ``MOD_NNNN.GCT`` to the
SHA-1 a picture names in ``frames[0].frame.geometryCorrectionRef``; the white image with the GCT's
stem is the one that picture was taken with (:func:`geometry_refs`).

The writers (:func:`write_caldata_tar`, :func:`write_datac_volumes`) write both kinds for the
generator and the tests.
"""

from __future__ import annotations

import io
import logging
import os
import re
import tarfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any, Iterator, Mapping, Sequence

from ...errors import FormatError
from ...types import RawCapture
from ..atomic import atomic_outputs, refuse_existing
from .container import FILE_MAGIC, read_container, section_name, write_container
from .fields import lookup, normalise_sha1
from .rawpair import pair_metadata, raw_from_buffer, sidecar_document

log = logging.getLogger(__name__)

#: Separates the archive's path from the member's name in an archive member path.
MEMBER_SEPARATOR = "::"
#: The manifest that links ``*.GCT`` files to pictures' ``geometryCorrectionRef``.
MANIFEST_NAME = "cal_file_manifest.json"
#: Extensions a white image's JSON sidecar may have, in the order they are tried.
SIDECAR_SUFFIXES = (".TXT", ".txt", ".json", ".JSON")


@dataclass(frozen=True)
class MemberPath:
    """A file inside a calibration archive: ``archive`` on disk and ``member``, its name in the archive.

    ``str()`` gives ``'<archive>::<member>'``, the form the calibration database and
    :func:`plenodecode.io.read_raw` take.
    """

    archive: Path
    member: str

    def __str__(self) -> str:
        return f"{self.archive}{MEMBER_SEPARATOR}{self.member}"

    @property
    def name(self) -> str:
        """The member's file name (last component), e.g. ``'MOD_0000.RAW'``."""
        return PurePosixPath(self.member).name


def split_member_path(path: str | os.PathLike | MemberPath) -> MemberPath | None:
    """The :class:`MemberPath` of ``'<archive>::<member>'``, or None for an ordinary path."""
    if isinstance(path, MemberPath):
        return path
    text = os.fspath(path)
    if MEMBER_SEPARATOR not in text:
        return None
    archive, member = text.split(MEMBER_SEPARATOR, 1)
    return MemberPath(Path(archive), member) if archive and member else None


def archive_kind(path: str | os.PathLike) -> str | None:
    """``'illum-tar'`` for a tar file, ``'f01-datac'`` for a Lytro container of files (``data.C.N``), else None."""
    p = Path(path)
    if not p.is_file():
        return None
    try:
        with open(p, "rb") as fh:
            head = fh.read(8)
    except OSError:
        return None
    if head == FILE_MAGIC:
        try:
            return "f01-datac" if read_container(p, verify=False).kind == "calibration" else None
        except FormatError:
            return None
    try:
        return "illum-tar" if tarfile.is_tarfile(p) else None
    except OSError:
        return None


def looks_like_archive(path: Path) -> bool:
    """By name only (cheap, for folder scans): ``*.tar`` / ``*.tar.gz`` / ``*.tgz`` or the first volume ``data.C.0``."""
    name = path.name.lower()
    return name.endswith((".tar", ".tar.gz", ".tgz")) or name == "data.c.0"


def _datac_member_name(name: str) -> str:
    """``'C:\\T1CALIB\\MOD_0000.RAW'`` -> ``'T1CALIB/MOD_0000.RAW'`` (drive dropped, ``/`` separators)."""
    name = re.sub(r"^[A-Za-z]:", "", name.strip()).replace("\\", "/")
    return name.lstrip("/")


class CalibrationArchive:
    """An open calibration archive: its members by name, their sizes and bytes (use as a context manager).

    Parameters
    ----------
    path : path-like
        A tar file (Illum ``caldata-<serial>.tar``, any compression :mod:`tarfile` reads) or the first
        volume of an F01 ``data.C.N`` chain.

    Raises
    ------
    FormatError
        Neither kind, a damaged archive, or a ``nextFile`` volume that is missing.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.kind = archive_kind(self.path)
        self._tar: tarfile.TarFile | None = None
        self._sizes: dict[str, int] = {}
        self._tar_info: dict[str, tarfile.TarInfo] = {}
        self._datac: dict[str, tuple[Any, str]] = {}
        if self.kind == "illum-tar":
            self._open_tar()
        elif self.kind == "f01-datac":
            self._open_datac()
        else:
            raise FormatError(f"{self.path}: not a calibration archive; expected the Illum backup "
                              "caldata-<serial>.tar or the F01 volume data.C.0")

    def _open_tar(self) -> None:
        try:
            self._tar = tarfile.open(self.path, "r:*")
            infos = self._tar.getmembers()
        except (tarfile.TarError, OSError, EOFError) as exc:
            raise FormatError(f"{self.path}: cannot read the tar archive ({exc}); the file is damaged") from None
        for info in infos:
            if info.isreg():
                name = info.name[2:] if info.name.startswith("./") else info.name
                self._tar_info[name] = info
                self._sizes[name] = int(info.size)

    def _open_datac(self) -> None:
        volume: Path | None = self.path
        seen: set[Path] = set()
        while volume is not None:
            if volume.resolve() in seen:
                raise FormatError(f"{volume}: the data.C volumes' nextFile fields form a loop; the archive is damaged")
            seen.add(volume.resolve())
            if not volume.is_file():
                raise FormatError(f"{volume}: this calibration volume is missing (named by nextFile of the previous "
                                  "one); copy every data.C.N file of the camera into one folder")
            c = read_container(volume, verify=False)
            files = lookup(c.toc, "files")
            if c.kind != "calibration" or not isinstance(files, list):
                raise FormatError(f"{volume}: expected a calibration volume (a TOC with a 'files' list), found a "
                                  f"{c.kind} container")
            for entry in files:
                name, ref = lookup(entry, "name"), lookup(entry, "dataRef")
                if not isinstance(name, str) or not isinstance(ref, str):
                    continue
                if not c.has(ref):
                    raise FormatError(f"{volume}: the TOC names {name!r} but its section {ref[:17]}... is not in the "
                                      "file; the volume is damaged")
                member = _datac_member_name(name)
                self._datac[member] = (c, normalise_sha1(ref))
                self._sizes[member] = c.section(ref).length
            nxt = lookup(c.toc, "nextFile")
            volume = volume.parent / PurePosixPath(nxt.replace("\\", "/")).name if isinstance(nxt, str) and nxt else None

    def __enter__(self) -> "CalibrationArchive":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        """Close the tar file (the data.C volumes are memory maps, released when collected)."""
        if self._tar is not None:
            self._tar.close()
            self._tar = None

    def names(self) -> list[str]:
        """Every member (regular files), sorted."""
        return sorted(self._sizes)

    def size(self, name: str) -> int:
        """Bytes of a member."""
        return self._sizes[self._require(name)]

    def _require(self, name: str) -> str:
        if name not in self._sizes:
            raise FormatError(f"{self.path}: no member {name!r} in the archive (it holds {len(self._sizes)} files); "
                              "rebuild the calibration database from this archive")
        return name

    def read(self, name: str) -> bytes | memoryview:
        """The bytes of a member (a data.C payload is checked against its SHA-1 name).

        Raises
        ------
        FormatError
            No such member, or a damaged payload.
        """
        name = self._require(name)
        if self._tar is not None:
            fh = self._tar.extractfile(self._tar_info[name])
            if fh is None:
                raise FormatError(f"{self.path}: member {name} cannot be read")
            return fh.read()
        container, ref = self._datac[name]
        data = container.payload(ref)
        if section_name(data) != ref:
            raise FormatError(f"{container.path}: the payload of {name} does not match its SHA-1 name; the volume "
                              "is damaged")
        return data

    def member_path(self, name: str) -> MemberPath:
        """The :class:`MemberPath` of a member."""
        return MemberPath(self.path, name)

    def sidecar_of(self, name: str) -> str | None:
        """The JSON sidecar member of a headerless raw member (same folder and stem, ``.TXT``/``.json``)."""
        stem = PurePosixPath(name).with_suffix("")
        for ext in SIDECAR_SUFFIXES:
            cand = str(stem) + ext
            if cand != name and cand in self._sizes:
                return cand
        return None

    def white_images(self) -> list[str]:
        """The ``MOD_NNNN.RAW`` members that have a sidecar, sorted."""
        return [n for n in self.names() if _is_mod_raw(n) and self.sidecar_of(n) is not None]

    def raw_layout(self, name: str) -> tuple:
        """:func:`~plenodecode.io.lytro.rawpair.pair_metadata` of a raw member (its sidecar read and checked)."""
        side = self.sidecar_of(self._require(name))
        where = str(self.member_path(name))
        if side is None:
            raise FormatError(f"{where}: no metadata sidecar ({PurePosixPath(name).stem}.TXT) beside the raw in the "
                              "archive")
        side_where = str(self.member_path(side))
        return pair_metadata(sidecar_document(bytes(self.read(side)), side_where), self.size(name), where, side_where)

    def read_raw(self, name: str) -> RawCapture:
        """A ``MOD_NNNN.RAW`` member with its sidecar as a :class:`RawCapture` (``path`` = the member path)."""
        layout = self.raw_layout(name)
        return raw_from_buffer(self.read(name), layout, str(self.member_path(name)))

    def geometry_refs(self) -> dict[str, str]:
        """White-image member -> ``'sha1-<hex>'`` of its GCT, from every ``cal_file_manifest.json`` (see module doc)."""
        out: dict[str, str] = {}
        by_upper = {n.upper(): n for n in self.names()}
        for name in self.names():
            if PurePosixPath(name).name.lower() != MANIFEST_NAME:
                continue
            try:
                doc = sidecar_document(bytes(self.read(name)), str(self.member_path(name)))
            except FormatError as exc:
                log.warning("%s", exc)
                continue
            folder = PurePosixPath(name).parent
            for stem, sha in manifest_geometry_refs(doc).items():
                raw = by_upper.get(str(folder / stem).upper() + ".RAW")
                if raw is not None:
                    out[raw] = sha
        return out


def _is_mod_raw(name: str) -> bool:
    base = PurePosixPath(name).name.upper()
    return base.startswith("MOD_") and base.endswith(".RAW")


def manifest_geometry_refs(doc: Any) -> dict[str, str]:
    """``cal_file_manifest.json`` -> {white-image stem: ``'sha1-<hex>'`` of its ``*.GCT``}.

    Reads ``calibrationFiles[i].{name, hash}`` (``name`` may be a Windows or POSIX path, or the
    entry's ``gctFilePath``); entries that are not ``.GCT`` files are ignored.
    """
    out: dict[str, str] = {}
    files = lookup(doc, "calibrationFiles")
    for entry in files if isinstance(files, list) else []:
        name = lookup(entry, "name")
        name = name if isinstance(name, str) else lookup(entry, "gctFilePath")
        sha = lookup(entry, "hash")
        if not isinstance(name, str) or not isinstance(sha, str):
            continue
        base = PurePosixPath(name.replace("\\", "/")).name
        if base.upper().endswith(".GCT"):
            out[base[:-4]] = normalise_sha1(sha)
    return out


def read_member_raw(path: str | os.PathLike | MemberPath) -> RawCapture:
    """Read ``'<archive>::<member>'`` (a ``MOD_NNNN.RAW`` and its ``.TXT`` inside an archive) without extracting.

    Raises
    ------
    FormatError
        Not a member path, no such archive or member, or a damaged pair.
    """
    mp = split_member_path(path)
    if mp is None:
        raise FormatError(f"{path}: expected an archive member path ARCHIVE{MEMBER_SEPARATOR}MEMBER")
    if not mp.archive.is_file():
        raise FormatError(f"{mp.archive}: no such calibration archive (named by {mp})")
    with CalibrationArchive(mp.archive) as arch:
        return arch.read_raw(mp.member)


def member_exists(path: str | os.PathLike | MemberPath) -> bool:
    """True when ``'<archive>::<member>'`` names a member of an archive that exists."""
    mp = split_member_path(path)
    if mp is None or not mp.archive.is_file():
        return False
    try:
        with CalibrationArchive(mp.archive) as arch:
            return mp.member in arch.names()
    except FormatError:
        return False


# -- writers (the generator and tests) -----------------------------------------------------------
def write_caldata_tar(path: str | os.PathLike, files: Mapping[str, bytes], *, overwrite: bool = False) -> Path:
    """Write an Illum-style calibration backup: a plain tar of ``files`` (member name -> bytes), in order.

    Members get mode 0644 and mtime 0, so the same files give the same bytes.
    """
    p = Path(path)
    refuse_existing([p], overwrite)
    with atomic_outputs([p], overwrite=overwrite) as (tmp,):
        with tarfile.open(tmp, "w", format=tarfile.USTAR_FORMAT) as tf:
            for name, data in files.items():
                info = tarfile.TarInfo(name)
                info.size, info.mode, info.mtime = len(data), 0o644, 0
                tf.addfile(info, io.BytesIO(bytes(data)))
    return p


def write_datac_volumes(folder: str | os.PathLike, files: Sequence[tuple[str, bytes]], *, files_per_volume: int = 4,
                        overwrite: bool = False) -> list[Path]:
    """Write F01-style calibration volumes ``data.C.0``, ``data.C.1``, ... into ``folder``.

    Each volume is a Lytro container whose TOC lists its files (``{"name", "dataRef"}``, one LFC per
    file) and names the next volume in ``nextFile`` (absent in the last).

    Parameters
    ----------
    folder : path-like
    files : sequence of (name, bytes)
        ``name`` as the camera writes it, e.g. ``'C:\\T1CALIB\\MOD_0000.RAW'``.
    files_per_volume : int
        Files per volume (a pair may straddle two volumes).

    Returns
    -------
    list of Path, the volumes in chain order.
    """
    if files_per_volume < 1:
        raise ValueError(f"files_per_volume must be >= 1, got {files_per_volume!r}")
    out = Path(folder)
    chunks = [files[i:i + files_per_volume] for i in range(0, len(files), files_per_volume)] or [[]]
    paths = [out / f"data.C.{k}" for k in range(len(chunks))]
    refuse_existing(paths, overwrite)
    out.mkdir(parents=True, exist_ok=True)
    for k, (p, chunk) in enumerate(zip(paths, chunks)):
        toc: dict[str, Any] = {"files": [{"name": name, "dataRef": section_name(data)} for name, data in chunk]}
        if k + 1 < len(paths):
            toc["nextFile"] = paths[k + 1].name
        write_container(p, toc, [data for _, data in chunk], overwrite=overwrite)
    return paths


def iter_archives(folder: Path) -> Iterator[Path]:
    """Calibration archives under a folder (by name, :func:`looks_like_archive`, then by content), sorted."""
    for p in sorted(folder.rglob("*")):
        if p.is_file() and looks_like_archive(p) and archive_kind(p) is not None:
            yield p


__all__ = ["MEMBER_SEPARATOR", "MANIFEST_NAME", "MemberPath", "CalibrationArchive", "split_member_path",
           "archive_kind", "looks_like_archive", "manifest_geometry_refs", "read_member_raw", "member_exists",
           "write_caldata_tar", "write_datac_volumes", "iter_archives"]
