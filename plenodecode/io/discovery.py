"""Which files under some folders are raws: the input discovery of :func:`plenodecode.batch.run_batch`.

Reading only (headers and sidecars); nothing is written.
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path
from typing import Callable, Iterable

#: Suffixes always taken as raws when a folder is searched (Lytro containers, camera raws).
RAW_SUFFIXES = (".lfr", ".lfp", ".dng", ".cr2", ".cr3", ".nef", ".arw", ".raf", ".orf", ".rw2")
#: Headerless Lytro raws: taken when their JSON sidecar (.TXT/.json) is beside them.
PAIR_SUFFIXES = (".raw",)
#: Image mosaics: taken when a plenodecode mosaic sidecar or a Raytrix calibration XML is beside them, or, without
#: either, when the image has the size of a known lenslet sensor (:func:`plenodecode.io.generic.is_known_sensor_image`).
MOSAIC_SUFFIXES = (".png", ".tif", ".tiff", ".exr", ".pgm", ".jpg", ".jpeg")


def _mosaic_sidecar(p: Path) -> dict | None:
    """The plenodecode mosaic sidecar of image ``p`` (parsed), or None."""
    from . import generic

    side = generic.find_sidecar(p)
    if side is None:
        return None
    try:
        doc = json.loads(side.read_text(encoding="utf-8", errors="replace"))
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) and doc.get("format") == generic.SIDECAR_FORMAT else None


def _is_white_mosaic(doc: dict | None) -> bool:
    meta = None if doc is None else doc.get("metadata")
    return isinstance(meta, dict) and bool(meta.get("is_white_image"))


def _is_mosaic_with_sidecar(p: Path) -> bool:
    """An image with a plenodecode mosaic sidecar (not flagged as a white image) or a Raytrix XML."""
    from . import raytrix

    doc = _mosaic_sidecar(p)
    if doc is not None:
        return not _is_white_mosaic(doc)
    return raytrix.find_calibration_xml(p) is not None


def is_desktop_export(p: Path) -> bool:
    """True for a Lytro container (.lfp/.lfr) that holds no raw: a Lytro Desktop export (focal stack ``-stk.lfp``,
    depth map ``-dm.lfp``, living picture), whose items 'plenodecode extract' writes out.  Reads the section
    headers only; a file that is no container is not one (it fails for its own reason when decoded)."""
    if p.suffix.lower() not in (".lfp", ".lfr"):
        return False
    from ..errors import PlenodecodeError
    from .lytro.container import read_container

    # a probe of the headers: what they warn about (an odd container version) the raw's task says once
    container_log = logging.getLogger(read_container.__module__)
    level = container_log.level
    container_log.setLevel(logging.ERROR)
    try:
        return read_container(p, verify=False).kind == "processed"
    except (PlenodecodeError, OSError, ValueError):
        return False
    finally:
        container_log.setLevel(level)


def _is_raw_candidate(p: Path) -> bool:
    name = p.name
    if name.startswith(".") or name.upper().startswith("MOD_") or ".truth." in name.lower():
        return False      # hidden / staging files, white images, generator ground truth
    suffix = p.suffix.lower()
    if suffix in RAW_SUFFIXES:
        # a Lytro library keeps IMG_0001-stk.lfp and -dm.lfp beside the raw IMG_0001.lfp: not raws
        return not is_desktop_export(p)
    if suffix in PAIR_SUFFIXES:
        from . import lytro

        return lytro.find_sidecar(p) is not None
    if suffix in MOSAIC_SUFFIXES:
        from .generic import find_sidecar, is_known_sensor_image

        return _is_mosaic_with_sidecar(p) or (find_sidecar(p) is None and is_known_sensor_image(p))
    return False


def needs_no_database(p: Path) -> bool:
    """True for a raw never looked up in the calibration database: an image mosaic with a Raytrix XML beside
    it (the camera's own calibration) or with neither that nor a sidecar (self-calibrated); also a Lytro
    container that holds no raw (a Desktop export, or not a container at all: it fails for its own reason)."""
    from . import generic, raytrix

    if p.suffix.lower() in (".lfp", ".lfr"):
        from ..errors import PlenodecodeError
        from .lytro.container import read_container

        try:
            return read_container(p, verify=False).kind != "raw"
        except (PlenodecodeError, OSError, ValueError):
            return True
    if p.suffix.lower() not in MOSAIC_SUFFIXES:
        return False
    return raytrix.find_calibration_xml(p) is not None or generic.find_sidecar(p) is None


def _walk(folder: Path, exclude: set[Path], stop_marker: str | None,
          take: Callable[[Path], bool] = _is_raw_candidate) -> list[Path]:
    """The files under ``folder`` that ``take`` accepts (default: raw candidates); skips hidden folders,
    ``exclude`` and folders holding ``stop_marker``."""
    found: list[Path] = []
    for root, dirs, files in os.walk(folder):
        here = Path(root)
        if stop_marker is not None and stop_marker in files:     # e.g. a batch output folder: no inputs in it
            dirs[:] = []
            continue
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and (here / d).resolve() not in exclude)
        found.extend(here / f for f in sorted(files) if take(here / f))
    return found


def one_or_many(inputs: str | os.PathLike | Iterable[str | os.PathLike]) -> list[str | os.PathLike]:
    """``inputs`` as a list of paths: one path (``'shoot/'``, not its characters, which would be searched
    from '/') or an iterable of them."""
    return [inputs] if isinstance(inputs, (str, bytes, os.PathLike)) else list(inputs)


def find_raws(inputs: Iterable[str | os.PathLike], *, exclude: Iterable[str | os.PathLike] = (),
              stop_marker: str | None = None) -> list[Path]:
    """Every raw file under ``inputs``.

    Files are taken as given.  Folders are searched recursively for Lytro containers
    (``.lfr``/``.lfp``), camera raws and DNG, headerless ``.raw`` files with their JSON sidecar,
    image mosaics with a plenodecode sidecar or a Raytrix XML, and images without a sidecar only when
    their size is that of a known lenslet sensor (3280 x 3280 Lytro F01, 7728 x 5368 Illum; read from the
    header), so a folder of ordinary pictures yields nothing; any other sidecar-less mosaic is decoded
    when named as a file.  Skipped: Lytro Desktop exports (:func:`is_desktop_export`; one named as a file
    is taken and fails, naming 'plenodecode extract'), white images
    (``MOD_*``, or a mosaic whose sidecar says ``is_white_image``), the synthetic generator's ground
    truth (``*.truth.*``), sidecars, hidden files and folders, folders in ``exclude`` (e.g. the
    batch's own output folder) and folders holding ``stop_marker``.

    Parameters
    ----------
    inputs : path-like or iterable of path-like
    exclude : iterable of path-like
        Folders not to search.
    stop_marker : str, optional
        A file name that marks a folder as an output folder: neither it nor its sub-folders are searched.

    Returns
    -------
    list of Path
        In the order of ``inputs``, each folder's files sorted; duplicates removed.
    """
    skip = {Path(e).resolve() for e in exclude}
    found: list[Path] = []
    for item in one_or_many(inputs):
        p = Path(item)
        if p.is_dir():
            if p.resolve() not in skip:
                found.extend(_walk(p, skip, stop_marker))
        else:
            found.append(p)
    seen: set[Path] = set()
    unique = []
    for f in found:
        r = f.resolve()
        if r not in seen:
            seen.add(r)
            unique.append(f)
    return unique


def images_not_taken(inputs: Iterable[str | os.PathLike], *, exclude: Iterable[str | os.PathLike] = (),
                     stop_marker: str | None = None, taken: Iterable[str | os.PathLike] | None = None) -> list[Path]:
    """Images (:data:`MOSAIC_SUFFIXES`) in the folders among ``inputs`` that :func:`find_raws` with the same
    ``exclude`` and ``stop_marker`` does not take (no sidecar, not a known sensor's size): what to name when a
    folder yields no raw; white images that their sidecar flags as such are skipped on purpose, not listed.
    Each folder's files sorted.  ``taken``: what that :func:`find_raws` returned, so that
    no image's header, sidecar or Raytrix XML is looked up a second time."""
    found = None if taken is None else {Path(f).resolve() for f in taken}

    def not_taken(p: Path) -> bool:
        if p.name.startswith(".") or p.suffix.lower() not in MOSAIC_SUFFIXES:
            return False
        missed = not _is_raw_candidate(p) if found is None else p.resolve() not in found
        return missed and not _is_white_mosaic(_mosaic_sidecar(p))

    return _in_folders(inputs, exclude, stop_marker, not_taken)


def desktop_exports_not_taken(inputs: Iterable[str | os.PathLike], *, exclude: Iterable[str | os.PathLike] = (),
                              stop_marker: str | None = None) -> list[Path]:
    """The Lytro Desktop exports (:func:`is_desktop_export`) in the folders among ``inputs`` that :func:`find_raws`
    with the same ``exclude`` and ``stop_marker`` passes over; each folder's files sorted."""
    return _in_folders(inputs, exclude, stop_marker, lambda p: not p.name.startswith(".") and is_desktop_export(p))


def raws_without_metadata(inputs: Iterable[str | os.PathLike], *, exclude: Iterable[str | os.PathLike] = (),
                          stop_marker: str | None = None) -> list[Path]:
    """Headerless Lytro raws (:data:`PAIR_SUFFIXES`, not white images ``MOD_*``) in the folders among ``inputs``
    that :func:`find_raws` passes over because their metadata (``.TXT`` / ``.json``) is not beside them; each
    folder's files sorted."""
    from . import lytro

    def lone(p: Path) -> bool:
        return (p.suffix.lower() in PAIR_SUFFIXES and not p.name.startswith(".")
                and not p.name.upper().startswith("MOD_") and lytro.find_sidecar(p) is None)

    return _in_folders(inputs, exclude, stop_marker, lone)


def _in_folders(inputs: Iterable[str | os.PathLike], exclude: Iterable[str | os.PathLike], stop_marker: str | None,
                take: Callable[[Path], bool]) -> list[Path]:
    """The files ``take`` accepts in the folders among ``inputs`` (one path or several), searched as
    :func:`find_raws` searches them (``exclude``, ``stop_marker``); each folder's files sorted."""
    skip = {Path(e).resolve() for e in exclude}
    return [f for item in one_or_many(inputs) if Path(item).is_dir() and Path(item).resolve() not in skip
            for f in _walk(Path(item), skip, stop_marker, take=take)]


__all__ = ["RAW_SUFFIXES", "PAIR_SUFFIXES", "MOSAIC_SUFFIXES", "find_raws", "needs_no_database", "images_not_taken",
           "is_desktop_export", "desktop_exports_not_taken", "raws_without_metadata"]
