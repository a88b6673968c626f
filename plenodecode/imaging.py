"""Low-level image operations shared by decoding, rendering and depth: interpolation taps, luma, view warps, the
filling of the gaps a decode leaves at the frame's edge, and each view's share of samples with data
(:func:`view_data_share`).

Everything here is a pure function of numpy arrays; nothing depends on the light-field types, so any
layer of the package can use it (``types.py`` stays free of OpenCV: this module imports it, types does not
import this module).  OpenCV is imported by the two warps only, so the interpolation helpers stay light
(the CLI reads :data:`INTERPOLATION_TAPS` for its help).

Interpolation kernels (:data:`INTERPOLATION_TAPS`), for a sample at ``x + t`` with ``i = floor(t)``,
``f = t - i``:

* ``'linear'``: tent kernel, taps ``x + i`` and ``x + i + 1`` with weights ``(1 - f, f)``;
* ``'cubic'``: Keys' cubic convolution (R. Keys, "Cubic convolution interpolation for digital image
  processing", IEEE TASSP 29(6), 1981, eq. (15) with ``a = -0.5``), taps ``x + i - 1 .. x + i + 2`` with
  weights ``(k(1 + f), k(f), k(1 - f), k(2 - f))`` where

  ``k(s) = (a + 2) |s|^3 - (a + 3) |s|^2 + 1``            for ``|s| <= 1``,
  ``k(s) = a |s|^3 - 5 a |s|^2 + 8 a |s| - 4 a``         for ``1 < |s| < 2``, else 0.

  Both are interpolating (exact at integer ``t``) and their weights sum to 1.

View warps follow the disparity convention of ``docs/design.md``: a view ``(v, u)`` at offset
``(dv, du) = (v - vc, u - uc)`` from the centre view is brought onto the centre view for disparity ``d`` by
``out(y, x) = view(y - d dv, x - d du)``.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

#: Interpolation kernels of :func:`interpolation_taps`: name -> number of taps.
INTERPOLATION_TAPS = {"linear": 2, "cubic": 4}
#: The decoder's hex -> rect kernels: name -> number of taps (the row kernels above; ``'hex'``: 4 lenses in each of
#: 5 rows, :func:`plenodecode.decoding.resample.hex_taps`).  Here, not in the resampler, so that the CLI's
#: ``--resample`` help does not import numba.
RESAMPLE_METHODS = {**INTERPOLATION_TAPS, "hex": 20}

#: Keys' free parameter; -0.5 makes the kernel third-order accurate (Keys 1981).
KEYS_A = -0.5


def _keys_inner(s: np.ndarray) -> np.ndarray:
    """Keys' kernel on ``0 <= s <= 1``: ``(a + 2) s^3 - (a + 3) s^2 + 1``."""
    a = KEYS_A
    return (a + 2) * s**3 - (a + 3) * s**2 + 1


def _keys_outer(s: np.ndarray) -> np.ndarray:
    """Keys' kernel on ``1 <= s <= 2``: ``a s^3 - 5 a s^2 + 8 a s - 4 a`` (0 at s = 1 and s = 2)."""
    a = KEYS_A
    return a * s**3 - 5 * a * s**2 + 8 * a * s - 4 * a


def interpolation_taps(t: np.ndarray, interp: str) -> tuple[np.ndarray, np.ndarray]:
    """Taps that sample a row at ``x + t`` for every integer ``x``.

    Parameters
    ----------
    t : ndarray (...,) float64
        Sub-pixel positions or offsets.
    interp : 'linear' or 'cubic'
        A key of :data:`INTERPOLATION_TAPS` (see the module docstring for the kernels).

    Returns
    -------
    first : ndarray (...,) int64
        Offset of the first tap: tap ``k`` reads ``x + first + k``.
    weights : ndarray (..., T) float32
        ``T = INTERPOLATION_TAPS[interp]`` weights, evaluated in float64; they sum to 1.

    Raises
    ------
    ValueError
        ``interp`` is not a key of :data:`INTERPOLATION_TAPS`.
    """
    t = np.asarray(t, np.float64)
    i = np.floor(t)
    f = t - i                                  # exact: removes the integer part only
    if interp == "linear":
        return i.astype(np.int64), np.stack([1.0 - f, f], -1).astype(np.float32)
    if interp == "cubic":
        w = np.stack([_keys_outer(1 + f), _keys_inner(f), _keys_inner(1 - f), _keys_outer(2 - f)], -1)
        return (i - 1).astype(np.int64), w.astype(np.float32)
    raise ValueError(f"interp must be one of {', '.join(INTERPOLATION_TAPS)}, got {interp!r}")


