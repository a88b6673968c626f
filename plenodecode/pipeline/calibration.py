"""Step 2 of the workflow: the calibration policy (:func:`choose_calibration`), one log line per choice.

Part of :mod:`plenodecode.pipeline` (see its docstring for the five steps).
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import CalibrationError
from ..types import LensletGrid, RawCapture
from .inputs import Progress, open_raw

if TYPE_CHECKING:
    from ..io.mosaic_levels import MosaicOptions

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Calibration:
    """The lenslet grid a raw is decoded with, the white image that devignettes it, and where both came from.

    Attributes
    ----------
    grid : LensletGrid
    white : RawCapture or None
        Flat field of the same sensor (mosaic (H, W) uint16), None when there is none.
    source : str
        'grid file', 'white image', 'camera' (Raytrix XML), 'database' or 'self-calibration'.
    detail : str
        Which file(s): shown after ``source`` in the log line.
    """

    grid: LensletGrid
    white: RawCapture | None
    source: str
    detail: str = ""

    def describe(self) -> str:
        """One line, e.g. ``'calibration: database calib/ (white MOD_0003.RAW, cached grid)'``."""
        return f"calibration: {self.source}" + (f" {self.detail}" if self.detail else "")


def grid_from_file(path: str | os.PathLike) -> LensletGrid:
    """The lenslet grid JSON ``path`` (``--calibration``); :class:`~plenodecode.errors.CalibrationError` naming the
    file and what to pass instead when it is unreadable or not a grid."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"{path}: cannot read the lenslet grid ({exc}); pass a grid written by "
                               "'plenodecode calibrate'") from exc
    try:
        return LensletGrid.from_json(text)
    except CalibrationError as exc:     # which file, and what to pass instead
        hint = "" if "plenodecode calibrate" in str(exc) else "; pass a grid written by 'plenodecode calibrate'"
        raise CalibrationError(f"{path}: {exc}{hint}") from exc


def _from_database(raw: RawCapture, db: Path) -> Calibration:
    """The database's white image for ``raw`` and its grid, refused when it does not fit the raw
    (:func:`plenodecode.calib.check.check_white_fit`, naming the camera's other white images)."""
    from ..calib import store
    from ..calib.check import check_white_fit

    entry, grid = store.lookup_grid(raw, db)
    cached = entry.grid is not None and (db / entry.grid).is_file()  # a lookup never writes: as it was
    white = store.read_white(entry, db, raw)
    others = [f"{Path(e.file).name} at zoom {e.zoom_step:g} focus {e.focus_step:g}"
              if e.zoom_step is not None and e.focus_step is not None else Path(e.file).name
              for e in store.other_whites(db, raw, entry)]
    check_white_fit(raw, grid, white, white_name=f"{Path(entry.file).name} of {db}/", alternatives=others)
    return Calibration(grid, white, "database",
                       f"{db}/ (white {Path(entry.file).name}, {'cached grid' if cached else 'grid fitted now'})")


def _per_picture_white(raw: RawCapture) -> Calibration | None:
    """A Lytro Desktop raw LFP's own white image (``modulationDataRef``), calibrated and checked; None without one."""
    from ..io.lytro import frame_ref, read_modulation_white

    if not raw.path or frame_ref(raw.metadata, "modulationDataRef") is None:
        return None
    from ..calib import calibrate
    from ..calib.check import check_white_fit

    white = read_modulation_white(raw.path)
    if white is None:
        return None
    grid = calibrate(white)
    check_white_fit(raw, grid, white, white_name="the picture's own white image (modulationDataRef)")
    return Calibration(grid, white, "camera", "(the picture's white image, modulationDataRef)")


