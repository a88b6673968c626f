"""Headerless Lytro raws with a JSON sidecar: ``MOD_NNNN.RAW`` + ``.TXT`` white images, ``X__frame.raw`` + ``.json``."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ...errors import FormatError
from ...types import CameraMetadata, RawCapture
from .. import packing
from ..atomic import atomic_outputs, refuse_existing
from .container import map_file
from .fields import parse_json
from .metadata import packed_size_or_error, tags_entry, lytro_metadata, metadata_from_lytro

#: Known sensors: packed size in bytes -> (height, width, bits, endianness).
KNOWN_SENSORS = {
    packing.packed_size(3280, 3280, 12): (3280, 3280, 12, "big"),      # F01
    packing.packed_size(5368, 7728, 10): (5368, 7728, 10, "little"),   # Illum
}


def find_sidecar(path: str | os.PathLike) -> Path | None:
    """The JSON metadata file that belongs to a headerless Lytro raw.

    ``X.RAW`` -> ``X.TXT``, ``X.txt``, ``X.json`` or ``X.JSON`` (first that exists);
    this also covers ``IMG_0001__frame.raw`` -> ``IMG_0001__frame.json``.

    Returns
    -------
    Path or None
    """
    p = Path(path)
    for ext in (".TXT", ".txt", ".json", ".JSON"):
        cand = p.with_suffix(ext)
        if cand != p and cand.is_file():
            return cand
    return None


def read_sidecar(side: Path) -> Any:
    """The JSON document of a sidecar (a TXT may have trailing bytes after its last ``}``).

    Raises
    ------
    FormatError
        Unreadable file, or no valid JSON up to the last ``}``.
    """
    try:
        raw = side.read_bytes()
    except OSError as exc:
        raise FormatError(f"{side}: cannot read the metadata sidecar: {exc.strerror}") from None
    return sidecar_document(raw, str(side))


def sidecar_document(raw: bytes, where: str) -> Any:
    """The JSON document in a sidecar's bytes, cut at the last ``}`` (a camera TXT may have trailing bytes).

    Parameters
    ----------
    raw : bytes
        The whole sidecar file (from disk or from a calibration-archive member).
    where : str
        Names the sidecar in error messages.

    Raises
    ------
    FormatError
        No ``}``, or no valid JSON up to it.
    """
    end = raw.rfind(b"}")  # a TXT may have trailing bytes after the final '}'
    if end < 0:
        raise FormatError(f"{where}: expected a JSON object, found no '}}'; the metadata file is damaged")
    return parse_json(raw[:end + 1], f"{where}: the metadata sidecar")


def read_raw_pair_metadata(path: str | os.PathLike,
                           ) -> tuple[CameraMetadata, str, np.ndarray, np.ndarray, int, int, int, str]:
    """Metadata of a headerless raw + sidecar pair, checked against the raw's file size.

    Returns the same tuple as :func:`metadata_from_lytro`; width, height and packing come
    from the sidecar, or, when it lacks them, from the file size of a known sensor
    (F01 3280 x 3280 12 bit, Illum 7728 x 5368 10 bit).

    Raises
    ------
    FormatError
        No sidecar, unparsable sidecar, or a raw whose size disagrees with the metadata.
    """
    p = Path(path)
    if not p.is_file():
        raise FormatError(f"{p}: no such file")
    side = find_sidecar(p)
    if side is None:
        raise FormatError(f"{p}: no metadata sidecar ({p.stem}.TXT, .txt or .json) beside the raw; put the "
                          "camera's JSON next to it")
    private = _private_beside(p)
    return pair_metadata(read_sidecar(side), p.stat().st_size, str(p), str(side), private=private)


def _private_beside(raw: Path) -> Mapping[str, Any] | None:
    """The private metadata 'plenodecode extract' writes beside a container's raw (``frame.raw`` ->
    ``frame_private.json``: the camera's serial), or None."""
    side = raw.with_name(f"{raw.stem}_private.json")
    if not side.is_file():
        return None
    doc = read_sidecar(side)
    return doc if isinstance(doc, Mapping) else None


def pair_metadata(doc: Any, size: int, raw_where: str, side_where: str, *,
                  private: Mapping[str, Any] | None = None,
                  ) -> tuple[CameraMetadata, str, np.ndarray, np.ndarray, int, int, int, str]:
    """:func:`metadata_from_lytro` of a sidecar document, checked against the raw's size in bytes.

    Width, height and packing come from the sidecar or, when it lacks them, from the size of a
    known sensor (:data:`KNOWN_SENSORS`).  Shared by files on disk and calibration-archive members.

    Parameters
    ----------
    doc : object
        The parsed sidecar (:func:`sidecar_document`).
    size : int
        Bytes of the headerless raw.
    raw_where, side_where : str
        The raw's and the sidecar's paths, for messages.
    private : dict, optional
        The frame's private metadata (camera serial), when it is a file of its own.

    Raises
    ------
    FormatError
        Not a JSON object, or a raw whose size disagrees with the metadata.
    """
    if not isinstance(doc, Mapping):
        raise FormatError(f"{side_where}: expected a JSON object, found {type(doc).__name__}")
    default = KNOWN_SENSORS[size][:2] if size in KNOWN_SENSORS else None
    result = metadata_from_lytro(doc, private, side_where, default_size=default)
    _, _, _, _, w, h, bits, _ = result
    expected = packed_size_or_error(h, w, bits, raw_where)
    if size != expected:
        raise FormatError(f"{raw_where}: the raw is {size} bytes but {Path(side_where).name} declares {w} x {h} at {bits} bit = "
                          f"{expected} bytes; the pair does not match or the raw is truncated")
    return result