#: Rec. 601 luma weights (R, G, B) of :func:`luma`.
LUMA_WEIGHTS = np.array([0.299, 0.587, 0.114], np.float32)


def luma(img: np.ndarray) -> np.ndarray:
    """Rec. 601 luma ``Y' = 0.299 R + 0.587 G + 0.114 B`` of an image (the single channel of a grey one).

    Parameters
    ----------
    img : ndarray, shape (..., 3) or (..., 1), float32

    Returns
    -------
    ndarray, shape (...), float32, C-contiguous
        ``img @ LUMA_WEIGHTS``, or ``img[..., 0]`` when there is one channel (a view when already contiguous).
    """
    if img.shape[-1] not in (1, 3):
        raise ValueError(f"img must have 1 or 3 channels in its last axis, got shape {img.shape}")
    return np.ascontiguousarray(img[..., 0] if img.shape[-1] == 1 else img @ LUMA_WEIGHTS)


def shift_view(img: np.ndarray, d: float, dv: float, du: float, interpolation: int | None = None) -> np.ndarray:
    """One view brought onto the centre view for a constant disparity ``d``.

    ``out(y, x) = img(y - d dv, x - d du)`` (``cv2.warpAffine``; samples outside take the nearest edge value).

    Parameters
    ----------
    img : ndarray (Y, X) or (Y, X, C), float32, C <= 4
    d : float
        Disparity, pixels per view step.
    dv, du : float
        Offset of the view from the centre view, in view steps.
    interpolation : int, optional
        OpenCV interpolation flag (``cv2.INTER_LINEAR``, the default, ``cv2.INTER_CUBIC``, ...).

    Returns
    -------
    ndarray, shape (Y, X) or (Y, X, C) (OpenCV drops a single channel axis), float32
    """
    import cv2

    interpolation = cv2.INTER_LINEAR if interpolation is None else interpolation
    h, w = img.shape[:2]
    m = np.array([[1.0, 0.0, -d * du], [0.0, 1.0, -d * dv]], np.float32)
    return _in_channel_groups(lambda part: cv2.warpAffine(part, m, (w, h), flags=interpolation | cv2.WARP_INVERSE_MAP,
                                                          borderMode=cv2.BORDER_REPLICATE), img, interpolation)


def remap_view(img: np.ndarray, disparity: np.ndarray, dv: float, du: float, grid: tuple[np.ndarray, np.ndarray],
               interpolation: int | None = None) -> np.ndarray:
    """Per-pixel version of :func:`shift_view`: ``out(y, x) = img(y - d(y, x) dv, x - d(y, x) du)``.

    Parameters
    ----------
    img : ndarray (Y, X) or (Y, X, C), float32
    disparity : ndarray (Y, X), float32
        ``d(y, x)``, pixels per view step.
    dv, du : float
        Offset of the view from the centre view, in view steps.
    grid : (yy, xx), ndarray (Y, X) float32 each
        Pixel coordinates, e.g. ``np.mgrid[0:Y, 0:X].astype(np.float32)``.
    interpolation : int, optional
        OpenCV interpolation flag (default ``cv2.INTER_CUBIC``); samples outside take the nearest edge value
        (``cv2.remap``).

    Returns
    -------
    ndarray, shape (Y, X) or (Y, X, C) (OpenCV drops a single channel axis), float32
    """
    import cv2

    interpolation = cv2.INTER_CUBIC if interpolation is None else interpolation
    yy, xx = grid
    mx = xx - disparity * np.float32(du)
    my = yy - disparity * np.float32(dv)
    return _in_channel_groups(lambda part: cv2.remap(part, mx, my, interpolation, borderMode=cv2.BORDER_REPLICATE),
                              img, interpolation)


#: Channels OpenCV's warps take in one call: past 4, ``cv2.remap`` / ``cv2.warpAffine`` (OpenCV 5.0) refuse cubic
#: ('Unknown interpolation method') and round every bilinear sample position to 1/32 px (0.011-0.022 off on a random
#: texture against the exact interpolation, 6e-7 with 1, 3 or 4 channels).  They round 2 channels too, the grey depth
#: views with their contrast channel: warping those one by one (exact) moved bench.depth the wrong way (hci-antinous
#: BadPix0.07 3.95 -> 4.10 %, illum-mini decoded 0.54 -> 0.58 %, thin ideal / decoded means 4.80 / 21.78 -> 4.84 /
#: 21.89 %; the pipeline's constants were fitted with it) at twice the warp calls, so 2 stay in one call.
MAX_WARP_CHANNELS = 4


