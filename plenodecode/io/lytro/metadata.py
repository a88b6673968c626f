"""Lytro frame metadata <-> :class:`~plenodecode.types.CameraMetadata` and the raw's layout.

Both schemas of ``formats.md`` §2-3 are read (:func:`metadata_from_lytro`): the F01 / white-image
``image.rawDetails.{pixelFormat, pixelPacking, mosaic}`` and the Illum ``image.{pixelFormat,
pixelPacking, mosaic}``; :func:`lytro_metadata` generates either from a RawCapture (for the writers).
"""

from __future__ import annotations

import logging
import os
from typing import Any, Mapping

import numpy as np

from ...errors import FormatError, MetadataError
from ...types import CFA_PATTERNS, CameraMetadata, RawCapture
from .. import packing
from .fields import lookup_dict, first_number, first_frame, lookup, json_number, as_number, frame_tags

log = logging.getLogger(__name__)

#: Largest plausible sensor side (px); larger declared sizes are refused before allocating.
MAX_SIDE = 1 << 16
#: The Bayer tile every Lytro file declares; ``upperLeftPixel`` says which entry is at (0, 0).
LYTRO_TILE = "r,gr:gb,b"
ILLUM_PUBLIC_SCHEMA = "http://schema.lytro.com/lfp/lytro_illum_public/1.3.4/lytro_illum_public_schema.json"
ILLUM_PRIVATE_SCHEMA = "http://schema.lytro.com/lfp/lytro_illum_private/1.1.1/lytro_illum_private_schema.json"


def _int_side(v: Any, what: str, where: str) -> int:
    f = as_number(v)
    if f is None or f != int(f):
        raise MetadataError(f"{where}{what} should be a positive integer, found {v!r}; the metadata is damaged")
    n = int(f)
    if not 1 <= n <= MAX_SIDE:
        raise FormatError(f"{where}{what} = {n} is not a plausible sensor size (expected 1..{MAX_SIDE}); "
                          "the metadata is damaged, so the image is not read")
    return n


def _unwrap(doc: Mapping[str, Any]) -> tuple[Mapping[str, Any], Mapping[str, Any] | None, Mapping[str, Any]]:
    """``(metadata, privateMetadata, tags)`` of a TXT document with the ``master`` wrapper."""
    wrapper = first_frame(doc)
    frame = lookup_dict(wrapper, "frame")
    meta = frame.get("metadata")
    if not isinstance(meta, Mapping):
        raise MetadataError("the white-image TXT has no master.picture.frameArray[0].frame.metadata object; "
                            "it is not a Lytro MOD_NNNN.TXT")
    private = frame.get("privateMetadata")
    return meta, private if isinstance(private, Mapping) else None, frame_tags(wrapper)


def _cfa_names(tile: Any, upper_left: Any, where: str) -> list[list[str]]:
    """Names ('r', 'gr', 'gb', 'b') at the sensor's 2x2 positions from a Lytro mosaic description."""
    if not isinstance(tile, str) or not isinstance(upper_left, str):
        raise MetadataError(f"{where}mosaic should have string 'tile' and 'upperLeftPixel', found "
                            f"{tile!r}, {upper_left!r}")
    rows = [r.split(",") for r in tile.replace(" ", "").lower().split(":")]
    flat = [n for r in rows for n in r]
    if len(rows) != 2 or any(len(r) != 2 for r in rows) or sorted(flat) != ["b", "gb", "gr", "r"]:
        raise MetadataError(f"{where}mosaic tile should be a 2x2 Bayer tile like 'r,gr:gb,b', found {tile!r}")
    ul = upper_left.lower()
    if ul not in flat:
        raise MetadataError(f"{where}mosaic upperLeftPixel should be one of r, gr, gb, b, found {upper_left!r}")
    r0, c0 = divmod(flat.index(ul), 2)
    return [[rows[(r0 + i) % 2][(c0 + j) % 2] for j in range(2)] for i in range(2)]


def _levels(obj: Any, names: list[list[str]], what: str, where: str) -> np.ndarray:
    if as_number(obj) is not None:
        return np.full((2, 2), float(obj))
    if not isinstance(obj, Mapping):
        raise MetadataError(f"{where}pixelFormat.{what} should be an object {{r, gr, gb, b}}, found {obj!r}")
    out = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            v = as_number(obj.get(names[i][j]))
            if v is None:
                raise MetadataError(f"{where}pixelFormat.{what}.{names[i][j]} should be a number, found "
                                    f"{obj.get(names[i][j])!r}")
            out[i, j] = v
    return out


