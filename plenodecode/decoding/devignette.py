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

from ..types import cfa_channel_map

log = logging.getLogger(__name__)

#: default floor of the relative white below which a pixel is treated as missing
DEFAULT_FLOOR = 0.05


def _tile(values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    h, w = shape
    return np.tile(np.asarray(values, np.float32), ((h + 1) // 2, (w + 1) // 2))[:h, :w]


def _per_row_parity(values: np.ndarray, width: int) -> list[np.ndarray]:
    """The (2, 2) CFA-tile ``values`` as two rows of ``width`` (even and odd sensor rows), float32."""
    return [_tile(values[r], (1, width))[0] for r in range(2)]


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
    if dark is not None and dark.shape != mosaic.shape:
        raise ValueError(f"dark must have the mosaic's shape {mosaic.shape}, got {dark.shape}")
    # two numpy passes per row parity, each value rounded to float32 first: the same float32 operations, in the
    # same order, as an elementwise loop (and nothing to compile)
    w = mosaic.shape[1]
    offsets = _per_row_parity(black, w)
    scales = _per_row_parity(scale, w)
    for r in range(2):
        sub = out[r::2]
        level = offsets[r] if dark is None else dark[r::2].astype(np.float32, copy=False)
        np.subtract(mosaic[r::2], level, out=sub, dtype=np.float32, casting="unsafe")
        np.multiply(sub, scales[r], out=sub)
    return out


#: the 8 same-colour neighbours of the centre of a 5 x 5 window (2 px away along rows, columns and diagonals)
_SAME_COLOUR_RING = np.zeros((5, 5), np.uint8)
_SAME_COLOUR_RING[::2, ::2] = 1
_SAME_COLOUR_RING[2, 2] = 0
#: the 8 pixels adjacent to the centre of a 3 x 3 window (any colour): :func:`find_hot_pixels` with ``isolated``
_ADJACENT_RING = np.ones((3, 3), np.uint8)
_ADJACENT_RING[1, 1] = 0
#: Smallest normalised white a pixel is divided by in the ``isolated`` test (the gaps between micro-images).
ISOLATION_MIN_WHITE = 0.02


def _brighter_than(x: np.ndarray, ring: np.ndarray, threshold: np.float32, relative: np.float32,
                   out: np.ndarray) -> np.ndarray:
    """``out = x > m + max(threshold, relative * m)`` (float32), ``m`` the maximum of ``x`` over ``ring`` about each
    pixel (an OpenCV dilation whose constant border stands for "no pixel", -inf); returns ``m``."""
    m = cv2.dilate(x, ring, borderType=cv2.BORDER_CONSTANT, borderValue=-np.inf)
    margin = np.multiply(m, relative)
    np.maximum(margin, threshold, out=margin)
    margin += m
    np.greater(x, margin, out=out)
    return m


def _balanced_radiance(x: np.ndarray, white: np.ndarray | None) -> np.ndarray:
    """What the ``isolated`` test compares, (H, W) float32: ``y = x / max(white, ISOLATION_MIN_WHITE)`` (``x``
    without a white), each of the 2 x 2 CFA positions divided by its median over the pixels whose white is at least
    :data:`ISOLATION_MIN_WHITE` (a grey-world balance: a grey scene's channels differ by the camera's colour gains,
    up to 1.7x on the F01 preset, which the white image need not carry)."""
    if white is None:
        return np.asarray(x, np.float32)
    w = np.asarray(white, np.float32)
    y = x / np.maximum(w, np.float32(ISOLATION_MIN_WHITE))
    for r in range(2):
        for c in range(2):
            lit = w[r::2, c::2] >= ISOLATION_MIN_WHITE
            if np.any(lit):
                scale = float(np.median(y[r::2, c::2][lit]))
                if scale > 0:
                    y[r::2, c::2] /= np.float32(scale)
    return y


def _flag_hot(x: np.ndarray, threshold: np.float32, relative: np.float32, flags: np.ndarray,
              isolated: bool = False, white: np.ndarray | None = None) -> int:
    """Write the hot-pixel mask of ``x`` into ``flags``; return how many are hot (see :func:`find_hot_pixels`).

    ``m`` (the maximum of the same-colour ring) is an OpenCV dilation by :data:`_SAME_COLOUR_RING`; its constant
    border stands for "no pixel" (-inf), so pixels near the edge use their neighbours inside the image, as the
    rule says (in an image of at most 3 x 3 a pixel can have none: it is not hot).  Then
    ``flags = x > m + max(threshold, relative * m)`` in float32; with ``isolated`` the same must hold of the
    white-normalised, channel-balanced ``y`` (:func:`_balanced_radiance`) against its maximum over the 8
    adjacent pixels (:data:`_ADJACENT_RING`).
    """
    m = _brighter_than(x, _SAME_COLOUR_RING, threshold, relative, flags)
    if max(x.shape) <= 3:                # pixels without any same-colour neighbour in the image are not hot
        flags &= m > -np.inf
    if isolated:
        y = _balanced_radiance(x, white)
        alone = np.empty_like(flags)
        _brighter_than(y, _ADJACENT_RING, threshold, relative, alone)
        flags &= alone
    return int(np.count_nonzero(flags))


#: row and column steps to the 8 same-colour neighbours: the taps of :data:`_SAME_COLOUR_RING` from its centre
_NEIGHBOUR_DY, _NEIGHBOUR_DX = np.argwhere(_SAME_COLOUR_RING).T - 2


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


def find_hot_pixels(mosaic: np.ndarray, *, threshold: float = 0.1, relative: float = 0.5,
                    isolated: bool = False, white: np.ndarray | None = None) -> np.ndarray:
    """Pixels brighter than all their (up to 8) same-colour neighbours by a clear margin.

    A pixel ``p`` is hot when ``x[p] > m + max(threshold, relative * m)`` with ``m`` the maximum of
    its same-colour neighbours (2 px away along rows, columns and diagonals, so the rule holds
    for every Bayer position and for monochrome sensors).  Optical detail rarely does this: the
    micro-images are smooth at 2 px, and a lenslet rim usually has a brighter neighbour inside.
    Two hot pixels 2 px apart hide each other (a known limit of the rule).

    Not always: a sharp edge of the scene imaged across the rim (a light square seen by the rim pixel, a dark one
    by the pixels 2 px inside, the falling disk outside) passes the rule; on generated checkerboard raws 20-364
    pixels per capture, most within 1 px of the rim (for ~34 true hot pixels), and their repair pulled the outer
    views' corners towards the centre (parallax -2 to -5e-3 per view ring, issue 22).  ``isolated`` adds
    the same test of the radiance ``x / white`` (the white image of the same pixels) against the 8 adjacent
    pixels of any colour: a defect is a single pixel, whereas such an edge also lights the rim pixels beside
    it; divided by the white, they are not darker for being farther out on the disk's falling edge.

    Parameters
    ----------
    mosaic : ndarray, shape (H, W), float32
        Normalised mosaic (white level = 1).
    threshold : float
        Absolute margin (normalised units).
    relative : float
        Margin relative to the neighbours' maximum.
    isolated : bool
        Also brighter than its 8 adjacent pixels by that margin, divided by ``white``.
    white : ndarray, shape (H, W), float32, optional
        The normalised white image (``isolated`` only; without it the mosaic's own values are compared).

    Returns
    -------
    ndarray, shape (H, W), bool
    """
    flags = np.empty(mosaic.shape, np.bool_)
    _flag_hot(np.ascontiguousarray(mosaic, np.float32), np.float32(threshold), np.float32(relative), flags,
              isolated, white)
    return flags


def repair_hot_pixels(mosaic: np.ndarray, *, threshold: float = 0.1, relative: float = 0.5,
                      out: np.ndarray | None = None, flags: np.ndarray | None = None,
                      isolated: bool = False, white: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Replace hot pixels by the median of their lit same-colour neighbours.

    The neighbours are the (up to 8) same-colour pixels 2 px away that are not hot themselves;
    only those at least half as bright as the brightest of them count, so a hot pixel on a
    lenslet rim is filled from the disk and not from the dark gap outside it.

    Parameters
    ----------
    mosaic : ndarray, shape (H, W), float32
        Normalised mosaic; not modified.
    threshold, relative, isolated, white
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
    n = _flag_hot(x, np.float32(threshold), np.float32(relative), flags, isolated, white)
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
    x = np.asarray(mosaic, np.float32)
    # the divisor goes into ``out`` first unless ``out`` is the mosaic itself
    divisor = np.empty_like(out) if np.shares_memory(out, x) else out
    np.maximum(white, np.float32(1e-6), out=divisor)
    np.divide(x, divisor, out=out)
    out[np.less(rel, np.float32(floor))] = np.nan
    return out


def channel_of(cfa: str | None, shape: tuple[int, int]) -> np.ndarray:
    """CFA channel index (0 R, 1 G, 2 B; 0 for monochrome) of every pixel, shape (H, W), int8."""
    return _tile(cfa_channel_map(cfa), shape).astype(np.int8)


__all__ = ["normalise", "find_hot_pixels", "repair_hot_pixels", "white_envelope", "relative_white",
           "devignette", "channel_of", "DEFAULT_FLOOR"]
