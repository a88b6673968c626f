"""Generic raws: image mosaics with a JSON sidecar (OpenImageIO) and camera raws / DNG (rawpy).

Mosaic sidecar (``X.png.json`` or ``X.json`` beside ``X.png``)::

    {"format": "plenodecode.mosaic", "version": 1,
     "cfa": "RGGB" | "GRBG" | "GBRG" | "BGGR" | null,
     "black": 64 | [[r0c0, r0c1], [r1c0, r1c1]],
     "white": 1023 | [[...], [...]],
     "metadata": {...CameraMetadata.to_dict() fields...}}

Levels are in the units of the stored samples (``black``/``white`` are per position of the
2x2 CFA tile when given as a 2x2 list).
"""

from __future__ import annotations

import json
import logging
import math
import os
import struct
from dataclasses import replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import FormatError, LevelOptionError, MetadataError
from ..types import BARE_MOSAIC_KEY, CFA_PATTERNS, CameraMetadata, RawCapture
from .atomic import atomic_outputs, refuse_existing
from .images import read_image
from .images import srgb_decode
from .mosaic_levels import KNOWN_SENSORS, MosaicOptions, bare_mosaic_cfa, bare_mosaic_levels, linearise_srgb

log = logging.getLogger(__name__)
#: Sensor noise compresses poorly: the fastest zlib level costs ~1-2 % in size and saves a lot of time.
_FAST_PNG = {"png:compressionLevel": 1}

#: Extensions read through OpenImageIO as mosaics; everything else goes to rawpy.
MOSAIC_EXTENSIONS = (".png", ".tif", ".tiff", ".exr", ".pgm", ".pnm", ".bmp", ".jpg", ".jpeg")
#: Extensions :func:`write_mosaic` writes (16-bit).
MOSAIC_WRITE_EXTENSIONS = (".png", ".tif", ".tiff")
SIDECAR_FORMAT = "plenodecode.mosaic"
SIDECAR_VERSION = 1


# ----------------------------------------------------------------------------- sidecar
def find_sidecar(path: str | os.PathLike) -> Path | None:
    """The JSON sidecar of an image mosaic: ``X.png.json`` first, then ``X.json``; None if absent."""
    p = Path(path)
    for cand in (p.with_name(p.name + ".json"), p.with_suffix(".json")):
        if cand.is_file() and cand != p:
            return cand
    return None


def json_safe(value: Any) -> Any:
    """Recursively convert numpy scalars/arrays and tuples to plain JSON types."""
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


def _levels(value: Any, name: str, source: Path) -> np.ndarray:
    try:
        arr = np.asarray(value, np.float64)
        if arr.size == 4 and arr.ndim in (1, 2):
            arr = arr.reshape(2, 2)
        return np.broadcast_to(arr, (2, 2)).copy()
    except (TypeError, ValueError) as exc:
        raise MetadataError(f"{source}: '{name}' must be a number or a 2x2 list, got {value!r}; "
                            "fix the sidecar") from exc


def read_sidecar(path: str | os.PathLike) -> dict[str, Any]:
    """Parse a mosaic sidecar.

    Returns
    -------
    dict with keys ``cfa`` (str or None), ``black`` and ``white`` ((2, 2) float64 or None when
    absent) and ``metadata`` (:class:`CameraMetadata`).

    Raises
    ------
    MetadataError
        Not JSON, not an object, or a key of the wrong type.
    """
    p = Path(path)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise MetadataError(f"{p}: sidecar is not readable JSON ({exc}); fix or remove it") from exc
    if not isinstance(doc, dict):
        raise MetadataError(f"{p}: sidecar must be a JSON object with keys cfa, black, white, got {type(doc).__name__}")
    cfa = doc.get("cfa")
    if cfa is not None and cfa not in CFA_PATTERNS:
        raise MetadataError(f"{p}: 'cfa' must be one of {CFA_PATTERNS} or null, got {cfa!r}")
    meta = doc.get("metadata") or {}
    if not isinstance(meta, dict):
        raise MetadataError(f"{p}: 'metadata' must be an object of CameraMetadata fields, got {type(meta).__name__}")
    try:
        metadata = CameraMetadata.from_dict(meta)
    except (TypeError, ValueError) as exc:
        raise MetadataError(f"{p}: 'metadata' does not fit CameraMetadata ({exc})") from exc
    return {
        "cfa": cfa,
        "black": None if doc.get("black") is None else _levels(doc["black"], "black", p),
        "white": None if doc.get("white") is None else _levels(doc["white"], "white", p),
        "metadata": metadata,
    }


