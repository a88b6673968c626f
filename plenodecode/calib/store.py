"""The calibration database: white images indexed by camera serial, zoom and focus step.

Layout of a database folder (default ``calib/``, relative to the working directory)::

    calib/index.json                       the index (below)
    calib/<serial>/<stem>.grid.json        fitted grid of each white image (cached on first use)

:func:`calibration_for` gives a raw's grid together with the white image it was fitted on (for
devignetting); :func:`grid_for` gives the grid only.

``index.json``::

    {"format": "plenodecode.calibration-db", "version": 1,
     "entries": [{"file": "../sample_raws/illum-mini/MOD_0000.RAW",   # relative to the folder
                  "serial": "B5143909630", "model": "B01", "zoom_step": -312, "focus_step": 417,
                  "exposure_s": 0.008, "shape": [1072, 1544], "grid": "B5143909630/MOD_0000.grid.json"}]}

Selection follows LFToolbox's ``LFSelectFromDatabase``: the same serial first, then the smallest
``|zoom_step - zoom|``, then among those the smallest ``|focus_step - focus|``.  The white images
themselves are not copied; paths are stored relative to the database folder so a committed
database works from any checkout.  Files are written to a temporary name and renamed.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass
from pathlib import Path

from typing import Any, Callable, Mapping

from ..errors import CalibrationError, FormatError
from ..io.atomic import write_text_atomic
from ..types import CameraMetadata, LensletGrid, RawCapture

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None] | None

#: Default database folder (relative to the working directory).
DEFAULT_DB = "calib"
INDEX_NAME = "index.json"
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
    """

    file: str
    serial: str | None
    model: str | None = None
    zoom_step: float | None = None
    focus_step: float | None = None
    exposure_s: float | None = None
    shape: tuple[int, int] | None = None
    grid: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"file": self.file, "serial": self.serial, "model": self.model, "zoom_step": self.zoom_step,
                "focus_step": self.focus_step, "exposure_s": self.exposure_s,
                "shape": None if self.shape is None else list(self.shape), "grid": self.grid}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "WhiteEntry":
        shape = d.get("shape")
        return cls(file=str(d["file"]), serial=d.get("serial"), model=d.get("model"),
                   zoom_step=d.get("zoom_step"), focus_step=d.get("focus_step"), exposure_s=d.get("exposure_s"),
                   shape=None if shape is None else (int(shape[0]), int(shape[1])), grid=d.get("grid"))


# -- files ------------------------------------------------------------------------------------
def _atomic_write_text(path: Path, text: str, *, overwrite: bool = True) -> None:
    write_text_atomic(path, text, overwrite=overwrite)


def _rel(path: Path, db: Path) -> str:
    try:
        return os.path.relpath(path.resolve(), db.resolve())
    except ValueError:  # another drive (Windows)
        return str(path.resolve())


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


def save_index(db_dir: str | os.PathLike, entries: list[WhiteEntry]) -> Path:
    """Write ``index.json`` atomically; returns its path."""
    p = Path(db_dir) / INDEX_NAME
    doc = {"format": INDEX_FORMAT, "version": INDEX_VERSION, "entries": [e.to_dict() for e in entries]}
    _atomic_write_text(p, json.dumps(doc, indent=1))
    return p


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


def _find_whites(folder: Path) -> list[Path]:
    """Lytro ``MOD_NNNN.RAW`` white images, and mosaics whose sidecar says ``is_white_image``."""
    found = [p for p in folder.rglob("*") if p.is_file() and (
        (p.name.upper().startswith("MOD_") and p.suffix.upper() == ".RAW") or _is_white_mosaic(p))]
    return sorted(found)


def _grid_relpath(entry: WhiteEntry) -> str:
    serial = entry.serial or "unknown"
    return f"{serial}/{Path(entry.file).stem}.grid.json"


