"""Integer lenslet peaks: local maxima of a Gaussian-filtered image with a local-contrast test.

The Gaussian is a matched filter for the lenslet disk, as in LFToolbox [1]_ and PlenoptiCam [3]_.

References
----------
.. [1] D. G. Dansereau, O. Pizarro, S. B. Williams, "Decoding, calibration and rectification for
   lenselet-based plenoptic cameras", CVPR 2013.
.. [3] C. Hahne, A. Aggoun, "PlenoptiCam v1.0: a light-field imaging framework", IEEE TIP 2021.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..._numba import njit, run_in_blocks


def smoothing_sigma(pitch: float) -> float:
    """Gaussian sigma (px) matched to a lenslet disk of radius ~0.47 pitch: ``0.25 * pitch``."""
    return 0.25 * pitch


def smooth_for_peaks(img: np.ndarray, pitch: float) -> np.ndarray:
    """``img`` filtered with the Gaussian of :func:`smoothing_sigma` (the lenslet matched filter), reflected border.

    Parameters
    ----------
    img : ndarray, shape (H, W), float32
    pitch : float
        Lattice pitch, px.

    Returns
    -------
    ndarray, shape (H, W), float32
    """
    return cv2.GaussianBlur(img, (0, 0), smoothing_sigma(pitch), borderType=cv2.BORDER_REFLECT)


def _square(half: int) -> np.ndarray:
    """The ``(2 half + 1)^2`` structuring element of the window tests, uint8."""
    return np.ones((2 * half + 1, 2 * half + 1), np.uint8)


def window_maxima(g: np.ndarray, half: int, margin: int) -> np.ndarray:
    """Mask of the pixels that are the maximum of their square window.

    ``mask = (g >= D(g))`` with ``D`` the grey dilation (running maximum) over a
    ``(2 half + 1)^2`` window clipped to the image (``cv2.dilate``, whose default constant
    border is ignored); ties count as maxima.  Pixels closer than ``margin`` to the border
    are False.

    Parameters
    ----------
    g : ndarray, shape (H, W), float32 or float64
        Filtered image.
    half : int
        Half-width of the window, px.
    margin : int
        Border band (px) in which no maximum is reported.

    Returns
    -------
    ndarray, shape (H, W), bool
    """
    g = np.ascontiguousarray(g)
    h, w = g.shape
    rows = slice(margin, max(margin, h - margin))
    cols = slice(margin, max(margin, w - margin))
    mask = np.zeros((h, w), bool)
    mask[rows, cols] = g[rows, cols] >= cv2.dilate(g, _square(half))[rows, cols]
    return mask


@njit(cache=True, nogil=True)
def _window_contrast_at(g, rr, cc, half, out, k0, k1):  # pragma: no cover - compiled
    """Pixels ``k0 .. k1`` of :func:`window_contrast` into ``out``: visits only the windows of the listed pixels."""
    h, w = g.shape
    for k in range(k0, k1):
        i, j = rr[k], cc[k]
        mn = g[i, j]
        for r in range(max(0, i - half), min(h, i + half + 1)):
            for c in range(max(0, j - half), min(w, j + half + 1)):
                mn = min(mn, g[r, c])
        out[k] = g[i, j] - mn


def window_contrast(g: np.ndarray, rr: np.ndarray, cc: np.ndarray, half: int) -> np.ndarray:
    """Contrast of listed pixels against the minimum of their square window.

    ``c_k = g[r_k, c_k] - min over the (2 half + 1)^2 window (clipped to the image) of g``.
    A numba kernel that visits only the windows of the N listed pixels: on a full-size Illum
    image it is several times faster than eroding the whole image (``make bench`` compares it with
    :func:`window_contrast_reference`, the same value through ``cv2.erode``).

    Parameters
    ----------
    g : ndarray, shape (H, W), float32 or float64
    rr, cc : ndarray, shape (N,), int
        Rows and columns of the pixels (e.g. :func:`window_maxima`).
    half : int
        Half-width of the window, px.

    Returns
    -------
    ndarray, shape (N,), float32
    """
    g = np.ascontiguousarray(g)
    rr, cc = np.asarray(rr, np.int64), np.asarray(cc, np.int64)
    out = np.empty(len(rr), np.float32)
    run_in_blocks(lambda k0, k1: _window_contrast_at(g, rr, cc, int(half), out, k0, k1), len(rr))
    return out


def window_contrast_reference(g: np.ndarray, rr: np.ndarray, cc: np.ndarray, half: int) -> np.ndarray:
    """:func:`window_contrast` through the library: ``(g - E(g))[rr, cc]`` with ``E`` the grey erosion
    (``cv2.erode``, whose default constant border is ignored, so the window is clipped to the image).

    The reference the tests compare the kernel with, and its baseline in ``bench/bench_calib.py``.
    """
    g = np.ascontiguousarray(g)
    return (g - cv2.erode(g, _square(half)))[rr, cc].astype(np.float32)


def detect_peaks(img: np.ndarray, pitch: float, *, min_contrast: float = 0.15,
                 margin: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Integer local maxima of the Gaussian-filtered image, one per lenslet disk.

    A pixel is a peak when it is the maximum of the filtered image in a square window of side
    ``2 * floor(0.4 * pitch) + 1`` (smaller than the nearest-neighbour distance of a hex or square
    lattice in any direction) and its contrast against the window's minimum is at least
    ``min_contrast`` times the 90th percentile of all peak contrasts.

    Parameters
    ----------
    img : ndarray, shape (H, W), float32
    pitch : float
        Lattice pitch in px of ``img``.
    min_contrast : float
        Relative contrast threshold.
    margin : int, optional
        Peaks closer than this to the border are dropped (default ``ceil(0.5 * pitch)``).

    Returns
    -------
    peaks : ndarray, shape (N, 2), int64
        ``(row, col)`` of each peak.
    contrast : ndarray, shape (N,), float32
    """
    peaks, contrast, _ = detect_peaks_and_filtered(img, pitch, min_contrast=min_contrast, margin=margin)
    return peaks, contrast


def detect_peaks_and_filtered(img: np.ndarray, pitch: float, *, min_contrast: float = 0.15,
                              margin: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`detect_peaks` plus the Gaussian-filtered image it used.

    Returns
    -------
    peaks : ndarray, shape (N, 2), int64
    contrast : ndarray, shape (N,), float32
    filtered : ndarray, shape (H, W), float32
        ``img`` filtered with the Gaussian of :func:`smoothing_sigma`, which
        :func:`~plenodecode.calib.centroids.refine_peaks` reuses.
    """
    g = smooth_for_peaks(img, pitch)
    half = max(1, int(math.floor(0.4 * pitch)))
    margin = int(math.ceil(0.5 * pitch)) if margin is None else max(0, int(margin))
    rr, cc = np.nonzero(window_maxima(g, half, margin))
    contrast = window_contrast(g, rr, cc, half)
    if len(contrast) == 0:
        return np.zeros((0, 2), np.int64), contrast, g
    ref = float(np.percentile(contrast, 90))
    keep = contrast > max(min_contrast * ref, 1e-6)
    return np.stack([rr[keep], cc[keep]], axis=1).astype(np.int64), contrast[keep], g

