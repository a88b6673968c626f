"""Loading any input of the rendering and depth commands as a :class:`~plenodecode.types.LightField`.

An input is a saved light field (zarr store, views folder with ``lightfield.json``, ``.npy``, ``.mat``,
ESLF image with its JSON), an HCI benchmark scene folder (``input_Cam*.png`` + ``parameters.cfg``), or a raw
(anything :func:`plenodecode.io.read_raw` reads), which is decoded with its lenslet grid: from
``--calibration grid.json``, from ``--white WHITE`` (calibrated on the spot and used for devignetting), or
from the calibration database ``--white-dir`` (default ``calib/``).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Callable

import click

from ..types import LightField

log = logging.getLogger(__name__)

#: Extensions of saved light fields (anything else that is a file is read as a raw).
LIGHTFIELD_EXTENSIONS = (".npy", ".mat", ".zarr")
#: Default calibration database folder (relative to the working directory).
DEFAULT_DB = "calib"


def input_options(fn):
    """The options every command taking RAW_OR_LF shares (``--white-dir``, ``--calibration``, ``--white``)."""
    fn = click.option("--white", "white", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
                      help="White image of the same zoom/focus: calibrate from it and devignet (raws only).")(fn)
    fn = click.option("--calibration", "calibration", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                      default=None, help="Lenslet grid JSON written by 'plenodecode calibrate' (raws only).")(fn)
    fn = click.option("--white-dir", "white_dir", type=click.Path(file_okay=False, path_type=Path), default=None,
                      help=f"Calibration database folder for raws (default: ./{DEFAULT_DB}).")(fn)
    return fn


def _is_hci_folder(p: Path) -> bool:
    return p.is_dir() and not (p / "lightfield.json").exists() and not (p / "zarr.json").exists() \
        and any(p.glob("input_Cam*.png"))


def is_lightfield_path(path: str | os.PathLike) -> bool:
    """True when ``path`` is a saved light field or an HCI folder rather than a raw."""
    p = Path(path)
    if p.is_dir():
        return True
    if p.suffix.lower() in LIGHTFIELD_EXTENSIONS:
        return True
    # an ESLF mosaic is a PNG/TIFF whose JSON sidecar says format "plenodecode.eslf"
    if p.suffix.lower() in (".png", ".tif", ".tiff"):
        side = p.with_suffix(".json")
        if side.is_file():
            import json

            try:
                doc = json.loads(side.read_text())
            except (OSError, ValueError):
                return False
            return isinstance(doc, dict) and doc.get("format") == "plenodecode.eslf"
    return False


def load_input(path: str | os.PathLike, *, white_dir: str | os.PathLike | None = None,
               calibration: str | os.PathLike | None = None, white: str | os.PathLike | None = None,
               progress: Callable[[int, int], None] | None = None) -> LightField:
    """Read a light field, an HCI scene, or decode a raw.

    Parameters
    ----------
    path : path-like
        Saved light field (zarr / views folder / .npy / .mat / ESLF), HCI scene folder, or raw file.
    white_dir : path-like, optional
        Calibration database (raws only; default ``./calib``).
    calibration : path-like, optional
        Lenslet grid JSON (raws only); wins over the database.
    white : path-like, optional
        White image (raws only): the grid is calibrated from it and it devignets the raw.
    progress : callable(done, total), optional
        Progress of the decoding.

    Returns
    -------
    LightField

    Raises
    ------
    FormatError, CalibrationError, DecodeError
        Unreadable input, no calibration for the raw's camera, or a failed decode.
    """
    p = Path(path)
    if _is_hci_folder(p):
        from ..io.hci import read_hci

        log.info("reading HCI scene %s", p)
        return read_hci(p).lightfield
    if is_lightfield_path(p):
        from ..io.lightfield import load_lightfield

        log.info("reading light field %s", p)
        return load_lightfield(p)
    return _decode_raw(p, white_dir=white_dir, calibration=calibration, white=white, progress=progress)


def _decode_raw(p: Path, *, white_dir, calibration, white, progress) -> LightField:
    from ..decoding import decode
    from ..io import read_raw

    raw = read_raw(p)
    grid, white_cap = resolve_calibration(raw, calibration=calibration, white=white, white_dir=white_dir)
    log.info("decoding %s", p)
    return decode(raw, grid, white=white_cap, progress=progress)


def resolve_calibration(raw, *, calibration=None, white=None, white_dir=None):
    """The lenslet grid and white image for ``raw`` from the shared command options.

    ``--calibration grid.json`` gives the grid (``--white`` then only devignettes); ``--white`` alone is
    calibrated on the spot; otherwise the database (``--white-dir``, default ``./calib``) picks the white of
    the raw's camera and its cached grid.

    Returns
    -------
    (LensletGrid, RawCapture or None)

    Raises
    ------
    CalibrationError
        Nothing usable; the message says which option to pass.
    """
    from ..errors import CalibrationError
    from ..io import read_raw
    from ..types import LensletGrid

    white_cap = read_raw(white) if white is not None else None
    if calibration is not None:
        try:
            text = Path(calibration).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise CalibrationError(f"{calibration}: cannot read the lenslet grid ({exc}); pass a grid written by "
                                   "'plenodecode calibrate'") from exc
        return LensletGrid.from_json(text), white_cap
    if white_cap is not None:
        from ..calib import calibrate

        return calibrate(white_cap), white_cap
    from ..calib import store

    db = Path(white_dir) if white_dir is not None else Path(store.DEFAULT_DB)
    name = Path(raw.path).name if raw.path else "this raw"
    if not (db / store.INDEX_NAME).is_file():
        raise CalibrationError(
            f"no calibration for {name} (camera {raw.metadata.model or '?'} {raw.metadata.serial or '?'}): "
            f"no calibration database in {db}; pass --white-dir DATABASE, --calibration grid.json or "
            "--white WHITE_IMAGE")
    try:
        return store.calibration_for(raw, db)
    except CalibrationError as exc:
        raise CalibrationError(f"{exc}; or pass --calibration grid.json or --white WHITE_IMAGE") from exc


# ----------------------------------------------------------------------------------------------------------
# outputs shared by the rendering commands
# ----------------------------------------------------------------------------------------------------------
#: Refocus method names for click.Choice (kept equal to plenodecode.render.REFOCUS_METHODS by a test; listed
#: here so that --help does not import numba).
METHOD_NAMES = ("shift-sum", "fourier-slice")
#: Image extensions the rendering commands write.
IMAGE_EXTENSIONS = ("png", "tif", "exr")


def needs_display_encoding(lf: LightField) -> bool:
    """Linear light fields ('linear-srgb', 'camera') get the sRGB transfer function at export; 'srgb' not."""
    return lf.colour != "srgb"


def save_image(path: Path, image, *, lf: LightField, bit_depth: int, overwrite: bool) -> Path:
    """Write one rendered image through :func:`plenodecode.io.images.write_image` (display-encoded when the
    light field is linear, except for 32-bit float outputs, which stay linear)."""
    from ..io.images import write_image

    encode = needs_display_encoding(lf) and int(bit_depth) != 32
    try:
        return write_image(path, image, bit_depth=int(bit_depth), overwrite=overwrite, encode_srgb=encode)
    except FileExistsError as exc:
        raise click.UsageError(f"{exc}; pass --overwrite") from exc
    except ValueError as exc:
        raise click.UsageError(str(exc)) from exc


def write_json(path: Path, doc, *, overwrite: bool) -> Path:
    """Write a small JSON document atomically (see :mod:`plenodecode.io.atomic`)."""
    import json

    from ..io.atomic import write_text_atomic

    if path.exists() and not overwrite:
        raise click.UsageError(f"{path} exists; pass --overwrite to replace it")
    return write_text_atomic(path, json.dumps(doc, indent=1), overwrite=overwrite)


def prepare_folder(folder: Path, names: list[str], overwrite: bool) -> None:
    """Create ``folder``; refuse (usage error) if any of ``names`` already exists in it without ``overwrite``."""
    if folder.exists() and not folder.is_dir():
        raise click.UsageError(f"{folder} exists and is not a folder")
    if not overwrite:
        clash = [n for n in names if (folder / n).exists()]
        if clash:
            raise click.UsageError(f"{folder / clash[0]} exists; pass --overwrite to replace it")
    folder.mkdir(parents=True, exist_ok=True)