# -- build / select -----------------------------------------------------------------------------
def build_database(folder: str | os.PathLike, db_dir: str | os.PathLike = DEFAULT_DB, *, fit: bool = True,
                   overwrite: bool = False, progress: Progress = None, **calibrate_kw: Any) -> list[WhiteEntry]:
    """Index the white images (``MOD_NNNN.RAW`` + ``.TXT``) under a folder and fit each once.

    Parameters
    ----------
    folder : path
        Searched recursively for ``MOD_*.RAW`` files with a metadata sidecar.
    db_dir : path
        Database folder (created); its ``index.json`` is merged with the new entries (same file ->
        replaced).
    fit : bool
        Fit and cache every grid now (otherwise on first use by :func:`grid_for`).
    overwrite : bool
        Refit grids that are already cached.
    progress : callable(done, total), optional
    **calibrate_kw
        Passed to :func:`plenodecode.calib.calibrate`.

    Returns
    -------
    list of WhiteEntry

    Raises
    ------
    CalibrationError
        No white image found in ``folder``.
    """
    from ..io.generic import read_generic
    from ..io.lytro import read_raw_pair_metadata

    src, db = Path(folder), Path(db_dir)
    if not src.is_dir():
        raise CalibrationError(f"{src}: not a folder; pass the folder holding the MOD_NNNN.RAW/.TXT white images")
    paths = _find_whites(src)
    if not paths:
        raise CalibrationError(f"{src}: no white images found; expected the camera's calibration files "
                               "(MOD_0000.RAW + MOD_0000.TXT ...) or mosaics whose JSON sidecar sets is_white_image")
    db.mkdir(parents=True, exist_ok=True)
    try:
        existing = {e.file: e for e in load_index(db)}
    except CalibrationError:
        existing = {}
    entries: dict[str, WhiteEntry] = dict(existing)
    total = len(paths)
    for k, p in enumerate(paths):
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
        rel = _rel(p, db)
        old = existing.get(rel)
        entry = WhiteEntry(file=rel, serial=cam.serial, model=cam.model, zoom_step=cam.zoom_step,
                           focus_step=cam.focus_step, exposure_s=cam.exposure_s, shape=(int(h), int(w)),
                           grid=old.grid if old is not None and not overwrite else None)
        if fit and (entry.grid is None or not (db / entry.grid).is_file()):
            entry = _fit_entry(entry, db, **calibrate_kw)
        entries[rel] = entry
        if progress is not None:
            progress(k + 1, total)
    out = sorted(entries.values(), key=lambda e: (str(e.serial), e.zoom_step or 0, e.focus_step or 0, e.file))
    save_index(db, out)
    log.info("calibration database %s: %d white images of %d camera(s)", db, len(out),
             len({e.serial for e in out}))
    return out


def _fit_entry(entry: WhiteEntry, db: Path, **calibrate_kw: Any) -> WhiteEntry:
    from . import calibrate
    grid = calibrate(_white_path(entry, db), **calibrate_kw)
    rel = _grid_relpath(entry)
    info = {**grid.info, "source": entry.file, "database": str(db)}
    _atomic_write_text(db / rel, grid.replace(info=info).to_json())
    return WhiteEntry(**{**entry.__dict__, "grid": rel})


def select_white(db_dir: str | os.PathLike, metadata: CameraMetadata | RawCapture) -> WhiteEntry:
    """The database entry for a raw: same serial, then nearest zoom step, then nearest focus step.

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
        No white image of the raw's camera (the message lists the serials the database holds),
        or the raw has no serial while the database holds several cameras.
    """
    md = metadata.metadata if isinstance(metadata, RawCapture) else metadata
    entries = load_index(db_dir)
    serials = sorted({str(e.serial) for e in entries})
    if not entries:
        raise CalibrationError(f"{db_dir}: the calibration database is empty; add white images with "
                               "'plenodecode calibrate --database'")
    if md.serial is None:
        if len(serials) > 1:
            raise CalibrationError(f"the raw has no camera serial and the database {db_dir} holds several cameras "
                                   f"({', '.join(serials)}); pass a grid (-g) or a white image explicitly")
        log.warning("raw has no camera serial; using the only camera in %s (%s)", db_dir, serials[0])
        cands = entries
    else:
        cands = [e for e in entries if str(e.serial) == str(md.serial)]
        if not cands:
            raise CalibrationError(f"no white image of camera {md.serial} in {db_dir} (it holds "
                                   f"{', '.join(serials)}); add that camera's white images with "
                                   f"'plenodecode calibrate --database {db_dir} FOLDER'")

    def dist(v: float | None, ref: float | None) -> float:
        return 0.0 if v is None or ref is None else abs(float(v) - float(ref))
    best_zoom = min(dist(e.zoom_step, md.zoom_step) for e in cands)
    cands = [e for e in cands if dist(e.zoom_step, md.zoom_step) == best_zoom]
    return min(cands, key=lambda e: (dist(e.focus_step, md.focus_step), e.file))


