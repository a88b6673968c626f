"""Calibration archives as the cameras write them, filled with generated white images.

:func:`write_calibration_archive` packs white images (``MOD_NNNN.RAW`` + ``.TXT`` pairs) into

* ``'illum-tar'``: the Illum backup ``caldata-<serial>.tar``, its files in a ``<serial>/`` folder
  (``layout='serial'``) or a ``unitdata/`` folder (``layout='unitdata'``), with a ``MOD_NNNN.GCT`` per
  white image and the ``cal_file_manifest.json`` that lists each GCT's SHA-1;
* ``'f01-datac'``: the F01 volumes ``data.C.0``, ``data.C.1``, ... (Lytro containers, one LFC per
  file, the TOC naming ``C:\\T1CALIB\\MOD_NNNN.RAW``/``.TXT`` and the next volume).

A generated picture names its white image the way an Illum does when written with
``write_lfr(..., geometry_correction=archive.geometry_corrections[k])``.  The bytes are built here;
:mod:`plenodecode.io.lytro.archive` writes the files.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..types import RawCapture

#: Archive kinds :func:`write_calibration_archive` writes.
ARCHIVE_KINDS = ("illum-tar", "f01-datac")
#: Folder layouts of the Illum tar (``formats.md`` §3).
TAR_LAYOUTS = ("serial", "unitdata")


@dataclass(frozen=True)
class WrittenArchive:
    """What :func:`write_calibration_archive` wrote.

    Attributes
    ----------
    paths : tuple of Path
        The tar file, or the data.C volumes in chain order.
    whites : tuple of str
        The archive member path (``ARCHIVE::MEMBER``) of each white image, in input order.
    geometry_corrections : tuple of bytes or None
        The GCT bytes of each white image (Illum tar), None for the F01 (no GCT).
    """

    paths: tuple[Path, ...]
    whites: tuple[str, ...]
    geometry_corrections: tuple[bytes | None, ...]


def archive_name(kind: str, serial: str | None) -> str:
    """The file the camera writes: ``caldata-<serial>.tar`` (Illum) or the first volume ``data.C.0`` (F01)."""
    if kind not in ARCHIVE_KINDS:
        raise ValueError(f"kind must be one of {ARCHIVE_KINDS}, got {kind!r}")
    return f"caldata-{serial or 'unknown'}.tar" if kind == "illum-tar" else "data.C.0"


def geometry_correction_bytes(white: RawCapture, index: int) -> bytes:
    """A stand-in ``MOD_NNNN.GCT`` for a white image: unique per camera, zoom/focus step and index.

    Real GCT files hold the camera's geometry correction; only their SHA-1 matters here (the picture's
    ``geometryCorrectionRef`` and the manifest's ``hash``).
    """
    md = white.metadata
    doc = {"generator": "plenodecode.synthetic", "serial": md.serial, "zoom_step": md.zoom_step,
           "focus_step": md.focus_step, "index": int(index)}
    return b"GCT\x00" + json.dumps(doc, sort_keys=True).encode("ascii")


def write_calibration_archive(whites: Sequence[RawCapture | object], path: str | os.PathLike, *,
                              kind: str = "illum-tar", layout: str = "serial", files_per_volume: int = 4,
                              overwrite: bool = False) -> WrittenArchive:
    """Write white images into a calibration archive of a camera (see the module docstring).

    Parameters
    ----------
    whites : sequence of RawCapture or Simulation
        White images (a Simulation gives its ``white``), of one camera; white ``k`` becomes
        ``MOD_{k:04d}``.
    path : path-like
        The tar file to write (``'illum-tar'``), or the folder of the ``data.C.N`` volumes (``'f01-datac'``).
    kind : 'illum-tar' or 'f01-datac'
    layout : 'serial' or 'unitdata'
        Folder inside the Illum tar: ``<serial>/`` or ``unitdata/``.
    files_per_volume : int
        F01: files per ``data.C.N`` volume (a RAW and its TXT may land in two volumes).
    overwrite : bool

    Returns
    -------
    WrittenArchive
    """
    from ..io.lytro.archive import MEMBER_SEPARATOR, write_caldata_tar, write_datac_volumes
    from ..io.lytro.container import section_name
    from ..io.lytro.rawpair import raw_pair_bytes

    if kind not in ARCHIVE_KINDS:
        raise ValueError(f"kind must be one of {ARCHIVE_KINDS}, got {kind!r}")
    if layout not in TAR_LAYOUTS:
        raise ValueError(f"layout must be one of {TAR_LAYOUTS}, got {layout!r}")
    raws = [w if isinstance(w, RawCapture) else getattr(w, "white", None) for w in whites]
    if not raws or not all(isinstance(r, RawCapture) for r in raws):
        raise ValueError("whites must be a non-empty sequence of RawCapture white images (or Simulations)")
    pairs = [raw_pair_bytes(r) for r in raws]
    if kind == "f01-datac":
        files = []
        for k, (data, text) in enumerate(pairs):
            files += [(f"C:\\T1CALIB\\MOD_{k:04d}.RAW", data), (f"C:\\T1CALIB\\MOD_{k:04d}.TXT", text)]
        paths = write_datac_volumes(path, files, files_per_volume=files_per_volume, overwrite=overwrite)
        members = tuple(f"{paths[0]}{MEMBER_SEPARATOR}T1CALIB/MOD_{k:04d}.RAW" for k in range(len(raws)))
        return WrittenArchive(tuple(paths), members, (None,) * len(raws))
    folder = str(raws[0].metadata.serial or "unknown") if layout == "serial" else "unitdata"
    gcts = tuple(geometry_correction_bytes(r, k) for k, r in enumerate(raws))
    manifest = {"calibrationFiles": [{"name": f"MOD_{k:04d}.GCT", "hash": section_name(g)}
                                     for k, g in enumerate(gcts)]}
    content: dict[str, bytes] = {f"{folder}/cal_file_manifest.json": json.dumps(manifest, indent=1).encode()}
    for k, ((data, text), gct) in enumerate(zip(pairs, gcts)):
        content[f"{folder}/MOD_{k:04d}.RAW"] = data
        content[f"{folder}/MOD_{k:04d}.TXT"] = text
        content[f"{folder}/MOD_{k:04d}.GCT"] = gct
    tar = write_caldata_tar(path, content, overwrite=overwrite)
    members = tuple(f"{tar}{MEMBER_SEPARATOR}{folder}/MOD_{k:04d}.RAW" for k in range(len(raws)))
    return WrittenArchive((tar,), members, gcts)


__all__ = ["ARCHIVE_KINDS", "TAR_LAYOUTS", "WrittenArchive", "archive_name", "geometry_correction_bytes",
           "write_calibration_archive"]
