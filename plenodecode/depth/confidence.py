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

* **consistency with the matching cost** (:func:`cost_consistency`, when the cost volume is given): the
  regularised, cleaned-up estimate ``d`` against the winner ``d_w`` of the per-pixel matching cost (before any
  aggregation; a left-right style check between two estimates of the same pixel).  Near its minimum the cost is
  a parabola ``C(d) ~ C_min + kappa (d - d_w)^2 / 2``, and a cost floor ``C_min`` (the residual the views leave
  at their best match: noise, mixed pixels) makes ``d_w`` uncertain by about ``C_min / kappa`` px^2, so::

      c_cons = exp(-(d - d_w)^2 / (tau^2 + k_floor C_min / kappa)) * P_w^p_raw

  with ``P_w`` the peak ratio of the matching cost (as ``c_peak``, but of the per-pixel cost; power ``p_raw``
  as it partly repeats ``c_peak``).  It falls where the steps after the matching moved a pixel away from
  what its own views prefer: the 1-px mixed ring at a thin structure's edges, a slat's surround pulled to the
  slat, a far plane seen through a gap.  On the thin scenes of issue 20 the mean sparsification area over
  random fell 0.50 -> 0.29 (ground-truth light fields) and 0.51 -> 0.41 (decoded).
* **the neighbour's hypothesis** (:func:`competitor_ratio`, with the cost volume): where a 4-neighbour's
  disparity ``d_n`` (the one farthest from ``d``) differs from ``d`` by more than ``jump`` (a depth edge of the
  map), the matching cost must prefer ``d`` to ``d_n``: ``c_comp = clip((C(d_n) - C(d)) / C(d_n), 0, 1)``
  (a peak ratio whose rival is the surface across the edge, ``C`` linear between labels), else 1.  A mixed
  pixel on the edge, which the views fit about as well with either surface, gets a low value (thin scenes'
  means 0.29 -> 0.28 and 0.41 -> 0.40, hci-antinous 0.27 -> 0.25).

The product ``c = c_tex * c_peak * c_occ * c_cons * c_comp`` is the confidence (:func:`estimate_confidence`); the depth
pipeline computes it at its final disparity, with the peak ratio of its winner-take-all step and its matching
cost volume.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from .aggregation import winner
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
    "tau": 0.05,             # px per view step: disagreement with the matching cost's winner at which c_cons
                             # falls to exp(-1) where the cost's floor C_min is 0
    "k_floor": 1.0,          # weight of the cost floor's uncertainty C_min / kappa (px^2) in c_cons
    "p_raw": 0.5,            # power of the matching cost's peak ratio in c_cons
    "jump": 0.1,             # px per view step: a neighbour this far in disparity is a rival hypothesis (c_comp)
}

#: ``T`` of white noise of unit variance: the Sobel derivative (kernel / 8) has variance 12 / 64 per axis,
#: and the offsets' weights of ``T`` sum to 1 over the two axes.
NOISE_TEXTURE = 12.0 / 64.0


def image_noise(image: np.ndarray, *, robust: bool = False) -> float:
    """Standard deviation of white noise in an image (Immerkaer, CVIU 1996).

    ``sigma = sqrt(pi / 2) / (6 (Y - 2) (X - 2)) sum |I * N|`` with the Laplacian difference
    ``N = [[1, -2, 1], [-2, 4, -2], [1, -2, 1]]``, which cancels smooth image content (and lines), and
    has standard deviation ``6 sigma`` on white noise; ``robust``: ``median |I * N| / (0.6745 * 6)``, which
    edges and texture move less.

    Parameters
    ----------
    image : ndarray (Y, X) float
    robust : bool

    Returns
    -------
    float
    """
    img = np.ascontiguousarray(image, np.float32)
    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    r = np.abs(cv2.filter2D(img, -1, kernel)[1:-1, 1:-1])
    if robust:
        return float(np.median(r) / (0.6745 * 6.0))
    return float(math.sqrt(math.pi / 2.0) * np.mean(r) / 6.0)


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