def _white_path(entry: WhiteEntry, db: Path) -> Path:
    """Path of an entry's white image (stored relative to the database folder, or absolute)."""
    return Path(entry.file) if os.path.isabs(entry.file) else Path(os.path.normpath(db / entry.file))


def _cached_grid(raw: RawCapture, db: Path, **calibrate_kw: Any) -> tuple[WhiteEntry, LensletGrid]:
    """The entry :func:`select_white` picks for ``raw`` and its grid (fitted and cached on first use)."""
    entry = select_white(db, raw)
    if entry.grid is None or not (db / entry.grid).is_file():
        entries = load_index(db)
        entry = _fit_entry(entry, db, **calibrate_kw)
        save_index(db, [entry if e.file == entry.file else e for e in entries])
    try:
        grid = LensletGrid.from_json((db / entry.grid).read_text(encoding="utf-8"))  # type: ignore[operator]
    except OSError as exc:
        raise CalibrationError(f"{db / str(entry.grid)}: cannot read the cached grid ({exc}); rebuild the "
                               "database") from exc
    if tuple(grid.sensor_shape) != tuple(raw.shape):
        raise CalibrationError(f"the white image {entry.file} is {grid.sensor_shape[1]}x{grid.sensor_shape[0]} "
                               f"but the raw is {raw.shape[1]}x{raw.shape[0]}; the database entry belongs to "
                               "another sensor")
    log.info("grid for %s: white %s (zoom %s, focus %s)", raw.path, entry.file, entry.zoom_step, entry.focus_step)
    return entry, grid


def grid_for(raw: RawCapture, db_dir: str | os.PathLike = DEFAULT_DB, **calibrate_kw: Any) -> LensletGrid:
    """The lenslet grid for a raw from the database: nearest white image, fitted once, then cached.

    Parameters
    ----------
    raw : RawCapture
    db_dir : path
        Database folder (default ``calib``).
    **calibrate_kw
        Passed to :func:`plenodecode.calib.calibrate` when the grid is not cached yet.

    Returns
    -------
    LensletGrid

    Raises
    ------
    CalibrationError
        No matching camera (see :func:`select_white`), or a cached grid for another sensor size.
    """
    return _cached_grid(raw, Path(db_dir), **calibrate_kw)[1]


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
        Passed to :func:`plenodecode.calib.calibrate` when the grid is not cached yet.

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
    from ..io import read_raw

    db = Path(db_dir)
    entry, grid = _cached_grid(raw, db, **calibrate_kw)
    path = _white_path(entry, db)
    if not path.is_file():
        raise CalibrationError(f"{path}: the white image of database entry {entry.file} is missing; restore it or "
                               f"rebuild the database {db}")
    white = read_raw(path)
    if white.shape != raw.shape:
        raise CalibrationError(f"the white image {entry.file} is {white.shape[1]}x{white.shape[0]} but the raw is "
                               f"{raw.shape[1]}x{raw.shape[0]}; rebuild the database {db}")
    return grid, white


__all__ = ["DEFAULT_DB", "WhiteEntry", "build_database", "select_white", "grid_for", "calibration_for", "load_index",
           "save_index"]
