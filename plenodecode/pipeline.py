"""The workflow both front ends use: open any input, choose the calibration, decode, render a product, write it.

The command line (:mod:`plenodecode.cli`), :mod:`plenodecode.batch` and Python callers go through the same
five steps, each implemented once here::

    open_input(path)          raw file (Lytro container, raw + sidecar, Raytrix image + XML, camera raw, mosaic
                              + sidecar) -> RawCapture; saved light field or HCI scene folder -> LightField
    choose_calibration(raw)   explicit grid JSON / white image > the camera's own calibration (Raytrix XML)
                              > the calibration database > self-calibration from the scene (when allowed);
                              the choice is logged in one info line
    Source                    an opened input; a raw is decoded on first use of ``Source.lightfield``
    render_product(src, name) a product of :data:`PRODUCTS` (centre, views, refocus, focal-stack, all-in-focus,
                              parallax, depth, total-focus, focused-refocus) -> :class:`Rendered`
    write_product(r, output)  display encoding, bit depth, file names, atomic rename, overwrite checks

Display encoding (one rule, :func:`display_encoding`): images of a linear light field (colour state
'camera' or 'linear-srgb') get the sRGB transfer function, except 32-bit float outputs, which stay linear;
'srgb' images are written as they are.

Importing this module is light (no numba, OpenCV or OpenImageIO): the CLI reads its registries for
``click.Choice`` lists.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterator, Mapping, Sequence

from .errors import CalibrationError
from .registry import lazy, lookup
from .types import LensletGrid, LightField, RawCapture

if TYPE_CHECKING:
    from .io.mosaic_levels import MosaicOptions
    from .optics import MicroscopeOptics

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None] | None

#: Extensions of saved light fields (any other file is read as a raw).
LIGHTFIELD_EXTENSIONS = (".npy", ".mat", ".zarr")
#: Image types the rendering products are written as.
IMAGE_EXTENSIONS = ("png", "tif", "exr")
#: Bits per sample of image outputs (32 = float).
BIT_DEPTHS = (8, 16, 32)
#: Colour states that hold linear values (display-encoded when written, except as 32-bit float).
LINEAR_COLOURS = ("camera", "linear-srgb")


# ------------------------------------------------------------------------------------------------- inputs
def is_hci_folder(path: str | os.PathLike) -> bool:
    """True for an HCI benchmark scene folder (``input_Cam*.png`` views, not a saved views light field)."""
    p = Path(path)
    return p.is_dir() and not (p / "lightfield.json").exists() and not (p / "zarr.json").exists() \
        and any(p.glob("input_Cam*.png"))


def _is_eslf_image(p: Path) -> bool:
    """A PNG/TIFF whose JSON sidecar says format 'plenodecode.eslf' (a saved ESLF mosaic)."""
    side = p.with_suffix(".json")
    if p.suffix.lower() not in (".png", ".tif", ".tiff") or not side.is_file():
        return False
    try:
        doc = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and doc.get("format") == "plenodecode.eslf"


def input_kind(path: str | os.PathLike) -> str:
    """What ``path`` holds: a key of :data:`INPUT_READERS` ('hci', 'lightfield' or 'raw').

    Folders are HCI scenes or saved light fields (zarr store, views folder); ``.npy``, ``.mat``, ``.zarr``
    and ESLF images with their JSON are saved light fields; any other file is a raw.
    """
    p = Path(path)
    if is_hci_folder(p):
        return "hci"
    if p.is_dir() or p.suffix.lower() in LIGHTFIELD_EXTENSIONS or _is_eslf_image(p):
        return "lightfield"
    return "raw"


def is_lightfield_path(path: str | os.PathLike) -> bool:
    """True when ``path`` is a saved light field or an HCI folder rather than a raw."""
    return input_kind(path) != "raw"


def _read_hci(p: Path) -> LightField:
    from .io.hci import read_hci

    log.info("reading HCI scene %s", p)
    return read_hci(p).lightfield


def _read_lightfield(p: Path) -> LightField:
    from .io.lightfield import load_lightfield

    log.info("reading light field %s", p)
    return load_lightfield(p)


def with_optics(item: LightField | RawCapture, optics: MicroscopeOptics | None) -> LightField | RawCapture:
    """``item`` carrying the microscope optics ``optics`` (merged over those it has: given values win)."""
    from dataclasses import replace

    if optics is None or optics.empty:
        return item
    if isinstance(item, LightField):
        have = item.geometry.microscope
        return item.replace(geometry=replace(item.geometry, microscope=have.merged(optics) if have else optics))
    have = item.metadata.microscope
    return replace(item, metadata=replace(item.metadata, microscope=have.merged(optics) if have else optics))


def _read_raw(p: Path, mosaic: MosaicOptions | None = None, raytrix_xml: str | os.PathLike | None = None
              ) -> RawCapture:
    """:func:`plenodecode.io.read_raw`, or a Raytrix image with ``raytrix_xml`` or the RayCalibData XML
    :func:`plenodecode.io.raytrix.calibration_xml_for` finds beside it (same stem, or the only one in the folder)."""
    from .io import raytrix, read_raw

    xml = raytrix.calibration_xml_for(p, raytrix_xml) if p.is_file() else None
    if xml is not None:
        return raytrix.read_raytrix(p, xml=xml)
    return read_raw(p, mosaic=mosaic)


def open_raw(path: str | os.PathLike, *, mosaic: MosaicOptions | None = None,
             raytrix_xml: str | os.PathLike | None = None, optics: MicroscopeOptics | None = None) -> RawCapture:
    """Read a raw: :func:`plenodecode.io.read_raw`, a Raytrix image with its RayCalibData XML (``raytrix_xml``,
    else the one beside it), and the optics of a light-field microscope: those of a napari-LF ``metadata.txt``
    beside it (:func:`plenodecode.io.microscope.optics_beside`), overridden value by value by ``optics`` (the
    command line's ``--magnification``, ``--optics FILE``, ...).

    Raises
    ------
    MetadataError
        ``raytrix_xml`` is no RayCalibData, or several XMLs beside the image and none of its stem.
    FormatError
        Unreadable raw.
    """
    from .io.microscope import optics_beside

    p = Path(path)
    raw = _read_raw(p, mosaic, raytrix_xml)
    beside = optics_beside(p)
    return with_optics(raw, beside.merged(optics) if beside is not None else optics)


def read_dark_frame(dark: str | os.PathLike | RawCapture | None,
                    mosaic: MosaicOptions | None = None) -> RawCapture | None:
    """The dark frame (``--dark``), read like a raw; None for None.  :func:`plenodecode.decoding.decode`
    subtracts it pixel by pixel from the raw and the white image instead of the black level."""
    if dark is None or isinstance(dark, RawCapture):
        return dark
    log.info("dark frame %s", dark)
    return _read_raw(Path(dark), mosaic)


#: Input kind -> reader ``fn(path) -> LightField | RawCapture``.
INPUT_READERS: dict[str, Callable[[Path], LightField | RawCapture]] = {
    "hci": _read_hci, "lightfield": _read_lightfield, "raw": open_raw,
}


def open_input(path: str | os.PathLike, *, mosaic: MosaicOptions | None = None,
               raytrix_xml: str | os.PathLike | None = None, optics: MicroscopeOptics | None = None
               ) -> LightField | RawCapture:
    """Read any supported input.

    Parameters
    ----------
    path : path-like
        A raw (anything :func:`plenodecode.io.read_raw` reads: Lytro containers, ``.RAW`` + ``.TXT``, Raytrix
        image + ``RayCalibData`` XML, DNG / camera raws, image mosaics (JPEG/PNG/TIFF) with or without a JSON
        sidecar), a saved light field (:func:`plenodecode.io.lightfield.load_lightfield`) or an HCI scene folder
        with its ``parameters.cfg``.
    mosaic : MosaicOptions, optional
        How to read an image mosaic (CFA, levels, value encoding); raws only.
    raytrix_xml : path-like, optional
        The RayCalibData XML of a Raytrix image, when it is not the one beside it (:func:`open_raw`).
    optics : MicroscopeOptics, optional
        Light-field microscope optics given by the caller; they win over a ``metadata.txt`` beside a raw
        (:func:`open_raw`) and over those a saved light field carries.

    Returns
    -------
    RawCapture or LightField

    Raises
    ------
    FormatError
        Unreadable input.
    """
    p = Path(path)
    kind = input_kind(p)
    if kind == "raw":
        return open_raw(p, mosaic=mosaic, raytrix_xml=raytrix_xml, optics=optics)
    return with_optics(INPUT_READERS[kind](p), optics)


# -------------------------------------------------------------------------------------------- calibration
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


def _grid_from_file(path: str | os.PathLike) -> LensletGrid:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"{path}: cannot read the lenslet grid ({exc}); pass a grid written by "
                               "'plenodecode calibrate'") from exc
    return LensletGrid.from_json(text)


def _from_database(raw: RawCapture, db: Path) -> Calibration:
    """The database's white image for ``raw`` and its grid, refused when it does not fit the raw
    (:func:`plenodecode.calib.check.check_white_fit`, naming the camera's other white images)."""
    from .calib import store
    from .calib.check import check_white_fit

    entry = store.select_white(db, raw)
    cached = entry.grid is not None and (db / entry.grid).is_file()
    grid, white = store.calibration_for(raw, db)
    others = [f"{Path(e.file).name} at zoom {e.zoom_step:g} focus {e.focus_step:g}"
              if e.zoom_step is not None and e.focus_step is not None else Path(e.file).name
              for e in store.other_whites(db, raw, entry)]
    check_white_fit(raw, grid, white, white_name=f"{Path(entry.file).name} of {db}/", alternatives=others)
    return Calibration(grid, white, "database",
                       f"{db}/ (white {Path(entry.file).name}, {'cached grid' if cached else 'grid fitted now'})")


def _per_picture_white(raw: RawCapture) -> Calibration | None:
    """A Lytro Desktop raw LFP's own white image (``modulationDataRef``), calibrated and checked; None without one."""
    from .io.lytro import frame_ref, read_modulation_white

    if not raw.path or frame_ref(raw.metadata, "modulationDataRef") is None:
        return None
    from .calib import calibrate
    from .calib.check import check_white_fit

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
    3. the camera's own calibration: a Raytrix raw's ``RayCalibData`` (:func:`~plenodecode.calib.selfcal.calibrate_raytrix`);
    4. a Lytro raw LFP's own white image (``modulationDataRef``), else the calibration database ``database``
       (default :data:`plenodecode.calib.store.DEFAULT_DB`): the white image the raw's ``geometryCorrectionRef``
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
    from .calib import store
    from .io.generic import is_bare_mosaic

    white_raw = open_raw(white, mosaic=mosaic) if isinstance(white, (str, os.PathLike)) else white
    db = Path(database) if database is not None else Path(store.DEFAULT_DB)
    if grid is not None:
        cal = Calibration(_grid_from_file(grid), white_raw, "grid file",
                          str(grid) + (f" (white {Path(white_raw.path or '?').name})" if white_raw else ""))
    elif white_raw is not None:
        from .calib import calibrate
        from .calib.check import check_white_fit

        cal = Calibration(calibrate(white_raw, progress=progress), white_raw, "white image",
                          Path(white_raw.path or "?").name)
        check_white_fit(raw, cal.grid, white_raw)  # a scene given as its white, or another lattice: refused
    elif "raytrix" in raw.metadata.extra:
        from .calib.selfcal import calibrate_raytrix

        cal = Calibration(calibrate_raytrix(raw), None, "camera", "(Raytrix RayCalibData)")
    elif is_bare_mosaic(raw):
        log.warning("%s: no white image and no camera identity for the database: the lenslet grid comes from "
                    "self-calibration of the scene", Path(raw.path or "mosaic").name)
        cal = _self_calibration(raw, progress)
    else:
        cal = _database_or_scene(raw, db, self_calibrate=self_calibrate, progress=progress)
    log.info("%s", cal.describe())
    return cal


def _database_or_scene(raw: RawCapture, db: Path, *, self_calibrate: bool, progress: Progress) -> Calibration:
    """The raw's own white image (Lytro ``modulationDataRef``), else the database's, else self-calibration."""
    from .calib import store
    from .calib.check import WhiteMismatchError

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
    if (db / store.INDEX_NAME).is_file():
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
        raise CalibrationError(
            f"no calibration for {name} (camera {raw.metadata.model or '?'} {raw.metadata.serial or '?'}): "
            f"no calibration database in {db}; pass --database DIR, --calibration grid.json, "
            "--white WHITE_IMAGE or --self-calibrate")
    return _self_calibration(raw, progress)


def _self_calibration(raw: RawCapture, progress: Progress) -> Calibration:
    from .calib.selfcal import calibrate_from_scene

    name = Path(raw.path).name if raw.path else "this raw"
    return Calibration(calibrate_from_scene(raw, progress=progress), None, "self-calibration", f"from {name}")


# ------------------------------------------------------------------------------------------------ decoding
class Source:
    """An opened input, ready for rendering: a light field, or a raw with its calibration.

    A raw is decoded on the first use of :attr:`lightfield` (once); products that render from the raw itself
    (:func:`render_total_focus`) never decode it.

    Parameters
    ----------
    lightfield : LightField, optional
        An input that is already a light field.
    raw : RawCapture, optional
        A raw; needs ``calibration``.
    calibration : Calibration, optional
    decode_options : mapping, optional
        Keywords of :func:`plenodecode.decoding.decode` (``demosaic``, ``colour``, ``n_views``, ``dark``,
        ``hot_pixels``, ``workers``).
    progress : callable(done, total), optional
        Progress of the decoding.
    """

    def __init__(self, *, lightfield: LightField | None = None, raw: RawCapture | None = None,
                 calibration: Calibration | None = None, decode_options: Mapping[str, Any] | None = None,
                 progress: Progress = None) -> None:
        if (lightfield is None) == (raw is None):
            raise ValueError("pass exactly one of lightfield and raw")
        if raw is not None and calibration is None:
            raise ValueError("a raw needs its calibration")
        self.raw = raw
        self.calibration = calibration
        self.decode_options = dict(decode_options or {})
        self.progress = progress
        if lightfield is not None:
            self.__dict__["lightfield"] = lightfield

    @cached_property
    def lightfield(self) -> LightField:
        """The light field (V, U, Y, X, C) float32: the input itself, or the raw decoded."""
        return decode_raw(self.raw, self.calibration, progress=self.progress, **self.decode_options)

    @property
    def focused(self) -> bool:
        """True for a focused-plenoptic (Raytrix) raw: a grid with lens types."""
        return self.raw is not None and self.calibration.grid.lens_type is not None


def decode_raw(raw: RawCapture, calibration: Calibration, *, progress: Progress = None,
               **decode_options: Any) -> LightField:
    """Decode ``raw`` with ``calibration`` (:func:`plenodecode.decoding.decode`; devignetted by its white).
    A Raytrix RGB export is decoded channel by channel from its linear sRGB values (colour 'linear-srgb').

    Returns
    -------
    LightField
        ``data`` (V, U, Y, X, C) float32.
    """
    from .decoding import decode
    from .io.raytrix import is_rgb_export, rgb_export_channels

    log.info("decoding %s", raw.path)
    if not is_rgb_export(raw):
        return decode(raw, calibration.grid, white=calibration.white, progress=progress, **decode_options)
    # a Raytrix RGB export (already demosaiced, sRGB): its linear channels decoded one by one, stacked as C = 3
    import numpy as np

    white = calibration.white
    whites = rgb_export_channels(white) if white is not None and is_rgb_export(white) else [white] * 3
    planes = [decode(plane, calibration.grid, white=w, progress=progress, **decode_options)
              for plane, w in zip(rgb_export_channels(raw), whites)]
    state = "camera" if decode_options.get("colour") == "camera" else "linear-srgb"
    return planes[0].replace(data=np.concatenate([lf.data for lf in planes], axis=-1), colour=state)


def open_source(path: str | os.PathLike, *, grid: str | os.PathLike | None = None,
                white: str | os.PathLike | None = None, database: str | os.PathLike | None = None,
                self_calibrate: bool = False, mosaic: MosaicOptions | None = None,
                raytrix_xml: str | os.PathLike | None = None,
                dark: str | os.PathLike | RawCapture | None = None, optics: MicroscopeOptics | None = None,
                decode_options: Mapping[str, Any] | None = None, progress: Progress = None) -> Source:
    """:func:`open_input`, then for a raw :func:`choose_calibration`; the decoding waits for first use.

    The calibration, ``mosaic``, ``raytrix_xml`` and ``dark`` (a dark frame, :func:`read_dark_frame`, handed to
    the decoding) options apply to raws only; ``optics`` to every input (:func:`open_input`).
    """
    item = open_input(path, mosaic=mosaic, raytrix_xml=raytrix_xml, optics=optics)
    if isinstance(item, LightField):
        return Source(lightfield=item)
    cal = choose_calibration(item, grid=grid, white=white, database=database, self_calibrate=self_calibrate,
                             mosaic=mosaic)
    options = dict(decode_options or {})
    if dark is not None:
        options["dark"] = read_dark_frame(dark, mosaic)
    return Source(raw=item, calibration=cal, decode_options=options, progress=progress)


def load_lightfield_input(path: str | os.PathLike, **options: Any) -> LightField:
    """The light field of any input: read, or decoded (options of :func:`open_source`)."""
    return open_source(path, **options).lightfield


# ------------------------------------------------------------------------------------------------ products
@dataclass(frozen=True)
class Rendered:
    """A rendered product, before writing.

    Attributes
    ----------
    product : str
        Its key in :data:`PRODUCTS`.
    images : tuple of (str, ndarray)
        File stem and image (H, W, C) float32 of every image; one for single-image products.
    colour : str
        Colour state of the images ('camera', 'linear-srgb' or 'srgb'); decides the display encoding.
    folder : bool
        The product is a folder of images (and ``documents``), not one file.
    documents : tuple of (str, callable)
        JSON files written beside the images: file name and ``fn(ext) -> mapping``, the content given the
        image type the images are written as (documents list the image files).
    data : mapping
        Other results (depth map, animation frames, slopes, ...).
    """

    product: str
    images: tuple[tuple[str, Any], ...]
    colour: str
    folder: bool = False
    documents: tuple[tuple[str, Callable[[str], Mapping[str, Any]]], ...] = ()
    data: Mapping[str, Any] = field(default_factory=dict)

    def file_names(self, ext: str) -> list[str]:
        """The names written into a folder product: images ``<stem>.<ext>``, then the documents."""
        return [f"{stem}.{ext}" for stem, _ in self.images] + [name for name, _ in self.documents]


def render_centre(src: Source) -> Rendered:
    """The centre view ``(V // 2, U // 2)``, image (Y, X, C)."""
    lf = src.lightfield
    return Rendered("centre", (("centre", lf.centre_view()),), lf.colour)


def view_names(shape: Sequence[int]) -> list[str]:
    """File stems of all views of a light field of ``shape`` (V, U, ...): ``view_VV_UU``."""
    return [f"view_{v:02d}_{u:02d}" for v in range(shape[0]) for u in range(shape[1])]


def render_views(src: Source, *, view: tuple[float, float] | None = None, interp: str = "linear") -> Rendered:
    """Every sub-aperture view (a folder of ``view_VV_UU`` images), or with ``view=(v, u)`` the perspective view
    at that (fractional) position (:func:`plenodecode.render.perspective`, ``interp`` 'linear' or 'cubic')."""
    lf = src.lightfield
    if view is not None:
        from .render import perspective

        return Rendered("views", (("view", perspective(lf, view[0], view[1], interp=interp)),), lf.colour)
    nu = lf.shape[1]
    images = tuple((name, lf.data[i // nu, i % nu]) for i, name in enumerate(view_names(lf.shape)))
    return Rendered("views", images, lf.colour, folder=True)


def refocus_stem(*, slope: float | None = None, alpha: float | None = None) -> str:
    """File stem of a refocused photograph: ``refocus_s+0.30`` (slope) or ``refocus_a1.020`` (alpha)."""
    return f"refocus_s{slope:+.2f}" if slope is not None else f"refocus_a{alpha:.3f}"


def render_refocus(src: Source, *, slope: float | None = None, alpha: float | None = None,
                   at: tuple[float, float] | None = None, distance_m: float | None = None, at_method: str = "depth",
                   method: str = "shift-sum", aperture: float = 1.0, upsample: int = 1) -> Rendered:
    """One photograph focused by one of ``slope``, ``alpha``, ``at = (y, x)``, ``distance_m`` (:func:`~plenodecode.
    render.refocus_methods.focus_slope`); outside :func:`~plenodecode.render.alpha.refocus_range_units` it is
    still rendered, with a one-line warning.  ``data``: 'slope' (chosen), 'alpha', 'method', 'aperture', 'range'."""
    from .render import refocus, refocus_range_units
    from .render.refocus_methods import focus_slope

    lf = src.lightfield
    chosen = focus_slope(lf, slope=slope, alpha=alpha, at=at, distance_m=distance_m, at_method=at_method)
    span = refocus_range_units(lf)
    if not span.contains(chosen):
        log.warning("slope %.3g px/view%s is outside the refocusable range (%s): nothing in it can be sharp",
                    chosen, "" if alpha is None else f" (alpha {alpha:g})", span.describe())
    img = refocus(lf, slope=chosen, method=method, aperture=aperture, upsample=upsample)
    stem = refocus_stem(alpha=alpha) if alpha is not None else refocus_stem(slope=chosen)
    return Rendered("refocus", ((stem, img),), lf.colour,
                    data={"slope": chosen, "alpha": alpha, "method": method, "aperture": aperture, "range": span})


def focal_stack_names(n: int, ext: str) -> list[str]:
    """Files of a focal stack of ``n`` slices: ``slice_000.<ext>`` ..., ``all_in_focus.<ext>``, the JSON."""
    return [f"slice_{i:03d}.{ext}" for i in range(n)] + [f"all_in_focus.{ext}", "focal_stack.json"]


def _slopes_as_given(values: Any, lf: LightField) -> Any:
    return values


#: Most slices of one focal stack (a larger count is refused before any work).
MAX_STACK_SLICES = 512

#: Units of a focal stack's START and STOP -> ``fn(values, lf) -> slopes`` (px per view step).
STACK_UNITS: dict[str, Callable[..., Any]] = {
    "slope": _slopes_as_given,
    "alpha": lazy("plenodecode.render.alpha", "alpha_to_slope"),
}


def render_focal_stack(src: Source, *, start: float, stop: float, n: int, units: str = "slope",
                       method: str = "shift-sum", aperture: float = 1.0, upsample: int = 1,
                       progress: Progress = None) -> Rendered:
    """``n`` photographs from ``start`` to ``stop`` (slopes, or alphas with ``units='alpha'``), the all-in-focus
    image made from them, and ``focal_stack.json`` (slopes, alphas, method, file names).

    The all-in-focus image renders every pixel at the slope of its sharpest slice
    (:func:`~plenodecode.render.allinfocus.all_in_focus_from_stack`): it reuses the stack, where the
    depth-guided default of the 'all-in-focus' product estimates depth first (a full-size
    15 x 15 x 434 x 625 light field: 10 s, against 1 s from the stack; bench_allinfocus).
    """
    import numpy as np

    from .render import focal_stack, slope_to_alpha
    from .render.allinfocus import all_in_focus_from_stack

    if not 2 <= int(n) <= MAX_STACK_SLICES:
        raise ValueError(f"a focal stack has 2 to {MAX_STACK_SLICES} slices, got {n}")
    lf = src.lightfield
    slopes = lookup(STACK_UNITS, units, param="units")(np.linspace(start, stop, n), lf)
    imgs = focal_stack(lf, slopes, method=method, aperture=aperture, upsample=upsample, progress=progress)
    aif = all_in_focus_from_stack(lf, imgs, np.asarray(slopes), aperture=aperture)
    try:
        alphas = [float(a) for a in slope_to_alpha(np.asarray(slopes), lf)]
    except Exception:  # noqa: BLE001 - alphas are informative only; the camera may not be known
        alphas = None
    stems = [f"slice_{i:03d}" for i in range(n)]

    def document(ext: str) -> dict[str, Any]:
        return {"slopes": [float(s) for s in slopes], "alphas": alphas, "method": method, "aperture": aperture,
                "files": [f"{s}.{ext}" for s in stems], "all_in_focus": f"all_in_focus.{ext}"}

    return Rendered("focal-stack", (*zip(stems, imgs), ("all_in_focus", aif)), lf.colour, folder=True,
                    documents=(("focal_stack.json", document),), data={"slopes": slopes})


def render_all_in_focus(src: Source, *, method: str = "depth", slopes: Sequence[float] | None = None,
                        aperture: float = 1.0, progress: Progress = None, **options: Any) -> Rendered:
    """An image sharp everywhere (:func:`plenodecode.render.all_in_focus`): by default every pixel at the
    disparity of the 'fast' depth estimate, from the views that see it; ``method='focal-stack'`` (with
    ``slopes``, default the light field's) the sharpest slice of a focal stack.  ``options`` are the method's
    (``depth_method``, ``refocus_method``, ...)."""
    from .render import all_in_focus

    lf = src.lightfield
    img = all_in_focus(lf, method=method, slopes=slopes, aperture=aperture, progress=progress, **options)
    return Rendered("all-in-focus", (("all_in_focus", img),), lf.colour)


def parallax_frame_names(n: int, ext: str = "png") -> list[str]:
    """Files of the ``n`` numbered frames of a parallax product: ``frame_000.<ext>`` ..."""
    return [f"frame_{i:03d}.{ext}" for i in range(n)]


def render_parallax(src: Source, *, frames: int = 24, radius: float | None = None, interp: str = "linear",
                    progress: Progress = None) -> Rendered:
    """Perspective views along a circle of viewpoints (:func:`plenodecode.render.render_parallax`): the
    numbered frames ``frame_000`` ... and, in ``data['animation']``, the (N, Y, X, 3) frames of the animation."""
    from .render import render_parallax as parallax

    lf = src.lightfield
    out = parallax(lf, frames, radius, interp=interp, progress=progress)
    anim = out if out.shape[-1] == 3 else out.repeat(3, axis=-1)
    stems = [Path(name).stem for name in parallax_frame_names(len(out))]
    return Rendered("parallax", tuple(zip(stems, out)), lf.colour, folder=True,
                    data={"animation": anim})


def render_depth(src: Source, *, method: str | None = None, disparity_range: tuple[float, float] | None = None,
                 metric: bool = False, points: bool = False, focus_distance: float | None = None,
                 progress: Progress = None) -> Rendered:
    """Disparity of the centre view (:func:`plenodecode.depth.estimate_depth`), px per view step; with ``metric``
    also depth in metres (micrometres from the native object plane for a light-field microscope,
    :func:`plenodecode.depth.metric.depth_unit`), with ``points`` the 3-D point of every pixel and its display
    colour.

    ``data``: 'depthmap' (DepthMap), 'values' (Y, X) float32 (depth in 'unit' with ``metric``, else disparity),
    'unit', 'label', and with ``points`` 'points' (Y, X, 3) in 'unit' and 'colours' (Y, X, 3) uint8.
    """
    from .depth import DEFAULT_METHOD, disparity_to_depth, estimate_depth
    from .depth.metric import depth_constants, depth_to_points, depth_unit

    lf = src.lightfield
    method = method or DEFAULT_METHOD
    overrides = {} if focus_distance is None else {"focus_distance_m": focus_distance}
    unit, scale = depth_unit(lf, **overrides)      # micrometres for a light-field microscope, else metres
    if metric or points:
        depth_constants(lf, **overrides)    # fail before the estimate when the camera geometry is missing
    kw = {} if disparity_range is None else {"disparity_range": disparity_range}
    dm = estimate_depth(lf, method=method, progress=progress, **kw)
    depth = disparity_to_depth(dm, lf, **overrides) if (metric or points) else None
    data: dict[str, Any] = {"depthmap": dm, "method": method, "unit": unit if metric else "px / view step",
                            "values": depth * scale if metric else dm.disparity,
                            "label": f"depth ({unit})" if metric else "disparity (px / view step)"}
    if points:
        from .io.depthio import display_colours

        data["points"] = depth_to_points(depth, lf, **overrides) * scale
        data["colours"] = display_colours(lf.centre_view(), lf.colour)
    return Rendered("depth", (), lf.colour, data=data)


def check_total_focus_patch(grid: LensletGrid, patch: Any) -> None:
    """Raise ValueError naming ``patch`` unless it is None or every value lies in ``(0, 2 * grid.radius)`` px:
    a patch is cut from one micro-image, so it is smaller than the micro-image diameter."""
    import numpy as np

    if patch is None:
        return
    p, hi = np.asarray(patch, np.float64), 2.0 * float(grid.radius)
    if not (np.all(np.isfinite(p)) and np.all(p > 0) and np.all(p < hi)):
        raise ValueError(f"patch must lie in (0, {hi:.1f}) px (0 < P < the micro-image diameter), got "
                         f"{patch if p.ndim == 0 else 'an array outside it'}; P = lens pitch / virtual depth")


def _focused_input(src: Source, what: str) -> tuple[Any, Any, str]:
    """What a focused-plenoptic renderer reads: ``(image, white, colour state)``.

    A Raytrix RGB export (:func:`plenodecode.io.raytrix.is_rgb_export`: its RawCapture holds the luminance)
    is read again in colour, linear sRGB (:func:`~plenodecode.io.raytrix.read_raytrix_linear_rgb`), and so is
    its white image when that is an export too (else the white's normalised mosaic divides every channel);
    any other raw is rendered from its mosaic (demosaiced within the micro-images), in camera RGB.
    ``src`` holds a raw; ``what`` names the product in the warning for a grid without lens types.
    """
    if not src.focused:
        log.warning("the lenslet grid of %s has no lens types: %s expects a focused-plenoptic raw",
                    src.raw.path or "the raw", what)
    from .io.raytrix import is_rgb_export, read_raytrix_linear_rgb

    white = src.calibration.white
    if not is_rgb_export(src.raw):
        return src.raw, white, "camera"
    if white is not None:
        from .decoding.devignette import normalise

        white = read_raytrix_linear_rgb(white.path) if is_rgb_export(white) else \
            normalise(white.mosaic, white.black, white.white)
    return read_raytrix_linear_rgb(src.raw.path), white, "linear-srgb"


def _camera_to_srgb(image: Any, state: str, raw: RawCapture, colour: str) -> tuple[Any, str]:
    """A focused rendering in camera RGB converted as the decoder does, ``srgb = CCM @ diag(gains) @ camera``
    (:func:`plenodecode.decoding.colour.colour_matrix`), when ``colour='linear-srgb'`` and the metadata has a CCM."""
    from .decoding.colour import apply_matrix, colour_matrix

    if image.shape[-1] != 3 or state != "camera" or colour != "linear-srgb":
        return image, state
    matrix = colour_matrix(raw.metadata)
    if matrix is None:
        log.warning("the raw's metadata has no colour matrix (ccm): the focused rendering stays in camera RGB")
        return image, state
    return apply_matrix(image, matrix), "linear-srgb"


def _check_colour(colour: str) -> None:
    from .decoding.colour import DECODE_COLOURS

    if colour not in DECODE_COLOURS:
        raise ValueError(f"colour must be one of {DECODE_COLOURS}, got {colour!r}")


def render_total_focus(src: Source, *, patch: float | Any | None = None, sharpness: float = 2.0,
                       colour: str = "linear-srgb", progress: Progress = None) -> Rendered:
    """All-in-focus rendering of a focused-plenoptic (Raytrix) raw from its micro-images
    (:func:`plenodecode.decoding.focused.render_total_focus`), devignetted by the calibration's white.

    A colour raw (a CFA, demosaiced within each micro-image) is rendered in camera RGB and, with
    ``colour='linear-srgb'``, converted as the decoder does: ``srgb = CCM @ diag(gains) @ camera``
    (:func:`plenodecode.decoding.colour.colour_matrix`); without a CCM in the metadata it stays 'camera'.
    A Raytrix RGB export is rendered from its colour image, linear sRGB (:func:`_focused_input`).

    Parameters
    ----------
    src : Source
        A raw with its calibration.
    patch : float or ndarray (rows, cols), optional
        Patch size P per lens, px (lens pitch / virtual depth); default estimated per lens.
    sharpness : float
        Exponent of the per-lens focus weight (0: plain blending).
    colour : {'linear-srgb', 'camera'}
    progress : callable(done, total), optional

    Returns
    -------
    Rendered
        One image ``total_focus`` (Ho, Wo, C) float32, C = 3 for a colour raw; ``data['render']`` the
        :class:`~plenodecode.decoding.focused.FocusedRender` (patch sizes, focus, scale).

    Raises
    ------
    ValueError
        The input is not a raw (a light field has no micro-images); ``patch`` out of range
        (:func:`check_total_focus_patch`); an unknown ``colour``.
    """
    if src.raw is None:
        raise ValueError("total-focus renders a focused-plenoptic raw; the input is a light field")
    check_total_focus_patch(src.calibration.grid, patch)
    _check_colour(colour)
    image, white, state = _focused_input(src, "total focus")
    from .decoding.focused import render_total_focus as total_focus

    res = total_focus(image, src.calibration.grid, patch=patch, white=white, sharpness=sharpness, progress=progress)
    out, state = _camera_to_srgb(res.image, state, src.raw, colour)
    return Rendered("total-focus", (("total_focus", out),), state, data={"render": res})


def virtual_depth_stem(virtual_depth: float) -> str:
    """File stem of a focused raw refocused at a virtual depth: ``refocus_v2.50``."""
    return f"refocus_v{virtual_depth:.2f}"


def render_focused_refocus(src: Source, *, virtual_depth: float, colour: str = "linear-srgb") -> Rendered:
    """A focused-plenoptic (Raytrix) raw refocused at ``virtual_depth``
    (:func:`plenodecode.decoding.focused.render_at_virtual_depth`: patches of ``lens pitch / virtual_depth`` px,
    the lens types in focus there weighted most), in colour as :func:`render_total_focus`.

    Returns
    -------
    Rendered
        One image ``refocus_v<V>`` (Ho, Wo, C) float32; ``data['render']`` the FocusedRender.

    Raises
    ------
    ValueError
        A light-field input; ``virtual_depth`` outside the camera's range
        (:func:`plenodecode.decoding.focused.check_virtual_depth`); an unknown ``colour``.
    """
    from .decoding.focused import check_virtual_depth, render_at_virtual_depth

    if src.raw is None:
        raise ValueError("a refocus at a virtual depth renders a focused-plenoptic raw; the input is a light field")
    check_virtual_depth(src.calibration.grid, virtual_depth)
    _check_colour(colour)
    image, white, state = _focused_input(src, "a refocus at a virtual depth")
    res = render_at_virtual_depth(image, src.calibration.grid, virtual_depth, white=white)
    out, state = _camera_to_srgb(res.image, state, src.raw, colour)
    return Rendered("focused-refocus", ((virtual_depth_stem(virtual_depth), out),), state,
                    data={"render": res, "virtual_depth": virtual_depth})


#: Product name -> ``fn(source, **options) -> Rendered``; the same names in the CLI, batch and Python.
PRODUCTS: dict[str, Callable[..., Rendered]] = {
    "centre": render_centre,
    "views": render_views,
    "refocus": render_refocus,
    "focal-stack": render_focal_stack,
    "all-in-focus": render_all_in_focus,
    "parallax": render_parallax,
    "depth": render_depth,
    "total-focus": render_total_focus,
    "focused-refocus": render_focused_refocus,
}


def render_product(src: Source, name: str, **options: Any) -> Rendered:
    """Render the product ``name`` (a key of :data:`PRODUCTS`) of ``src`` with its ``options``."""
    return lookup(PRODUCTS, name, param="product")(src, **options)


# ------------------------------------------------------------------------------------------------- writing
def display_encoding(colour: str, bit_depth: int) -> bool:
    """Whether an image of colour state ``colour`` gets the sRGB transfer function when written at
    ``bit_depth``: linear states ('camera', 'linear-srgb') do, except 32-bit float outputs."""
    return colour in LINEAR_COLOURS and int(bit_depth) != 32


def default_extension(bit_depth: int) -> str:
    """Image type of a product written without an explicit one: 'exr' for 32-bit float, else 'png'."""
    return "exr" if int(bit_depth) == 32 else "png"


def write_image_file(path: str | os.PathLike, image: Any, *, colour: str, bit_depth: int,
                     overwrite: bool = False) -> Path:
    """Write one rendered image (:func:`plenodecode.io.images.write_image`, atomic) with :func:`display_encoding`.

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    ValueError
        A bit depth the image type cannot hold.
    """
    from .io import images

    return images.write_image(path, image, bit_depth=int(bit_depth), overwrite=overwrite,
                              encode_srgb=display_encoding(colour, bit_depth))


def refuse_folder_clash(folder: str | os.PathLike, names: Sequence[str], overwrite: bool) -> None:
    """Check a folder output before any work: ``folder`` is a folder (or absent) and, unless ``overwrite``,
    none of ``names`` exists in it.  Creates nothing.

    Raises
    ------
    FileExistsError
        A clash; or ``folder`` is a file.
    """
    from .io.atomic import refuse_existing

    p = Path(folder)
    if p.exists() and not p.is_dir():
        raise FileExistsError(f"{p} exists and is not a folder")
    if p.is_dir():
        refuse_existing([p / n for n in names], overwrite)


@contextlib.contextmanager
def staged_folder(folder: str | os.PathLike, names: Sequence[str], *, overwrite: bool = False) -> Iterator[Path]:
    """Context manager for the files ``names`` of a folder output: write them into the yielded staging folder;
    they appear under ``folder`` together on normal exit, and on an exception nothing is left.

    A missing ``folder`` is staged whole and renamed into place (so a failed run leaves no empty folder); into
    an existing one the files are renamed one by one, other files in it are kept.

    Raises
    ------
    FileExistsError
        See :func:`refuse_folder_clash` (checked on entry, before anything is created).
    """
    from .io.atomic import atomic_output, commit, discard, temporary_sibling

    p = Path(folder)
    refuse_folder_clash(p, names, overwrite)
    if not p.exists():
        with atomic_output(p, folder=True) as tmp:
            yield tmp
        return
    stage = temporary_sibling(p / "staging", folder=True)
    created: list[Path] = []
    try:
        yield stage
        refuse_folder_clash(p, names, overwrite)
        for name in names:
            existed = os.path.lexists(p / name)
            commit(stage / name, p / name)
            if not existed:
                created.append(p / name)
    except BaseException:
        for f in created:      # a rename failed half-way: do not leave an incomplete set behind
            discard(f)
        raise
    finally:
        discard(stage)


def write_product(rendered: Rendered, output: str | os.PathLike, *, bit_depth: int = 16, ext: str | None = None,
                  overwrite: bool = False, progress: Progress = None) -> list[Path]:
    """Write the images and documents of a product: one image file ``output``, or the folder ``output``.

    Parameters
    ----------
    rendered : Rendered
        An image product (not 'depth': :func:`write_depth`).
    output : path-like
        The image file (its extension gives the type), or the folder of a folder product.
    bit_depth : {8, 16, 32}
    ext : str, optional
        Image type of a folder product's files (default :func:`default_extension`).
    overwrite : bool
    progress : callable(done, total), optional
        After every image of a folder product.

    Returns
    -------
    list of Path
        The written file, or the folder's files.
    """
    out = Path(output)
    if not rendered.folder:
        (_, image), = rendered.images
        return [write_image_file(out, image, colour=rendered.colour, bit_depth=bit_depth, overwrite=overwrite)]
    from .io.atomic import write_text_atomic

    ext = ext or default_extension(bit_depth)
    names = rendered.file_names(ext)
    with staged_folder(out, names, overwrite=overwrite) as stage:
        for i, (name, (_, image)) in enumerate(zip(names, rendered.images)):
            write_image_file(stage / name, image, colour=rendered.colour, bit_depth=bit_depth)
            if progress is not None:
                progress(i + 1, len(rendered.images))
        for name, document in rendered.documents:
            write_text_atomic(stage / name, json.dumps(document(ext), indent=1))
    return [out / n for n in names]


def write_parallax(rendered: Rendered, animation: str | os.PathLike, *, fps: float,
                   frames_dir: str | os.PathLike | None = None, bit_depth: int = 16,
                   overwrite: bool = False) -> list[Path]:
    """Write a parallax product: the animation (.gif / .webp) and, with ``frames_dir``, its numbered frames
    (``frame_000.png`` ...).  Both or neither: the frames folder is committed after the animation is written."""
    from .io import images

    def write_animation() -> Path:
        return images.write_animation(animation, rendered.data["animation"], fps=fps, overwrite=overwrite,
                                      encode_srgb=rendered.colour in LINEAR_COLOURS)

    if frames_dir is None:
        return [write_animation()]
    names = rendered.file_names("png")
    with staged_folder(frames_dir, names, overwrite=overwrite) as stage:
        for name, (_, frame) in zip(names, rendered.images):
            write_image_file(stage / name, frame, colour=rendered.colour, bit_depth=bit_depth)
        written = [write_animation()]
    return written + [Path(frames_dir) / n for n in names]


def write_depth(rendered: Rendered, pfm_path: str | os.PathLike, *, ply: str | os.PathLike | None = None,
                title: str | None = None, full: bool = True, overwrite: bool = False) -> list[Path]:
    """Write a depth product: ``X.pfm`` (the values, float32), and with ``full`` ``X.exr`` and a colour-mapped
    ``X.png`` (:func:`plenodecode.io.depthio.write_depth_outputs`), plus a PLY point cloud with ``ply``."""
    values = rendered.data["values"]
    if not full:
        from .io.pfm import write_pfm

        return [write_pfm(pfm_path, values, overwrite=overwrite)]
    from .io.depthio import write_depth_outputs

    return write_depth_outputs(pfm_path, values, label=rendered.data["label"], points=rendered.data.get("points"),
                               colours=rendered.data.get("colours"), ply=ply, title=title, overwrite=overwrite)


def write_lightfield(lf: LightField, path: str | os.PathLike, *, format: str | None = None, bit_depth: int = 16,
                     display: bool = False, overwrite: bool = False, progress: Progress = None) -> Path:
    """Save a light field (:func:`plenodecode.io.lightfield.save_lightfield`, atomic).

    ``display=True`` applies :func:`display_encoding` (for image formats meant for viewing, e.g. the views of a
    batch); otherwise the data are stored as they are (linear).
    """
    from .io.lightfield import save_lightfield

    return Path(save_lightfield(lf, path, format=format, bit_depth=int(bit_depth), overwrite=overwrite,
                                progress=progress, encode_srgb=display and display_encoding(lf.colour, bit_depth)))


__all__ = ["LIGHTFIELD_EXTENSIONS", "IMAGE_EXTENSIONS", "BIT_DEPTHS", "MAX_STACK_SLICES", "INPUT_READERS", "PRODUCTS", "STACK_UNITS", "Calibration", "Source",
           "Rendered", "input_kind", "is_hci_folder", "is_lightfield_path", "open_input", "choose_calibration",
           "decode_raw", "open_raw", "open_source", "with_optics", "read_dark_frame", "virtual_depth_stem",
           "load_lightfield_input", "render_product", "check_total_focus_patch",
           "display_encoding", "default_extension", "write_image_file", "refuse_folder_clash", "staged_folder", "write_product",
           "write_parallax", "write_depth", "write_lightfield", "view_names", "refocus_stem", "focal_stack_names",
           "parallax_frame_names"]