def raw_from_buffer(buf: Any, layout: tuple[CameraMetadata, str, np.ndarray, np.ndarray, int, int, int, str],
                    where: str) -> RawCapture:
    """The :class:`RawCapture` of a packed headerless raw ``buf`` with the ``layout`` of :func:`pair_metadata`.

    ``mosaic`` (H, W) uint16 unpacked from ``bits``-bit ``endianness`` packing; ``path`` = ``where``.
    """
    cam, cfa, black, white, w, h, bits, endian = layout
    return RawCapture(mosaic=packing.unpack(buf, h, w, bits, endian), cfa=cfa, black=black, white=white,
                      metadata=cam, path=where)


def read_raw_pair(path: str | os.PathLike) -> RawCapture:
    """Read a headerless Lytro raw with its JSON sidecar.

    Covers ``MOD_NNNN.RAW`` + ``MOD_NNNN.TXT`` white images (F01 12-bit or Illum 10-bit,
    decided from ``pixelPacking``/``bitsPerPixel``/``width``/``height``; the TXT may have
    trailing bytes after its last ``}``) and F01 ``X__frame.raw`` + ``X__frame.json``.
    White images (``modulationFrame`` true) get ``metadata.is_white_image = True``.

    Returns
    -------
    RawCapture

    Raises
    ------
    FormatError
        No or unparsable sidecar; raw size disagreeing with the metadata.
    """
    p = Path(path)
    layout = read_raw_pair_metadata(p)
    with open(p, "rb") as fh:
        buf = map_file(fh)
    try:
        return raw_from_buffer(buf, layout, str(p))
    finally:
        try:
            buf.close()
        except BufferError:  # a view is still alive; the map closes when it is collected
            pass


def write_raw_pair(path: str | os.PathLike, raw: RawCapture, *, overwrite: bool = False) -> tuple[Path, Path]:
    """Write a white-image style ``MOD_NNNN.RAW`` + ``MOD_NNNN.TXT`` pair.

    Packing follows ``raw.metadata.model``: 'F01' -> 12-bit big-endian, anything else ->
    Illum 10-bit (written with ``camera.model`` 'B01', as the Illum does for its white
    images).  The TXT has the ``master.picture.frameArray[0].frame.{metadata,
    privateMetadata}`` wrapper and the ``modulationFrame`` tag from ``raw.metadata.is_white_image``.
    The sidecar's extension follows the raw's case (``.RAW`` -> ``.TXT``, ``.raw`` -> ``.txt``).

    Returns
    -------
    (raw path, txt path)
    """
    p = Path(path)
    side = p.with_suffix(".txt" if p.suffix.islower() and p.suffix else ".TXT")
    refuse_existing([p, side], overwrite)
    data, text = raw_pair_bytes(raw)
    with atomic_outputs([p, side], overwrite=overwrite) as (tmp, tmp_side):
        tmp.write_bytes(data)
        tmp_side.write_bytes(text)
    return p, side


def raw_pair_bytes(raw: RawCapture) -> tuple[bytes, bytes]:
    """The two files of a ``MOD_NNNN.RAW`` + ``.TXT`` pair as bytes (see :func:`write_raw_pair`).

    Returns
    -------
    (raw bytes, TXT bytes)
        The packed mosaic (F01: 12-bit big-endian; else 10-bit little-endian) and the TXT JSON with
        the ``master`` wrapper, tab-indented with CR LF line ends as the cameras write it.
    """
    f01 = raw.metadata.model == "F01"
    bits = 12 if f01 else 10
    meta, private = lytro_metadata(raw, schema="rawdetails", bits=bits)
    if not f01 and meta["camera"].get("model", "ILLUM") in ("ILLUM", "Illum"):
        meta["camera"]["model"] = "B01"
    data = packing.pack(raw.mosaic, bits)
    doc = {
        "master": {
            "version": {"major": 1, "minor": 0, "provisionalDate": "2014-Sep-06"},
            "picture": {
                "viewArray": [],
                "accelerationArray": [],
                "frameArray": [{"frame": {"privateMetadata": private, "metadata": meta, "imageRef": "unknown"},
                                "parameters": tags_entry(raw)}],
                "derivationArray": [],
            },
            "thumbnailArray": [],
        }
    }
    return data, json.dumps(doc, indent="\t").replace("\n", "\r\n").encode("utf-8")