def metadata_from_lytro(meta: Mapping[str, Any], private: Mapping[str, Any] | None = None,
                        path: str | os.PathLike | None = None, *, white_image: bool | None = None,
                        default_size: tuple[int, int] | None = None,
                        ) -> tuple[CameraMetadata, str, np.ndarray, np.ndarray, int, int, int, str]:
    """Map Lytro frame metadata (F01 or Illum schema) to :class:`CameraMetadata` and raw layout.

    Reads the F01 / white-image schema (``image.rawDetails.{pixelFormat, pixelPacking, mosaic}``,
    ``image.color.ccmRgbToSrgbArray``) and the Illum LFR schema (``image.{pixelFormat,
    pixelPacking, mosaic}``, ``image.color.ccm``, ``image.iso``); see ``formats.md`` §2-3.

    Parameters
    ----------
    meta : dict
        The frame's ``metadata`` object, or a whole ``MOD_NNNN.TXT`` document (``master`` wrapper),
        whose private metadata and ``modulationFrame`` tag are then used too.
    private : dict, optional
        The ``privateMetadata`` object (``camera.serialNumber``).
    path : path-like, optional
        Only used in error messages.
    white_image : bool, optional
        The frame's ``modulationFrame`` tag, when known from elsewhere (the TOC).
    default_size : (height, width), optional
        Used when the metadata declares no image size (headerless raws of a known sensor).

    Returns
    -------
    (CameraMetadata, cfa, black, white, width, height, bits, endianness)
        ``cfa`` one of 'RGGB', 'GRBG', 'GBRG', 'BGGR' (the tile ``r,gr:gb,b`` shifted to
        ``upperLeftPixel``: 'gr' gives GRBG (Illum), 'b' gives BGGR (F01)); ``black``/``white``
        (2, 2) float64 levels at the sensor's 2x2 CFA positions; ``bits`` 10/12/...;
        ``endianness`` 'little' or 'big'.

    Raises
    ------
    MetadataError
        A required entry (levels, mosaic, size, packing) is missing or of the wrong type.
    FormatError
        The declared image size is implausible (> 65536 px a side).
    """
    where = f"{path}: " if path is not None else ""
    if not isinstance(meta, Mapping):
        raise MetadataError(f"{where}Lytro metadata should be a JSON object, found {type(meta).__name__}")
    tags: Mapping[str, Any] = {}
    doc = meta
    if "master" in meta:
        meta, private2, tags = _unwrap(meta)
        private = private if private is not None else private2
    if not isinstance(private, Mapping):
        private = None
    image = lookup_dict(meta, "image")
    devices = lookup_dict(meta, "devices")
    sensor = lookup_dict(devices, "sensor")
    raw_details = image.get("rawDetails")
    src = raw_details if isinstance(raw_details, Mapping) else image
    if not image:
        raise MetadataError(f"{where}Lytro metadata has no 'image' object; it is not frame metadata")

    w_decl = first_number(image.get("width"), sensor.get("pixelWidth"))
    h_decl = first_number(image.get("height"), sensor.get("pixelHeight"))
    if (w_decl is None or h_decl is None) and default_size is not None:
        h_decl, w_decl = default_size
    width = _int_side(w_decl, "image.width", where)
    height = _int_side(h_decl, "image.height", where)

    pk = lookup_dict(src, "pixelPacking")
    bits_f = first_number(pk.get("bitsPerPixel"), sensor.get("bitsPerPixel"))
    if bits_f is None or bits_f not in (8, 10, 12, 16):
        raise MetadataError(f"{where}pixelPacking.bitsPerPixel should be 8, 10, 12 or 16, found "
                            f"{pk.get('bitsPerPixel', sensor.get('bitsPerPixel'))!r}")
    bits = int(bits_f)
    endian = pk.get("endianness")
    if endian is None:
        endian = "big" if bits == 12 else "little"
    if not isinstance(endian, str) or endian.lower() not in ("little", "big"):
        raise MetadataError(f"{where}pixelPacking.endianness should be 'little' or 'big', found {endian!r}")
    endian = endian.lower()

    mosaic = src.get("mosaic") if isinstance(src.get("mosaic"), Mapping) else sensor.get("mosaic")
    if not isinstance(mosaic, Mapping):
        raise MetadataError(f"{where}Lytro metadata has no mosaic {{tile, upperLeftPixel}}; cannot tell the Bayer "
                            "pattern")
    names = _cfa_names(mosaic.get("tile"), mosaic.get("upperLeftPixel"), where)
    cfa = "".join(n[0] for row in names for n in row).upper()
    if cfa not in CFA_PATTERNS:  # pragma: no cover - every valid shift of the tile is a Bayer pattern
        raise MetadataError(f"{where}mosaic gives an unknown CFA {cfa}")
    pf = lookup_dict(src, "pixelFormat")
    if not pf:
        raise MetadataError(f"{where}Lytro metadata has no pixelFormat {{black, white}}; cannot tell the levels")
    black = _levels(pf.get("black"), names, "black", where)
    white = _levels(pf.get("white"), names, "white", where)
    if as_number(pf.get("rightShift")) not in (None, 0.0):
        log.warning("%spixelFormat.rightShift = %s is not 0; levels used as written", where, pf.get("rightShift"))

    color = lookup_dict(image, "color")
    gains = color.get("whiteBalanceGain")
    if not isinstance(gains, Mapping):
        gains = lookup(meta, "algorithms", "awb", "computed", "gain")
    wb = None
    if isinstance(gains, Mapping):
        wb = {k: float(v) for k, v in gains.items() if k in ("r", "gr", "gb", "b", "g") and as_number(v) is not None}
        wb = wb or None
    ccm_list = color.get("ccmRgbToSrgbArray", color.get("ccm"))
    ccm = None
    if isinstance(ccm_list, list) and len(ccm_list) == 9 and all(as_number(x) is not None for x in ccm_list):
        vals = [float(x) for x in ccm_list]
        ccm = (tuple(vals[0:3]), tuple(vals[3:6]), tuple(vals[6:9]))

    mla = lookup_dict(devices, "mla")
    lens = lookup_dict(devices, "lens")
    off = lookup_dict(mla, "sensorOffset")
    offset = tuple(as_number(off.get(k)) for k in ("x", "y", "z"))
    scale = tuple(as_number(lookup_dict(mla, "scaleFactor").get(k)) for k in ("x", "y"))
    camera = lookup_dict(meta, "camera")
    serial = lookup(private, "camera", "serialNumber")
    if white_image is None:
        white_image = lookup(tags, "modulationFrame") is True
    text = lambda v: str(v) if isinstance(v, (str, int)) and not isinstance(v, bool) else None  # noqa: E731

    cam = CameraMetadata(
        make=text(camera.get("make")),
        model=text(camera.get("model")),
        serial=text(serial),
        zoom_step=as_number(lens.get("zoomStep")),
        focus_step=as_number(lens.get("focusStep")),
        exposure_s=as_number(lookup(devices, "shutter", "frameExposureDuration")),
        iso=first_number(image.get("iso"), sensor.get("iso")),
        wb_gains=wb,
        ccm=ccm,  # type: ignore[arg-type]
        pixel_pitch_m=as_number(sensor.get("pixelPitch")),
        lens_pitch_m=as_number(mla.get("lensPitch")),
        mla_rotation=as_number(mla.get("rotation")),
        mla_offset_m=offset if all(v is not None for v in offset) else None,  # type: ignore[arg-type]
        mla_scale=scale if all(v is not None for v in scale) else None,  # type: ignore[arg-type]
        focal_length_m=as_number(lens.get("focalLength")),
        f_number=as_number(lens.get("fNumber")),
        is_white_image=bool(white_image),
        extra={"lytro": {"metadata": meta, "privateMetadata": private,
                         **({"document": doc} if doc is not meta else {})}},
    )
    return cam, cfa, black, white, width, height, bits, endian