def sidecar_document(raw: RawCapture) -> dict[str, Any]:
    """The sidecar JSON object describing ``raw`` (see the module docstring)."""
    return {
        "format": SIDECAR_FORMAT,
        "version": SIDECAR_VERSION,
        "cfa": raw.cfa,
        "black": raw.black.tolist(),
        "white": raw.white.tolist(),
        "metadata": json_safe(raw.metadata.to_dict()),
    }


# ----------------------------------------------------------------------------- image mosaics
def _image_bits(path: Path, dtype: np.dtype) -> int:
    """Significant bits per sample: OpenImageIO's ``oiio:BitsPerSample`` if present, else the dtype's."""
    default = {np.dtype(np.uint8): 8, np.dtype(np.uint16): 16}.get(np.dtype(dtype), 16)
    try:
        import OpenImageIO as oiio

        inp = oiio.ImageInput.open(str(path))
        if inp is None:
            oiio.geterror()     # taken, or OpenImageIO prints it when the process exits
            return default
        bits = inp.spec().get_int_attribute("oiio:BitsPerSample", default)
        inp.close()
        return int(bits) if 0 < bits <= default else default
    except Exception:  # pragma: no cover - metadata probe only
        return default


def _to_uint16(img: np.ndarray, path: Path) -> tuple[np.ndarray, float]:
    """Stored samples as uint16 and the factor applied to them (levels are scaled alike)."""
    if img.dtype == np.uint16:
        return img, 1.0
    if img.dtype == np.uint8:
        return img.astype(np.uint16), 1.0
    finite = img[np.isfinite(img)] if img.dtype.kind == "f" else img
    lo = float(finite.min()) if finite.size else 0.0
    hi = float(finite.max()) if finite.size else 0.0
    if img.dtype.kind == "f" and lo >= 0.0 and hi <= 1.0:
        return np.rint(np.nan_to_num(img.astype(np.float64)) * 65535.0).astype(np.uint16), 65535.0
    if lo >= 0 and hi <= 65535 and np.all(np.mod(finite, 1) == 0):
        return np.nan_to_num(img).astype(np.uint16), 1.0
    raise FormatError(f"{path}: samples of type {img.dtype} in [{lo:g}, {hi:g}] cannot be stored as a uint16 "
                      "mosaic; expected integers up to 65535 or floats in [0, 1]")


