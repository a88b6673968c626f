"""Readers and writers.  :func:`read_raw` picks the reader from the file's content.

Only this subpackage, ``report``, ``batch`` and ``cli`` touch the disk.
"""

from __future__ import annotations

import os
from pathlib import Path

from typing import TYPE_CHECKING

from ..errors import FormatError
from ..types import RawCapture

if TYPE_CHECKING:
    from .mosaic_levels import MosaicOptions

#: First bytes of a Lytro LFP/LFR container.
LYTRO_MAGIC = b"\x89LFP\r\n\x1a\n"
#: Extensions of headerless Lytro white images / raws that come with a JSON .TXT/.json sidecar.
LYTRO_PAIR_EXTENSIONS = (".raw",)


def read_raw(path: str | os.PathLike, *, mosaic: MosaicOptions | None = None) -> RawCapture:
    """Read any supported raw file into a :class:`RawCapture`.

    Dispatch: an archive member path ``ARCHIVE::MEMBER`` (a ``MOD_NNNN.RAW`` inside an Illum
    ``caldata-<serial>.tar`` or F01 ``data.C.N``, read in place by
    :func:`plenodecode.io.lytro.archive.read_member_raw`); Lytro container by magic
    (``.lfp``/``.lfr`` of any case); a headerless
    ``.RAW`` with a ``.TXT``/``.json`` metadata sidecar (Lytro white images and frames);
    a PNG/TIFF/BMP with a ``RayCalibData`` XML beside it (Raytrix); other images (PNG, TIFF,
    JPEG, EXR, PGM), with or without a JSON sidecar, as mosaics; anything else through rawpy
    (DNG, camera raws).

    ``mosaic`` (:class:`~plenodecode.io.mosaic_levels.MosaicOptions`: CFA, levels, value encoding)
    applies to image mosaics (:func:`plenodecode.io.generic.read_generic`); the other readers take
    what their files say.

    Raises
    ------
    FormatError
        The file is missing, of no supported kind, or malformed.
    """
    p = Path(path)
    if not p.is_file():
        from .lytro.archive import read_member_raw, split_member_path

        if split_member_path(path) is not None:  # 'ARCHIVE::MEMBER', a white image inside a calibration archive
            return read_member_raw(path)
        raise FormatError(f"{p}: is a folder; read_raw reads one raw file (the folder's raws: "
                          "plenodecode.io.discovery.find_raws)" if p.is_dir() else f"{p}: no such file")
    with open(p, "rb") as fh:
        head = fh.read(8)
    from . import lytro

    if head == LYTRO_MAGIC:
        return lytro.read_lytro(p)
    if p.suffix.lower() in LYTRO_PAIR_EXTENSIONS and lytro.find_sidecar(p) is not None:
        return lytro.read_raw_pair(p)
    if p.suffix.lower() in (".lfp", ".lfr"):
        # a Lytro name without the container's magic: say that, not what LibRaw makes of it
        raise FormatError(f"{p}: not a Lytro container (it does not start with the LFP signature): the file is "
                          "damaged or not a Lytro file")
    from . import generic, raytrix

    if raytrix.find_calibration_xml(p) is not None:
        return raytrix.read_raytrix(p)
    if p.suffix.lower() not in LYTRO_PAIR_EXTENSIONS:
        return generic.read_generic(p, mosaic=mosaic)
    try:        # some camera raws are named .RAW too
        return generic.read_generic(p, mosaic=mosaic)
    except FormatError:
        raise FormatError(f"{p}: a headerless Lytro raw (a white image MOD_NNNN.RAW or a frame) is read with its "
                          f"metadata beside it, {p.stem}.TXT or {p.stem}.json, which is missing (nor is it a camera "
                          "raw LibRaw reads); copy the metadata file next to it") from None


__all__ = ["read_raw", "LYTRO_MAGIC"]
