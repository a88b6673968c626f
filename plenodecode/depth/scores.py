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