def read_pgm(path: str | os.PathLike) -> tuple[np.ndarray, int]:
    """Read a binary PGM (Netpbm ``P5``) with its samples exactly as stored.

    OpenImageIO rescales PNM samples to the full type range; a sensor mosaic needs the stored
    values, so ``P5`` is parsed here: ASCII header ``P5 W H MAXVAL`` (whitespace separated,
    ``#`` comments), then one byte per sample (MAXVAL < 256) or two, big-endian.

    Returns
    -------
    image : ndarray, shape (H, W), uint8 or uint16
    maxval : int
    """
    p = Path(path)
    raw = p.read_bytes()
    fields: list[bytes] = []
    pos = 0
    while len(fields) < 4:
        while pos < len(raw) and raw[pos:pos + 1].isspace():
            pos += 1
        if raw[pos:pos + 1] == b"#":
            pos = raw.find(b"\n", pos) + 1 or len(raw)
            continue
        start = pos
        while pos < len(raw) and not raw[pos:pos + 1].isspace():
            pos += 1
        if start == pos:
            break
        fields.append(raw[start:pos])
    try:
        if fields[0] != b"P5":
            raise ValueError(f"magic {fields[0]!r}")
        w, h, maxval = (int(x) for x in fields[1:4])
    except (ValueError, IndexError) as exc:
        raise FormatError(f"{p}: not a binary PGM (P5) file ({exc}); expected 'P5 W H MAXVAL' header") from exc
    if not (0 < maxval < 65536 and w > 0 and h > 0):
        raise FormatError(f"{p}: PGM header gives {w}x{h}, maxval {maxval}; expected positive sizes, maxval < 65536")
    dtype = np.dtype(">u2") if maxval > 255 else np.dtype("u1")
    body = raw[pos + 1:]
    if len(body) < w * h * dtype.itemsize:
        raise FormatError(f"{p}: PGM holds {len(body)} bytes of samples, {w * h * dtype.itemsize} expected")
    img = np.frombuffer(body, dtype, count=w * h).reshape(h, w)
    return img.astype(np.uint16 if maxval > 255 else np.uint8), maxval


def _single_channel(img: np.ndarray, p: Path) -> np.ndarray:
    """A mosaic's one channel: 2-D as is; a 3-channel JPEG whose channels agree within one code (a grey
    mosaic that an encoder stored as YCbCr colour) as its first channel."""
    if img.ndim == 2:
        return img
    if p.suffix.lower() in (".jpg", ".jpeg") and img.shape[2] == 3:
        colour = img.astype(np.int16)
        if int(np.abs(colour - colour[:, :, :1]).max()) <= 1:
            return img[:, :, 0]
    raise FormatError(f"{p}: a single-channel mosaic is expected, found {img.shape[2]} channels; "
                      "demosaiced images are not raws (convert to the sensor mosaic first)")


def _read_image_mosaic(p: Path, options: MosaicOptions) -> RawCapture:
    maxval = None
    with open(p, "rb") as fh:
        is_p5 = fh.read(2) == b"P5"
    if is_p5:
        img, maxval = read_pgm(p)
    else:
        img = _single_channel(read_image(p), p)
    mosaic, factor = _to_uint16(img, p)
    if maxval is not None:
        default_white = float(maxval)
    else:
        bits = _image_bits(p, img.dtype)
        default_white = 65535.0 if factor != 1.0 else float(2**bits - 1)
    side = find_sidecar(p)
    if side is None:
        if factor != 1.0:       # levels given in the file's float units
            options = replace(options,
                              black_level=None if options.black_level is None else options.black_level * factor,
                              white_level=None if options.white_level is None else options.white_level * factor)
        return _bare_mosaic(p, mosaic, 8 if img.dtype == np.uint8 else 16, default_white, options)
    sc = read_sidecar(side)
    black = np.zeros((2, 2)) if sc["black"] is None else sc["black"] * factor
    white = np.full((2, 2), default_white) if sc["white"] is None else sc["white"] * factor
    if (sc["black"] is None and options.black_level is None) or (sc["white"] is None and options.white_level is None):
        log.warning("%s: sidecar gives no %s; using black 0 / white %g", side,
                    "black" if sc["black"] is None else "white", default_white)
    black = black if options.black_level is None else np.full((2, 2), options.black_level * factor)
    white = white if options.white_level is None else np.full((2, 2), options.white_level * factor)
    cfa = sc["cfa"] if options.cfa is None else (None if options.cfa == "mono" else options.cfa)
    if options.input_encoding == "srgb":
        mosaic, black, white = _linearise(mosaic, black, white, default_white)
    if np.any(white <= black):
        raise MetadataError(f"{side}: white level {white.tolist()} must exceed black level {black.tolist()}")
    return RawCapture(mosaic, cfa, black, white, sc["metadata"], str(p))