def cost_consistency(cost: np.ndarray, labels: np.ndarray, disparity: np.ndarray, *, tau: float, k_floor: float,
                     p_raw: float) -> np.ndarray:
    """``c_cons`` of the module docstring: agreement of ``disparity`` with the winner of the matching cost.

    Parameters
    ----------
    cost : ndarray (Y, X, L) float32
        Per-pixel matching cost over ``labels`` (any positive scale: only ``C_min / kappa`` and the peak ratio
        enter).
    labels : ndarray (L,) uniformly spaced, px per view step
    disparity : ndarray (Y, X) float32
        The estimate to check.
    tau, k_floor, p_raw : float
        As :data:`CONFIDENCE_DEFAULTS`.

    Returns
    -------
    ndarray (Y, X) float32 in [0, 1]
    """
    cost = np.ascontiguousarray(cost, np.float32)
    L = cost.shape[-1]
    raw, raw_peak = winner(cost, labels)
    if L >= 3:
        step = float(labels[-1] - labels[0]) / (L - 1)
        k = np.clip(np.argmin(cost, axis=-1), 1, L - 2)[..., None]
        c_lo, c_mid, c_hi = (np.take_along_axis(cost, k + o, -1)[..., 0] for o in (-1, 0, 1))
        kappa = np.maximum((c_lo - 2 * c_mid + c_hi) / np.float32(step * step), np.float32(1e-6))
        spread = np.float32(tau * tau) + np.float32(k_floor) * np.maximum(c_mid, 0) / kappa
    else:
        spread = np.full(raw.shape, tau * tau, np.float32)
    delta = np.asarray(disparity, np.float32) - raw
    c = np.exp(-delta * delta / spread) * np.clip(raw_peak, 0, 1) ** np.float32(p_raw)
    return np.clip(c, 0.0, 1.0).astype(np.float32)


def _cost_at(cost: np.ndarray, labels: np.ndarray, disparity: np.ndarray) -> np.ndarray:
    """``C(d)`` linear between the labels (clamped to their range): (Y, X) float32."""
    L = cost.shape[-1]
    step = float(labels[-1] - labels[0]) / max(L - 1, 1)
    t = np.clip((np.asarray(disparity, np.float64) - labels[0]) / (step if step > 0 else 1.0), 0, max(L - 1, 0))
    k = np.minimum(np.floor(t).astype(np.int64), max(L - 2, 0))
    frac = (t - k).astype(np.float32)
    lo = np.take_along_axis(cost, k[..., None], -1)[..., 0]
    hi = np.take_along_axis(cost, np.minimum(k + 1, L - 1)[..., None], -1)[..., 0]
    return lo + frac * (hi - lo)


def competitor_ratio(cost: np.ndarray, labels: np.ndarray, disparity: np.ndarray, *, jump: float) -> np.ndarray:
    """``c_comp`` of the module docstring: how clearly the matching cost prefers a pixel's disparity to that of
    its 4-neighbour farthest from it in disparity, where the two differ by more than ``jump``.

    Parameters
    ----------
    cost : ndarray (Y, X, L) float32
        Per-pixel matching cost over ``labels``, non-negative.
    labels : ndarray (L,) uniformly spaced
    disparity : ndarray (Y, X) float32
    jump : float
        px per view step.

    Returns
    -------
    ndarray (Y, X) float32 in [0, 1]; 1 away from the map's depth edges.
    """
    d = np.asarray(disparity, np.float32)
    pad = np.pad(d, 1, mode="edge")
    Y, X = d.shape
    gap = np.zeros_like(d)
    rival = d.copy()
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        nb = pad[1 + dy:1 + dy + Y, 1 + dx:1 + dx + X]
        diff = np.abs(nb - d)
        farther = diff > gap
        gap = np.where(farther, diff, gap)
        rival = np.where(farther, nb, rival)
    edge = gap > jump
    out = np.ones_like(d)
    if np.any(edge):
        cost = np.ascontiguousarray(cost, np.float32)
        own, other = _cost_at(cost, labels, d), _cost_at(cost, labels, rival)
        ratio = np.clip((other - own) / np.maximum(other, np.float32(1e-12)), 0.0, 1.0)
        out = np.where(edge, ratio, out).astype(np.float32)
    return out


def estimate_confidence(views: Views, peak_ratio: np.ndarray, disparity: np.ndarray, *, radius: int = 1,
                        valid: np.ndarray | None = None, cost: np.ndarray | None = None,
                        labels: np.ndarray | None = None, **params: float) -> np.ndarray:
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
    cost : ndarray (Y, X, L) float32, optional
        The per-pixel matching cost over ``labels`` (before aggregation); with it the product includes
        ``c_cons`` (:func:`cost_consistency`) and ``c_comp`` (:func:`competitor_ratio`), without it both are 1.
    labels : ndarray (L,), optional
        Disparities of ``cost``'s last axis; required with ``cost``.
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
    conf = c_tex * np.asarray(peak_ratio, np.float32) * c_occ
    if cost is not None:
        if labels is None:
            raise ValueError("labels are required with cost")
        labels = np.asarray(labels, np.float64)
        conf = conf * cost_consistency(cost, labels, disparity, tau=float(p["tau"]), k_floor=float(p["k_floor"]),
                                       p_raw=float(p["p_raw"]))
        conf = conf * competitor_ratio(cost, labels, disparity, jump=float(p["jump"]))
    conf = np.clip(conf, 0.0, 1.0).astype(np.float32)
    if valid is not None:
        conf[~np.asarray(valid, bool)] = 0.0
    return conf


__all__ = ["CONFIDENCE_DEFAULTS", "NOISE_TEXTURE", "image_noise", "epipolar_texture", "view_agreement",
           "cost_consistency", "competitor_ratio", "estimate_confidence"]
