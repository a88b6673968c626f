"""How to read an image mosaic that has no sidecar: colour filter, levels and value encoding.

A lenslet mosaic saved as an ordinary 8-bit or 16-bit image (JPEG, PNG, TIFF) carries no CFA and
no levels.  :class:`MosaicOptions` holds what the user says about it (the CLI's ``--cfa``,
``--black-level``, ``--white-level``, ``--input-encoding``); what is not said is filled in, in this
order (:func:`bare_mosaic_levels` and :func:`bare_mosaic_cfa`):

* the CFA: ``--cfa``; else the sensor known by the image size (:data:`KNOWN_SENSORS`: 3280 x 3280
  Lytro F01 BGGR, 7728 x 5368 (W x H) Lytro Illum GRBG); else monochrome (an image of unknown size is read
  as monochrome unless ``--cfa`` is given);
* the levels: ``--black-level`` / ``--white-level``; else the known sensor's levels carried through the
  known chain that wrote the file (:func:`known_levels`: the raw values as stored, or the F01 JPEGs of
  Tao et al.); else the black level is estimated from the dark gaps between micro-images
  (:func:`estimate_black_level`) and the white level is the file's full scale.

``--input-encoding srgb`` says the samples are display-encoded: they (and the levels) get the inverse
sRGB transfer function (:func:`plenodecode.io.images.srgb_decode`) before decoding.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from ..types import CFA_PATTERNS
from .images import srgb_decode

log = logging.getLogger(__name__)

#: ``--cfa`` choices: a Bayer pattern, or 'mono' for a sensor without colour filters.
CFA_CHOICES = (*CFA_PATTERNS, "mono")
#: ``--input-encoding`` choices: 'linear' (sensor values) or 'srgb' (display-encoded values).
INPUT_ENCODINGS = ("linear", "srgb")
#: Window (px) in which a dark spot between micro-images is the darkest (:func:`estimate_black_level`).
DARK_WINDOW = 5
#: Share of the dark spots, the darkest, whose median is the black level (:func:`estimate_black_level`).
DARK_SHARE = 0.1
#: The black estimate must not exceed this percentile of the image, else there were no dark gaps.
GAP_PERCENTILE = 5.0
#: Smallest mosaic (pixels) whose black level is estimated: smaller images hold too few micro-images.
MIN_ESTIMATE_PIXELS = 64 * 64
#: A mosaic whose 1st..99th percentiles span less than this share of full scale holds no micro-images (a dark
#: frame: the ant-leg microscope's spans 0.02 %, its light field 5 %, the darkest F01 JPEG 23 %).
UNIFORM_SPAN = 0.005
#: Below this share of full scale (99th percentile) a nearly uniform mosaic is dark.
DARK_SHARE_OF_FULL = 0.05


@dataclass(frozen=True)
class MosaicOptions:
    """What the user says about an image mosaic; None (and 'linear') mean "find out".

    Attributes
    ----------
    cfa : str or None
        A Bayer pattern of :data:`~plenodecode.types.CFA_PATTERNS`, 'mono', or None (sidecar, known
        sensor, else monochrome).
    black_level, white_level : float or None
        Levels in the units of the stored samples (before any sRGB decoding); ``white > black >= 0``.
    input_encoding : {'linear', 'srgb'}
        'srgb': the samples are display-encoded and get the inverse sRGB transfer function.
    dark_frame : str or None
        Name of the dark frame (``--dark``) the decoder subtracts pixel by pixel instead of the black level: the
        reader's log line then names it rather than a black level the decoding will not use.

    The names are those of the CLI options (``--black-level``) and of :class:`plenodecode.batch.BatchOptions`.

    Raises
    ------
    ValueError
        A value out of range; the message names the parameter.
    """

    cfa: str | None = None
    black_level: float | None = None
    white_level: float | None = None
    input_encoding: str = "linear"
    dark_frame: str | None = None

    def __post_init__(self) -> None:
        if self.cfa is not None and self.cfa not in CFA_CHOICES:
            raise ValueError(f"cfa must be one of {CFA_CHOICES} or None, got {self.cfa!r}")
        if self.input_encoding not in INPUT_ENCODINGS:
            raise ValueError(f"input_encoding must be one of {INPUT_ENCODINGS}, got {self.input_encoding!r}")
        for name in ("black_level", "white_level"):
            value = getattr(self, name)
            if value is not None:
                value = float(value)
                if not np.isfinite(value) or value < 0:
                    raise ValueError(f"{name} must be a finite level >= 0, got {getattr(self, name)!r}")
                object.__setattr__(self, name, value)
        if self.black_level is not None and self.white_level is not None and self.white_level <= self.black_level:
            raise ValueError(f"white_level ({self.white_level:g}) must exceed black_level ({self.black_level:g})")

    @property
    def given(self) -> bool:
        """True when any of the mosaic options (not ``dark_frame``) differs from its default."""
        return replace(self, dark_frame=None) != MosaicOptions()


@dataclass(frozen=True)
class KnownSensor:
    """A plenoptic camera's sensor, recognised by the size of its mosaic.

    Attributes
    ----------
    name : str
    cfa : str
        Bayer pattern of the full sensor read-out.
    bits : int
        Bits of the raw values.
    black, white : float
        Levels of the raw values.
    """

    name: str
    cfa: str
    bits: int
    black: float
    white: float


#: (rows, cols) -> sensor.  Levels from the cameras' metadata (F01 ``image.rawDetails``, Illum frame JSON).
KNOWN_SENSORS: dict[tuple[int, int], KnownSensor] = {
    (3280, 3280): KnownSensor("Lytro F01", "BGGR", 12, 168.0, 4095.0),
    (5368, 7728): KnownSensor("Lytro Illum", "GRBG", 10, 64.0, 1023.0),
}

#: Tao et al.'s ``raw2jpeg.m`` (the F01 lenslet JPEGs): the 12-bit values in 16-bit words (x 16), times 1.5
#: with uint16 saturation, then ``im2uint8`` (/ 257, rounded).
F01_JPEG_GAIN = 16 * 1.5


def known_levels(sensor: KnownSensor, bits: int, peak: float) -> tuple[float, float, str] | None:
    """The sensor's levels in the units of a file that holds its mosaic, when the chain that wrote it is known.

    * 8-bit file of the F01: ``raw2jpeg.m`` of Tao et al., ``v = min(raw * 16 * 1.5, 65535) / 257``, so
      black ``168 * 24 / 257 = 15.7`` and white ``min(4095 * 24, 65535) / 257 = 255`` (the clip);
    * a file of more than 8 bits whose samples never exceed the sensor's white level: the raw values
      as stored.

    Parameters
    ----------
    sensor : KnownSensor
    bits : int
        Bits per sample of the file.
    peak : float
        Largest sample in the file.

    Returns
    -------
    (black, white, how) or None
        None when the chain is not known.
    """
    if bits == 8 and sensor.name == "Lytro F01":
        black = sensor.black * F01_JPEG_GAIN / 257.0
        white = min(sensor.white * F01_JPEG_GAIN, 65535.0) / 257.0
        return black, white, (f"{sensor.name} levels {sensor.black:g}/{sensor.white:g} through raw2jpeg.m "
                              "(x16 x1.5, im2uint8)")
    if bits > 8 and peak <= sensor.white:
        return sensor.black, sensor.white, f"{sensor.name} levels, raw values as stored"
    return None


def estimate_black_level(mosaic: np.ndarray) -> float | None:
    """Black level of a lenslet mosaic from the dark gaps between its micro-images; no grid needed.

    1. ``s = B * x``: the mosaic smoothed by the 3x3 binomial filter ``B`` (the CFA pattern and most of
       the noise gone);
    2. the dark spots: pixels where ``s`` is the minimum of its :data:`DARK_WINDOW` x :data:`DARK_WINDOW`
       neighbourhood (``s == erode(s)``); between micro-images there is at least one per lens;
    3. the darkest :data:`DARK_SHARE` of the dark spots by ``s`` (those of dark parts of the scene,
       where the least light spills into the gaps);
    4. the estimate is the median of the *raw* values ``x`` at those spots.

    Light spilling into gaps narrower than a pixel raises the estimate; choosing the spots by ``s``,
    which holds a quarter of the pixel's own noise, lowers it by up to about one noise sigma where the
    gaps are wide and flat.  Measured on the generated cameras (12-bit, 4095 = white): F01 +8, Illum
    (10-bit) -1, square microscope -4.

    Parameters
    ----------
    mosaic : ndarray, shape (H, W), integer or float
        The stored samples (any CFA: in the gaps every colour is black).

    Returns
    -------
    float or None
        None when the mosaic is smaller than :data:`MIN_ESTIMATE_PIXELS`, or the estimate is above the
        image's :data:`GAP_PERCENTILE`-th percentile (no dark gaps: not a lenslet mosaic, or one with
        overlapping micro-images; on lenslet mosaics it lies at or below the 1st percentile).
    """
    import cv2

    x = np.asarray(mosaic, np.float32)
    if x.ndim != 2 or x.size < MIN_ESTIMATE_PIXELS:
        return None
    taps = np.array([0.25, 0.5, 0.25], np.float32)
    s = cv2.sepFilter2D(x, -1, taps, taps, borderType=cv2.BORDER_REFLECT)
    spots = s <= cv2.erode(s, np.ones((DARK_WINDOW, DARK_WINDOW), np.uint8), borderType=cv2.BORDER_REFLECT)
    smooth, raw = s[spots], x[spots]
    black = float(np.median(raw[smooth <= np.quantile(smooth, DARK_SHARE)]))
    if black > float(np.percentile(x[::3, ::3], GAP_PERCENTILE)):
        return None
    return black


def nearly_uniform(mosaic: np.ndarray, full_scale: float) -> tuple[float, float] | None:
    """The 1st and 99th percentiles of a mosaic that holds no micro-images: they span less than
    :data:`UNIFORM_SPAN` of ``full_scale`` (a dark frame, a capture without light); None otherwise.

    Parameters
    ----------
    mosaic : ndarray, shape (H, W)
        The stored samples.
    full_scale : float
        The largest value the file can hold.
    """
    x = np.asarray(mosaic)
    if x.ndim != 2 or x.size == 0:
        return None
    lo, hi = (float(v) for v in np.percentile(x[::3, ::3], [1.0, 99.0]))
    return (lo, hi) if hi - lo < UNIFORM_SPAN * float(full_scale) else None


def linearise_srgb(mosaic: np.ndarray, full_scale: float) -> np.ndarray:
    """Display-encoded uint8/uint16 samples -> linear uint16 ``rint(65535 * srgb_decode(x / full_scale))``.

    A lookup table of every stored value keeps it fast for 8- and 16-bit mosaics.

    Parameters
    ----------
    mosaic : ndarray, shape (H, W), uint16
    full_scale : float
        The stored value that means 1.0 (255 for 8-bit files).

    Returns
    -------
    ndarray, shape (H, W), uint16
    """
    lut = np.rint(65535.0 * srgb_decode(np.arange(65536) / float(full_scale))).astype(np.uint16)
    return lut[mosaic]


def bare_mosaic_cfa(shape: tuple[int, int], options: MosaicOptions) -> tuple[str | None, str]:
    """CFA of a mosaic without a sidecar and where it came from: ``--cfa``, the known sensor, or monochrome."""
    if options.cfa is not None:
        return (None if options.cfa == "mono" else options.cfa), "--cfa"
    sensor = KNOWN_SENSORS.get(tuple(shape))
    if sensor is not None:
        return sensor.cfa, f"{shape[1]} x {shape[0]}: {sensor.name} sensor"
    return None, f"unknown sensor size {shape[1]} x {shape[0]}, monochrome unless --cfa is given"   # W x H, as info


def bare_mosaic_levels(mosaic: np.ndarray, bits: int, full_scale: float,
                       options: MosaicOptions) -> tuple[float, float, str]:
    """Black and white level (units of the stored samples) of a mosaic without a sidecar, and where they came from.

    ``--black-level``/``--white-level`` first; then :func:`known_levels` of the sensor known by the size;
    then :func:`estimate_black_level` (black 0 when it finds no gaps, or the image is :func:`nearly_uniform`) and the
    file's full scale.

    Parameters
    ----------
    mosaic : ndarray, shape (H, W), uint16
        The stored samples.
    bits : int
        8 for an 8-bit file, else 16.
    full_scale : float
        The largest value the file can hold (``2**bits - 1``, a PGM's MAXVAL).
    options : MosaicOptions

    Returns
    -------
    black, white : float
    how : str
        One phrase for the log line.
    """
    full = float(full_scale)
    sensor = KNOWN_SENSORS.get(tuple(mosaic.shape))
    known = None if sensor is None else known_levels(sensor, bits, float(mosaic.max()))
    if known is not None:
        black, white, how = known
    else:
        uniform = None if options.black_level is not None else nearly_uniform(mosaic, full)
        estimated = None if options.black_level is not None or uniform is not None else estimate_black_level(mosaic)
        black, white = (0.0 if estimated is None else estimated), full
        if uniform is not None:     # no gaps to take a black level from: say what the image is instead
            dark = uniform[1] < DARK_SHARE_OF_FULL * full
            how = (f"no micro-images to estimate the black level from: nearly uniform{' and dark' * dark}, 98 % of "
                   f"the values within {uniform[0]:g}..{uniform[1]:g}{', as in a dark frame' * dark}; white = full "
                   f"scale {full:g}")
        else:
            how = ("black estimated from the gaps between micro-images" if estimated is not None
                   else "no dark gaps found to estimate the black level from, black 0")
            how += f", white = full scale {full:g}"
    if options.black_level is not None or options.white_level is not None:
        black = black if options.black_level is None else options.black_level
        white = white if options.white_level is None else options.white_level
        given = [f"{name} {value:g}" for name, value in (("--black-level", options.black_level),
                                                          ("--white-level", options.white_level)) if value is not None]
        how = " and ".join(given) + ("" if options.black_level is not None and options.white_level is not None else f"; {how}")
    return black, white, how


__all__ = ["MosaicOptions", "KnownSensor", "KNOWN_SENSORS", "CFA_CHOICES", "INPUT_ENCODINGS", "known_levels",
           "estimate_black_level", "nearly_uniform", "linearise_srgb", "bare_mosaic_cfa", "bare_mosaic_levels"]
