"""The calibration database: white images indexed by camera serial, zoom and focus step.

Layout of a database folder (default: the first ``calib/`` holding an ``index.json`` in the working directory,
else beside the raw or in a folder above it, :func:`find_database`)::

    calib/index.json                       the index (below)
    calib/.index.json.lock                 lock file that serialises writers of the index
    calib/<serial>/<stem>.grid.json        fitted grid of each white image (written by :func:`cache_grids`)

Looking up never writes: :func:`calibration_for` gives a raw's grid together with the white image it
was fitted on (for devignetting), :func:`grid_for` gives the grid only; a grid that is not cached
yet is fitted in memory and a log line suggests caching it.  Writing is explicit:
:func:`build_database` indexes white images, :func:`cache_grids` fits the grids the index lacks and
stores them (``plenodecode calibrate --database DIR [FOLDER...]`` does both).

``index.json``::

    {"format": "plenodecode.calibration-db", "version": 1,
     "entries": [{"file": "../sample_raws/illum-mini/MOD_0000.RAW",   # relative to the folder
                  "serial": "B5143909630", "model": "B01", "zoom_step": -312, "focus_step": 417,
                  "exposure_s": 0.008, "shape": [1072, 1544], "grid": "B5143909630/MOD_0000.grid.json"}]}

White images are indexed from folders of ``MOD_NNNN.RAW`` + ``.TXT`` pairs and, in place (never
extracted), from the cameras' calibration archives: the Illum backup ``caldata-<serial>.tar`` (a
``<serial>/`` or ``unitdata/`` folder) and the F01 volumes ``data.C.0..N``; such an entry's ``file``
is an archive member path ``ARCHIVE::MEMBER`` (:mod:`plenodecode.io.lytro.archive`), read through
:func:`plenodecode.io.read_raw`.  An entry's ``geometry_ref`` is the SHA-1 of its ``MOD_NNNN.GCT``
listed in ``cal_file_manifest.json``.

Selection: a picture whose ``frames[0].frame.geometryCorrectionRef`` equals an entry's
``geometry_ref`` gets that white image (the camera's own link, as PlenoptiCam follows it); otherwise
LFToolbox's ``LFSelectFromDatabase``: the same serial first, then the smallest
``|zoom_step - zoom|``, then among those the smallest ``|focus_step - focus|``.  The white images
themselves are not copied; paths are stored relative to the database folder so a committed
database works from any checkout.  Files are written to a temporary name and renamed; every
read-modify-write of ``index.json`` holds an exclusive ``flock`` on ``.index.json.lock`` (POSIX),
so concurrent batch workers or commands cannot lose each other's entries.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no advisory locks, one writer at a time is the user's job
    fcntl = None  # type: ignore[assignment]

from ..errors import CalibrationError, FormatError
from ..io.atomic import write_text_atomic
from ..types import CameraMetadata, LensletGrid, RawCapture

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None] | None

#: Name of the default database folder, looked for in the working directory, then beside the raw and above it
#: (:func:`find_database`).
DEFAULT_DB = "calib"
INDEX_NAME = "index.json"
#: Lock file beside the index; writers hold an exclusive ``flock`` on it while they read, merge and write.
LOCK_NAME = ".index.json.lock"
INDEX_FORMAT = "plenodecode.calibration-db"
INDEX_VERSION = 1


@dataclass(frozen=True)
class WhiteEntry:
    """One white image of the database.

    Attributes
    ----------
    file : str
        Path of the white image relative to the database folder (or absolute).
    serial, model : str or None
    zoom_step, focus_step, exposure_s : float or None
    shape : (H, W) or None
    grid : str or None
        Path of the cached grid JSON relative to the database folder, None until fitted.
    geometry_ref : str or None
        ``'sha1-<hex>'`` of the white image's ``MOD_NNNN.GCT`` (from ``cal_file_manifest.json``): the
        ``geometryCorrectionRef`` of the pictures taken with it.
    """

    file: str
    serial: str | None
    model: str | None = None
    zoom_step: float | None = None
    focus_step: float | None = None
    exposure_s: float | None = None
    shape: tuple[int, int] | None = None
    grid: str | None = None
    geometry_ref: str | None = None

    def to_dict(self) -> dict[str, Any]:
        d = {"file": self.file, "serial": self.serial, "model": self.model, "zoom_step": self.zoom_step,
             "focus_step": self.focus_step, "exposure_s": self.exposure_s,
             "shape": None if self.shape is None else list(self.shape), "grid": self.grid}
        return d if self.geometry_ref is None else {**d, "geometry_ref": self.geometry_ref}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "WhiteEntry":
        shape = d.get("shape")
        return cls(file=str(d["file"]), serial=d.get("serial"), model=d.get("model"),
                   zoom_step=d.get("zoom_step"), focus_step=d.get("focus_step"), exposure_s=d.get("exposure_s"),
                   shape=None if shape is None else (int(shape[0]), int(shape[1])), grid=d.get("grid"),
                   geometry_ref=d.get("geometry_ref"))


# -- files ------------------------------------------------------------------------------------
def _rel(path: Path | str, db: Path) -> str:
    """``path`` relative to the database folder (an archive member path: its archive part)."""
    from ..io.lytro.archive import MemberPath, split_member_path

    member = split_member_path(path) if isinstance(path, (str, MemberPath)) else None
    if member is not None:
        return str(MemberPath(Path(_rel(member.archive, db)), member.member))
    path = Path(path)
    try:
        return os.path.relpath(path.resolve(), db.resolve())
    except ValueError:  # another drive (Windows)
        return str(path.resolve())


def _raw_folder(raw_path: str | os.PathLike) -> Path:
    """The folder of a raw (absolute); an archive member's (``ARCHIVE::MEMBER``): its archive's."""
    return Path(str(raw_path).split("::", 1)[0]).resolve().parent


def database_candidates(raw_path: str | os.PathLike | None = None) -> list[Path]:
    """The folders :func:`find_database` tries, in order: ``calib`` in the working directory (relative), then
    ``calib/`` in the raw's folder and in each folder above it up to the root (absolute), as git finds its
    ``.git``: a project's database serves its raws from any working directory."""
    out = [Path(DEFAULT_DB)]
    if raw_path is not None:
        folder = _raw_folder(raw_path)
        here = Path(DEFAULT_DB).resolve()
        out += [d / DEFAULT_DB for d in (folder, *folder.parents) if (d / DEFAULT_DB) != here]
    return out


