"""Disparity scores of the HCI 4D light-field benchmark (Honauer et al., ACCV 2016): BadPix and MSE x 100.

Both ignore a border of ``border`` pixels (15 in the benchmark's toolkit) and pixels whose ground truth is
not finite.  A non-finite estimate counts as a bad pixel and makes the MSE infinite.
"""

from __future__ import annotations

import numpy as np


def _errors(est: np.ndarray, gt: np.ndarray, border: int, mask: np.ndarray | None) -> np.ndarray:
    est = np.asarray(getattr(est, "disparity", est), np.float64)
    gt = np.asarray(gt, np.float64)
    if est.ndim != 2 or est.shape != gt.shape:
        raise ValueError(f"est and gt must be 2-D arrays of the same shape, got {est.shape} and {gt.shape}")
    b = int(border)
    if b < 0 or 2 * b >= min(gt.shape):
        raise ValueError(f"border must be in [0, {min(gt.shape) // 2}), got {border!r}")
    keep = np.isfinite(gt)
    if mask is not None:
        mask = np.asarray(mask, bool)
        if mask.shape != gt.shape:
            raise ValueError(f"mask must have shape {gt.shape}, got {mask.shape}")
        keep &= mask
    if b:
        inner = np.zeros_like(keep)
        inner[b:-b, b:-b] = True
        keep &= inner
    if not keep.any():
        raise ValueError("no pixel left to evaluate (border, mask and non-finite ground truth remove all)")
    e = np.abs(est[keep] - gt[keep])
    return np.where(np.isfinite(e), e, np.inf)


def badpix(est: np.ndarray, gt: np.ndarray, t: float = 0.07, border: int = 15,
           mask: np.ndarray | None = None) -> float:
    """BadPix(t): percentage of evaluated pixels with ``|est - gt| > t``.

    Parameters
    ----------
    est : ndarray (Y, X) or DepthMap
        Estimated disparity.
    gt : ndarray (Y, X)
        Ground-truth disparity.
    t : float
        Threshold in px per view step (the benchmark reports 0.01, 0.03 and 0.07).
    border : int
        Pixels ignored at each image edge.
    mask : ndarray (Y, X) bool, optional
        Evaluate only where True.

    Returns
    -------
    float, percent in [0, 100]
    """
    if not t >= 0:
        raise ValueError(f"t must be >= 0, got {t!r}")
    e = _errors(est, gt, border, mask)
    return float(100.0 * np.mean(e > t))


def mse100(est: np.ndarray, gt: np.ndarray, border: int = 15, mask: np.ndarray | None = None) -> float:
    """Mean squared disparity error times 100 (the benchmark's 'MSE x 100'); arguments as :func:`badpix`."""
    e = _errors(est, gt, border, mask)
    return float(100.0 * np.mean(e * e))


__all__ = ["badpix", "mse100"]


#: Fractions of the pixels (most confident first) at which :func:`sparsification` evaluates the error.
SPARSIFICATION_FRACTIONS = tuple(np.round(np.arange(0.1, 1.0001, 0.1), 10))