def choose_calibration(raw: RawCapture, *, grid: str | os.PathLike | None = None,
                       white: str | os.PathLike | RawCapture | None = None,
                       database: str | os.PathLike | None = None, self_calibrate: bool = False,
                       mosaic: MosaicOptions | None = None, progress: Progress = None) -> Calibration:
    """The calibration of ``raw``, chosen by one policy (first that applies).

    1. ``grid`` (a grid JSON written by ``plenodecode calibrate``); ``white``, when given, devignettes;
    2. ``white`` alone: calibrated on the spot (:func:`plenodecode.calib.calibrate`), and devignettes;
       refused when it does not fit the raw (:func:`plenodecode.calib.check.check_white_fit`, as in 4);
    3. the camera's own calibration: a Raytrix raw's ``RayCalibData``
       (:func:`~plenodecode.calib.selfcal.calibrate_raytrix`);
    4. a Lytro raw LFP's own white image (``modulationDataRef``), else the calibration database ``database``
       (default: ``./calib``, else ``calib/`` beside the raw or above it,
       :func:`plenodecode.calib.store.find_database`): the white image the raw's ``geometryCorrectionRef``
       names, else that of the raw's camera at the nearest zoom and focus, and its cached grid; a white image
       whose lattice is off the raw's micro-images, or that is a scene, is refused in one line naming the
       camera's other white images (with ``self_calibrate``: self-calibration instead);
    5. with ``self_calibrate``: the grid found in the scene itself
       (:func:`~plenodecode.calib.selfcal.calibrate_from_scene`), no devignetting.

    An image mosaic read without a sidecar (:func:`plenodecode.io.generic.is_bare_mosaic`) has no camera
    identity to look up, so it skips the database and, with no grid and no white image, is self-calibrated
    (said in one warning line); a camera raw without a database entry still needs ``self_calibrate``.

    The choice is logged in one info line (:meth:`Calibration.describe`).

    Parameters
    ----------
    raw : RawCapture
    grid, white : path-like, optional
    database : path-like, optional
    self_calibrate : bool
        Fall back to self-calibration when nothing above applies (instead of raising).
    mosaic : MosaicOptions, optional
        How to read ``white`` when it is an image mosaic (as for the raw).
    progress : callable(done, total), optional
        Progress of an on-the-spot calibration.

    Returns
    -------
    Calibration

    Raises
    ------
    CalibrationError
        Nothing usable; the message says which option to pass.
    """
    from ..calib import store
    from ..io.generic import is_bare_mosaic

    white_raw = open_raw(white, mosaic=mosaic) if isinstance(white, (str, os.PathLike)) else white
    db = Path(database) if database is not None else store.find_database(raw.path)
    if grid is not None:
        cal = Calibration(grid_from_file(grid), white_raw, "grid file",
                          str(grid) + (f" (white {Path(white_raw.path or '?').name})" if white_raw else ""))
    elif white_raw is not None:
        from ..calib import calibrate
        from ..calib.check import check_white_fit

        cal = Calibration(calibrate(white_raw, progress=progress), white_raw, "white image",
                          Path(white_raw.path or "?").name)
        check_white_fit(raw, cal.grid, white_raw)  # a scene given as its white, or another lattice: refused
    elif "raytrix" in raw.metadata.extra:
        from ..calib.selfcal import calibrate_raytrix

        xml = raw.metadata.extra.get("raytrix_xml")
        cal = Calibration(calibrate_raytrix(raw), None, "camera",
                          f"(Raytrix RayCalibData{' ' + Path(xml).name if xml else ''})")
    elif is_bare_mosaic(raw):
        # what the decoding will do without a white image and metadata, said once here (the decoder logs it at INFO)
        log.warning("%s: no white image and no camera identity for the database: the lenslet grid comes from "
                    "self-calibration of the scene; the light field is not devignetted%s",
                    Path(raw.path or "mosaic").name, " and stays in camera RGB (no colour matrix)" if raw.cfa else "")
        cal = _self_calibration(raw, progress)
    else:
        cal = _database_or_scene(raw, db, self_calibrate=self_calibrate, progress=progress)
    log.info("%s", cal.describe())
    return cal


def _database_or_scene(raw: RawCapture, db: Path | None, *, self_calibrate: bool, progress: Progress) -> Calibration:
    """The raw's own white image (Lytro ``modulationDataRef``), else the database's (``db``; None: none was given
    or found), else self-calibration."""
    from ..calib import store
    from ..calib.check import WhiteMismatchError

    name = Path(raw.path).name if raw.path else "this raw"
    try:
        own = _per_picture_white(raw)
    except WhiteMismatchError as exc:
        if not self_calibrate:
            raise
        log.info("%s", exc)
        own = None
    if own is not None:
        return own
    if db is not None and (db / store.INDEX_NAME).is_file():
        try:
            return _from_database(raw, db)
        except WhiteMismatchError as exc:  # its message already names the better choices
            if not self_calibrate:
                raise
            log.warning("%s: self-calibrating instead", exc)
        except CalibrationError as exc:
            if not self_calibrate:
                raise CalibrationError(f"{exc}; or pass --calibration grid.json, --white WHITE_IMAGE or "
                                       "--self-calibrate") from exc
            log.info("database %s: %s", db, exc)
    elif not self_calibrate:
        where = f"in {db} (no {store.INDEX_NAME})" if db is not None else \
            f"(looked for its {store.INDEX_NAME} in {store.where_looked(raw.path)})"
        raise CalibrationError(
            f"no calibration for {name} (camera {raw.metadata.model or '?'} {raw.metadata.serial or '?'}): "
            f"no calibration database {where}; {_how_to_calibrate(raw, db or Path(store.DEFAULT_DB))}")
    return _self_calibration(raw, progress)


def _how_to_calibrate(raw: RawCapture, db: Path) -> str:
    """The commands that give ``raw`` a calibration when the database ``db`` is missing: built from the white
    images beside the raw (Lytro ``MOD_NNNN.RAW``, one folder, not recursive) when there are some, else from
    a FOLDER of them; and the options that do without a database."""
    from ..calib.store import find_whites

    folder = Path(raw.path).parent if raw.path else None
    whites = [] if folder is None else find_whites(folder, recursive=False)
    if not whites:
        return (f"'plenodecode calibrate --database {db} FOLDER' makes one of the white images in FOLDER; pass "
                "--database DIR, --calibration grid.json, --white WHITE_IMAGE or --self-calibrate")
    names = ", ".join(w.name for w in whites)
    return (f"white images beside it ({names}): 'plenodecode calibrate --database {db} {folder}' builds the "
            f"database of them, or pass --white {whites[0]} (or --database DIR, --calibration grid.json, "
            "--self-calibrate)")


def _self_calibration(raw: RawCapture, progress: Progress) -> Calibration:
    from ..calib.selfcal import calibrate_from_scene

    name = Path(raw.path).name if raw.path else "this raw"
    return Calibration(calibrate_from_scene(raw, progress=progress), None, "self-calibration", f"from {name}")
