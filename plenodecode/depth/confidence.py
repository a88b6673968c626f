"""Confidence of a disparity estimate: low where the match is ambiguous, the texture too weak, or the views
disagree (occlusions); high on well-matched texture.

:func:`estimate_confidence` multiplies three factors in [0, 1], each measuring one way a match fails:

* **texture** (:func:`epipolar_texture`): how fast the matching cost can rise away from the true disparity.
  To first order ``I_vu(p - (d + e) o) - I_c(p) ~ -e o . grad I(p)``, so the cost's curvature is the
  structure tensor of the centre view projected on the views' offsets ``o``::

      T(p) = G * [ sum_vu w_vu (o_vu . grad I)^2 ] / sum_vu w_vu |o_vu|^2

  (``G`` a Gaussian of the matching window, ``grad`` the Sobel gradient).  White noise of variance ``s^2``
  (:func:`image_noise`, Immerkaer 1996) alone gives ``T = NOISE_TEXTURE s^2``; what exceeds it is signal, and
  ``c_tex = clip((T - NOISE_TEXTURE s^2) / (k_tex s^2), 0, 1)``: 0 on a featureless background or along an
  edge parallel to every baseline, 1 once the texture's energy is ``k_tex`` noise variances.
* **distinctiveness**: the peak ratio ``(A_2 - A_1) / A_2`` of the aggregated cost curve (best and
  second-best distinct minimum, :func:`~plenodecode.depth.aggregation.winner`; Hu & Mordohai, TPAMI 2012):
  a flat or multi-modal cost curve (repetitive texture) gives low values.
* **view agreement** (:func:`view_agreement`): at the estimate, the residual over *all* views against the
  residual over the best half-plane of views (the occlusion-aware half of the cost,
  :func:`~plenodecode.depth.cost.half_plane_cost_volume`)::

      c_occ = (R_half + k_agree s^2) / (R_all + k_agree s^2) * k_fit s^2 / (R_half + k_fit s^2)

  The first ratio falls where a point is hidden in some views (an occlusion: the views disagree, and the
  estimate there is often the occluder's, edge fattening); the second where even the best half-plane does
  not match (a wrong disparity, a specular or moving surface).

The product ``c = c_tex * c_peak * c_occ`` is the confidence (:func:`estimate_confidence`); the depth pipeline
computes it at its final disparity, with the peak ratio of its winner-take-all step.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from .cost import N_SECTORS, half_plane_cost_volume
from .views import Views

#: Parameters of :func:`estimate_confidence` (chosen on the sparsification area of the benchmark scenes).
CONFIDENCE_DEFAULTS = {
    "texture_sigma": 4.0,    # Gaussian window of the texture, px (the semi-global aggregation reaches further
                             # than the matching window)
    "k_texture": 0.1,        # texture energy above the noise's, in noise variances, at which c_tex reaches 1
    "k_agreement": 4.0,      # noise variances added to both residuals of the view-agreement ratio
    "k_fit": 100.0,          # residual (noise variances) at which the fit factor is 0.5
    "noise_floor": 1.0 / (255.0 * math.sqrt(12.0)),  # lower bound of the noise sigma: 8-bit quantisation
}

#: ``T`` of white noise of unit variance: the Sobel derivative (kernel / 8) has variance 12 / 64 per axis,
#: and the offsets' weights of ``T`` sum to 1 over the two axes.
NOISE_TEXTURE = 12.0 / 64.0


def image_noise(image: np.ndarray) -> float:
    """Standard deviation of white noise in an image (Immerkaer, CVIU 1996).

    ``sigma = sqrt(pi / 2) / (6 (Y - 2) (X - 2)) sum |I * N|`` with the Laplacian difference
    ``N = [[1, -2, 1], [-2, 4, -2], [1, -2, 1]]``, which cancels smooth image content.

    Parameters
    ----------
    image : ndarray (Y, X) float

    Returns
    -------
    float
    """
    img = np.asarray(image, np.float32)
    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    r = cv2.filter2D(img, -1, kernel)[1:-1, 1:-1]
    return float(math.sqrt(math.pi / 2.0) * np.mean(np.abs(r)) / 6.0)


def epipolar_texture(guide: np.ndarray, views: Views, sigma: float, valid: np.ndarray | None = None) -> np.ndarray:
    """Texture energy of the centre view along the views' baselines, ``T`` of the module docstring.

    Parameters
    ----------
    guide : ndarray (Y, X) float32
        Grey centre view.
    views : Views
        Its used views and their weights give the baseline directions.
    sigma : float
        Gaussian window, px.
    valid : ndarray (Y, X) bool, optional
        Pixels with data.  The window then averages only the gradients whose 3 x 3 stencil lies on valid
        pixels (a normalised convolution, Knutsson & Westin, CVPR 1993), so the step to a no-data border is
        not texture; 0 where the window holds none.

    Returns
    -------
    ndarray (Y, X) float32
        Squared intensity change per unit disparity per unit baseline (intensity^2 / px^2).
    """
    dv, du = views.offsets
    w = views.weight.astype(np.float64).copy()
    w[views.centre] = 0.0
    norm = float(np.sum(w * (dv * dv + du * du)))
    if not norm > 0:
        return np.zeros(guide.shape, np.float32)
    a, b, c = (float(np.sum(w * q)) / norm for q in (du * du, du * dv, dv * dv))
    gx = cv2.Sobel(guide, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(guide, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    t = np.float32(a) * gx * gx + np.float32(2 * b) * gx * gy + np.float32(c) * gy * gy
    if valid is None:
        return cv2.GaussianBlur(t, (0, 0), sigma)
    inner = cv2.erode(np.asarray(valid, np.uint8), np.ones((3, 3), np.uint8), borderType=cv2.BORDER_REPLICATE)
    inner = inner.astype(np.float32)
    num = cv2.GaussianBlur(t * inner, (0, 0), sigma)
    den = cv2.GaussianBlur(inner, (0, 0), sigma)
    return np.where(den > 1e-3, num / np.maximum(den, 1e-3), 0.0).astype(np.float32)


def view_agreement(views: Views, disparity: np.ndarray, *, radius: int, noise_var: float, k_agreement: float,
                   k_fit: float) -> np.ndarray:
    """``c_occ`` of the module docstring from the residuals at ``disparity`` over all views and over the best
    half-plane (each one pass of per-pixel warps, :func:`half_plane_cost_volume` with ``base``).

    Returns
    -------
    ndarray (Y, X) float32 in (0, 1]
    """
    zero = np.zeros(1)
    base = np.asarray(disparity, np.float32)
    half = half_plane_cost_volume(views, zero, radius=radius, base=base)[..., 0]
    every = half_plane_cost_volume(views, zero, radius=radius, base=base, span=N_SECTORS)[..., 0]
    a, f = np.float32(k_agreement * noise_var), np.float32(k_fit * noise_var)
    agree = (half + a) / (every + a)
    fit = f / (half + f)
    return np.clip(agree * fit, 0.0, 1.0).astype(np.float32)


def estimate_confidence(views: Views, peak_ratio: np.ndarray, disparity: np.ndarray, *, radius: int = 1,
                        valid: np.ndarray | None = None, **params: float) -> np.ndarray:
    """Confidence of a disparity estimate, the product of texture, distinctiveness and view agreement
    (equations in the module docstring).

    Parameters
    ----------
    views : Views
        The matching views (the cost volume's).
    peak_ratio : ndarray (Y, X) float32 in [0, 1]
        Distinctiveness of the cost curve (the second output of :func:`~plenodecode.depth.aggregation.winner`).
    disparity : ndarray (Y, X) float32
        The estimate (px per view step) whose views' agreement is measured.
    radius : int
        Box radius of the matching cost (the residuals of the view agreement are averaged over it).
    valid : ndarray (Y, X) bool, optional
        Pixels of the centre view with data (e.g. ``lf.weight > 0``); the others get confidence 0 and lend
        no texture to their neighbours.
    **params
        Keys of :data:`CONFIDENCE_DEFAULTS`.

    Returns
    -------
    ndarray (Y, X) float32 in [0, 1]
    """
    unknown = set(params) - set(CONFIDENCE_DEFAULTS)
    if unknown:
        raise ValueError(f"unknown confidence parameter(s) {sorted(unknown)}; valid: {sorted(CONFIDENCE_DEFAULTS)}")
    p = {**CONFIDENCE_DEFAULTS, **params}
    guide = np.ascontiguousarray(views.guide(), np.float32)
    noise_var = max(image_noise(guide), float(p["noise_floor"])) ** 2
    texture = epipolar_texture(guide, views, float(p["texture_sigma"]), valid)
    c_tex = np.clip((texture - np.float32(NOISE_TEXTURE * noise_var)) / np.float32(p["k_texture"] * noise_var),
                    0.0, 1.0)
    c_occ = view_agreement(views, disparity, radius=radius, noise_var=noise_var,
                           k_agreement=float(p["k_agreement"]), k_fit=float(p["k_fit"]))
    conf = np.clip(c_tex * np.asarray(peak_ratio, np.float32) * c_occ, 0.0, 1.0).astype(np.float32)
    if valid is not None:
        conf[~np.asarray(valid, bool)] = 0.0
    return conf


__all__ = ["CONFIDENCE_DEFAULTS", "NOISE_TEXTURE", "image_noise", "epipolar_texture", "view_agreement",
           "estimate_confidence"]
