"""Step 1 of the workflow: what a path holds and opening it (raw, Raytrix image + XML, light field, HCI folder).

Part of :mod:`plenodecode.pipeline` (see its docstring for the five steps).
"""

from __future__ import annotations

import json
import logging
import os
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterator

from ..types import LINEAR_COLOUR_STATES, LightField, RawCapture

if TYPE_CHECKING:
    from ..io.mosaic_levels import MosaicOptions
    from ..optics import MicroscopeOptics

log = logging.getLogger(__name__)


Progress = Callable[[int, int], None] | None

#: Extensions of saved light fields (any other file is read as a raw).
LIGHTFIELD_EXTENSIONS = (".npy", ".mat", ".zarr")
#: Image types the rendering products are written as.
IMAGE_EXTENSIONS = ("png", "tif", "exr")
#: Bits per sample of image outputs (32 = float).
BIT_DEPTHS = (8, 16, 32)
#: Colour states that hold linear values (display-encoded when written, except as 32-bit float).
LINEAR_COLOURS = LINEAR_COLOUR_STATES


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
    from ..io.hci import read_hci

    log.info("reading HCI scene %s", p)
    return read_hci(p).lightfield


def _read_lightfield(p: Path) -> LightField:
    from ..io.lightfield import load_lightfield

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
    from ..io import raytrix, read_raw

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
    from ..io.microscope import optics_beside

    p = Path(path)
    raw = _read_raw(p, mosaic, raytrix_xml)
    beside = optics_beside(p)
    return with_optics(raw, beside.merged(optics) if beside is not None else optics)


@contextmanager
def quieted(logger: str) -> Iterator[None]:
    """Within the block, the logger ``logger`` shows errors only (its warnings would repeat or not apply)."""
    log_ = logging.getLogger(logger)
    level = log_.level
    log_.setLevel(logging.ERROR)
    try:
        yield
    finally:
        log_.setLevel(level)


def read_dark_frame(dark: str | os.PathLike | RawCapture | None,
                    mosaic: MosaicOptions | None = None, *, raw: RawCapture | None = None) -> RawCapture | None:
    """The dark frame (``--dark``), read like a raw; None for None.  :func:`plenodecode.decoding.decode`
    subtracts it pixel by pixel from the raw and the white image instead of the black level.  With ``raw``, a
    frame of another size is refused now (:class:`~plenodecode.errors.DarkFrameMismatchError`), before the
    calibration and the decoding.

    Its own black and white levels are not used, so the reader's warnings about them (a mosaic without a
    sidecar: levels estimated 'from the gaps between micro-images', which a dark frame has none of) are not
    shown; an unreadable file still raises.
    """
    if dark is None:
        return None
    if not isinstance(dark, RawCapture):
        log.info("dark frame %s", dark)
        with quieted("plenodecode.io.generic"):
            dark = _read_raw(Path(dark), mosaic)
    if raw is not None and dark.shape != raw.shape:
        from ..errors import DarkFrameMismatchError

        name = Path(dark.path).name if dark.path else "the dark frame"
        raise DarkFrameMismatchError(f"{name} is {dark.shape[1]} x {dark.shape[0]} px but the raw "
                                     f"{Path(raw.path).name if raw.path else ''} is {raw.shape[1]} x {raw.shape[0]}; "
                                     "pass the dark frame of this camera")
    if raw is not None:        # the check decode(dark=...) makes, before the calibration
        from ..decoding.decoder import refuse_bright_dark

        refuse_bright_dark(dark.mosaic, raw, Path(dark.path).name if dark.path else "the dark frame")
    return dark


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