def _in_channel_groups(warp: Callable[[np.ndarray], np.ndarray], img: np.ndarray, interpolation: int) -> np.ndarray:
    """``warp(img)``, applied to groups of at most :data:`MAX_WARP_CHANNELS` channels and stacked again when ``img``
    has more (the colour depth views with their contrast channels beside them: 6), unless nearest-neighbour."""
    import cv2

    if img.ndim < 3 or img.shape[2] <= MAX_WARP_CHANNELS or interpolation == cv2.INTER_NEAREST:
        return warp(img)
    # whole groups of 4, then the rest one by one: a rest of 2 would be rounded as above
    n = img.shape[2]
    cuts = list(range(0, n - n % 4, 4)) + list(range(n - n % 4, n + 1))
    parts = [warp(np.ascontiguousarray(img[..., a:b])) for a, b in zip(cuts[:-1], cuts[1:])]
    return np.concatenate([q if q.ndim == 3 else q[..., None] for q in parts], axis=2)


#: Weight below which a view's sample (or a photograph's pixel, its weight sum per unit of aperture) counts as no
#: data in images: the decoder divides by the white, so a sample with 1 % of a full lens's white carries 100x the
#: noise (a microscope's border lens with 1e-4 of it read 25x its neighbours).
MIN_DATA_WEIGHT = 0.01

#: Deepest gap (px) that :func:`fill_gaps` fills: the frame edges a decode leaves without samples (the hex ->
#: rect grid's alternate edge pixels, a lens row half off the sensor) are 1 px deep; larger holes are parts of
#: a view that no lens sees, and stay as they are.
GAP_DEPTH_PX = 2.0


#: A view with data (weight at least :data:`MIN_DATA_WEIGHT`) in fewer than this share of its samples
#: (:func:`view_data_share`) lies partly outside the micro-images: the corner views of a 9 x 9 F01 decode
#: without a white image (44 %: diagonal stripes of the lenses' edges) or of the 27 x 27 ant-leg microscope
#: decode (72 %: holes).  Every other view of both has 94-99 % (the rest is the frame's edge).
MIN_VIEW_DATA = 0.9


def view_data_share(weight: np.ndarray) -> np.ndarray:
    """Share of each view's samples that carry data, ``mean(w[v, u] >= MIN_DATA_WEIGHT)``.

    Parameters
    ----------
    weight : ndarray (V, U, Y, X) float
        A light field's sample weights.

    Returns
    -------
    ndarray (V, U) float64 in [0, 1]
    """
    V, U = weight.shape[:2]
    return np.array([[np.mean(weight[v, u] >= MIN_DATA_WEIGHT) for u in range(U)] for v in range(V)])


def fill_gaps(image: np.ndarray, known: np.ndarray, depth: float = GAP_DEPTH_PX) -> np.ndarray:
    """``image`` with each unknown pixel within ``depth`` px of a known one set to its nearest known pixel.

    ``out(p) = image(q*)``, ``q* = argmin_{q known} |p - q|`` (Euclidean, from
    :func:`scipy.ndimage.distance_transform_edt`), where ``0 < |p - q*| <= depth``; elsewhere ``out = image``.

    Parameters
    ----------
    image : ndarray (Y, X) or (Y, X, C)
    known : ndarray (Y, X) bool
        The pixels that carry data.
    depth : float

    Returns
    -------
    ndarray, like ``image`` (a copy when anything is filled, else ``image`` itself)
    """
    known = np.asarray(known, dtype=bool)
    if known.all() or not known.any():
        return image
    from scipy.ndimage import distance_transform_edt

    distance, (iy, ix) = distance_transform_edt(~known, return_indices=True)
    fill = (distance > 0) & (distance <= depth)
    out = np.array(image, copy=True)
    out[fill] = image[iy[fill], ix[fill]]
    return out


__all__ = ["INTERPOLATION_TAPS", "RESAMPLE_METHODS", "KEYS_A", "interpolation_taps", "LUMA_WEIGHTS", "luma",
           "shift_view", "remap_view", "MIN_DATA_WEIGHT", "GAP_DEPTH_PX", "fill_gaps", "MIN_VIEW_DATA",
           "view_data_share"]
