"""Radiometric preparation of a lenslet mosaic: levels, dark frame, hot pixels, devignetting.

All functions are pure and work on any horizontal band of the sensor whose first row is even
(so the 2x2 CFA phase is kept); :func:`plenodecode.decoding.decode` calls them band by band.

Devignetting (LFToolbox, Dansereau et al. CVPR 2013; formats.md section 4.2) divides the
normalised raw by the normalised white image of the same camera, zoom and focus::

    radiance = (raw - black) / (white - black)      (per pixel, per CFA channel)

which removes the lenslet disk profile and the main-lens vignetting together.  Where the white is
dark (lenslet rims, gaps between lenses) the ratio is noise: pixels whose white is below ``floor``
times the local peak of the white are marked missing (NaN) and the weight of the decoded samples
comes from the white itself (:func:`relative_white`).
"""

from __future__ import annotations

import logging

import cv2
import numpy as np

from .._numba import njit
from ..types import cfa_channel_map

log = logging.getLogger(__name__)

#: default floor of the relative white below which a pixel is treated as missing
DEFAULT_FLOOR = 0.05


def _tile(values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    h, w = shape
    return np.tile(np.asarray(values, np.float32), ((h + 1) // 2, (w + 1) // 2))[:h, :w]


@njit(cache=True, nogil=True, error_model="numpy")
def _normalise(mosaic, black, scale, out):  # pragma: no cover - numba
    h, w = mosaic.shape
    for y in range(h):
        for x in range(w):
            out[y, x] = (np.float32(mosaic[y, x]) - black[y & 1, x & 1]) * scale[y & 1, x & 1]


@njit(cache=True, nogil=True, error_model="numpy")
def _normalise_dark(mosaic, dark, scale, out):  # pragma: no cover - numba
    h, w = mosaic.shape
    for y in range(h):
        for x in range(w):
            out[y, x] = (np.float32(mosaic[y, x]) - np.float32(dark[y, x])) * scale[y & 1, x & 1]


def normalise(mosaic: np.ndarray, black: np.ndarray, white: np.ndarray, *, dark: np.ndarray | None = None,
              gains: np.ndarray | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """Scale a mosaic to ``g (x - black) / (white - black)`` per CFA position (``g = 1`` by default).

    The one implementation of level normalisation (:meth:`plenodecode.types.RawCapture.normalised` gives
    the same values).

    Parameters
    ----------
    mosaic : ndarray, shape (H, W), uint16 or float
        Sensor values (a band starting on an even row).
    black, white : ndarray, shape (2, 2)
        Levels of each position of the 2x2 CFA tile.
    dark : ndarray, shape (H, W), optional
        Dark frame in sensor units; replaces the black level pixel by pixel (the scale stays
        ``g / (white - black)``).
    gains : ndarray, shape (2, 2), optional
        Per-position factors ``g`` (e.g. CFA equalisation gains of a white image).
    out : ndarray, shape (H, W), float32, optional
        Destination (a scratch buffer); a new array when None.

    Returns
    -------
    ndarray, shape (H, W), float32 (not clipped)
    """
    black = np.broadcast_to(np.asarray(black, np.float32), (2, 2)).copy()
    g = 1.0 if gains is None else np.broadcast_to(np.asarray(gains, np.float64), (2, 2))
    scale = (g / (np.broadcast_to(np.asarray(white, np.float64), (2, 2)) - black)).astype(np.float32)
    out = np.empty(mosaic.shape, np.float32) if out is None else out
    if dark is not None:
        if dark.shape != mosaic.shape:
            raise ValueError(f"dark must have the mosaic's shape {mosaic.shape}, got {dark.shape}")
        _normalise_dark(mosaic, dark, scale, out)
    else:
        _normalise(mosaic, black, scale, out)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _hot(x, threshold, relative, flags):  # pragma: no cover - numba
    h, w = x.shape
    n = 0
    for y in range(h):
        inner_row = y >= 2 and y < h - 2
        for xx in range(w):
            if inner_row and xx >= 2 and xx < w - 2:      # all 8 neighbours exist
                m = max(max(max(x[y - 2, xx - 2], x[y - 2, xx]), max(x[y - 2, xx + 2], x[y, xx - 2])),
                        max(max(x[y, xx + 2], x[y + 2, xx - 2]), max(x[y + 2, xx], x[y + 2, xx + 2])))
                hot = x[y, xx] > m + max(threshold, relative * m)
                flags[y, xx] = hot
                if hot:
                    n += 1
                continue
            m = -np.inf
            for t in range(9):
                if t == 4:
                    continue
                yy = y + 2 * (t // 3 - 1)
                xq = xx + 2 * (t % 3 - 1)
                if yy < 0 or yy >= h or xq < 0 or xq >= w:
                    continue
                v = x[yy, xq]
                if v > m:
                    m = v
            hot = m > -np.inf and x[y, xx] > m + max(threshold, relative * m)
            flags[y, xx] = hot
            if hot:
                n += 1
    return n


#: row and column steps to the 8 same-colour neighbours (2 px away along rows, columns and diagonals)
_NEIGHBOUR_DY = np.array([-2, -2, -2, 0, 0, 2, 2, 2])
_NEIGHBOUR_DX = np.array([-2, 0, 2, -2, 2, -2, 0, 2])


def _repair(x: np.ndarray, flags: np.ndarray, out: np.ndarray) -> None:
    """Write ``x`` into ``out`` with every flagged pixel replaced by the median of its lit neighbours.

    The neighbours of a flagged pixel are its (up to 8) same-colour pixels 2 px away that are inside the image
    and not flagged; the lit ones are those ``>= 0.5 * max`` of them, and the value is their median (the mean
    of the two middle ones for an even count; 0 without any)::

        out[p] = median{ x[q] : q in N8(p), not flags[q], x[q] >= max_N8(p) x / 2 }

    numpy on the gathered ``(n, 8)`` neighbour
    values: hot pixels are few (hundreds in a 40 Mpx raw), so this costs a copy of the band, and no compiled
    kernel (numba's ``np.median`` took 1.3-2.0 CPU s to compile on a cold decode).

    Parameters
    ----------
    x : ndarray, shape (H, W), float32
    flags : ndarray, shape (H, W), bool
    out : ndarray, shape (H, W), float32
        Destination (not ``x``).
    """
    np.copyto(out, x)
    h, w = x.shape
    # np.flatnonzero: about 20x faster than np.nonzero on a 2-D mask
    ys, xs = np.divmod(np.flatnonzero(flags), w)
    if ys.size == 0:
        return
    ny = ys[:, None] + _NEIGHBOUR_DY
    nx = xs[:, None] + _NEIGHBOUR_DX
    inside = (ny >= 0) & (ny < h) & (nx >= 0) & (nx < w)
    ny, nx = np.where(inside, ny, 0), np.where(inside, nx, 0)
    usable = inside & ~flags[ny, nx]
    vals = np.where(usable, x[ny, nx], np.float32(-np.inf))
    top = vals.max(axis=1, keepdims=True)
    lit = usable & (vals >= 0.5 * top.astype(np.float64))
    vals = np.sort(np.where(lit, vals, np.float32(np.inf)), axis=1)       # lit values first, ascending
    m = lit.sum(axis=1)
    rows = np.arange(m.size)
    lo = vals[rows, np.maximum(m - 1, 0) // 2]
    hi = vals[rows, m // 2]
    out[ys, xs] = np.where(m > 0, np.float32(0.5) * (lo + hi), np.float32(0.0))


def find_hot_pixels(mosaic: np.ndarray, *, threshold: float = 0.1, relative: float = 0.5) -> np.ndarray:
    """Pixels brighter than all their (up to 8) same-colour neighbours by a clear margin.

    A pixel ``p`` is hot when ``x[p] > m + max(threshold, relative * m)`` with ``m`` the maximum of
    its same-colour neighbours (2 px away along rows, columns and diagonals, so the rule holds
    for every Bayer position and for monochrome sensors).  Optical detail cannot do this: the
    micro-images are smooth at 2 px, and a lenslet rim always has a brighter neighbour inside.
    Two hot pixels 2 px apart hide each other (a known limit of the rule).

    Parameters
    ----------
    mosaic : ndarray, shape (H, W), float32
        Normalised mosaic (white level = 1).
    threshold : float
        Absolute margin (normalised units).
    relative : float
        Margin relative to the neighbours' maximum.

    Returns
    -------
    ndarray, shape (H, W), bool
    """
    flags = np.empty(mosaic.shape, np.bool_)
    _hot(np.ascontiguousarray(mosaic, np.float32), np.float32(threshold), np.float32(relative), flags)
    return flags


def repair_hot_pixels(mosaic: np.ndarray, *, threshold: float = 0.1, relative: float = 0.5,
                      out: np.ndarray | None = None, flags: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Replace hot pixels by the median of their lit same-colour neighbours.

    The neighbours are the (up to 8) same-colour pixels 2 px away that are not hot themselves;
    only those at least half as bright as the brightest of them count, so a hot pixel on a
    lenslet rim is filled from the disk and not from the dark gap outside it.

    Parameters
    ----------
    mosaic : ndarray, shape (H, W), float32
        Normalised mosaic; not modified.
    threshold, relative : float
        See :func:`find_hot_pixels`.
    out : ndarray, shape (H, W), float32, optional
        Destination of the repaired copy (not ``mosaic`` itself).
    flags : ndarray, shape (H, W), bool, optional
        Work buffer for the hot-pixel mask.

    Returns
    -------
    repaired : ndarray, shape (H, W), float32
        A copy with hot pixels replaced (the input itself when there are none).
    count : int
        Number of pixels repaired.
    """
    x = np.ascontiguousarray(mosaic, np.float32)
    flags = np.empty(x.shape, np.bool_) if flags is None else flags
    n = int(_hot(x, np.float32(threshold), np.float32(relative), flags))
    if n == 0:
        return mosaic, 0
    out = np.empty_like(x) if out is None else out
    _repair(x, flags, out)
    return out, n


def white_envelope(white: np.ndarray, cfa: str | None, *, window: int, out: np.ndarray | None = None) -> np.ndarray:
    """Local peak of a normalised white image, per CFA channel.

    The white is smoothed (3x3 box on each CFA sub-plane, against noise) and dilated with a
    ``window`` x ``window`` square (about one lens pitch), so each pixel gets the peak of its lens's
    disk, including the main-lens vignetting there and the channel's own scale.

    Parameters
    ----------
    white : ndarray, shape (H, W), float32
        Normalised white mosaic (band starting on an even row).
    cfa : str or None
    window : int
        Dilation size in sensor px (about the lens pitch).
    out : ndarray, shape (H, W), float32, optional
        Destination.

    Returns
    -------
    ndarray, shape (H, W), float32, > 0
    """
    env = np.empty_like(white) if out is None else out
    k = max(1, window // 2) | 1
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (k, k))
    if cfa is None:
        sm = cv2.blur(white, (3, 3), borderType=cv2.BORDER_REFLECT)
        env[...] = cv2.dilate(sm, cv2.getStructuringElement(cv2.MORPH_RECT, (2 * k - 1, 2 * k - 1)),
                              borderType=cv2.BORDER_REFLECT)
    else:
        for r in range(2):
            for c in range(2):
                sub = np.ascontiguousarray(white[r::2, c::2])
                sm = cv2.blur(sub, (3, 3), borderType=cv2.BORDER_REFLECT)
                env[r::2, c::2] = cv2.dilate(sm, kernel, borderType=cv2.BORDER_REFLECT)
    np.maximum(env, np.float32(1e-6), out=env)
    return env


def relative_white(white: np.ndarray, cfa: str | None, *, window: int, out: np.ndarray | None = None) -> np.ndarray:
    """Fraction of its lens's peak light that each pixel receives: ``white / white_envelope``.

    Parameters
    ----------
    white : ndarray, shape (H, W), float32
        Normalised white mosaic.
    cfa : str or None
    window : int
        About one lens pitch, px.
    out : ndarray, shape (H, W), float32, optional
        Destination.

    Returns
    -------
    ndarray, shape (H, W), float32 in [0, 1]
    """
    rel = white_envelope(white, cfa, window=window, out=out)
    np.divide(white, rel, out=rel)
    np.clip(rel, 0.0, 1.0, out=rel)
    return rel


@njit(cache=True, nogil=True, error_model="numpy")
def _devignette(x, white, rel, floor, out):  # pragma: no cover - numba
    h, w = x.shape
    nan = np.float32(np.nan)
    for y in range(h):
        for xx in range(w):
            if rel[y, xx] < floor:
                out[y, xx] = nan
            else:
                out[y, xx] = x[y, xx] / max(white[y, xx], np.float32(1e-6))


def devignette(mosaic: np.ndarray, white: np.ndarray, rel: np.ndarray, *, floor: float = DEFAULT_FLOOR,
               out: np.ndarray | None = None) -> np.ndarray:
    """Divide a normalised mosaic by the normalised white, NaN where the white is too dark.

    Parameters
    ----------
    mosaic, white : ndarray, shape (H, W), float32
        Normalised raw and white (same camera settings).
    rel : ndarray, shape (H, W), float32
        Relative white (:func:`relative_white`).
    floor : float
        Pixels with ``rel < floor`` become NaN (missing).
    out : ndarray, shape (H, W), float32, optional
        Destination (may be ``mosaic`` itself: the division is elementwise).

    Returns
    -------
    ndarray, shape (H, W), float32
        ``mosaic / white`` (camera-RGB radiance, white image = 1), NaN where missing.
    """
    if not 0.0 < floor < 1.0:
        raise ValueError(f"floor must be in (0, 1), got {floor}")
    out = np.empty(mosaic.shape, np.float32) if out is None else out
    _devignette(np.ascontiguousarray(mosaic, np.float32), np.ascontiguousarray(white, np.float32),
                np.ascontiguousarray(rel, np.float32), np.float32(floor), out)
    return out


def channel_of(cfa: str | None, shape: tuple[int, int]) -> np.ndarray:
    """CFA channel index (0 R, 1 G, 2 B; 0 for monochrome) of every pixel, shape (H, W), int8."""
    return _tile(cfa_channel_map(cfa), shape).astype(np.int8)


__all__ = ["normalise", "find_hot_pixels", "repair_hot_pixels", "white_envelope", "relative_white",
           "devignette", "channel_of", "DEFAULT_FLOOR"]
