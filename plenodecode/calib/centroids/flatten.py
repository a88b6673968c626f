"""Bayer collapse: a monochrome float32 image of a white (or scene) raw in which the CFA structure is gone.

:func:`flatten_white` applies the levels, per-CFA-position gains (:func:`cfa_gains`), isolated
hot/dead pixel replacement (:func:`fix_hot_pixels`) and a centred 3x3 binomial low-pass whose response
is zero at the CFA's Nyquist frequencies; optionally 2x2 binning.  :func:`flatten_image` does the same
for image arrays (mosaics or RGB).
"""

from __future__ import annotations

import logging

import cv2
import numpy as np

from ..._numba import njit, run_in_blocks
from ...decoding.devignette import normalise
from ...types import RawCapture

log = logging.getLogger(__name__)

#: 3x3 binomial kernel (1, 2, 1)/4: centred, and its response is 0 at 0.5 cycles/px, so it removes
#: the 2x2 CFA tile's residual pattern without moving any centre.
_BINOMIAL = np.array([0.25, 0.5, 0.25], np.float32)


def cfa_gains(raw: RawCapture, *, sample_step: int = 7) -> np.ndarray:
    """Per-CFA-position gains that equalise a white image's four Bayer phases.

    Each phase ``(r % 2, c % 2)`` is scaled so that its 95th percentile (the bright disk interiors;
    robust to vignetting and to the dark gaps between disks) matches the mean of the four.

    Parameters
    ----------
    raw : RawCapture
    sample_step : int
        Every ``sample_step``-th row of each phase is used for the percentiles (speed).

    Returns
    -------
    ndarray, shape (2, 2), float64
        Multiplicative gain per CFA position (all ones for a monochrome sensor).
    """
    if raw.cfa is None:
        return np.ones((2, 2))
    lev = np.empty((2, 2))
    for r in range(2):
        for c in range(2):
            sub = raw.mosaic[r::2 * sample_step, c::2 * sample_step].astype(np.float32)
            lev[r, c] = (np.percentile(sub, 95) - raw.black[r, c]) / (raw.white[r, c] - raw.black[r, c])
    if not np.all(lev > 0):
        return np.ones((2, 2))
    return lev.mean() / lev


@njit(cache=True, fastmath=True)
def _hot_row(up, mid, dn, threshold, flag):  # pragma: no cover - compiled
    """``flag[j]`` = ``mid[j]`` leaves the range of its 8 neighbours (clamped at the row ends) by
    more than ``threshold`` plus half that range; branch-free over the interior so that it vectorises."""
    w = mid.shape[0]
    for j in range(1, w - 1):
        mx = max(max(max(up[j - 1], up[j]), max(up[j + 1], mid[j - 1])),
                 max(max(mid[j + 1], dn[j - 1]), max(dn[j], dn[j + 1])))
        mn = min(min(min(up[j - 1], up[j]), min(up[j + 1], mid[j - 1])),
                 min(min(mid[j + 1], dn[j - 1]), min(dn[j], dn[j + 1])))
        v = mid[j]
        margin = threshold + np.float32(0.5) * (mx - mn)
        flag[j] = (v > mx + margin) | (v < mn - margin)
    for j in (0, w - 1):
        jl, jr = max(j - 1, 0), min(j + 1, w - 1)
        mx = max(max(max(up[jl], up[j]), max(up[jr], mid[jl])), max(max(mid[jr], dn[jl]), max(dn[j], dn[jr])))
        mn = min(min(min(up[jl], up[j]), min(up[jr], mid[jl])), min(min(mid[jr], dn[jl]), min(dn[j], dn[jr])))
        margin = threshold + np.float32(0.5) * (mx - mn)
        flag[j] = (mid[j] > mx + margin) | (mid[j] < mn - margin)