def _error_of_fraction(order_key: np.ndarray, err: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Mean of ``err`` over the ``fraction`` of the pixels with the highest ``order_key``, for each fraction.

    Pixels with equal keys are in no particular order, so the cut through a group of ties takes the group's
    mean error per pixel (the expectation over the orderings of the ties).
    """
    order = np.argsort(-order_key, kind="stable")
    key, e = order_key[order], err[order]
    n = e.size
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])       # first pixel of every group of ties
    ends = np.r_[starts[1:], n]
    cum = np.r_[0.0, np.cumsum(e)]
    group_mean = (cum[ends] - cum[starts]) / (ends - starts)
    k = np.maximum(1, np.round(fractions * n).astype(np.int64))     # pixels kept
    g = np.searchsorted(ends, k, side="left")                       # the group the cut falls in
    total = cum[starts[g]] + (k - starts[g]) * group_mean[g]
    return total / k


def sparsification(disparity: np.ndarray, truth: np.ndarray, confidence: np.ndarray, *, error: str = "badpix",
                   t: float = 0.07, border: int = 15, mask: np.ndarray | None = None,
                   fractions: tuple[float, ...] = SPARSIFICATION_FRACTIONS) -> dict[str, object]:
    """Sparsification curve of a confidence map: the error of the most confident pixels as fewer are kept.

    The pixels evaluated by :func:`badpix` are sorted by decreasing ``confidence``; for each fraction ``x``
    the error of the first ``x N`` is::

        E(x) = mean_{i < x N} e_i,   e_i = 100 [|d_i - g_i| > t]  ('badpix')  or  100 |d_i - g_i|^2  ('mse')

    and the area is the mean of ``E`` over the fractions (the area under the curve over ``x`` in
    ``[0.1, 1]`` divided by the width, in the error's unit).  A random ordering keeps the overall error at
    every fraction (in expectation), so its area is ``E(1)``; the oracle sorts by the true error (its area is
    the lowest possible).  A useful confidence has ``area / random_area`` well below 1 (Hu & Mordohai,
    TPAMI 2012; Ilg et al., ECCV 2018, "AUSE").  Ties in confidence count as in random order.

    Parameters
    ----------
    disparity, truth : ndarray (Y, X)
        Estimate and ground truth (px per view step); a DepthMap for ``disparity`` also works.
    confidence : ndarray (Y, X)
        Higher = more trusted; non-finite values rank last.
    error : {'badpix', 'mse'}
        Per-pixel error: bad-pixel indicator (percent) at threshold ``t``, or squared error x 100 (MSE x 100).
    t : float
        BadPix threshold, px per view step.
    border, mask
        As :func:`badpix`.
    fractions : tuple of float in (0, 1]
        Fractions of the evaluated pixels kept, increasing.

    Returns
    -------
    dict
        'fractions' (F,) float64; 'curve', 'oracle' (F,) float64 errors of the kept pixels in confidence and in
        true-error order; 'area', 'random_area', 'oracle_area' float; 'ratio' = area / random_area (0 when
        the random area is 0); 'error' the error's name.
    """
    if error not in ("badpix", "mse"):
        raise ValueError(f"error must be 'badpix' or 'mse', got {error!r}")
    if not t >= 0:
        raise ValueError(f"t must be >= 0, got {t!r}")
    f = np.asarray(fractions, np.float64)
    if f.ndim != 1 or f.size == 0 or not (np.all(f > 0) and np.all(f <= 1) and np.all(np.diff(f) > 0)):
        raise ValueError(f"fractions must be increasing values in (0, 1], got {fractions!r}")
    conf = np.asarray(confidence, np.float64)
    gt = np.asarray(truth, np.float64)
    if conf.shape != gt.shape:
        raise ValueError(f"confidence must have the shape of truth {gt.shape}, got {conf.shape}")
    e = _errors(disparity, gt, border, mask)
    # the same selection and order of pixels as e: |confidence - 0| where the truth is finite
    c = _errors(np.abs(conf), np.where(np.isfinite(gt), 0.0, np.nan), border, mask)
    c[~np.isfinite(c)] = -1.0
    per_pixel = 100.0 * (e > t) if error == "badpix" else 100.0 * np.where(np.isfinite(e), e * e, np.inf)
    curve = _error_of_fraction(c, per_pixel, f)
    oracle = _error_of_fraction(-per_pixel, per_pixel, f)
    random_area = float(np.mean(per_pixel))
    area = float(np.mean(curve))
    return {"error": error, "fractions": f, "curve": curve, "oracle": oracle, "area": area,
            "random_area": random_area, "oracle_area": float(np.mean(oracle)),
            "ratio": area / random_area if random_area > 0 else 0.0}


__all__ += ["SPARSIFICATION_FRACTIONS", "sparsification"]


# ---------------------------------------------------------------------------------------
# thin-structure band (issue 20)
# ---------------------------------------------------------------------------------------
def depth_edge_band(gt: np.ndarray, radius: float = 2.0, jump: float = 0.1) -> np.ndarray:
    """Pixels within ``radius`` px of a ground-truth depth edge: the thin-structure band.

    A depth edge lies between two 4-neighbours whose finite ground-truth disparities differ by more than
    ``jump`` (px per view step; a slanted surface changes by far less per pixel).  Both pixels of such a pair
    are edge pixels, half a pixel from the edge; a pixel is in the band when its Euclidean distance
    (:func:`scipy.ndimage.distance_transform_edt`) to the nearest edge pixel is at most ``radius - 0.5``,
    i.e. its centre is within about ``radius`` px of the edge: with ``radius = 2``, two pixels on each side of
    a straight edge.

    Parameters
    ----------
    gt : ndarray (Y, X)
        Ground-truth disparity (non-finite pixels never make an edge).
    radius : float
        Half-width of the band (px), >= 0.5.
    jump : float
        Smallest disparity step that counts as a depth edge (px per view step), > 0.

    Returns
    -------
    ndarray (Y, X) bool
    """
    from scipy import ndimage

    gt = np.asarray(gt, np.float64)
    if gt.ndim != 2:
        raise ValueError(f"gt must be a 2-D array, got shape {gt.shape}")
    if not radius >= 0.5:
        raise ValueError(f"radius must be >= 0.5, got {radius!r}")
    if not jump > 0:
        raise ValueError(f"jump must be > 0, got {jump!r}")
    edge = np.zeros(gt.shape, bool)
    with np.errstate(invalid="ignore"):
        for axis in (0, 1):
            step = np.abs(np.diff(gt, axis=axis)) > jump      # NaN compares False
            lo = [slice(None), slice(None)]
            hi = [slice(None), slice(None)]
            lo[axis], hi[axis] = slice(None, -1), slice(1, None)
            edge[tuple(lo)] |= step
            edge[tuple(hi)] |= step
    if not edge.any():
        return edge
    return ndimage.distance_transform_edt(~edge) <= radius - 0.5


def badpix_in_band(est: np.ndarray, gt: np.ndarray, t: float = 0.07, border: int = 15, radius: float = 2.0,
                   jump: float = 0.1) -> float:
    """BadPix(t) restricted to the thin-structure band :func:`depth_edge_band` (``radius``, ``jump``) of ``gt``;
    other arguments as :func:`badpix`.  NaN when the band is empty inside the border.

    Returns
    -------
    float, percent in [0, 100], or NaN
    """
    band = depth_edge_band(gt, radius, jump)
    b = int(border)
    inner = band[b:-b, b:-b] if b else band
    if not inner.any():
        return float("nan")
    return badpix(est, gt, t, border, mask=band)


__all__ += ["depth_edge_band", "badpix_in_band"]
