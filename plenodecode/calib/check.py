"""Does a white image's grid fit the raw?  Checked on the raw itself, before decoding.

A white image of the same camera but another zoom/focus (or another unit) puts the lattice a
fraction of a pitch off the raw's micro-images, and the decode is visibly damaged; the scene given
as its own white image devignettes everything to a uniform grey-pink.  :func:`check_white_fit`
catches both cheaply, in the manner of a self-calibration restricted to a sample of lenses:

1. **The white is a flat field.**  Not the raw itself, and, unless its metadata tags it as a white
   image (Lytro ``modulationFrame``, a sidecar's ``is_white_image``), its lenslet-scale brightness
   varies less than :data:`MAX_SCENE_LIKENESS` beyond a smooth vignetting
   (:func:`~plenodecode.calib.white.scene_likeness`; white images < ~0.08, scenes > ~0.15; the same
   rule as :func:`~plenodecode.calib.calibrate`'s warning).
2. **The lattice sits on the raw's micro-images.**  In a few tiles of the raw (centre and four
   off-centre), the Bayer-collapsed image is turned into lenslet contrast ``I / L - 1``
   (:func:`~plenodecode.calib.centroids.devignette`) and smoothed with the lenslet matched filter
   (Gaussian, sigma = pitch / 4, as LFToolbox and PlenoptiCam detect disks).  For every lens the grid
   predicts in a tile, the filtered image's maximum within ``0.45 * pitch`` of the prediction,
   refined by a parabola through its neighbours along each axis, is the measured micro-image centre
   ``m_i``; the offset is ``d_i = m_i - p_i``.  Lenses with little contrast (dark scene parts) are
   dropped.  The lattice is refused when, in any tile, ``|median_i d_i| > MAX_SHIFT_PITCH * pitch``
   (the median is robust to the scene texture inside micro-images, which moves single maxima); the
   spread is the median of ``|d_i - median d|``.

A raw whose micro-images cannot be measured (too few lenses with contrast, e.g. a black frame)
passes with a log line: the check refuses only what it has seen.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import CalibrationError
from ..types import LensletGrid, RawCapture

log = logging.getLogger(__name__)

#: Refuse a lattice whose centres are off the raw's micro-images by more than this fraction of the pitch.
MAX_SHIFT_PITCH = 0.15
#: Refuse a white image whose lens-scale brightness varies more than this (:func:`~plenodecode.calib.white.scene_likeness`).
MAX_SCENE_LIKENESS = 0.12
#: Fewest measured lenses for a verdict on the lattice.
MIN_LENSES = 30
#: Side of the tiles measured, in pitches (at least :data:`MIN_TILE_PX`).
TILE_PITCHES = 24
MIN_TILE_PX = 256
#: Search radius around a predicted centre, in pitches (inside the lens's own Voronoi cell, radius pitch / 2).
SEARCH_PITCH = 0.45


class WhiteMismatchError(CalibrationError):
    """The white image does not fit the raw (:func:`check_white_fit`); the message names better choices."""


@dataclass(frozen=True)
class LatticeFit:
    """How the grid's centres sit on the raw's micro-images (:func:`measure_lattice_fit`).

    Attributes
    ----------
    offset_px : (float, float)
        Median ``(row, col)`` offset measured - predicted over all measured lenses, px.
    worst_shift_pitch : float
        Largest ``|median offset|`` of a tile, in pitches.
    spread_px : float
        Median ``|d_i - median d|`` over all measured lenses, px.
    n_lenses : int
        Lenses measured (with enough contrast).
    tile_offsets_px : tuple of (float, float)
        Median offset of each tile that had at least a few lenses.
    """

    offset_px: tuple[float, float]
    worst_shift_pitch: float
    spread_px: float
    n_lenses: int
    tile_offsets_px: tuple[tuple[float, float], ...]

    @property
    def measured(self) -> bool:
        """Enough lenses for a verdict (:data:`MIN_LENSES`)."""
        return self.n_lenses >= MIN_LENSES


def _tile_origins(shape: tuple[int, int], side: int) -> list[tuple[int, int]]:
    """Top-left corners (even, so the CFA phase is kept) of the centre tile and four off-centre tiles."""
    h, w = shape
    out = []
    for fy, fx in ((0.5, 0.5), (0.25, 0.25), (0.25, 0.75), (0.75, 0.25), (0.75, 0.75)):
        r0 = int(min(max(0, fy * h - side / 2), max(0, h - side))) & ~1
        c0 = int(min(max(0, fx * w - side / 2), max(0, w - side))) & ~1
        if (r0, c0) not in out:
            out.append((r0, c0))
    return out


def _disk_offsets(radius: float) -> np.ndarray:
    """Integer ``(dy, dx)`` within ``radius`` of 0, shape (K, 2) int64."""
    n = int(math.ceil(radius))
    dy, dx = np.mgrid[-n:n + 1, -n:n + 1]
    keep = dy ** 2 + dx ** 2 <= radius ** 2
    return np.stack([dy[keep], dx[keep]], axis=1)


def _measure_tile(g: np.ndarray, pred: np.ndarray, pitch: float) -> np.ndarray:
    """Offsets ``m_i - p_i`` (M, 2) float64 of the lenses with contrast; ``pred`` (N, 2) in tile px.

    ``m_i`` is the maximum of ``g`` within :data:`SEARCH_PITCH` pitches of ``round(p_i)``, refined by the
    vertex of the parabola through the maximum and its two neighbours along each axis.
    """
    disk = _disk_offsets(SEARCH_PITCH * pitch)
    base = np.rint(pred).astype(np.int64)
    rr, cc = base[:, None, 0] + disk[None, :, 0], base[:, None, 1] + disk[None, :, 1]
    vals = g[rr, cc]                                               # (N, K)
    k = np.argmax(vals, axis=1)
    idx = np.arange(len(pred))
    peak_r, peak_c = rr[idx, k], cc[idx, k]
    contrast = vals[idx, k] - vals.min(axis=1)
    keep = contrast >= 0.5 * float(np.median(contrast))
    h, w = g.shape
    keep &= (peak_r > 0) & (peak_r < h - 1) & (peak_c > 0) & (peak_c < w - 1)
    peak_r, peak_c = peak_r[keep], peak_c[keep]

    def vertex(m1: np.ndarray, m0: np.ndarray, p1: np.ndarray) -> np.ndarray:
        den = m1 - 2.0 * m0 + p1
        return np.where(den < 0, 0.5 * (m1 - p1) / np.where(den < 0, den, -1.0), 0.0).clip(-0.5, 0.5)
    g0 = g[peak_r, peak_c].astype(np.float64)
    sub_r = vertex(g[peak_r - 1, peak_c].astype(np.float64), g0, g[peak_r + 1, peak_c].astype(np.float64))
    sub_c = vertex(g[peak_r, peak_c - 1].astype(np.float64), g0, g[peak_r, peak_c + 1].astype(np.float64))
    measured = np.stack([peak_r + sub_r, peak_c + sub_c], axis=1)
    return measured - pred[keep]


def measure_lattice_fit(raw: RawCapture, grid: LensletGrid) -> LatticeFit:
    """Measure where the raw's micro-images are relative to the grid's centres (see the module docstring).

    Parameters
    ----------
    raw : RawCapture
        The scene raw, mosaic (H, W) uint16 of the grid's sensor size.
    grid : LensletGrid

    Returns
    -------
    LatticeFit
    """
    from .centroids import devignette, flatten_white
    from .centroids.peaks import smooth_for_peaks

    pitch = float(grid.pitch)
    side = int(max(MIN_TILE_PX, TILE_PITCHES * pitch))
    centres = grid.centres()
    margin = SEARCH_PITCH * pitch + 2.0
    all_d: list[np.ndarray] = []
    tiles: list[tuple[float, float]] = []
    for r0, c0 in _tile_origins(raw.shape, side):
        crop = RawCapture(raw.mosaic[r0:r0 + side, c0:c0 + side], raw.cfa, raw.black, raw.white)
        h, w = crop.shape
        if min(h, w) < 4 * pitch:
            continue
        g = smooth_for_peaks(devignette(flatten_white(crop), pitch), pitch)
        pred = centres - (r0, c0)
        inside = ((pred[:, 0] >= margin) & (pred[:, 0] < h - 1 - margin) &
                  (pred[:, 1] >= margin) & (pred[:, 1] < w - 1 - margin))
        if inside.sum() < 4:
            continue
        d = _measure_tile(g, pred[inside], pitch)
        if len(d) >= 4:
            med = np.median(d, axis=0)
            tiles.append((float(med[0]), float(med[1])))
            all_d.append(d)
    if not all_d:
        return LatticeFit((0.0, 0.0), 0.0, 0.0, 0, ())
    d = np.concatenate(all_d)
    med = np.median(d, axis=0)
    spread = float(np.median(np.hypot(*(d - med).T)))
    worst = max(math.hypot(*t) for t in tiles) / pitch
    return LatticeFit((float(med[0]), float(med[1])), float(worst), spread, int(len(d)), tuple(tiles))


def _same_picture(raw: RawCapture, white: RawCapture) -> bool:
    if white is raw or (raw.path and white.path and Path(str(raw.path)) == Path(str(white.path))):
        return True
    return white.shape == raw.shape and bool(np.array_equal(white.mosaic, raw.mosaic))


def white_scene_likeness(white: RawCapture, pitch: float) -> float:
    """:func:`~plenodecode.calib.white.scene_likeness` of the central part of a white image (about 48 x 48 lenses)."""
    from .centroids import flatten_white
    from .white import scene_likeness

    side = int(max(2 * MIN_TILE_PX, 2 * TILE_PITCHES * pitch))
    h, w = white.shape
    r0, c0 = max(0, (h - side) // 2) & ~1, max(0, (w - side) // 2) & ~1
    crop = RawCapture(white.mosaic[r0:r0 + side, c0:c0 + side], white.cfa, white.black, white.white)
    return scene_likeness(flatten_white(crop), pitch)


def check_white_fit(raw: RawCapture, grid: LensletGrid, white: RawCapture | None = None, *,
                    white_name: str | None = None, alternatives: Sequence[str] = ()) -> LatticeFit:
    """Refuse, in one line naming better choices, a white image (and its grid) that does not fit ``raw``.

    Parameters
    ----------
    raw : RawCapture
        The scene raw to be decoded.
    grid : LensletGrid
        The grid fitted on ``white``.
    white : RawCapture, optional
        The white image that will devignette ``raw``.
    white_name : str, optional
        How the message names the white image (default its file name).
    alternatives : sequence of str
        Other white images of the camera to offer (e.g. ``'MOD_0003.RAW (zoom 100, focus 10)'``).

    Returns
    -------
    LatticeFit
        The measurement, when the white image fits.

    Raises
    ------
    WhiteMismatchError
        The white image is the picture itself or a scene, or the lattice is more than
        :data:`MAX_SHIFT_PITCH` pitch off the raw's micro-images.
    """
    name = white_name or (Path(str(white.path)).name if white is not None and white.path else "the white image")
    raw_name = Path(str(raw.path)).name if raw.path else "the raw"
    others = f"another white image of this camera ({', '.join(alternatives)})" if alternatives else \
        "the white image of this camera taken at the raw's zoom and focus (--white MOD_NNNN.RAW or --database DIR)"
    choices = f"use {others} or --self-calibrate"
    if white is not None:
        if _same_picture(raw, white):
            raise WhiteMismatchError(f"the white image {name} is the picture {raw_name} itself, not a flat field; "
                                     f"{choices}")
        likeness = 0.0 if white.metadata.is_white_image else white_scene_likeness(white, float(grid.pitch))
        if likeness > MAX_SCENE_LIKENESS:
            raise WhiteMismatchError(f"the white image {name} is a scene, not a flat field (its lenslet-scale "
                                     f"brightness varies by {likeness:.0%}, a white image's by < "
                                     f"{MAX_SCENE_LIKENESS:.0%}); {choices}")
    if tuple(grid.sensor_shape) != tuple(raw.shape):
        raise WhiteMismatchError(f"the grid of {name} is for a {grid.sensor_shape[1]}x{grid.sensor_shape[0]} sensor "
                                 f"but {raw_name} is {raw.shape[1]}x{raw.shape[0]}; {choices}")
    fit = measure_lattice_fit(raw, grid)
    if not fit.measured:
        log.info("%s: too few micro-images with contrast (%d) to check the lattice of %s", raw_name, fit.n_lenses,
                 name)
        return fit
    if fit.worst_shift_pitch > MAX_SHIFT_PITCH:
        shift_px = fit.worst_shift_pitch * grid.pitch
        raise WhiteMismatchError(
            f"the white image {name} does not fit {raw_name}: its lenslet centres are {fit.worst_shift_pitch:.2f} "
            f"pitch ({shift_px:.1f} px) off the micro-images measured in the raw ({fit.n_lenses} lenses, spread "
            f"{fit.spread_px:.2f} px; at most {MAX_SHIFT_PITCH:.2f} pitch is accepted); {choices}")
    log.info("white %s fits %s: lattice offset %.2f px (%.3f pitch), spread %.2f px over %d lenses", name, raw_name,
             math.hypot(*fit.offset_px), fit.worst_shift_pitch, fit.spread_px, fit.n_lenses)
    return fit


__all__ = ["LatticeFit", "WhiteMismatchError", "check_white_fit", "measure_lattice_fit", "white_scene_likeness",
           "MAX_SHIFT_PITCH", "MAX_SCENE_LIKENESS"]