def is_known_sensor_image(path: str | os.PathLike) -> bool:
    """True for an image file whose size (from its header only) is a known lenslet sensor's
    (:data:`~.mosaic_levels.KNOWN_SENSORS`) and which has one channel (or three: a grey mosaic saved as RGB)."""
    try:
        import OpenImageIO as oiio

        inp = oiio.ImageInput.open(str(path))
        if inp is None:
            oiio.geterror()     # a probe: taken, or OpenImageIO prints it when the process exits
            return False
        spec = inp.spec()
        inp.close()
    except Exception:  # noqa: BLE001 - a probe: anything unreadable is not a mosaic
        return False
    return (spec.height, spec.width) in KNOWN_SENSORS and spec.nchannels in (1, 3)


def is_bare_mosaic(raw: RawCapture) -> bool:
    """True for a raw read from an image mosaic without a sidecar (no camera identity, levels chosen by rule)."""
    return BARE_MOSAIC_KEY in raw.metadata.extra


def _linearise(mosaic: np.ndarray, black: np.ndarray, white: np.ndarray,
               full_scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Display-encoded mosaic and levels -> linear 16-bit (:func:`~.mosaic_levels.linearise_srgb`)."""
    def level(v: np.ndarray) -> np.ndarray:
        return 65535.0 * srgb_decode(np.asarray(v, np.float64) / full_scale)

    return linearise_srgb(mosaic, full_scale), level(black), level(white)


def _bare_mosaic(p: Path, mosaic: np.ndarray, bits: int, full_scale: float, options: MosaicOptions) -> RawCapture:
    """A mosaic without a sidecar, read by the rules of :mod:`.mosaic_levels`; each choice logged in one line."""
    cfa, cfa_from = bare_mosaic_cfa(mosaic.shape, options)
    black, white, levels_from = bare_mosaic_levels(mosaic, bits, full_scale, options)
    # one line per file; with a dark frame its pixels replace the black level, which is then not worth a guess
    levels = (f"black from the dark frame {options.dark_frame}, pixel by pixel; white {white:.5g} of {full_scale:g}"
              if options.dark_frame and options.black_level is None
              else f"black {black:.5g}, white {white:.5g} of {full_scale:g} ({levels_from})")   # 65535 whole
    log.warning("%s: no JSON sidecar; CFA %s (%s); %s", p.name, cfa or "none, monochrome", cfa_from, levels)
    if white <= black:
        typed = "--black-level" if options.black_level is not None else "--white-level" \
            if options.white_level is not None else None
        if typed is not None:
            raise LevelOptionError(f"{p.name}: white level {white:g} must exceed black level {black:g} ({levels_from})",
                                   typed)
        raise MetadataError(f"{p}: white level {white:g} must exceed black level {black:g}; "
                            "pass --black-level and --white-level")
    for option, value in (("--black-level", options.black_level), ("--white-level", options.white_level)):
        if value is not None and value > full_scale:
            raise LevelOptionError(f"{value:g} is above the full scale of {p.name}, {full_scale:g} ({bits}-bit "
                                   "samples): give the level in the file's units", option)
    black2, white2 = np.full((2, 2), black), np.full((2, 2), white)
    if options.input_encoding == "srgb":
        mosaic, black2, white2 = _linearise(mosaic, black2, white2, full_scale)
        log.warning("%s: values display-encoded (--input-encoding srgb): inverse sRGB transfer applied", p.name)
    extra = {BARE_MOSAIC_KEY: {"cfa_from": cfa_from, "levels_from": levels_from, "encoding": options.input_encoding,
                               "file_black": black, "file_white": white, "file_full_scale": full_scale}}
    return RawCapture(mosaic, cfa, black2, white2, CameraMetadata(extra=extra), str(p))


# ----------------------------------------------------------------------------- rawpy
def _tiff_make_model(path: Path) -> tuple[str | None, str | None]:
    """Make (271) and Model (272) from IFD0 of a TIFF-based raw (DNG, NEF, CR2, ARW, ...).

    rawpy does not expose LibRaw's make/model; most camera raws are TIFF containers, so the
    two ASCII tags are read from the first IFD (TIFF 6.0, section 2).  None when absent.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
            if head[:4] not in (b"II*\0", b"MM\0*"):
                return None, None
            e = "<" if head[:2] == b"II" else ">"
            (ifd,) = struct.unpack(e + "I", head[4:8])
            fh.seek(ifd)
            (n,) = struct.unpack(e + "H", fh.read(2))
            if n > 4096:
                return None, None
            entries = fh.read(12 * n)
            found: dict[int, str] = {}
            for k in range(n):
                tag, typ, count, value = struct.unpack(e + "HHI4s", entries[12 * k:12 * k + 12])
                if tag in (271, 272) and typ == 2 and 0 < count < 1024:
                    if count <= 4:
                        raw = value[:count]
                    else:
                        here = fh.tell()
                        fh.seek(struct.unpack(e + "I", value)[0])
                        raw = fh.read(count)
                        fh.seek(here)
                    text = raw.split(b"\0", 1)[0].decode("latin-1").strip()
                    found[tag] = text or None
            return found.get(271), found.get(272)
    except (OSError, struct.error):
        return None, None


def ccm_from_xyz_to_camera(xyz_to_cam: np.ndarray) -> np.ndarray:
    """Camera RGB -> linear sRGB matrix from an XYZ -> camera matrix (e.g. DNG ColorMatrix).

    ``A = M_xyz2cam @ M_srgb2xyz`` maps linear sRGB to camera RGB; its rows are normalised to
    sum to 1 (so sRGB white maps to camera white, as in dcraw / the DNG specification's
    white-balanced camera space), and the result is ``inv(A)``, whose rows then also sum to 1.
    ``M_srgb2xyz`` is colour-science's sRGB (D65) matrix.

    Parameters
    ----------
    xyz_to_cam : ndarray, shape (3, 3), float

    Returns
    -------
    ndarray, shape (3, 3), float64
    """
    import colour

    m_srgb_to_xyz = np.asarray(colour.models.RGB_COLOURSPACE_sRGB.matrix_RGB_to_XYZ, np.float64)
    a = np.asarray(xyz_to_cam, np.float64)[:3, :3] @ m_srgb_to_xyz
    s = a.sum(axis=1, keepdims=True)
    if np.any(np.abs(s) < 1e-12):
        raise MetadataError("colour matrix maps sRGB white to zero in some camera channel; it is unusable")
    ccm = np.linalg.inv(a / s)
    return ccm / ccm.sum(axis=1, keepdims=True)


def _rawpy_capture(p: Path) -> RawCapture:
    import rawpy

    try:
        rp = rawpy.imread(str(p))
    except (rawpy.LibRawError, OSError, ValueError) as exc:
        raise FormatError(f"{p}: not a raw LibRaw can read ({exc.__class__.__name__}: {exc}); expected a DNG "
                          "or camera raw, or an image mosaic (.png/.tif/.exr/.pgm) with a JSON sidecar") from exc
    with rp:
        try:
            if rp.raw_type != rawpy.RawType.Flat:
                raise FormatError(f"{p}: raw data has several samples per pixel ({rp.raw_type}); only single-"
                                  "channel sensor mosaics are supported")
            mosaic = np.array(rp.raw_image_visible, dtype=np.uint16, copy=True)
            pattern = rp.raw_pattern
            desc = rp.color_desc.decode("ascii", "replace")
            blpc = list(rp.black_level_per_channel)
            white_level = float(rp.white_level)
            white_pc = rp.camera_white_level_per_channel
            cam_wb = list(rp.camera_whitebalance)
            xyz_cam = np.asarray(rp.rgb_xyz_matrix, np.float64)
            rgb_cam = np.asarray(rp.color_matrix, np.float64)
            other = rp.other
        except rawpy.LibRawError as exc:
            raise FormatError(f"{p}: LibRaw failed to unpack the raw data ({exc})") from exc

    if pattern is None or _num_colours(desc) == 1:
        cfa = None
        idx = np.zeros((2, 2), int)
    else:
        pattern = np.asarray(pattern)
        if pattern.shape != (2, 2):
            raise FormatError(f"{p}: colour filter array repeats every {pattern.shape} pixels; only 2x2 Bayer "
                              "patterns are supported (X-Trans and others are not)")
        letters = "".join(desc[int(k)] for k in pattern.ravel())
        cfa = letters
        if cfa not in CFA_PATTERNS:
            raise FormatError(f"{p}: colour filter pattern {letters!r} (colours {desc!r}) is not a Bayer "
                              f"pattern {CFA_PATTERNS}")
        idx = pattern.astype(int)

    black = np.array([[blpc[idx[r, c]] for c in range(2)] for r in range(2)], np.float64)
    if white_pc is not None and all(v > 0 for v in white_pc):
        white = np.array([[float(white_pc[idx[r, c]]) for c in range(2)] for r in range(2)])
    else:
        white = np.full((2, 2), white_level)

    wb = None
    if cfa is not None and any(v > 0 for v in cam_wb):
        gains = np.array(cam_wb[:4] + [0.0] * (4 - len(cam_wb[:4])), np.float64)
        g_first = gains[[k for k, ch in enumerate(desc) if ch == "G"][0]]
        gains = np.where(gains > 0, gains, g_first)
        names = _cfa_names(cfa)
        wb_map = {names[r][c]: float(gains[idx[r, c]]) for r in range(2) for c in range(2)}
        g = wb_map.get("gr") or 1.0
        wb = {k: v / g for k, v in wb_map.items()}

    ccm = None
    if cfa is not None:
        if np.any(xyz_cam[:3] != 0):
            ccm = ccm_from_xyz_to_camera(xyz_cam[:3])
        elif np.any(rgb_cam[:, :3] != 0):
            m = rgb_cam[:, :3]
            ccm = m / m.sum(axis=1, keepdims=True)

    make, model = _tiff_make_model(p)
    meta = CameraMetadata(
        make=make, model=model,
        exposure_s=float(other.shutter_speed) or None,
        iso=float(other.iso_speed) or None,
        focal_length_m=(float(other.focal_length) * 1e-3) or None,
        f_number=float(other.aperture) or None,
        wb_gains=wb,
        ccm=None if ccm is None else tuple(tuple(float(x) for x in row) for row in ccm),
        extra={"reader": "rawpy", "color_desc": desc},
    )
    return RawCapture(mosaic, cfa, black, white, meta, str(p))


def _num_colours(desc: str) -> int:
    """Number of distinct colours in a LibRaw colour description such as 'RGBG'."""
    return len(set(desc.strip("\0")))


def _cfa_names(cfa: str) -> list[list[str]]:
    """Channel names ('r', 'gr', 'gb', 'b') of the 2x2 tile of a Bayer pattern."""
    red_row = 0 if "R" in cfa[:2] else 1
    out = []
    for r in range(2):
        row = []
        for c in range(2):
            ch = cfa[2 * r + c]
            row.append("r" if ch == "R" else "b" if ch == "B" else ("gr" if r == red_row else "gb"))
        out.append(row)
    return out


# ----------------------------------------------------------------------------- public
def read_generic(path: str | os.PathLike, *, mosaic: MosaicOptions | None = None) -> RawCapture:
    """Read a mosaic image (PNG/TIFF/JPEG/EXR/PGM, with or without a JSON sidecar) or a DNG / camera raw (rawpy).

    Image mosaics
        Read with OpenImageIO (binary PGM by :func:`read_pgm`, white = MAXVAL); a grey mosaic saved
        with three equal channels is read as one.  The sidecar (see the module docstring) gives the
        CFA, the levels and the metadata; ``mosaic`` (the CLI's ``--cfa``, ``--black-level``,
        ``--white-level``) overrides them.  Without a sidecar the CFA and levels follow
        :mod:`.mosaic_levels` (``--cfa``, else the sensor known by the size, else monochrome; given
        levels, else the known sensor's, else the black level estimated from the gaps between
        micro-images), each choice said in one warning line, and ``metadata.extra[BARE_MOSAIC_KEY]``
        records them.  ``mosaic.input_encoding == 'srgb'``: samples and levels get the inverse sRGB transfer
        function (stored as linear 16-bit).  Float images in [0, 1] are stored as ``rint(x * 65535)``
        and their levels scaled alike.
    Raws (any other extension)
        ``raw_image_visible`` from rawpy; the CFA from ``raw_pattern`` and ``color_desc``
        (2x2 Bayer only); ``black_level_per_channel``; ``white_level`` (per channel when
        LibRaw knows it); ``camera_whitebalance`` as gains normalised to green; the colour
        matrix from ``rgb_xyz_matrix`` (:func:`ccm_from_xyz_to_camera`) or, when LibRaw leaves
        it empty (DNG), LibRaw's own camera->sRGB matrix; make/model from the TIFF IFD0.

    Returns
    -------
    RawCapture
        ``mosaic`` (H, W) uint16.

    Raises
    ------
    FormatError
        Unreadable file, multi-channel image, non-Bayer CFA.
    MetadataError
        Malformed sidecar.
    """
    p = Path(path)
    if not p.is_file():
        raise FormatError(f"{p}: no such file; check the path")
    if p.suffix.lower() in MOSAIC_EXTENSIONS:
        return _read_image_mosaic(p, mosaic or MosaicOptions())
    if mosaic is not None and mosaic.given:
        log.warning("%s: --cfa, --black-level, --white-level and --input-encoding apply to image mosaics; "
                    "ignored for this camera raw", p.name)
    return _rawpy_capture(p)


def write_mosaic(path: str | os.PathLike, raw: RawCapture, *, overwrite: bool = False) -> Path:
    """Write a RawCapture as a 16-bit PNG/TIFF mosaic plus the JSON sidecar ``X.json``.

    :func:`read_generic` reads the pair back bit-exactly with equal cfa, levels and metadata
    (``metadata.extra`` must be JSON-serialisable; tuples come back as lists).  Both files are
    written atomically; neither is replaced unless ``overwrite`` is True.

    Parameters
    ----------
    path : path-like
        ``.png``, ``.tif`` or ``.tiff``.
    raw : RawCapture
    overwrite : bool

    Returns
    -------
    Path
        The image file.
    """
    from .images import write_image

    p = Path(path)
    if p.suffix.lower() not in MOSAIC_WRITE_EXTENSIONS:
        raise ValueError(f"path must end in one of {MOSAIC_WRITE_EXTENSIONS}, got {p.name!r}")
    side = p.with_suffix(".json")
    stale = p.with_name(p.name + ".json")  # would shadow X.json when reading back
    refuse_existing([stale], overwrite)
    text = json.dumps(sidecar_document(raw), indent=1)
    with atomic_outputs([p, side], overwrite=overwrite, keep_suffix=True) as (tmp, tmp_side):
        tmp_side.write_text(text, encoding="utf-8")
        write_image(tmp, raw.mosaic, bit_depth=16, overwrite=True, attributes=_FAST_PNG)
    if stale.exists():
        stale.unlink()
    return p


__all__ = ["read_generic", "MosaicOptions", "BARE_MOSAIC_KEY", "is_bare_mosaic", "is_known_sensor_image", "write_mosaic", "read_pgm", "find_sidecar", "read_sidecar", "sidecar_document",
           "ccm_from_xyz_to_camera", "json_safe", "MOSAIC_EXTENSIONS"]