def find_database(raw_path: str | os.PathLike | None = None) -> Path | None:
    """The calibration database a raw at ``raw_path`` uses when none is given (``--database``): the first of
    :func:`database_candidates` that holds an ``index.json``; None when none does (:func:`where_looked` says where
    it looked)."""
    return next((d for d in database_candidates(raw_path) if (d / INDEX_NAME).is_file()), None)


def where_looked(raw_path: str | os.PathLike | None = None) -> str:
    """Where :func:`find_database` looked, in words, e.g. ``'/home/me/calib (the current folder's), then calib/
    in /data/shoot and each folder above it'``."""
    text = f"{Path(DEFAULT_DB).resolve()} (the current folder's)"
    if raw_path is None:
        return text
    return f"{text}, then {DEFAULT_DB}/ in {_raw_folder(raw_path)} and each folder above it"


def load_index(db_dir: str | os.PathLike = DEFAULT_DB) -> list[WhiteEntry]:
    """The entries of a database folder's ``index.json``.

    Raises
    ------
    CalibrationError
        No index, or not a plenodecode calibration database.
    """
    db = Path(db_dir)
    p = db / INDEX_NAME
    if not p.is_file():
        raise CalibrationError(f"{db}: no calibration database ({INDEX_NAME} missing); build one with "
                               f"'plenodecode calibrate --database {db} FOLDER_OF_MOD_FILES'")
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise CalibrationError(f"{p}: unreadable calibration index ({exc}); rebuild the database") from exc
    if not isinstance(doc, Mapping) or doc.get("format") != INDEX_FORMAT:
        raise CalibrationError(f"{p}: not a plenodecode calibration index (format {doc.get('format')!r}); "
                               "rebuild the database")
    if int(doc.get("version", 0)) > INDEX_VERSION:
        raise CalibrationError(f"{p}: index version {doc.get('version')} is newer than this plenodecode "
                               f"({INDEX_VERSION}); upgrade plenodecode")
    return [WhiteEntry.from_dict(e) for e in doc.get("entries", [])]