@njit(cache=True, nogil=True)
def _fix_hot_rows(img, threshold, out, i0, i1):  # pragma: no cover - compiled
    """Rows ``i0 .. i1`` of :func:`fix_hot_pixels` into ``out`` (a copy of ``img``): neighbours clamped at the
    border (= OpenCV's replicate); the median of the 8 neighbours by an insertion sort (no ``np.median``, whose
    generic implementation takes seconds to compile).  Returns the number of pixels repaired."""
    h, w = img.shape
    flag = np.zeros(w, np.bool_)
    nb = np.empty(8, np.float32)
    n_bad = 0
    for i in range(i0, i1):
        up = img[max(i - 1, 0)]
        mid = img[i]
        dn = img[min(i + 1, h - 1)]
        _hot_row(up, mid, dn, threshold, flag)
        for j in range(w):
            if flag[j]:
                jl, jr = max(j - 1, 0), min(j + 1, w - 1)
                nb[0], nb[1], nb[2], nb[3] = up[jl], up[j], up[jr], mid[jl]
                nb[4], nb[5], nb[6], nb[7] = mid[jr], dn[jl], dn[j], dn[jr]
                for a in range(1, 8):
                    x = nb[a]
                    b = a - 1
                    while b >= 0 and nb[b] > x:
                        nb[b + 1] = nb[b]
                        b -= 1
                    nb[b + 1] = x
                out[i, j] = np.float32(0.5 * (np.float64(nb[3]) + np.float64(nb[4])))  # median of the 8 neighbours
                n_bad += 1
    return n_bad


@njit(cache=True, nogil=True)
def _levels_bin2_rows(m, k, offset, out, i0, i1):  # pragma: no cover - compiled
    """Rows ``i0 .. i1`` of ``out``: ``sum over the 2x2 tile of m * k[r % 2, c % 2] - offset`` per tile."""
    k00, k01, k10, k11 = k[0, 0], k[0, 1], k[1, 0], k[1, 1]
    for i in range(i0, i1):
        r0 = m[2 * i]
        r1 = m[2 * i + 1]
        for j in range(out.shape[1]):
            out[i, j] = (np.float32(r0[2 * j]) * k00 + np.float32(r0[2 * j + 1]) * k01
                         + np.float32(r1[2 * j]) * k10 + np.float32(r1[2 * j + 1]) * k11) - offset


#: Images of at least this many pixels go through the compiled kernel of :func:`fix_hot_pixels`, smaller ones
#: through OpenCV (about 0.05 s per megapixel, against ~1.4 CPU s to compile the kernel on first use).
_KERNEL_MIN_PIXELS = 4_000_000


def fix_hot_pixels(img: np.ndarray, *, threshold: float = 0.1) -> np.ndarray:
    """Replace isolated hot or dead pixels by the median of their 3x3 neighbourhood.

    A pixel is hot when it exceeds the maximum of its 8 neighbours by more than
    ``threshold + (max - min) / 2`` of the neighbours (dead: below their minimum by as much).  The
    spread term keeps real structure: the bottom of a narrow gap between lenslet disks is below
    all its neighbours too, but they span the whole disk-to-gap range (without it, a binned Illum
    white lost the bottom of every gap, 270 000 pixels).  A full median filter would remove
    defects as well, but it also flattens every disk's peak and locks sub-pixel centres to the
    pixel grid (biases of ~0.1 px); this touches only the outliers.

    Parameters
    ----------
    img : ndarray, shape (H, W), float32
        Normalised image (white level ~1).
    threshold : float
        Jump above the neighbours that marks a pixel as defective, in normalised units.

    Returns
    -------
    ndarray, shape (H, W), float32 -- a new array (``img`` is not modified).

    Notes
    -----
    From :data:`_KERNEL_MIN_PIXELS` pixels on, a serial numba kernel (rows in blocks on threads,
    :func:`plenodecode._numba.run_in_blocks`) tests and repairs each row in one pass: on a full-size
    Illum image it is about 9x faster than the same test through OpenCV (``make bench`` compares it
    with :func:`fix_hot_pixels_reference`, which the tests check it against).  Smaller images (the tiles
    of a white-fit check, the bundled samples) go through that reference, which takes less time than
    compiling the kernel (about 1.4 CPU s).
    """
    a = np.ascontiguousarray(img, np.float32)
    if a.size < _KERNEL_MIN_PIXELS:
        return fix_hot_pixels_reference(a, threshold=threshold)
    out = a.copy()
    n_bad = sum(run_in_blocks(lambda i0, i1: _fix_hot_rows(a, np.float32(threshold), out, i0, i1), a.shape[0]))
    if n_bad:
        log.debug("replaced %d hot/dead pixels", n_bad)
    return out


#: The 8-neighbourhood of a pixel as a structuring element (the centre left out).
_RING = np.array([[1, 1, 1], [1, 0, 1], [1, 1, 1]], np.uint8)


