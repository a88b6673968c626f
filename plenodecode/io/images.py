"""Image reading and writing.  Every image plenodecode writes goes through this module.

Pixel data goes through OpenImageIO, except PFM (written and read by :mod:`plenodecode.io.pfm`,
which keeps the bottom-up row order the HCI benchmark toolkit expects) and animated WebP
(OpenImageIO writes one WebP frame only, so Pillow, already installed as a matplotlib
dependency, writes animations).

Conventions
-----------
* Float input is linear data in [0, 1]; 8- and 16-bit outputs are ``round(clip(x, 0, 1) * (2**b - 1))``.
  ``uint8``/``uint16`` input is written unchanged when its depth equals ``bit_depth`` and is
  otherwise rescaled by its type's maximum (``x / 255`` or ``x / 65535``) first.
* ``bit_depth=32`` writes float32 (EXR, TIFF, PFM); ``bit_depth=16`` on EXR writes half floats.
* ``encode_srgb=True`` applies the sRGB transfer function (IEC 61966-2-1, through
  ``colour.cctf_encoding(x, function='sRGB')``) before quantising.  Display encoding happens only
  here, at export; the library keeps light fields linear.
* Writes are atomic (:func:`plenodecode.io.atomic.atomic_output`): a temporary file in the
  destination folder, then a rename.
  An existing file is never replaced without ``overwrite=True`` (:class:`FileExistsError`).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import FormatError
from . import pfm
from .atomic import atomic_output

log = logging.getLogger(__name__)

#: Extension -> bit depths that format can hold (32 = float32; 16 on EXR = half float).
IMAGE_FORMATS: dict[str, tuple[int, ...]] = {
    ".png": (8, 16),
    ".tif": (8, 16, 32),
    ".tiff": (8, 16, 32),
    ".exr": (16, 32),
    ".jpg": (8,),
    ".jpeg": (8,),
    ".pfm": (32,),
}
#: Extensions :func:`write_animation` can write.
ANIMATION_FORMATS = (".gif", ".webp")

_MAX_CHANNELS = {".jpg": 3, ".jpeg": 3, ".pfm": 3}
#: OpenImageIO ``oiio:ColorSpace`` of the pixels written, per colour state (:data:`plenodecode.metadata.COLOUR_STATES`)
#: of the values in the file: sRGB (its primaries and curve); linear Rec.709 = sRGB primaries (a PNG gets gAMA 1.0);
#: camera RGB, whose primaries are the sensor's and were never converted, is 'unknown' (the Color Interop Forum's
#: ID for colour of an unknown space: no sRGB, cHRM or gAMA chunk in a PNG, ``colorInteropID`` in an EXR).
COLOUR_SPACE_TAGS = {"srgb": "sRGB", "linear-srgb": "lin_srgb", "camera": "unknown", "camera-srgb-curve": "unknown"}
_FLOAT_KINDS = "f"


def _oiio():
    import OpenImageIO as oiio  # imported lazily: importing plenodecode stays light

    return oiio


def to_unit_float(image: np.ndarray) -> np.ndarray:
    """Image as float32 in the [0, 1] convention of this module (no clipping).

    ``uint8``/``uint16`` are divided by their type's maximum; floats are converted to float32.

    Parameters
    ----------
    image : ndarray, any shape, uint8, uint16 or floating

    Returns
    -------
    ndarray, same shape, float32
    """
    a = np.asarray(image)
    if a.dtype == np.uint8 or a.dtype == np.uint16:
        return a.astype(np.float32) * np.float32(1.0 / np.iinfo(a.dtype).max)
    if a.dtype.kind in _FLOAT_KINDS:
        return a.astype(np.float32, copy=False)
    raise ValueError(f"image must be uint8, uint16 or floating point, got dtype {a.dtype}")


def _srgb_oetf(linear: np.ndarray) -> np.ndarray:
    """``12.92 L`` for ``L <= 0.0031308``, else ``1.055 sign(L) |L|**(1/2.4) - 0.055``; float64 in, float32 out."""
    x = np.asarray(linear, np.float64)
    curve = 1.055 * (np.sign(x) * np.abs(x) ** (1.0 / 2.4)) - 0.055
    return np.where(x <= 0.0031308, x * 12.92, curve).astype(np.float32)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """sRGB transfer function (IEC 61966-2-1) of linear values, float32.

    ``V = 12.92 L`` for ``L <= 0.0031308``, else ``1.055 L**(1/2.4) - 0.055``, evaluated in float64
    as ``colour.cctf_encoding(L, function='sRGB')`` does (the test compares the two) without importing
    colour-science, whose import pulls in matplotlib (seconds).  Large arrays are encoded in slabs
    along the first axis, so the float64 temporaries stay small.
    """
    a = np.asarray(linear, np.float32)
    if a.ndim < 2 or a.size <= 1 << 22:
        return _srgb_oetf(a)
    out = np.empty(a.shape, np.float32)
    for k in range(a.shape[0]):
        out[k] = _srgb_oetf(a[k])
    return out


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """Inverse of :func:`srgb_encode` (IEC 61966-2-1) for values in [0, 1] (clipped), float64.

    ``L = V / 12.92`` for ``V <= 0.04045``, else ``((V + 0.055) / 1.055) ** 2.4``.
    """
    v = np.clip(np.asarray(encoded, np.float64), 0.0, 1.0)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def quantise(image: np.ndarray, bit_depth: int, *, encode_srgb: bool = False) -> np.ndarray:
    """Convert an image to the sample type written for ``bit_depth``.

    Parameters
    ----------
    image : ndarray, uint8, uint16 or floating, any shape
    bit_depth : {8, 16, 32}
    encode_srgb : bool
        Apply :func:`srgb_encode` first.

    Returns
    -------
    ndarray, same shape
        uint8 (8), uint16 (16) or float32 (32).  Integer outputs are
        ``rint(clip(x, 0, 1) * (2**bit_depth - 1))``; NaN becomes 0.
    """
    if bit_depth not in (8, 16, 32):
        raise ValueError(f"bit_depth must be 8, 16 or 32, got {bit_depth!r}")
    a = np.asarray(image)
    target = {8: np.uint8, 16: np.uint16, 32: np.float32}[bit_depth]
    if not encode_srgb and a.dtype == target:
        return a
    x = to_unit_float(a)
    if encode_srgb:
        x = srgb_encode(x)
    if bit_depth == 32:
        return x
    top = np.float32(2**bit_depth - 1)
    y = np.multiply(x, top, dtype=np.float32)          # one float32 work array; the input is untouched
    np.nan_to_num(y, copy=False, nan=0.0, posinf=top, neginf=0.0)
    np.clip(y, 0.0, top, out=y)
    np.rint(y, out=y)
    return y.astype(target)


def colour_space_tag(colour: str | None, *, encode_srgb: bool = False, channels: int = 3) -> str | None:
    """The ``oiio:ColorSpace`` of an image of colour state ``colour`` written with ``encode_srgb``
    (:data:`COLOUR_SPACE_TAGS` of the state in the file); one channel has no primaries, so only its curve counts
    ('sRGB' or 'lin_srgb').  ``colour`` None: 'sRGB' when encoded, else None (untagged)."""
    from ..metadata import LINEAR_COLOUR_STATES, encoded_colour_state

    if colour is None:
        return "sRGB" if encode_srgb else None
    if colour not in COLOUR_SPACE_TAGS:
        raise ValueError(f"colour must be one of {sorted(COLOUR_SPACE_TAGS)} or None, got {colour!r}")
    stored = encoded_colour_state(colour) if encode_srgb else colour
    if channels == 1:
        return "lin_srgb" if stored in LINEAR_COLOUR_STATES else "sRGB"
    return COLOUR_SPACE_TAGS[stored]


def write_image(path: str | os.PathLike, image: np.ndarray, *, bit_depth: int, overwrite: bool = False,
                encode_srgb: bool = False, attributes: Mapping[str, Any] | None = None,
                colour: str | None = None) -> Path:
    """Write one image (PNG, TIFF, EXR, JPEG or PFM, chosen by the extension), atomically.

    Parameters
    ----------
    path : path-like
        ``.png`` (8, 16 bit), ``.tif``/``.tiff`` (8, 16, 32), ``.exr`` (16 = half, 32 = float),
        ``.jpg``/``.jpeg`` (8), ``.pfm`` (32; rows stored bottom-up, see :mod:`plenodecode.io.pfm`).
    image : ndarray, shape (H, W) or (H, W, C), C in 1..4 (JPEG, PFM: 1 or 3)
        Float data in [0, 1] (clipped for integer outputs) or uint8 / uint16 (see the module
        docstring).
    bit_depth : {8, 16, 32}
        Bits per sample in the file; 32 = float32.
    overwrite : bool
        Replace an existing file; otherwise :class:`FileExistsError`.
    encode_srgb : bool
        Apply the sRGB transfer function before quantising (display encoding).
    attributes : mapping, optional
        Extra OpenImageIO metadata attributes (e.g. ``{"ImageDescription": "..."}``).
    colour : str, optional
        Colour state of ``image`` as given (:data:`plenodecode.metadata.COLOUR_STATES`), which sets the file's
        ``oiio:ColorSpace`` (:func:`colour_space_tag`): camera RGB is never tagged sRGB.  None: 'sRGB' when
        ``encode_srgb``, else untagged.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    ValueError
        Unknown extension, a bit depth the format cannot hold, or a bad image shape or dtype.
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in IMAGE_FORMATS:
        raise ValueError(f"path must end in one of {sorted(IMAGE_FORMATS)}, got {p.name!r}")
    if bit_depth not in IMAGE_FORMATS[ext]:
        raise ValueError(f"bit_depth {bit_depth!r} cannot be stored in {ext} files; "
                         f"use one of {IMAGE_FORMATS[ext]}")
    a = np.asarray(image)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    channels = 1 if a.ndim == 2 else (a.shape[2] if a.ndim == 3 else 0)
    if not 1 <= channels <= _MAX_CHANNELS.get(ext, 4) or (ext in _MAX_CHANNELS and channels == 2):
        raise ValueError(f"image must have shape (H, W) or (H, W, C) with a channel count {ext} can hold, "
                         f"got {a.shape}")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"image must not be empty, got shape {a.shape}")
    tag = colour_space_tag(colour, encode_srgb=encode_srgb, channels=channels)
    data = quantise(a, 32 if ext == ".exr" else bit_depth, encode_srgb=encode_srgb)
    if ext == ".pfm":
        return pfm.write_pfm(p, data, overwrite=overwrite)

    oiio = _oiio()
    fmt = {8: "uint8", 16: "half" if ext == ".exr" else "uint16", 32: "float"}[bit_depth]
    spec = oiio.ImageSpec(a.shape[1], a.shape[0], channels, fmt)
    if ext in (".jpg", ".jpeg"):
        spec.attribute("Compression", "jpeg:95")
    if tag is not None:
        spec.attribute("oiio:ColorSpace", tag)
    # samples are stored as given: a 4th (or 2nd) channel is data, never premultiplied into the others
    spec.attribute("oiio:UnassociatedAlpha", 1)
    # no write-time stamp (OpenImageIO stamps EXR and TIFF with the clock otherwise): the same image gives the
    # same bytes, so outputs can be compared and a batch can be resumed; pass attributes={"DateTime": ...} to set one
    spec.attribute("DateTime", "")
    for key, value in (attributes or {}).items():
        spec.attribute(key, value)
    with atomic_output(p, overwrite=overwrite, suffix=p.suffix) as tmp:
        out = oiio.ImageOutput.create(str(p))
        if out is None:
            raise FormatError(f"{p}: OpenImageIO has no writer for {ext} ({oiio.geterror()})")
        if not out.open(str(tmp), spec):
            raise FormatError(f"{p}: cannot open for writing: {out.geterror()}")
        # OpenImageIO's Python binding expects (H, W, C); a 2-D array is not laid out as rows
        ok = out.write_image(np.ascontiguousarray(data.reshape(a.shape[0], a.shape[1], channels)))
        err = out.geterror()
        out.close()
        if not ok:
            raise FormatError(f"{p}: writing failed: {err}")
    log.debug("wrote %s (%s, %d bit)", p, a.shape, bit_depth)
    return p


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image in its stored sample type.

    Parameters
    ----------
    path : path-like
        Any format OpenImageIO reads (PNG, TIFF, EXR, JPEG, PNM, ...); ``.pfm`` is read by
        :func:`plenodecode.io.pfm.read_pfm` (rows returned top-down).

    Returns
    -------
    ndarray, shape (H, W) for one channel, else (H, W, C)
        dtype as stored: uint8, uint16, float16 (half EXR), float32, ...  First subimage only.

    Raises
    ------
    FormatError
        The file is missing or not a readable image.
    """
    p = Path(path)
    if not p.is_file():
        raise FormatError(f"{p}: no such image file; check the path")
    if p.suffix.lower() == ".pfm":
        return pfm.read_pfm(p)
    oiio = _oiio()
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)   # return alpha files' samples as stored
    inp = oiio.ImageInput.open(str(p), config)
    if inp is None:
        raise FormatError(f"{p}: not a readable image ({oiio.geterror().strip()}); "
                          "expected PNG, TIFF, EXR, JPEG, PNM or another OpenImageIO format")
    try:
        spec = inp.spec()
        data = inp.read_image(0, 0, 0, spec.nchannels, "unknown")
        if data is None:
            raise FormatError(f"{p}: image data unreadable ({inp.geterror().strip()}); the file may be truncated")
        if inp.has_error:
            # a JPEG cut short is still returned whole, its missing rows filled with mid-grey: refused, not decoded
            message = inp.geterror().strip()
            if "premature end" in message.lower():
                raise FormatError(f"{p}: the image data ends early ({message}); the file is truncated "
                                  "(an interrupted copy or download?)")
            log.warning("%s: %s", p.name, message)
    finally:
        inp.close()
    data = np.asarray(data)
    if data.ndim == 3 and data.shape[2] == 1:
        data = data[:, :, 0]
    return data


def _strip_gif_loop(raw: bytes) -> bytes:
    """Remove the NETSCAPE2.0 looping extension that OpenImageIO always writes (GIF89a spec:
    header 6 B, logical screen descriptor 7 B, optional global colour table, then extensions)."""
    packed = raw[10]
    pos = 13 + (3 * 2 ** ((packed & 7) + 1) if packed & 0x80 else 0)
    block = b"\x21\xff\x0bNETSCAPE2.0\x03\x01"
    if raw[pos:pos + len(block)] == block and raw[pos + 18:pos + 19] == b"\x00":
        return raw[:pos] + raw[pos + 19:]
    return raw


def write_animation(path: str | os.PathLike, frames: np.ndarray, *, fps: float, loop: bool = True,
                    overwrite: bool = False, encode_srgb: bool = False) -> Path:
    """Write an animated GIF (OpenImageIO) or WebP (Pillow), atomically.

    Parameters
    ----------
    path : path-like
        ``.gif`` or ``.webp``.
    frames : ndarray, shape (N, H, W, 3) (or (N, H, W)), float in [0, 1] or uint8
    fps : float
        Frames per second (> 0).  GIF stores delays in 1/100 s, so the rate is rounded.
    loop : bool
        Loop forever (True) or play once (False).
    overwrite : bool
        Replace an existing file; otherwise :class:`FileExistsError`.
    encode_srgb : bool
        Apply the sRGB transfer function before quantising to 8 bits.

    Returns
    -------
    Path
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in ANIMATION_FORMATS:
        raise ValueError(f"path must end in one of {ANIMATION_FORMATS}, got {p.name!r}")
    if not (fps > 0):
        raise ValueError(f"fps must be positive, got {fps!r}")
    f = np.asarray(frames)
    if f.ndim == 3:
        f = np.repeat(f[..., None], 3, axis=-1)
    if f.ndim != 4 or f.shape[-1] != 3 or f.shape[0] < 1:
        raise ValueError(f"frames must have shape (N, H, W, 3), got {np.shape(frames)}")
    data = quantise(f, 8, encode_srgb=encode_srgb)
    with atomic_output(p, overwrite=overwrite, suffix=p.suffix) as tmp:
        if ext == ".gif":
            _write_gif(p, tmp, data, fps, loop)
        else:
            from PIL import Image

            images = [Image.fromarray(np.ascontiguousarray(frame), "RGB") for frame in data]
            images[0].save(tmp, format="WEBP", save_all=True, append_images=images[1:],
                           duration=int(round(1000.0 / fps)), loop=0 if loop else 1, lossless=True)
    return p