@contextlib.contextmanager
def index_lock(db_dir: str | os.PathLike) -> Iterator[Path]:
    """Hold the database's writer lock (exclusive ``flock`` on ``<db>/.index.json.lock``) in a block.

    The folder is created.  The lock is per open file, so a block must not be nested in the same
    process; it is released when the block ends or the process dies (a killed writer never leaves
    the database locked).

    Yields
    ------
    Path
        The database folder.
    """
    db = Path(db_dir)
    db.mkdir(parents=True, exist_ok=True)
    fd = os.open(db / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield db
    finally:
        os.close(fd)  # closing the file releases the lock


def _write_index(db: Path, entries: Iterable[WhiteEntry]) -> Path:
    """Write ``index.json`` atomically (temporary name + rename); the caller holds :func:`index_lock`."""
    p = db / INDEX_NAME
    doc = {"format": INDEX_FORMAT, "version": INDEX_VERSION, "entries": [e.to_dict() for e in entries]}
    write_text_atomic(p, json.dumps(doc, indent=1), overwrite=True)
    return p


def _sorted(entries: Iterable[WhiteEntry]) -> list[WhiteEntry]:
    return sorted(entries, key=lambda e: (str(e.serial), e.zoom_step or 0, e.focus_step or 0, e.file))


def save_index(db_dir: str | os.PathLike, entries: list[WhiteEntry]) -> Path:
    """Replace the whole ``index.json`` by ``entries``, atomically and under :func:`index_lock`; returns its path."""
    with index_lock(db_dir) as db:
        return _write_index(db, entries)


def update_index(db_dir: str | os.PathLike, entries: Iterable[WhiteEntry]) -> list[WhiteEntry]:
    """Merge entries into ``index.json``: an entry replaces the one of the same ``file``, others are kept.

    Read, merge and write happen under :func:`index_lock`, so concurrent writers (batch workers,
    two ``calibrate --database`` commands) each see the other's entries; the file is replaced
    atomically, so readers never see a half-written index.

    Parameters
    ----------
    db_dir : path
        Database folder (created, with an empty index, if new).
    entries : iterable of WhiteEntry

    Returns
    -------
    list of WhiteEntry
        The whole index after the merge, sorted by serial, zoom step, focus step, file.

    Raises
    ------
    CalibrationError
        The folder holds an index that is not a readable plenodecode calibration index.
    """
    with index_lock(db_dir) as db:
        merged = {e.file: e for e in (load_index(db) if (db / INDEX_NAME).is_file() else [])}
        merged.update((e.file, e) for e in entries)
        out = _sorted(merged.values())
        _write_index(db, out)
    return out


#: image mosaics whose JSON sidecar marks them as white images are indexed too (microscopes, generic cameras)
MOSAIC_SUFFIXES = (".png", ".tif", ".tiff", ".exr")


def _is_white_mosaic(p: Path) -> bool:
    from ..errors import PlenodecodeError
    from ..io.generic import find_sidecar, read_sidecar

    if p.suffix.lower() not in MOSAIC_SUFFIXES or find_sidecar(p) is None:
        return False
    try:
        return bool(read_sidecar(find_sidecar(p))["metadata"].is_white_image)
    except PlenodecodeError:
        return False


def find_whites(folder: Path, *, recursive: bool = True) -> list[Path]:
    """Lytro ``MOD_NNNN.RAW`` white images, and mosaics whose sidecar says ``is_white_image``, in ``folder``
    and (``recursive``) its sub-folders; sorted."""
    files = folder.rglob("*") if recursive else folder.glob("*")
    found = [p for p in files if p.is_file() and (
        (p.name.upper().startswith("MOD_") and p.suffix.upper() == ".RAW") or _is_white_mosaic(p))]
    return sorted(found)


def _grid_relpath(entry: WhiteEntry) -> str:
    """``<serial>/<stem>.grid.json``; a white inside an archive: ``<serial>/<archive>--<stem>.grid.json``."""
    from ..io.lytro.archive import split_member_path

    serial = entry.serial or "unknown"
    member = split_member_path(entry.file)
    if member is not None:
        return f"{serial}/{member.archive.name}--{Path(member.name).stem}.grid.json"
    return f"{serial}/{Path(entry.file).stem}.grid.json"


def _new_entry(file: str, cam: CameraMetadata, shape: tuple[int, int], existing: Mapping[str, WhiteEntry],
               overwrite: bool, geometry_ref: str | None = None) -> WhiteEntry:
    """The index entry of a white image; the cached grid of the same ``file`` is kept unless ``overwrite``."""
    old = existing.get(file)
    return WhiteEntry(file=file, serial=cam.serial, model=cam.model, zoom_step=cam.zoom_step,
                      focus_step=cam.focus_step, exposure_s=cam.exposure_s, shape=(int(shape[0]), int(shape[1])),
                      grid=old.grid if old is not None and not overwrite else None, geometry_ref=geometry_ref)


def _archive_entries(archive: Path, db: Path, existing: Mapping[str, WhiteEntry],
                     overwrite: bool) -> list[WhiteEntry]:
    """Entries of the white images inside a calibration archive, read in place (TXT sidecars only)."""
    from ..io.lytro.archive import CalibrationArchive

    found = []
    with CalibrationArchive(archive) as arch:
        refs = arch.geometry_refs()
        for name in arch.white_images():
            try:
                cam, *layout = arch.raw_layout(name)
            except FormatError as exc:
                log.warning("skipping %s: %s", arch.member_path(name), exc)
                continue
            found.append(_new_entry(_rel(arch.member_path(name), db), cam, (layout[4], layout[3]), existing,
                                    overwrite, refs.get(name)))
    return found


def _folder_geometry_ref(raw_path: Path, manifests: dict[Path, Mapping[str, str]]) -> str | None:
    """The GCT SHA-1 of an extracted ``MOD_NNNN.RAW`` from the ``cal_file_manifest.json`` beside it."""
    from ..io.lytro.archive import MANIFEST_NAME, manifest_geometry_refs
    from ..io.lytro.rawpair import read_sidecar

    folder = raw_path.parent
    if folder not in manifests:
        manifest = folder / MANIFEST_NAME
        try:
            manifests[folder] = manifest_geometry_refs(read_sidecar(manifest)) if manifest.is_file() else {}
        except FormatError as exc:
            log.warning("%s", exc)
            manifests[folder] = {}
    return manifests[folder].get(raw_path.stem)


# -- build / cache (the explicit writing steps) ----------------------------------------------------
def build_database(folder: str | os.PathLike, db_dir: str | os.PathLike = DEFAULT_DB, *, fit: bool = True,
                   overwrite: bool = False, progress: Progress = None, **calibrate_kw: Any) -> list[WhiteEntry]:
    """Index the white images of a folder or a calibration archive and, with ``fit``, cache their grids.

    Parameters
    ----------
    folder : path
        A folder, searched recursively for ``MOD_*.RAW`` files with a metadata sidecar, mosaics whose
        sidecar sets ``is_white_image``, and calibration archives; or one archive: an Illum
        ``caldata-<serial>.tar`` or the first F01 volume ``data.C.0`` (the chain is followed through
        ``nextFile``), indexed in place as ``ARCHIVE::MEMBER`` entries.  A ``cal_file_manifest.json``
        beside the white images gives each entry its ``geometry_ref``.
    db_dir : path
        Database folder (created); its ``index.json`` is merged with the new entries (same file ->
        replaced) under the writer lock (:func:`update_index`).
    fit : bool
        Fit and cache the grids of these white images now (:func:`cache_grids`); otherwise a lookup
        fits them in memory each time until :func:`cache_grids` is run.
    overwrite, progress, **calibrate_kw
        As :func:`cache_grids` (``overwrite`` also drops the cached grid names of these files from the index).

    Returns
    -------
    list of WhiteEntry, the whole index afterwards

    Raises
    ------
    CalibrationError
        Neither a folder nor a calibration archive, or no white image found in it.
    FormatError
        A damaged archive.
    """
    from ..io.generic import read_generic
    from ..io.lytro import read_raw_pair_metadata
    from ..io.lytro.archive import archive_kind, iter_archives

    src, db = Path(folder), Path(db_dir)
    is_archive = src.is_file() and archive_kind(src) is not None
    if not src.is_dir() and not is_archive:
        raise CalibrationError(f"{src}: not a folder or a calibration archive; pass the folder holding the "
                               "MOD_NNNN.RAW/.TXT white images, the Illum caldata-<serial>.tar or the F01 data.C.0")
    paths = [] if is_archive else find_whites(src)
    archives = [src] if is_archive else list(iter_archives(src))
    try:
        existing = {e.file: e for e in load_index(db)}
    except CalibrationError:
        existing = {}
    found: list[WhiteEntry] = []
    manifests: dict[Path, Mapping[str, str]] = {}
    for p in paths:
        try:
            if p.suffix.lower() in MOSAIC_SUFFIXES:
                white = read_generic(p)
                cam, (h, w) = white.metadata, white.shape
            else:
                cam, *_rest = read_raw_pair_metadata(p)
                w, h = _rest[3], _rest[4]
        except FormatError as exc:
            log.warning("skipping %s: %s", p, exc)
            continue
        found.append(_new_entry(_rel(p, db), cam, (h, w), existing, overwrite, _folder_geometry_ref(p, manifests)))
    for archive in archives:
        found += _archive_entries(archive, db, existing, overwrite)
    if not found:
        raise CalibrationError(f"{src}: no white images found; expected the camera's calibration files "
                               "(MOD_0000.RAW + MOD_0000.TXT ..., a caldata-<serial>.tar or data.C.0) or mosaics "
                               "whose JSON sidecar sets is_white_image")
    out = update_index(db, found)  # creates the folder
    if fit:
        out = cache_grids(db, files=[e.file for e in found], overwrite=overwrite, progress=progress, **calibrate_kw)
    log.info("calibration database %s: %d white images of %d camera(s)", db, len(out),
             len({e.serial for e in out}))
    return out


def cache_grids(db_dir: str | os.PathLike = DEFAULT_DB, *, files: Iterable[str] | None = None,
                overwrite: bool = False, progress: Progress = None, **calibrate_kw: Any) -> list[WhiteEntry]:
    """Fit the grids the index lacks and store them in the database: the one step that writes grids.

    Each grid goes to ``<db>/<serial>/<stem>.grid.json`` (atomic write) and its entry's ``grid``
    field is set in ``index.json`` through :func:`update_index` (locked read-merge-write), so
    several processes may cache grids of one database at once.

    Parameters
    ----------
    db_dir : path
        Database folder with an ``index.json``.
    files : iterable of str, optional
        Only these entries (their ``file`` field); default all.
    overwrite : bool
        Refit grids that are already cached.
    progress : callable(done, total), optional
        Called after each white image considered.
    **calibrate_kw
        Passed to :func:`plenodecode.calib.calibrate`.

    Returns
    -------
    list of WhiteEntry
        The whole index afterwards.

    Raises
    ------
    CalibrationError
        No index, or a white image cannot be calibrated.
    """
    db = Path(db_dir)
    wanted = None if files is None else set(files)
    todo = [e for e in load_index(db) if wanted is None or e.file in wanted]
    fitted: list[WhiteEntry] = []
    for k, entry in enumerate(todo):
        if overwrite or entry.grid is None or not (db / entry.grid).is_file():
            rel = _grid_relpath(entry)
            write_text_atomic(db / rel, _fit_grid(entry, db, **calibrate_kw).to_json(), overwrite=True)
            fitted.append(replace(entry, grid=rel))
        if progress is not None:
            progress(k + 1, len(todo))
    out = update_index(db, fitted) if fitted else load_index(db)
    log.info("calibration database %s: %d grid(s) fitted and cached", db, len(fitted))
    return out


def _fit_grid(entry: WhiteEntry, db: Path, **calibrate_kw: Any) -> LensletGrid:
    """Fit the grid of an entry's white image (in memory); ``info`` names the white and the database."""
    from . import calibrate
    grid = calibrate(_existing_white(entry, db), **calibrate_kw)
    return grid.replace(info={**grid.info, "source": entry.file, "database": str(db)})


# -- look up (never writes) ------------------------------------------------------------------------
def select_white(db_dir: str | os.PathLike, metadata: CameraMetadata | RawCapture) -> WhiteEntry:
    """The database entry for a raw: the white its ``geometryCorrectionRef`` names, else same serial, then
    nearest zoom step, then nearest focus step.

    Parameters
    ----------
    db_dir : path
    metadata : CameraMetadata or RawCapture

    Returns
    -------
    WhiteEntry

    Raises
    ------
    CalibrationError
        No white image of the raw's camera (the message lists the serials the database holds), or the raw has
        no serial while the database holds several cameras, or none of the raw's sensor size (a RawCapture's).
    """
    from ..io.lytro import frame_ref

    md = metadata.metadata if isinstance(metadata, RawCapture) else metadata
    entries = load_index(db_dir)
    serials = sorted({str(e.serial) for e in entries})
    if not entries:
        raise CalibrationError(f"{db_dir}: the calibration database is empty; add white images with "
                               "'plenodecode calibrate --database'")
    ref = frame_ref(md, "geometryCorrectionRef")
    linked = [e for e in entries if ref is not None and e.geometry_ref == ref
              and (md.serial is None or str(e.serial) == str(md.serial))]
    if linked:
        log.info("white image %s: named by the picture's geometryCorrectionRef through cal_file_manifest.json",
                 linked[0].file)
        return min(linked, key=lambda e: e.file)
    if md.serial is None:  # only a white image of the raw's sensor size can be its camera's
        shape = tuple(metadata.shape) if isinstance(metadata, RawCapture) else None
        cands = [e for e in entries if shape is None or e.shape is None or tuple(e.shape) == shape]
        cameras = sorted({str(e.serial) for e in cands})
        size = "" if shape is None else f" of its sensor size {shape[1]} x {shape[0]}"
        if not cands:
            held = ", ".join(sorted({f"{e.serial} ({e.shape[1]} x {e.shape[0]})" for e in entries}))
            raise CalibrationError(f"the raw has no camera serial and the database {db_dir} holds no white image"
                                   f"{size} (it holds {held}); give this camera's white image or grid")
        if len(cameras) > 1:
            raise CalibrationError(f"the raw has no camera serial and the database {db_dir} holds several cameras"
                                   f"{size} ({', '.join(cameras)}); give this camera's white image or grid")
        log.warning("raw has no camera serial; using the only camera%s in %s (%s)", size, db_dir, cameras[0])
    else:
        cands = [e for e in entries if str(e.serial) == str(md.serial)]
        if not cands:
            raise CalibrationError(f"no white image of camera {md.serial} in {db_dir} (it holds "
                                   f"{', '.join(serials)}); add that camera's white images with "
                                   f"'plenodecode calibrate --database {db_dir} FOLDER'")

    best_zoom = min(_step_distance(e.zoom_step, md.zoom_step) for e in cands)
    cands = [e for e in cands if _step_distance(e.zoom_step, md.zoom_step) == best_zoom]
    return min(cands, key=lambda e: (_step_distance(e.focus_step, md.focus_step), e.file))


def _step_distance(v: float | None, ref: float | None) -> float:
    """``|v - ref|`` of two zoom or focus steps, 0 when either is unknown."""
    return 0.0 if v is None or ref is None else abs(float(v) - float(ref))


def other_whites(db_dir: str | os.PathLike, metadata: CameraMetadata | RawCapture, exclude: WhiteEntry,
                 limit: int = 3) -> list[WhiteEntry]:
    """The raw's camera's other white images in the database, nearest zoom then focus step first.

    What to offer when the selected white image does not fit the raw (:mod:`plenodecode.calib.check`).

    Returns
    -------
    list of WhiteEntry
        At most ``limit`` entries of the raw's serial (all serials when the raw has none), ``exclude`` left out.
    """
    md = metadata.metadata if isinstance(metadata, RawCapture) else metadata
    cands = [e for e in load_index(db_dir) if e.file != exclude.file
             and (md.serial is None or str(e.serial) == str(md.serial))]
    cands.sort(key=lambda e: (_step_distance(e.zoom_step, md.zoom_step), _step_distance(e.focus_step, md.focus_step),
                              e.file))
    return cands[:limit]


def white_path(entry: WhiteEntry, db_dir: str | os.PathLike) -> Path | str:
    """Where an entry's white image is: its path (stored relative to the database folder, or absolute), or
    for a white inside a calibration archive the member path ``'<archive path>::<member>'`` (a str)."""
    from ..io.lytro.archive import MemberPath, split_member_path

    db = Path(db_dir)
    member = split_member_path(entry.file)
    if member is not None:
        archive = member.archive if member.archive.is_absolute() else Path(os.path.normpath(db / member.archive))
        return str(MemberPath(archive, member.member))
    return Path(entry.file) if os.path.isabs(entry.file) else Path(os.path.normpath(db / entry.file))


def _existing_white(entry: WhiteEntry, db: Path) -> Path | str:
    """:func:`white_path`, or a CalibrationError naming the entry when the file (or archive member) is gone."""
    from ..io.lytro.archive import member_exists

    path = white_path(entry, db)
    if not (path.is_file() if isinstance(path, Path) else member_exists(path)):
        raise CalibrationError(f"{path}: the white image of database entry {entry.file} is missing; restore it or "
                               f"rebuild the database {db}")
    return path


def lookup_grid(raw: RawCapture, db_dir: str | os.PathLike, **calibrate_kw: Any) -> tuple[WhiteEntry, LensletGrid]:
    """The entry :func:`select_white` picks for ``raw`` and its grid: read from the cache, else fitted in memory.

    Writes nothing; a missing cached grid costs a fit per call and is logged with the command that
    caches it.
    """
    db = Path(db_dir)
    entry = select_white(db, raw)
    if entry.grid is not None and (db / entry.grid).is_file():
        try:
            grid = LensletGrid.from_json((db / entry.grid).read_text(encoding="utf-8"))
        except OSError as exc:
            raise CalibrationError(f"{db / str(entry.grid)}: cannot read the cached grid ({exc}); rebuild the "
                                   "database") from exc
    else:
        log.warning("grid of %s is not cached in %s: fitting it in memory (cache it once with "
                    "'plenodecode calibrate --database %s')", entry.file, db, db)
        grid = _fit_grid(entry, db, **calibrate_kw)
    if tuple(grid.sensor_shape) != tuple(raw.shape):
        raise CalibrationError(f"the white image {entry.file} is {grid.sensor_shape[1]}x{grid.sensor_shape[0]} "
                               f"but the raw is {raw.shape[1]}x{raw.shape[0]}; the database entry belongs to "
                               "another sensor")
    log.info("grid for %s: white %s (zoom %s, focus %s)", raw.path, entry.file, entry.zoom_step, entry.focus_step)
    return entry, grid


def grid_for(raw: RawCapture, db_dir: str | os.PathLike = DEFAULT_DB, **calibrate_kw: Any) -> LensletGrid:
    """The lenslet grid for a raw from the database: nearest white image, its cached grid (read only).

    Parameters
    ----------
    raw : RawCapture
    db_dir : path
        Database folder (default ``calib``).
    **calibrate_kw
        Passed to :func:`plenodecode.calib.calibrate` when the grid is not cached (it is then fitted in
        memory and not stored: :func:`cache_grids` stores it).

    Returns
    -------
    LensletGrid

    Raises
    ------
    CalibrationError
        No matching camera (see :func:`select_white`), or a cached grid for another sensor size.
    """
    return lookup_grid(raw, db_dir, **calibrate_kw)[1]


def calibration_for(raw: RawCapture, db_dir: str | os.PathLike = DEFAULT_DB,
                    **calibrate_kw: Any) -> tuple[LensletGrid, RawCapture]:
    """The grid for a raw (as :func:`grid_for`) and the white image it was fitted on, read back.

    Decoders devignette with that white, so grid and flat field always come from the same
    database entry (same serial, nearest zoom step, then nearest focus step).

    Parameters
    ----------
    raw : RawCapture
    db_dir : path
        Database folder (default ``calib``).
    **calibrate_kw
        Passed to :func:`plenodecode.calib.calibrate` when the grid is not cached (it is then fitted in
        memory and not stored: :func:`cache_grids` stores it).

    Returns
    -------
    grid : LensletGrid
    white : RawCapture
        The selected white image (mosaic (H, W) uint16, same size as ``raw``).

    Raises
    ------
    CalibrationError
        No matching camera, a cached grid or a white image of another sensor size, or the
        white image file is missing.
    FormatError
        The white image file cannot be parsed.
    """
    entry, grid = lookup_grid(raw, db_dir, **calibrate_kw)
    return grid, read_white(entry, db_dir, raw)


def read_white(entry: WhiteEntry, db_dir: str | os.PathLike, raw: RawCapture) -> RawCapture:
    """The white image of a database entry, read back; a CalibrationError when it is missing or not of ``raw``'s
    sensor size (mosaic (H, W) uint16)."""
    from ..io import read_raw

    db = Path(db_dir)
    white = read_raw(_existing_white(entry, db))
    if white.shape != raw.shape:
        raise CalibrationError(f"the white image {entry.file} is {white.shape[1]}x{white.shape[0]} but the raw is "
                               f"{raw.shape[1]}x{raw.shape[0]}; rebuild the database {db}")
    return white


__all__ = ["DEFAULT_DB", "database_candidates", "find_database", "where_looked", "WhiteEntry", "build_database",
           "find_whites", "cache_grids", "select_white", "other_whites",
           "white_path", "grid_for", "calibration_for", "lookup_grid", "read_white", "load_index", "save_index",
           "update_index", "index_lock"]