def fix_hot_pixels_reference(img: np.ndarray, *, threshold: float = 0.1) -> np.ndarray:
    """:func:`fix_hot_pixels` through the library, the reference its numba kernel is tested against.

    ``M, m`` = grey dilation and erosion of ``img`` with the 8-neighbourhood (``cv2.dilate`` /
    ``cv2.erode`` with the centre left out of the element, border replicated); a pixel with
    ``img > M + t + (M - m) / 2`` or ``img < m - t - (M - m) / 2`` becomes the median of its
    8 neighbours in ``img``.

    Parameters
    ----------
    img : ndarray, shape (H, W), float32
    threshold : float
        ``t``, in normalised units.

    Returns
    -------
    ndarray, shape (H, W), float32 -- a new array.
    """
    a = np.ascontiguousarray(img, np.float32)
    hi = cv2.dilate(a, _RING, borderType=cv2.BORDER_REPLICATE)
    lo = cv2.erode(a, _RING, borderType=cv2.BORDER_REPLICATE)
    margin = np.float32(threshold) + np.float32(0.5) * (hi - lo)
    rr, cc = np.nonzero((a > hi + margin) | (a < lo - margin))
    padded = np.pad(a, 1, mode="edge")
    neighbours = np.stack([padded[rr + 1 + dr, cc + 1 + dc] for dr in (-1, 0, 1) for dc in (-1, 0, 1)
                           if dr or dc])
    out = a.copy()
    out[rr, cc] = np.median(neighbours.astype(np.float64), axis=0)
    return out


def flatten_white(raw: RawCapture, *, equalise: bool = True, binning: int = 1,
                  hot_pixels: bool = True) -> np.ndarray:
    """Monochrome float32 image of a white (or scene) raw in which the CFA structure is gone.

    ``y = B * fix( g[cfa] * (x - black) / (white - black) )`` with ``g`` from :func:`cfa_gains`,
    ``fix`` = :func:`fix_hot_pixels` and ``B`` the centred 3x3 binomial filter (zero response at
    the CFA's Nyquist frequencies).  With ``binning=2`` the four pixels of each 2x2 tile are
    averaged instead of ``B``; a binned pixel ``(r, c)`` covers sensor pixels ``2r..2r+1``, so
    sensor coordinates are ``2 * p + 0.5``.

    Parameters
    ----------
    raw : RawCapture
        Mosaic (H, W) uint16 with its levels.
    equalise : bool
        Apply per-CFA-position gains (for white images; pass False for scenes).
    binning : int
        1 or 2.
    hot_pixels : bool
        Replace isolated hot / dead pixels first.

    Returns
    -------
    ndarray, shape (H, W) or (H // 2, W // 2), float32
    """
    if binning not in (1, 2):
        raise ValueError(f"binning must be 1 or 2, got {binning!r}")
    gains = cfa_gains(raw) if equalise else np.ones((2, 2))
    scale = gains / (raw.white - raw.black)
    m = np.ascontiguousarray(raw.mosaic)
    if binning == 2:
        # average of the four equalised CFA phases; the hot-pixel test runs on the binned image,
        # where a defective pixel still stands out by a quarter of its jump
        k = (scale / 4.0).astype(np.float32)
        offset = np.float32(float((raw.black * scale).sum() / 4.0))
        out = np.empty((m.shape[0] // 2, m.shape[1] // 2), np.float32)
        run_in_blocks(lambda i0, i1: _levels_bin2_rows(m, k, offset, out, i0, i1), out.shape[0])
        return fix_hot_pixels(out, threshold=0.05) if hot_pixels else out
    out = normalise(m, raw.black, raw.white, gains=gains)
    if hot_pixels:
        out = fix_hot_pixels(out)
    return cv2.sepFilter2D(out, cv2.CV_32F, _BINOMIAL, _BINOMIAL, borderType=cv2.BORDER_REFLECT)


def flatten_image(image: np.ndarray) -> np.ndarray:
    """Monochrome float32 version of an image array for centre detection.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C), any real dtype
        A mosaic or an RGB image; channels are averaged.

    Returns
    -------
    ndarray, shape (H, W), float32, the 3x3-binomial-filtered image scaled to [0, ~1].
    """
    a = np.asarray(image)
    if a.ndim == 3:
        a = a.astype(np.float32).mean(axis=2)
    elif a.ndim != 2:
        raise ValueError(f"image must be 2-D or 3-D, got shape {a.shape}")
    a = a.astype(np.float32)
    top = float(np.percentile(a[::7], 99.9)) or 1.0
    return cv2.sepFilter2D(a / top, cv2.CV_32F, _BINOMIAL, _BINOMIAL, borderType=cv2.BORDER_REFLECT)
