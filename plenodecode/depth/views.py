"""View preparation for depth: matching-ready views, local contrast normalisation, noise estimate, view patterns.

* :func:`prepare_views`: the views normalised (centre view's 99.5th percentile = 1), display-encoded when
  linear, with per-view weights from ``lf.weight`` (dark border views of decoded camera light fields are
  dropped or down-weighted), optionally with a local contrast normalisation beside them (:func:`add_contrast`).
* :func:`noise_sigma`: the views' noise, which sets the floor of that normalisation.
* :func:`colour_guide`: the centre view in colour, the guide of the occlusion-edge snapping.

Shift convention (design.md): for a disparity ``d``, view ``(v, u)`` is compared with the centre view at
``view[v, u](y - d (v - vc), x - d (u - uc))``.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import DecodeError
from ..imaging import LUMA_WEIGHTS, MIN_DATA_WEIGHT, fill_gaps, luma, shift_view
from ..types import LightField

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Views:
    """Matching-ready views of a light field.

    Attributes
    ----------
    data : ndarray, shape (V, U, Y, X, C), float32
        Views scaled so the centre view's 99.5th percentile is 1; linear light fields are display-encoded
        (``x ** (1 / 2.2)``) so that the photometric noise is closer to uniform across brightness.
    weight : ndarray, shape (V, U), float32
        Per-view weight in [0, 1]; 0 = not used.  From ``lf.weight`` (median over the view, relative to the
        centre view's), else 1.
    centre : tuple of int
        ``(vc, uc)``.
    guide_image : ndarray (Y, X) float32 or None
        Grey centre view before the local contrast normalisation (None: derived from ``data``).
    encoding_gamma : float
        2.2 where ``data`` is display-encoded (``data ** 2.2`` is proportional to the light), else 1.
    """

    data: np.ndarray
    weight: np.ndarray
    centre: tuple[int, int]
    guide_image: np.ndarray | None = None
    encoding_gamma: float = 1.0

    @property
    def offsets(self) -> tuple[np.ndarray, np.ndarray]:
        """``(dv, du)``: (V, U) float64 arrays of ``v - vc`` and ``u - uc``."""
        V, U = self.data.shape[:2]
        dv, du = np.meshgrid(np.arange(V) - self.centre[0], np.arange(U) - self.centre[1], indexing="ij")
        return dv.astype(np.float64), du.astype(np.float64)

    def used(self) -> list[tuple[int, int]]:
        """Views with a positive weight, the centre excluded, row-major."""
        V, U = self.data.shape[:2]
        return [(v, u) for v in range(V) for u in range(U) if (v, u) != self.centre and self.weight[v, u] > 0]

    def centre_view(self) -> np.ndarray:
        """(Y, X, C) float32."""
        return self.data[self.centre]

    def guide(self) -> np.ndarray:
        """Grey centre view (Y, X) float32 in about [0, 1]: the guide of the edge-aware steps."""
        if self.guide_image is not None:
            return self.guide_image
        return luma(self.centre_view())

    def linear(self, vu: tuple[int, int]) -> np.ndarray:
        """View ``vu`` in light proportional to the scene's (the display encoding undone): (Y, X, C) float32,
        the space where a pixel cut by an edge is the coverage-weighted mean of the two surfaces."""
        img = self.data[vu]
        if self.encoding_gamma == 1.0:
            return img
        return np.power(np.clip(img, 0.0, None), np.float32(self.encoding_gamma))


def view_pattern(V: int, U: int, pattern: str | None) -> np.ndarray:
    """(V, U) bool mask of the views a pattern keeps: None = all, 'star' = the horizontal, vertical and
    diagonal lines through the centre (the views of EPI methods)."""
    if pattern is None:
        return np.ones((V, U), bool)
    if pattern != "star":
        raise ValueError(f"pattern must be None or 'star', got {pattern!r}")
    dv, du = np.meshgrid(np.arange(V) - V // 2, np.arange(U) - U // 2, indexing="ij")
    return (dv == 0) | (du == 0) | (np.abs(dv) == np.abs(du))


def prepare_views(lf: LightField, *, min_view_weight: float = 0.1, grey: bool = False,
                  pattern: str | None = None, contrast_sigma: float = 0.0, contrast_eps: float = 0.01,
                  contrast_weight: float | None = None) -> Views:
    """Views of ``lf`` ready for matching (see :class:`Views`).

    Parameters
    ----------
    lf : LightField
        (V, U, Y, X, C) float32; NaN samples (no data) are set to 0 and do not count.  A sample whose
        ``lf.weight`` is below :data:`~plenodecode.imaging.MIN_DATA_WEIGHT` (the frame's edge, a lens half off
        the sensor) takes its view's nearest sample with data (:func:`~plenodecode.imaging.fill_gaps`).
    min_view_weight : float
        Views whose weight (median of ``lf.weight`` over the view, relative to the centre view) is below this
        are not used; the others are weighted by it.
    grey : bool
        Return one luma channel.
    pattern : None or 'star'
        Views to use (:func:`view_pattern`); the others get weight 0 and are not processed (left zero).
    contrast_sigma, contrast_eps : float
        When ``contrast_sigma > 0`` every view gets the same local contrast normalisation
        ``(I - G*I) / (sqrt(G*(I - G*I)^2) + eps)`` (G a Gaussian of that sigma, px): texture in shadows
        then weighs as much in the matching cost as texture in bright areas (as in a normalised
        cross-correlation).  ``eps`` (in the [0, 1] intensity scale) keeps flat, noise-only areas small.
    contrast_weight : float or None
        None: the normalised views replace the intensities.  A number: they are stacked as extra channels,
        scaled by it, beside the intensities, so the matching cost is ``|dI|^2 + w^2 |dLCN|^2``: the
        normalised term dominates where the local contrast is below about ``w`` (faint texture, shadows)
        and the intensities where it is higher (smooth, strong texture that the high-pass would discard).

    Raises
    ------
    DecodeError
        The light field has a single view, or its centre view is empty.
    """
    if not 0.0 <= min_view_weight < 1.0:
        raise ValueError(f"min_view_weight must be in [0, 1), got {min_view_weight!r}")
    V, U, Y, X, C = lf.shape
    if V * U < 2:
        raise DecodeError(f"depth needs at least 2 views, the light field has {V}x{U}; decode with more views")
    vc, uc = lf.centre_index
    weight = view_pattern(V, U, pattern).astype(np.float32)
    if lf.weight is not None:
        med = np.array([[np.median(lf.weight[v, u, ::2, ::2]) if weight[v, u] > 0 else 0.0 for u in range(U)]
                        for v in range(V)], np.float32)
        ref = med[vc, uc] if med[vc, uc] > 0 else float(med.max())
        if not ref > 0:
            raise DecodeError("every view has zero weight; nothing to match. Check the decode")
        weight = np.clip(med / ref, 0.0, 1.0).astype(np.float32)
        weight[weight < min_view_weight] = 0.0
        log.debug("view weights: %d of %d views used", int((weight > 0).sum()), V * U)
    weight[vc, uc] = 1.0
    nc = 1 if (grey or C == 1) else C
    out = np.zeros((V, U, Y, X, nc), np.float32)
    centre = _clean(lf.data[vc, uc], grey)
    scale = float(np.percentile(centre, 99.5))
    if not scale > 0:
        raise DecodeError("the centre view is empty (all zero or NaN); nothing to match. Check the decode")
    gamma = not lf.geometry.display_encoded
    for v in range(V):
        for u in range(U):
            if weight[v, u] > 0:
                img = centre if (v, u) == (vc, uc) else _clean(lf.data[v, u], grey)
                if lf.weight is not None:
                    # a sample without data (the frame's edge, a lens half off the sensor) is 0: matched as it is,
                    # its step to the data beside it is texture the other views do not show
                    img = fill_gaps(img, np.asarray(lf.weight[v, u]) >= MIN_DATA_WEIGHT, depth=np.inf)
                out[v, u] = _display_encode(img, scale, gamma).reshape(Y, X, nc)
    plain = Views(out, weight, (vc, uc), luma(out[vc, uc]).copy(), 2.2 if gamma else 1.0)
    return add_contrast(plain, contrast_sigma, contrast_eps, contrast_weight) if contrast_sigma > 0 else plain


def add_contrast(views: Views, sigma: float, eps: float, weight: float | None, smooth: float = 0.0) -> Views:
    """The views with their local contrast normalisation (:func:`local_contrast`, smoothed by ``smooth``)
    stacked beside them (scaled by ``weight``) or, when ``weight`` is None, in their place; see
    :func:`prepare_views`.

    Returns
    -------
    Views
        A new object; ``views`` is not modified.  (V, U, Y, X, 2 C) float32, or (V, U, Y, X, C).
    """
    V, U, Y, X, nc = views.data.shape
    out = np.zeros((V, U, Y, X, nc if weight is None else 2 * nc), np.float32)
    for vu in [views.centre, *views.used()]:
        lcn = local_contrast(views.data[vu], float(sigma), float(eps), float(smooth))
        if weight is None:
            out[vu] = lcn
        else:
            out[vu][..., :nc] = views.data[vu]
            out[vu][..., nc:] = np.float32(weight) * lcn
    return Views(out, views.weight, views.centre, views.guide())


def noise_sigma(views: Views, lo: float, hi: float, step: float = 0.1) -> float:
    """Standard deviation of the views' noise, from how well the centre view's direct neighbours match it.

    For each used neighbour ``n`` at offset ``o`` (|o| = 1) and each pixel, the lowest 3 x 3 mean of
    ``(I_n(p - d o) - I_c(p))^2`` over the disparities ``d`` in ``[lo, hi]`` (spacing ``step``) is the
    residual after matching (about ``2 sigma^2`` where the views differ only by noise); the median over the
    neighbours and then over the image, over ``2 C``, gives ``sigma^2``.  It also counts the fine texture a
    bilinear shift cannot reproduce, so it is an upper bound on the noise of finely textured views.  The
    views must hold intensities only (no contrast channels).

    Returns
    -------
    float
        sigma in the views' intensity scale; 0.0 when no direct neighbour is used.
    """
    return noise_sigmas(views, lo, hi, step)[0]


#: The 10th percentile of :func:`noise_sigmas`' per-pixel residual over its median, for views that differ by
#: white noise only (measured on flat grey 15 x 15 views of 87 x 125 px with Gaussian noise).
LOW_QUANTILE_RATIO = 0.62


def noise_sigmas(views: Views, lo: float, hi: float, step: float = 0.1) -> tuple[float, float]:
    """The views' noise from the residual of :func:`noise_sigma`: from its median and from its 10th percentile.

    The median (``sigma``, :func:`noise_sigma`) counts every pixel whose neighbours cannot match it by a
    shift: the edges of thin structures, where the views see different surfaces, lift it on noise-free views
    of dense slats to as much as decoded views' noise (0.0108 on the thin scene slats-o-j2-tex).  The 10th
    percentile over :data:`LOW_QUANTILE_RATIO` (``sigma_low``) reads the pixels that do match, where only the
    noise is left: for white noise both agree; on the noise-free thin scenes ``sigma_low`` is 0.0004-0.0032,
    on their decoded versions 0.006-0.011.

    Returns
    -------
    (sigma, sigma_low) : floats in the views' intensity scale; (0.0, 0.0) when no direct neighbour is used.
    """
    vc, uc = views.centre
    V, U, Y, X, nc = views.data.shape
    centre = views.data[vc, uc]
    labels = np.arange(lo, hi + 0.5 * step, step)
    residuals = []
    for dv, du in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        v, u = vc + dv, uc + du
        if not (0 <= v < V and 0 <= u < U) or views.weight[v, u] <= 0:
            continue
        best = None
        for d in labels:
            diff = shift_view(views.data[v, u], float(d), dv, du).reshape(centre.shape) - centre
            r = cv2.boxFilter((diff * diff).sum(axis=-1), -1, (3, 3))
            best = r if best is None else np.minimum(best, r, out=best)
        m = 4 if min(Y, X) > 16 else 0         # skip the border the shifts fill by replication
        residuals.append(best[m:Y - m, m:X - m])
    if not residuals:
        return 0.0, 0.0
    per_pixel = np.median(np.stack(residuals), axis=0)
    med, low = np.percentile(per_pixel, [50, 10])
    return (math.sqrt(float(med) / (2.0 * nc)),
            math.sqrt(max(0.0, float(low)) / (LOW_QUANTILE_RATIO * 2.0 * nc)))


def local_contrast(img: np.ndarray, sigma: float, eps: float, smooth: float = 0.0) -> np.ndarray:
    """``S * [(I - G*I) / (sqrt(G*(I - G*I)^2) + eps)]`` per channel; (Y, X, C) float32 in and out.

    ``S`` is a Gaussian of ``smooth`` px (0 = none).  On noisy views the normalisation lifts the noise of
    flat areas to about ``1 / (1 + eps / sigma_n)`` of the texture's level, and that white noise biases a
    matching cost that shifts the views by interpolation: a shift by a fraction ``f`` of a pixel averages
    the noise of neighbours (bilinear: its variance times ``(1 - f)^2 + f^2``, half at ``f = 1/2``), so the
    cost is lowest where the shifts are fractional.  On the decoded slits-v-j2-weak scene (sigma_n 0.0096)
    the winner sat 0.09 px per view step below the near surface's disparity of 1.0, 0.02 without the
    normalisation and 0.01 with ``smooth`` 0.6.  Smoothing correlates the noise of neighbouring pixels, so
    an interpolation no longer averages it away.
    """
    low = cv2.GaussianBlur(img, (0, 0), sigma).reshape(img.shape)
    hp = img - low
    sd = np.sqrt(cv2.GaussianBlur(hp * hp, (0, 0), sigma)).reshape(img.shape)
    out = (hp / (sd + np.float32(eps))).astype(np.float32)
    if smooth > 0:
        out = cv2.GaussianBlur(out, (0, 0), smooth).reshape(img.shape)
    return out


def _display_encode(img: np.ndarray, scale: float, linear: bool) -> np.ndarray:
    """``img / scale``, then ``x ** (1 / 2.2)`` when the light field is linear (float32)."""
    img = img * np.float32(1.0 / scale)
    return np.power(np.clip(img, 0.0, None), np.float32(1.0 / 2.2)) if linear else img


def _clean(img: np.ndarray, grey: bool) -> np.ndarray:
    """One view with NaN set to 0, optionally converted to luma; a new (Y, X, C) float32 array."""
    img = np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)
    if grey and img.shape[-1] == 3:
        img = cv2.transform(img, LUMA_WEIGHTS[None, :]).reshape(img.shape[:2] + (1,))
    return img.astype(np.float32, copy=False)


def colour_guide(lf: LightField) -> np.ndarray:
    """The centre view as the guide of the edge snapping: (Y, X, 3) or (Y, X, 1) uint8, scaled so its 99.5th
    percentile is 255, display-encoded (``x ** (1 / 2.2)``) when linear."""
    c = _clean(lf.data[lf.centre_index], False)
    c = _display_encode(c, max(float(np.percentile(c, 99.5)), 1e-12),
                        not lf.geometry.display_encoded)
    return np.ascontiguousarray(np.clip(np.round(c * 255.0), 0, 255).astype(np.uint8))



__all__ = ["Views", "view_pattern", "prepare_views", "add_contrast", "local_contrast", "noise_sigma", "noise_sigmas",
           "LOW_QUANTILE_RATIO",
           "colour_guide"]