def packed_size_or_error(h: int, w: int, bits: int, where: str) -> int:
    """Bytes of an ``h x w`` raw packed at ``bits``; a FormatError naming ``where`` for an impossible layout."""
    try:
        return packing.packed_size(h, w, bits)
    except ValueError as exc:
        raise FormatError(f"{where}: {exc}; the metadata is damaged") from None


def _level_dict(levels: np.ndarray, names: list[list[str]]) -> dict[str, int | float]:
    return {names[i][j]: json_number(levels[i, j]) for i in range(2) for j in range(2)}


def _upper_left_for(cfa: str) -> tuple[str, list[list[str]]]:
    for ul in ("r", "gr", "gb", "b"):
        names = _cfa_names(LYTRO_TILE, ul, "")
        if "".join(n[0] for row in names for n in row).upper() == cfa:
            return ul, names
    raise ValueError(f"raw.cfa must be one of {CFA_PATTERNS} to write a Lytro file, got {cfa!r}")  # pragma: no cover


def lytro_metadata(raw: RawCapture, *, schema: str, bits: int | None = None) -> tuple[dict, dict]:
    """Lytro ``(metadata, privateMetadata)`` JSON objects generated from a RawCapture.

    Parameters
    ----------
    raw : RawCapture
        Its ``cfa`` (a Bayer pattern), levels and :class:`CameraMetadata` are written.
    schema : 'illum' or 'rawdetails'
        'illum': the Illum LFR schema (``image.pixelFormat``, ``image.color.ccm``, ``image.iso``).
        'rawdetails': the F01 / white-image schema (``image.rawDetails``, ``ccmRgbToSrgbArray``).
    bits : int, optional
        10 (little-endian) or 12 (big-endian); default 10 for 'illum', 12 for 'rawdetails'.
    """
    from ... import __version__

    if schema not in ("illum", "rawdetails"):
        raise ValueError(f"schema must be 'illum' or 'rawdetails', got {schema!r}")
    if raw.cfa is None:
        raise ValueError("raw.cfa is None: a Lytro file needs a Bayer pattern")
    bits = bits if bits is not None else (10 if schema == "illum" else 12)
    if bits not in (10, 12):
        raise ValueError(f"bits must be 10 or 12, got {bits!r}")
    endian = "little" if bits == 10 else "big"
    m = raw.metadata
    ul, names = _upper_left_for(raw.cfa)
    h, w = raw.shape
    mosaic = {"tile": LYTRO_TILE, "upperLeftPixel": ul}
    pixel_format = {"rightShift": 0, "black": _level_dict(raw.black, names), "white": _level_dict(raw.white, names)}
    pixel_packing = {"endianness": endian, "bitsPerPixel": bits}
    color: dict[str, Any] = {}
    if m.ccm is not None:
        color["ccm" if schema == "illum" else "ccmRgbToSrgbArray"] = [float(x) for row in m.ccm for x in row]
    if m.wb_gains is not None:
        g = {k: float(v) for k, v in m.wb_gains.items()}
        if "g" in g:
            g.setdefault("gr", g["g"])
            g.setdefault("gb", g.pop("g"))
        color["whiteBalanceGain"] = g
    image: dict[str, Any] = {"width": w, "height": h, "orientation": 1}
    if schema == "illum":
        image.update(pixelPacking=pixel_packing, pixelFormat=pixel_format, mosaic=mosaic)
        if m.iso is not None:
            image["iso"] = json_number(m.iso)
        image["color"] = color
    else:
        image.update(representation="rawPacked",
                     rawDetails={"pixelFormat": pixel_format, "pixelPacking": pixel_packing, "mosaic": mosaic},
                     color={**color, "applied": {}})
    sensor: dict[str, Any] = {"bitsPerPixel": bits, "mosaic": dict(mosaic)}
    if schema == "illum":
        sensor.update(pixelWidth=w, pixelHeight=h)
    elif m.iso is not None:
        sensor["iso"] = json_number(m.iso)
    if m.pixel_pitch_m is not None:
        sensor["pixelPitch"] = float(m.pixel_pitch_m)
    lens: dict[str, Any] = {}
    for key, v in (("zoomStep", m.zoom_step), ("focusStep", m.focus_step),
                   ("focalLength", m.focal_length_m), ("fNumber", m.f_number)):
        if v is not None:
            lens[key] = json_number(v) if key.endswith("Step") else float(v)
    mla: dict[str, Any] = {"tiling": "hexUniformRowMajor", "config": "com.lytro.mla.3", "defectArray": []}
    if m.lens_pitch_m is not None:
        mla["lensPitch"] = float(m.lens_pitch_m)
    if m.mla_rotation is not None:
        mla["rotation"] = float(m.mla_rotation)
    if m.mla_scale is not None:
        mla["scaleFactor"] = {"x": float(m.mla_scale[0]), "y": float(m.mla_scale[1])}
    if m.mla_offset_m is not None:
        mla["sensorOffset"] = dict(zip("xyz", (float(v) for v in m.mla_offset_m)))
    devices: dict[str, Any] = {"sensor": sensor, "lens": lens, "mla": mla}
    if m.exposure_s is not None:
        devices["shutter"] = {"frameExposureDuration": float(m.exposure_s),
                              "pixelExposureDuration": float(m.exposure_s)}
    camera: dict[str, Any] = {"firmware": f"plenodecode {__version__}"}
    if m.make is not None:
        camera["make"] = m.make
    if m.model is not None:
        camera["model"] = m.model
    meta: dict[str, Any] = {}
    if schema == "illum":
        meta.update(schema=ILLUM_PUBLIC_SCHEMA, generator="plenodecode")
    else:
        meta["type"] = "lightField"
    meta.update(image=image, devices=devices, camera=camera)
    private: dict[str, Any] = {"schema": ILLUM_PRIVATE_SCHEMA, "generator": "plenodecode"} if schema == "illum" else {}
    if m.serial is not None:
        private["camera"] = {"serialNumber": m.serial}
    return meta, private


def tags_entry(raw: RawCapture) -> dict:
    """The frame's ``parameters`` entry: ``com.lytro.tags`` with ``modulationFrame`` (white image) and ``darkFrame``."""
    return {"vendorContent": {"com.lytro.tags": {"darkFrame": False,
                                                 "modulationFrame": bool(raw.metadata.is_white_image)}}}