def _write_gif(p: Path, tmp: Path, data: np.ndarray, fps: float, loop: bool) -> None:
    oiio = _oiio()
    n, h, w, _ = data.shape
    spec = oiio.ImageSpec(w, h, 3, "uint8")
    delay_cs = max(1, int(round(100.0 / fps)))
    spec.attribute("FramesPerSecond", oiio.TypeDesc("rational"), (100, delay_cs))
    spec.attribute("oiio:Movie", 1)
    out = oiio.ImageOutput.create(str(p))
    if out is None or not out.open(str(tmp), [spec] * n):
        raise FormatError(f"{p}: cannot open GIF for writing ({oiio.geterror()})")
    try:
        for i in range(n):
            if i and not out.open(str(tmp), spec, "AppendSubimage"):
                raise FormatError(f"{p}: cannot append GIF frame {i}: {out.geterror()}")
            if not out.write_image(np.ascontiguousarray(data[i])):
                raise FormatError(f"{p}: writing GIF frame {i} failed: {out.geterror()}")
    finally:
        out.close()
    if not loop:
        tmp.write_bytes(_strip_gif_loop(tmp.read_bytes()))


__all__ = ["IMAGE_FORMATS", "ANIMATION_FORMATS", "write_image", "read_image", "write_animation",
           "quantise", "to_unit_float", "srgb_encode", "srgb_decode"]
