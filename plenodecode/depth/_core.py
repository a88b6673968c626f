"""Building blocks shared by the depth methods.

* :func:`prepare_views`: matching-ready views (normalised, display-encoded when linear), per-view weights
  from ``lf.weight`` (dark border views of decoded camera light fields are dropped or down-weighted).
* :func:`disparity_range`: from the caller, the metadata, or estimated from a coarse search.
* :func:`half_plane_cost_volume`: the occlusion-aware photo-consistency cost volume.
* :func:`sgm`: semi-global aggregation (Hirschmueller, TPAMI 2008) with an edge-adaptive penalty.
* :func:`winner`: sub-label minimum and peak-ratio confidence.

Shift convention (design.md): for a disparity ``d``, view ``(v, u)`` is compared with the centre view at
``view[v, u](y - d (v - vc), x - d (u - uc))``.
"""

from __future__ import annotations

import logging
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import cv2
import numpy as np
from numba import njit, prange

from ..errors import DecodeError
from ..types import LightField

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None] | None

#: Number of angular sectors the views are split into; a half-plane is ``N_SECTORS // 2`` consecutive sectors.
N_SECTORS = 8
#: Luma weights (Rec. 601) used when a method works on one channel.
LUMA = np.array([0.299, 0.587, 0.114], np.float32)


# ---------------------------------------------------------------------------------------------------------------
# views
# ---------------------------------------------------------------------------------------------------------------
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


def luma(img: np.ndarray) -> np.ndarray:
    """(Y, X) float32 luma of a (Y, X, 1) or (Y, X, 3) view."""
    return np.ascontiguousarray(img[..., 0] if img.shape[-1] == 1 else img @ LUMA)


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
        (V, U, Y, X, C) float32; NaN samples (no data) are set to 0 and do not count.
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
    gamma = lf.colour != "srgb"
    for v in range(V):
        for u in range(U):
            if weight[v, u] > 0:
                img = centre if (v, u) == (vc, uc) else _clean(lf.data[v, u], grey)
                out[v, u] = _display_encode(img, scale, gamma).reshape(Y, X, nc)
    plain = Views(out, weight, (vc, uc), luma(out[vc, uc]).copy(), 2.2 if gamma else 1.0)
    return add_contrast(plain, contrast_sigma, contrast_eps, contrast_weight) if contrast_sigma > 0 else plain


def add_contrast(views: Views, sigma: float, eps: float, weight: float | None) -> Views:
    """The views with their local contrast normalisation (:func:`local_contrast`) stacked beside them
    (scaled by ``weight``) or, when ``weight`` is None, in their place; see :func:`prepare_views`.

    Returns
    -------
    Views
        A new object; ``views`` is not modified.  (V, U, Y, X, 2 C) float32, or (V, U, Y, X, C).
    """
    V, U, Y, X, nc = views.data.shape
    out = np.zeros((V, U, Y, X, nc if weight is None else 2 * nc), np.float32)
    for vu in [views.centre, *views.used()]:
        lcn = local_contrast(views.data[vu], float(sigma), float(eps))
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
    bilinear shift cannot reproduce (about 0.007 on clean, pixel-scale random texture; 0.0017 on
    hci-antinous, 0.006 on a decoded illum-mini raw); added Gaussian noise is found within 20 %.  The views
    must hold intensities only (no contrast channels).

    Returns
    -------
    float
        sigma in the views' intensity scale; 0.0 when no direct neighbour is used.
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
        return 0.0
    return math.sqrt(float(np.median(np.median(np.stack(residuals), axis=0))) / (2.0 * nc))


def local_contrast(img: np.ndarray, sigma: float, eps: float) -> np.ndarray:
    """``(I - G*I) / (sqrt(G*(I - G*I)^2) + eps)`` per channel; (Y, X, C) float32 in and out."""
    low = cv2.GaussianBlur(img, (0, 0), sigma).reshape(img.shape)
    hp = img - low
    sd = np.sqrt(cv2.GaussianBlur(hp * hp, (0, 0), sigma)).reshape(img.shape)
    return (hp / (sd + np.float32(eps))).astype(np.float32)


def _threads() -> int:
    """Threads for the depth kernels that release the GIL: the CPU cores, at most 4."""
    return max(1, min(4, os.cpu_count() or 1))


def _display_encode(img: np.ndarray, scale: float, linear: bool) -> np.ndarray:
    """``img / scale``, then ``x ** (1 / 2.2)`` when the light field is linear (float32)."""
    img = img * np.float32(1.0 / scale)
    return np.power(np.clip(img, 0.0, None), np.float32(1.0 / 2.2)) if linear else img


def _clean(img: np.ndarray, grey: bool) -> np.ndarray:
    """One view with NaN set to 0, optionally converted to luma; a new (Y, X, C) float32 array."""
    img = np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)
    if grey and img.shape[-1] == 3:
        img = cv2.transform(img, LUMA[None, :]).reshape(img.shape[:2] + (1,))
    return img.astype(np.float32, copy=False)


def sector_of(dv: float, du: float, n: int = N_SECTORS) -> int:
    """Angular sector (0..n-1) of the view offset ``(dv, du)``: sector ``k`` covers angles
    ``[-pi + k 2pi/n, -pi + (k + 1) 2pi/n)`` of ``atan2(dv, du)``."""
    a = math.atan2(dv, du) + math.pi + 1e-9
    return int(a // (2 * math.pi / n)) % n


def shift_view(img: np.ndarray, d: float, dv: float, du: float, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
    """``out(y, x) = img(y - d dv, x - d du)``: one view brought onto the centre view for disparity ``d``."""
    h, w = img.shape[:2]
    m = np.array([[1.0, 0.0, -d * du], [0.0, 1.0, -d * dv]], np.float32)
    return cv2.warpAffine(img, m, (w, h), flags=interpolation | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)


def remap_view(img: np.ndarray, disparity: np.ndarray, dv: float, du: float, grid: tuple[np.ndarray, np.ndarray],
               interpolation: int = cv2.INTER_CUBIC) -> np.ndarray:
    """Per-pixel version of :func:`shift_view`: ``out(y, x) = img(y - d(y,x) dv, x - d(y,x) du)``."""
    yy, xx = grid
    mx = xx - disparity * np.float32(du)
    my = yy - disparity * np.float32(dv)
    return cv2.remap(img, mx, my, interpolation, borderMode=cv2.BORDER_REPLICATE)


# ---------------------------------------------------------------------------------------------------------------
# disparity range
# ---------------------------------------------------------------------------------------------------------------
def _check_range(r: Any, name: str) -> tuple[float, float]:
    try:
        lo, hi = (float(r[0]), float(r[1]))
    except (TypeError, ValueError, IndexError) as exc:
        raise ValueError(f"{name} must be a pair (min, max) of numbers, got {r!r}") from exc
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ValueError(f"{name} must be finite with min < max, got {r!r}")
    return lo, hi


def metadata_disparity_range(metadata: Mapping[str, Any]) -> tuple[float, float] | None:
    """``metadata['disparity_range']``, or an HCI scene's ``[meta] disp_min / disp_max``; None if absent."""
    r = metadata.get("disparity_range")
    if r is not None:
        return _check_range(r, "metadata['disparity_range']")
    hci = (metadata.get("hci_parameters") or {}).get("meta") or {}
    if "disp_min" in hci and "disp_max" in hci:
        return _check_range((hci["disp_min"], hci["disp_max"]), "HCI disp_min/disp_max")
    return None


def estimate_disparity_range(views: Views, *, max_abs: float | None = None, n_labels: int = 48,
                             margin: float = 0.15) -> tuple[float, float]:
    """Disparity range from a coarse search on 4x down-sampled views.

    Searches ``[-max_abs, max_abs]`` (default: a shift of at most a quarter of the image's smaller side at
    the outermost view), takes the 2nd and 98th percentiles of the confident per-pixel minima and widens them
    by ``margin`` of the span (at least 0.25 px).

    Returns
    -------
    (float, float)
    """
    Y, X = views.data.shape[2:4]
    dv, du = views.offsets
    reach = float(max(np.abs(dv).max(), np.abs(du).max()))
    if max_abs is None:
        max_abs = 0.25 * min(Y, X) / reach
    f = 4 if min(Y, X) >= 64 else 1
    small = views.data[:, :, ::f, ::f] if f == 1 else _downsample(views.data, f)
    sv = Views(small, views.weight, views.centre)
    labels = np.linspace(-max_abs / f, max_abs / f, n_labels)
    cost = half_plane_cost_volume(sv, labels, radius=2)
    disp, conf = winner(cost, labels)
    d = disp[conf > np.percentile(conf, 50)] * f
    if d.size == 0:
        d = disp.ravel() * f
    lo, hi = np.percentile(d, [2, 98])
    pad = max(0.25, margin * (hi - lo))
    log.info("estimated disparity range [%.2f, %.2f]", lo - pad, hi + pad)
    return float(lo - pad), float(hi + pad)


def _downsample(data: np.ndarray, f: int) -> np.ndarray:
    V, U, Y, X, C = data.shape
    out = np.empty((V, U, Y // f, X // f, C), np.float32)
    for v in range(V):
        for u in range(U):
            r = cv2.resize(data[v, u], (X // f, Y // f), interpolation=cv2.INTER_AREA)
            out[v, u] = r.reshape(Y // f, X // f, C)
    return out


def disparity_range(lf: LightField, views: Callable[[], Views], requested: Any = None
                    ) -> tuple[tuple[float, float], str]:
    """The search range: ``requested`` (``disparity_range=`` keyword), else the metadata, else estimated
    from the matching views ``views()`` builds (called only then).

    Returns
    -------
    ((lo, hi), source) with source in {'argument', 'metadata', 'estimated'}.
    """
    if requested is not None:
        return _check_range(requested, "disparity_range"), "argument"
    r = metadata_disparity_range(lf.metadata)
    if r is not None:
        return r, "metadata"
    return estimate_disparity_range(views()), "estimated"


def make_labels(lo: float, hi: float, step: float, *, pad: float = 0.0) -> np.ndarray:
    """Uniform labels covering ``[lo - pad, hi + pad]`` with spacing at most ``step``; float64."""
    if not step > 0:
        raise ValueError(f"label_step must be positive, got {step!r}")
    a, b = lo - pad, hi + pad
    n = max(3, int(math.ceil((b - a) / step)) + 1)
    return np.linspace(a, b, n)


# ---------------------------------------------------------------------------------------------------------------
# occlusion-aware cost volume
# ---------------------------------------------------------------------------------------------------------------
def half_plane_groups(views: Views, n_sectors: int, span: int) -> tuple[list[list[tuple[int, int]]], np.ndarray]:
    """Views per angular sector and the weight of each group of ``span`` consecutive sectors.

    Returns
    -------
    sectors : list of n_sectors lists of (v, u)
    group_weight : ndarray (n_sectors,) float64
        Total view weight of group ``h`` = sectors ``h .. h + span - 1`` (mod n); ``span = n_sectors // 2``
        makes half-planes.
    """
    dv, du = views.offsets
    sectors: list[list[tuple[int, int]]] = [[] for _ in range(n_sectors)]
    for v, u in views.used():
        sectors[sector_of(dv[v, u], du[v, u], n_sectors)].append((v, u))
    sw = np.array([sum(float(views.weight[vu]) for vu in s) for s in sectors])
    hw = np.array([sum(sw[(h + i) % n_sectors] for i in range(span)) for h in range(n_sectors)])
    return sectors, hw


def half_plane_cost_volume(views: Views, labels: np.ndarray, *, radius: int = 2, interpolation: int = cv2.INTER_LINEAR,
                           base: np.ndarray | None = None, progress: Progress = None,
                           n_sectors: int = N_SECTORS, span: int | None = None,
                           threads: int | None = None) -> np.ndarray:
    """Occlusion-aware matching cost for every label.

    For label ``d`` every used view is shifted onto the centre view (:func:`shift_view`), and the
    weighted squared colour difference to the centre view is summed per angular sector.  A half-plane of
    views (``n_sectors / 2`` consecutive sectors, Kang, Szeliski & Chai, CVPR 2001; the occluder-edge split
    of the angular patch of Wang, Efros & Ramamoorthi, ICCV 2015) sees an occluded point in none of its views
    when the occluder lies on the other side, so the cost is the minimum over the ``n_sectors`` half-planes of
    the box-aggregated (``(2 radius + 1)^2``) mean squared difference::

        C(p, d) = min_h  box_r[ sum_{(v,u) in h} w_vu |I_vu(p - d o_vu) - I_c(p)|^2 ] / sum_{h} w_vu

    Parameters
    ----------
    views : Views
    labels : ndarray (L,) float64
        Disparities (px per view step).
    radius : int
        Box aggregation radius (0 = none).
    interpolation : int
        OpenCV interpolation flag of the shifts.
    base : ndarray (Y, X) float32, optional
        A disparity map: the labels are then offsets from it and every view is warped per pixel with
        ``base + label`` (:func:`remap_view`), which follows slanted surfaces exactly.
    progress : callable(done, total), optional
        Called after every label.
    n_sectors, span : int
        The views are split into ``n_sectors`` angular sectors and the minimum is taken over the groups of
        ``span`` consecutive sectors (default ``n_sectors // 2``: half-planes).  A narrower group (a wedge of
        ``span * 360 / n_sectors`` degrees) leaves out more of the views that look past the occluder's edge.
    threads : int, optional
        Labels computed concurrently (OpenCV releases the GIL); default: the number of CPU cores, at most 4.

    Returns
    -------
    ndarray, shape (Y, X, L), float32
        Labels last (the layout :func:`sgm` and :func:`winner` read).
    """
    if threads is None:
        threads = _threads()
    span = max(1, n_sectors // 2) if span is None else int(span)
    if not 1 <= span <= n_sectors:
        raise ValueError(f"span must be in [1, n_sectors={n_sectors}], got {span!r}")
    sectors, hw = half_plane_groups(views, n_sectors, span)
    if not np.all(hw > 0):
        # too few views for every group (e.g. a 1 x N light field): fall back to the plain mean over views
        n_sectors = span = 1
        sectors = [[vu for s in sectors for vu in s]]
        hw = np.array([sum(float(views.weight[vu]) for vu in sectors[0])])
    dv, du = views.offsets
    data = views.data
    Y, X, C = data.shape[2:]
    if C == 1:
        data = data[..., 0]
    centre = np.ascontiguousarray(data[views.centre])
    L = len(labels)
    out = np.empty((Y, X, L), np.float32)
    ones = np.ones((1, C), np.float32)
    ksize = (2 * radius + 1, 2 * radius + 1)
    sqrt_w = {vu: math.sqrt(float(views.weight[vu])) for s in sectors for vu in s}
    grid = None
    if base is not None:
        base = np.ascontiguousarray(base, np.float32)
        if base.shape != (Y, X):
            raise ValueError(f"base must have shape {(Y, X)}, got {base.shape}")
        yy, xx = np.mgrid[0:Y, 0:X].astype(np.float32)
        grid = (yy, xx)
    def one_label(k: int) -> None:
        # one label's cost into out[:, :, k]; own buffers, so labels can run on several threads (OpenCV
        # releases the GIL)
        d = labels[k]
        acc = np.empty(centre.shape, np.float32)
        sums = []
        dmap = None if base is None else base + np.float32(d)
        for s in sectors:
            acc.fill(0.0)
            for vu in s:
                if dmap is None:
                    warped = shift_view(data[vu], float(d), dv[vu], du[vu], interpolation)
                else:
                    warped = remap_view(data[vu], dmap, dv[vu], du[vu], grid, interpolation)
                diff = cv2.subtract(warped, centre)
                if sqrt_w[vu] != 1.0:
                    diff *= np.float32(sqrt_w[vu])
                cv2.accumulateSquare(diff, acc)
            sums.append(cv2.transform(acc, ones).reshape(Y, X) if C > 1 else acc.copy())
        best = None
        for h in range(n_sectors):
            hsum = sums[h].copy()
            for i in range(1, span):
                hsum += sums[(h + i) % n_sectors]
            hsum *= np.float32(1.0 / hw[h])
            if radius > 0:
                hsum = cv2.boxFilter(hsum, -1, ksize)
            best = hsum if best is None else np.minimum(best, hsum, out=best)
        out[:, :, k] = best

    workers = min(max(1, int(threads)), L)
    if workers == 1:
        for k in range(L):
            one_label(k)
            if progress is not None:
                progress(k + 1, L)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            for i, _ in enumerate(pool.map(one_label, range(L))):
                if progress is not None:
                    progress(i + 1, L)
    return out


# ---------------------------------------------------------------------------------------------------------------
# semi-global aggregation
# ---------------------------------------------------------------------------------------------------------------
@njit(cache=True, fastmath=True)
def _sgm_line(cost, guide, out, ys, xs, n, p1, p2, sigma, prev, cur, first):
    # cost, out: (Y, X, D) so that the labels of one pixel are contiguous
    D = cost.shape[2]
    y, x = ys[0], xs[0]
    pm = np.float32(np.inf)
    for d in range(D):
        c = cost[y, x, d]
        prev[d] = c
        if first:
            out[y, x, d] = c
        else:
            out[y, x, d] += c
        if c < pm:
            pm = c
    for i in range(1, n):
        y, x = ys[i], xs[i]
        g = abs(guide[y, x] - guide[ys[i - 1], xs[i - 1]])
        q2 = p2 / (1.0 + g / sigma)
        if q2 < p1:
            q2 = p1
        jump = pm + q2
        m = np.float32(np.inf)
        for d in range(D):
            best = prev[d]
            if d > 0 and prev[d - 1] + p1 < best:
                best = prev[d - 1] + p1
            if d < D - 1 and prev[d + 1] + p1 < best:
                best = prev[d + 1] + p1
            if jump < best:
                best = jump
            c = cost[y, x, d] + best - pm
            cur[d] = c
            if c < m:
                m = c
        if first:
            for d in range(D):
                prev[d] = cur[d]
                out[y, x, d] = cur[d]
        else:
            for d in range(D):
                prev[d] = cur[d]
                out[y, x, d] += cur[d]
        pm = m


@njit(parallel=True, cache=True)
def _sgm_direction(cost, guide, out, dy, dx, p1, p2, sigma, first):
    Y, X, D = cost.shape
    # start pixels: those whose predecessor along (dy, dx) lies outside the image
    starts = np.empty((2 * (Y + X), 2), np.int64)
    ns = 0
    for y in range(Y):
        for x in range(X):
            if y == 0 or y == Y - 1 or x == 0 or x == X - 1:
                py = y - dy
                px = x - dx
                if py < 0 or py >= Y or px < 0 or px >= X:
                    starts[ns, 0] = y
                    starts[ns, 1] = x
                    ns += 1
    m = max(Y, X)
    for s in prange(ns):
        ys = np.empty(m, np.int64)
        xs = np.empty(m, np.int64)
        prev = np.empty(D, np.float32)
        cur = np.empty(D, np.float32)
        y = starts[s, 0]
        x = starts[s, 1]
        n = 0
        while y >= 0 and y < Y and x >= 0 and x < X:
            ys[n] = y
            xs[n] = x
            n += 1
            y += dy
            x += dx
        _sgm_line(cost, guide, out, ys, xs, n, p1, p2, sigma, prev, cur, first)


#: Path directions of :func:`sgm` (dy, dx).
SGM_DIRECTIONS = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (-1, -1), (1, -1), (-1, 1))


def sgm(cost: np.ndarray, guide: np.ndarray, *, p1: float, p2: float, sigma: float, paths: int = 8,
        progress: Progress = None) -> np.ndarray:
    """Semi-global aggregation of a cost volume (Hirschmueller, TPAMI 2008, eq. 13-14).

    Along each of ``paths`` directions r::

        L_r(p, d) = C(p, d) + min(L_r(p-r, d), L_r(p-r, d+-1) + P1, min_k L_r(p-r, k) + P2(p)) - min_k L_r(p-r, k)

    with the edge-adaptive ``P2(p) = max(P1, p2 / (1 + |g(p) - g(p-r)| / sigma))`` (``g`` the guide), and
    ``S(p, d) = sum_r L_r(p, d)``.  Each pixel lies on exactly one line per direction, so the lines of a
    direction run in parallel.

    Parameters
    ----------
    cost : ndarray (Y, X, D) float32
        Labels last.
    guide : ndarray (Y, X) float32
    p1, p2, sigma : float
        Penalties in cost units and the guide step that halves P2.
    paths : {4, 8}

    Returns
    -------
    ndarray (Y, X, D) float32
        The aggregated cost, labels last (the layout :func:`winner` reads).
    """
    if paths not in (4, 8):
        raise ValueError(f"paths must be 4 or 8, got {paths!r}")
    cost = np.ascontiguousarray(cost, np.float32)
    guide = np.ascontiguousarray(guide, np.float32)
    if guide.shape != cost.shape[:2]:
        raise ValueError(f"guide must have shape {cost.shape[:2]}, got {guide.shape}")
    out = np.empty_like(cost)
    dirs = SGM_DIRECTIONS[:paths]
    for i, (dy, dx) in enumerate(dirs):
        _sgm_direction(cost, guide, out, dy, dx, np.float32(p1), np.float32(p2), np.float32(sigma), i == 0)
        if progress is not None:
            progress(i + 1, len(dirs))
    return out


# ---------------------------------------------------------------------------------------------------------------
# minima and confidence
# ---------------------------------------------------------------------------------------------------------------
@njit(parallel=True, cache=True)
def _winner(cost, lo, step, exclude, disp, conf):
    Y, X, D = cost.shape
    for y in prange(Y):
        for x in range(X):
            k = 0
            c1 = cost[y, x, 0]
            for d in range(1, D):
                if cost[y, x, d] < c1:
                    c1 = cost[y, x, d]
                    k = d
            off = 0.0
            if 0 < k < D - 1:
                a = cost[y, x, k - 1]
                b = cost[y, x, k + 1]
                den = a - 2.0 * c1 + b
                if den > 1e-12:
                    off = 0.5 * (a - b) / den
                    off = min(0.5, max(-0.5, off))
            disp[y, x] = lo + (k + off) * step
            c2 = np.inf
            for d in range(D):
                if abs(d - k) > exclude and cost[y, x, d] < c2:
                    c2 = cost[y, x, d]
            if c2 == np.inf or c2 <= 0.0:
                conf[y, x] = 0.0
            else:
                conf[y, x] = min(1.0, max(0.0, (c2 - c1) / c2))


def winner(cost_yxd: np.ndarray, labels: np.ndarray, *, exclude: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Winner-take-all with a parabolic sub-label minimum and peak-ratio confidence, in one pass.

    Parameters
    ----------
    cost_yxd : ndarray (Y, X, L) float32
        Non-negative cost, labels last (the output of :func:`sgm`).
    labels : ndarray (L,) uniformly spaced

    Returns
    -------
    disparity : (Y, X) float32
        ``labels[k] + step (c[k-1] - c[k+1]) / (2 (c[k-1] - 2 c[k] + c[k+1]))``, offset within half a label.
    confidence : (Y, X) float32
        ``(c2 - c1) / c2`` with ``c1`` the minimum and ``c2`` the lowest cost more than ``exclude`` labels away
        (a peak-ratio measure, Hu & Mordohai, TPAMI 2012), in [0, 1].
    """
    Y, X, L = cost_yxd.shape
    step = (labels[-1] - labels[0]) / (L - 1)
    disp = np.empty((Y, X), np.float32)
    conf = np.empty((Y, X), np.float32)
    _winner(np.ascontiguousarray(cost_yxd, np.float32), float(labels[0]), float(step), int(exclude), disp, conf)
    return disp, conf


def weighted_median(guide: np.ndarray, disparity: np.ndarray, radius: int, sigma: float = 0.1) -> np.ndarray:
    """Edge-aware weighted median of the disparity (Ma et al., ICCV 2013 via ``cv2.ximgproc``), guided by the
    grey centre view in [0, 1]; ``sigma`` in the guide's units."""
    if radius <= 0:
        return disparity
    g8 = np.clip(np.round(guide * 255.0), 0, 255).astype(np.uint8)
    return cv2.ximgproc.weightedMedianFilter(g8, np.ascontiguousarray(disparity, np.float32), int(radius),
                                              float(sigma * 255.0))


def colour_guide(lf: LightField) -> np.ndarray:
    """The centre view as the guide of the edge snapping: (Y, X, 3) or (Y, X, 1) uint8, scaled so its 99.5th
    percentile is 255, display-encoded (``x ** (1 / 2.2)``) when linear."""
    c = _clean(lf.data[lf.centre_index], False)
    c = _display_encode(c, max(float(np.percentile(c, 99.5)), 1e-12), lf.colour != "srgb")
    return np.ascontiguousarray(np.clip(np.round(c * 255.0), 0, 255).astype(np.uint8))


def _edge_band(disparity: np.ndarray, radius: int, jump: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(near, far, band): local max and min of the disparity over a (2 radius + 1)^2 window, and the pixels
    where they differ by more than ``jump`` (within ``radius`` of a depth discontinuity)."""
    k = np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)
    near = cv2.dilate(disparity, k)
    far = cv2.erode(disparity, k)
    return near, far, (near - far) > np.float32(jump)


@njit(cache=True, nogil=True)
def _splat_max(disparity, dv, du, out):
    # z-buffer of one view: every centre pixel p lands at p - d(p) (dv, du) in the view; the four pixels around
    # that point keep the largest (nearest) disparity landing on them
    Y, X = disparity.shape
    for y in range(Y):
        for x in range(X):
            d = disparity[y, x]
            ty = y - d * dv
            tx = x - d * du
            fy = int(math.floor(ty))
            fx = int(math.floor(tx))
            for qy in range(fy, fy + 2):
                if 0 <= qy < Y:
                    for qx in range(fx, fx + 2):
                        if 0 <= qx < X and d > out[qy, qx]:
                            out[qy, qx] = d


def nearest_surface(disparity: np.ndarray, dv: float, du: float) -> np.ndarray:
    """Z-buffer of the view at offset ``(dv, du)``: (Y, X) float32, the largest disparity of the centre-view
    pixels ``p`` whose image ``p - d(p) (dv, du)`` falls within one pixel, ``-inf`` where none does."""
    out = np.full(disparity.shape, -np.inf, np.float32)
    _splat_max(np.ascontiguousarray(disparity, np.float32), float(dv), float(du), out)
    return out


def _side_fill(disparity: np.ndarray, mask: np.ndarray, sigma: float) -> np.ndarray:
    """Normalised convolution of the disparity over ``mask``: each pixel's Gaussian-weighted mean of the
    masked pixels (its own value where no masked pixel is near)."""
    m = mask.astype(np.float32)
    num = cv2.GaussianBlur(disparity * m, (0, 0), sigma)
    den = cv2.GaussianBlur(m, (0, 0), sigma)
    return np.where(den > 1e-3, num / np.maximum(den, 1e-6), disparity).astype(np.float32)


def _pixel_image_shape(n: int) -> tuple[int, int]:
    """(rows, cols) of an image holding ``n`` scattered pixels for cv2.remap, whose maps must be under 32767
    wide: rows of 1024."""
    cols = min(n, 1024)
    return -(-n // cols), cols


def _as_pixel_image(a: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """Per-pixel values ``a`` (n, ...) laid out as a (rows, cols, ...) image, zero-padded."""
    flat = np.zeros((rows * cols,) + a.shape[1:], a.dtype)
    flat[:len(a)] = a
    return flat.reshape((rows, cols) + a.shape[1:])


def _band_hypotheses(d: np.ndarray, radius: int, jump: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(band, is_near, h_near, h_far), all (Y, X): the pixels within ``radius`` of a jump (:func:`_edge_band`)
    whose two sides differ by more than ``jump``, which of them are on the near side (``d > (max + min) / 2``
    over the window), and the near and far hypotheses: Gaussian-weighted means (``sigma = radius / 2``) of the
    band's pixels on each side."""
    near, far, band = _edge_band(d, radius, jump)
    is_near = d > 0.5 * (near + far)
    sigma = max(radius / 2.0, 1.0)
    h_near = _side_fill(d, band & is_near, sigma)
    h_far = _side_fill(d, band & ~is_near, sigma)
    band &= (h_near - h_far) > np.float32(jump)
    return band, is_near, h_near, h_far


def visibility_relabel(intensities: Views, disparity: np.ndarray, *, radius: int = 4, jump: float = 0.5,
                       ratio: float = 1.5, search: float = 0.2, min_visible: float = 0.25) -> np.ndarray:
    """Move edge pixels to the side of a depth edge their own colour matches in the views that see it.

    Within ``radius`` px of a jump (:func:`_edge_band`) each pixel has two hypotheses, the disparity of the
    near side and of the far side around it (Gaussian-weighted means of the pixels on each side,
    ``sigma = radius / 2``).  Its per-pixel cost (no box: a box beside an edge mixes both surfaces) is

        C(p, h) = min_{|e| <= search}  sum_{t in vis(p, h + e)} w_t |I_t(p - (h + e) o_t) - I_c(p)|^2
                                        / sum_{t in vis(p, h + e)} w_t

    over the intensities (the local contrast normalisation mixes both surfaces near an edge), bicubic.
    A near hypothesis is seen by every view.  A far one is hidden in view ``t`` when a z-buffer of the
    current map (:func:`nearest_surface`) has a surface nearer by more than ``jump / 2`` at its image: the
    occlusion reasoning of Kang, Szeliski & Chai (CVPR 2001) with the occluders taken from the map itself
    rather than from a fixed split of the views.  Fewer than ``min_visible`` of the view weight: no far
    hypothesis.  A pixel moves to the other side when that side's cost is ``ratio`` times lower and it
    touches that side, one pixel layer per round, up to ``radius`` rounds; a 3 x 3 median over the band
    then removes isolated decisions.

    This places the thin rims the box costs cannot: the 1-3 px band of an occluder's silhouette that has
    the background's colour (on hci-antinous the dark outline of the statue, MSE x 100 4.7 -> 2.3).

    Parameters
    ----------
    intensities : Views
        Views without contrast channels (:func:`prepare_views` with ``contrast_sigma=0``).
    disparity : ndarray (Y, X) float32

    Returns
    -------
    ndarray (Y, X) float32, a new array.
    """
    d = np.ascontiguousarray(disparity, np.float32)
    band, is_near, h_near, h_far = _band_hypotheses(d, radius, jump)
    ys, xs = np.nonzero(band)
    out = d.copy()
    if len(ys) == 0:
        return out
    n = len(ys)
    rows, cols = _pixel_image_shape(n)

    def as_image(a: np.ndarray) -> np.ndarray:
        return _as_pixel_image(a, rows, cols)

    px, py = as_image(xs.astype(np.float32)), as_image(ys.astype(np.float32))
    hyp = {"near": as_image(h_near[ys, xs]), "far": as_image(h_far[ys, xs])}
    centre = as_image(intensities.data[intensities.centre][ys, xs])                # (rows, cols, C)
    offsets = np.linspace(-search, search, 5).astype(np.float32)
    dv_all, du_all = intensities.offsets
    used = intensities.used()
    threads = _threads()
    total = np.float32(sum(float(intensities.weight[vu]) for vu in used))
    margin = np.float32(0.5 * jump)

    def best_cost(h0: np.ndarray, current: np.ndarray | None) -> np.ndarray:
        # min over the offsets of the visible views' mean squared difference; current: the map the z-buffers
        # come from (None: every view sees the hypothesis).  The views are split into 4 parts, each with its
        # own sums, run on threads (the z-buffer kernel and OpenCV release the GIL); the fixed split keeps the
        # sums the same on any number of cores.
        with ThreadPoolExecutor(max_workers=threads) as pool:
            parts = list(pool.map(lambda i: view_sums(h0, current, used[i::4]), range(4)))
        cost = sum(p[0] for p in parts)
        seen = sum(p[1] for p in parts)
        c = np.where(seen >= min_visible * total, cost / np.maximum(seen, 1e-12), np.inf)
        return c.min(axis=0).reshape(-1)[:n]

    def view_sums(h0: np.ndarray, current: np.ndarray | None, views: list[tuple[int, int]]
                  ) -> tuple[np.ndarray, np.ndarray]:
        cost = np.zeros((len(offsets), rows, cols), np.float32)
        seen = np.zeros((len(offsets), rows, cols), np.float32)
        for vu in views:
            w = np.float32(intensities.weight[vu])
            dv, du = np.float32(dv_all[vu]), np.float32(du_all[vu])
            zbuf = None if current is None else nearest_surface(current, dv, du)
            for k, e in enumerate(offsets):
                h = h0 + e
                mx, my = px - h * du, py - h * dv
                sample = cv2.remap(intensities.data[vu], mx, my, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
                diff = np.square(sample.reshape(centre.shape) - centre).sum(axis=-1)
                if zbuf is None:
                    visible = w
                else:
                    z = cv2.remap(zbuf, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
                    visible = (z <= h + margin).astype(np.float32) * w
                cost[k] += visible * diff
                seen[k] += visible
        return cost, seen

    near_cost = best_cost(hyp["near"], None)
    near_value, far_value = hyp["near"].reshape(-1)[:n], hyp["far"].reshape(-1)[:n]
    side = is_near[ys, xs]
    r = np.float32(ratio)
    ring = np.ones((3, 3), np.uint8)
    # one pixel layer per round: a pixel may join a side only next to it, and the next layer is judged with
    # the z-buffers of the map that includes this one (a far point beside an eroded occluder looks visible
    # in views where the occluder's cut-off rim hides it)
    for _ in range(max(1, radius)):
        far_cost = best_cost(hyp["far"], out)
        near_map = np.zeros(d.shape, bool)
        near_map[ys, xs] = side
        next_to_near = cv2.dilate(near_map.astype(np.uint8), ring).astype(bool)[ys, xs]
        next_to_far = cv2.dilate((band & ~near_map).astype(np.uint8), ring).astype(bool)[ys, xs]
        to_far = side & (far_cost * r < near_cost) & next_to_far
        to_near = ~side & (near_cost * r < far_cost) & next_to_near
        if not (to_far.any() or to_near.any()):
            break
        out[ys[to_far], xs[to_far]] = far_value[to_far]
        out[ys[to_near], xs[to_near]] = near_value[to_near]
        side = (side & ~to_far) | to_near
        log.debug("visibility relabel: %d band pixels, %d to the far side, %d to the near side", n,
                  int(to_far.sum()), int(to_near.sum()))
    # where both sides match about equally (one flat colour on both) the per-pixel decisions are speckled: a
    # 3 x 3 median over the band removes isolated ones (hci-antinous MSE x 100 2.55 -> 2.30)
    out[ys, xs] = cv2.medianBlur(out, 3)[ys, xs]
    return out


def two_colour_edge(image: np.ndarray, ys: np.ndarray, xs: np.ndarray, normal: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Where each pixel's colour lies between its two neighbours across an edge, and how flat the two sides
    are: (mixing, flatness), each (n,) float64,

        m = (I(p) - I(p - n)) . (I(p + n) - I(p - n)) / |I(p + n) - I(p - n)|^2
        f = (|I(p + 2n) - I(p + n)| + |I(p - 2n) - I(p - n)|) / |I(p + n) - I(p - n)|

    with ``n`` the unit ``normal`` (n, 2) as (y, x), ``I`` the (Y, X, C) ``image`` (bilinear).  On an edge
    between two flat colours ``m`` is the fraction of pixel ``p`` the ``+n`` side covers and ``f = 0``; a side
    whose colour still changes a pixel further out (texture, shading, a second edge) raises ``f``.  NaN where
    the two neighbours have the same colour."""
    img = np.ascontiguousarray(image, np.float32)
    img = img if img.ndim == 3 else img[..., None]
    rows, cols = _pixel_image_shape(len(ys))

    def at(k: float) -> np.ndarray:
        mx = _as_pixel_image((xs + k * normal[:, 1]).astype(np.float32), rows, cols)
        my = _as_pixel_image((ys + k * normal[:, 0]).astype(np.float32), rows, cols)
        sample = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return sample.reshape(rows * cols, -1)[:len(ys)].astype(np.float64)

    back_out, back, front, front_out = at(-2.0), at(-1.0), at(1.0), at(2.0)
    own = img[ys, xs].astype(np.float64)
    step = front - back
    contrast = np.einsum("nc,nc->n", step, step)
    spread = np.linalg.norm(front_out - front, axis=1) + np.linalg.norm(back_out - back, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        valid = contrast > 1e-12
        mixing = np.where(valid, np.einsum("nc,nc->n", own - back, step) / contrast, np.nan)
        flatness = np.where(valid, spread / np.sqrt(contrast), np.nan)
    return mixing, flatness


def mixing_agrees(mixed: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Where the centre view's colour mixing (:func:`two_colour_edge`) backs a coverage estimate: both on the
    same side of 1/2, and the mixing a mix, inside (0, 1).  A colour outside the range between its two
    neighbours' (the dark band of a shaded silhouette, darker than the wall and the lit surface) says
    nothing about coverage.  Arrays (n,); NaN mixing never agrees."""
    same_side = ((mixed > 0.5) & (covered > 0.5)) | ((mixed < 0.5) & (covered < 0.5))
    return same_side & (mixed > 0.0) & (mixed < 1.0)


def coverage_relabel(intensities: Views, disparity: np.ndarray, *, radius: int = 4, jump: float = 0.5,
                     significance: float = 2.0, agreed_significance: float = 0.5, min_views: int = 6,
                     flat_edge: float = 0.2, mixing_margin: float = 0.1) -> np.ndarray:
    """Give each pixel on a depth edge to the surface that covers most of it, measured by the background's
    motion through it.

    A pixel ``p`` cut by an occluder's outline is a mix: a fraction ``a`` of it shows the occluder (disparity
    ``h_n``) and ``1 - a`` the background (``h_f``).  Followed along the occluder, in view ``t`` (offset
    ``o_t``) it reads

        N_t = I_t(p - h_n o_t) = a S + (1 - a) B(p + (h_f - h_n) o_t)

    where ``B`` is the background as the centre view shows it: the occluder's part stays put while the
    background slides through the rest.  A weighted least-squares fit

        N_t = c_0 + (1 - a) B_t + c_v dv_t + c_u du_t

    over the views whose background point the centre view shows unoccluded (no near surface within 2 px of
    it in the map) gives ``1 - a``; the offset terms absorb what changes linearly across the aperture (an
    occluder disparity a little off moves the outline across the pixel in proportion to the offset; on
    hci-antinous, without them, most of the changed pixels were wrong).  Where ``a`` lies on the other side
    of 1/2 than the map by more than ``significance`` standard errors, the pixel takes the other side's
    hypothesis: the pixel-centre convention of a ground truth (a mixed pixel belongs to the surface at its
    centre).  A second, independent estimate of the same fraction comes from the centre view alone: where
    the pixel's colour lies between its neighbours one pixel outward and inward along the edge normal
    (:func:`two_colour_edge`; the normal is the gradient of the near side's indicator smoothed with
    ``sigma = 1``).  Where the two agree on the other side, ``agreed_significance`` standard errors
    suffice (a box-filtered disc: MSE x 100 1.68 -> 0.93; hci-antinous 2.07 -> 2.06); a colour outside
    the range between its neighbours' (mixing outside (0, 1): the dark band of a shaded silhouette) is no
    mix and does not agree (:func:`mixing_agrees`; hci-antinous 2.03 -> 1.90).

    Where the regression cannot decide (fewer than ``min_views`` views, a background without texture, not
    significant), a clean two-colour edge in the centre view decides alone: both sides flat a pixel further
    out (flatness below ``flat_edge``) and the mixing more than ``mixing_margin`` from 1/2.  The regression
    needs a background that moves; this needs two surfaces of different colour, and the flatness keeps out
    the shaded rims the colour of the background, where the mixing was wrong on most hci-antinous pixels
    (a disc over a flat background: 74 -> 14 wrong pixels; hci-antinous MSE x 100 2.06 -> 2.03, another
    generated disc 0.56 -> 0.32).  Only pixels next to the other side are tested, once; the others keep
    their side.  Both models mix light, so a linear light
    field's views are taken with their display encoding undone (:meth:`Views.linear`; generated
    illum-mini MSE x 100 0.65 -> 0.39); stored sRGB values are used as stored (decoding them made
    hci-antinous worse).

    Photo-consistency alone cannot do this: with a smooth background a mixed pixel matches the occluder's
    disparity almost as well as a fully covered one, so the relabel before it (:func:`visibility_relabel`)
    gives the occluder every pixel it covers by about 15 % or more (a disc of exact box-filtered coverage).

    Parameters
    ----------
    intensities : Views
        Views without contrast channels; the regression reduces colour views to luma.
    disparity : ndarray (Y, X) float32
    radius, jump : the band and hypotheses of :func:`_band_hypotheses`.
    significance, agreed_significance : float
        Standard errors of the regression's ``a - 1/2`` needed to move a pixel, alone and with the centre
        view's colour mixing agreeing.
    flat_edge, mixing_margin : float
        Where the regression does not decide: the centre view's flatness and ``|mixing - 1/2|`` that do.

    Returns
    -------
    ndarray (Y, X) float32, a new array.
    """
    d = np.ascontiguousarray(disparity, np.float32)
    out = d.copy()
    band, is_near, h_near, h_far = _band_hypotheses(d, radius, jump)
    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)
    near_px, far_px = band & is_near, band & ~is_near
    edge = (near_px & cv2.dilate(far_px.astype(np.uint8), cross).astype(bool)) | \
           (far_px & cv2.dilate(near_px.astype(np.uint8), cross).astype(bool))
    ys, xs = np.nonzero(edge)
    if len(ys) == 0:
        return out

    rows, cols = _pixel_image_shape(len(ys))
    px, py = (_as_pixel_image(a.astype(np.float32), rows, cols) for a in (xs, ys))
    hn, hf = (_as_pixel_image(h[ys, xs], rows, cols) for h in (h_near, h_far))
    # the models mix light: the display encoding of linear light fields' views is undone
    centre_light = intensities.linear(intensities.centre)
    centre = luma(centre_light)
    # a background point is seen unoccluded where no pixel within 2 px (the bicubic support) is nearer
    nearest_around = cv2.dilate(d, np.ones((5, 5), np.uint8))
    visible_below = hf + np.float32(0.5 * jump)
    dv_all, du_all = intensities.offsets
    # weighted least squares of y = follow on (1, x = back, dv, du); the view-offset terms absorb a colour
    # change linear across the aperture (a slightly wrong occluder disparity moves its outline across the
    # pixel in proportion to the offset, as a smooth background gradient moves past it)
    moments = np.zeros((4, 4, rows, cols), np.float64)
    rhs = np.zeros((4, rows, cols), np.float64)
    syy = np.zeros((rows, cols), np.float64)
    count = np.zeros((rows, cols), np.int32)
    for vu in intensities.used():
        dv, du = np.float32(dv_all[vu]), np.float32(du_all[vu])
        follow = cv2.remap(luma(intensities.linear(vu)), px - hn * du, py - hn * dv, cv2.INTER_CUBIC,
                           borderMode=cv2.BORDER_REPLICATE)
        bx, by = px + (hf - hn) * du, py + (hf - hn) * dv
        back = cv2.remap(centre, bx, by, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
        z = cv2.remap(nearest_around, bx, by, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                      borderValue=np.inf)
        ok = z < visible_below
        w = ok * np.float64(intensities.weight[vu])
        r = np.stack([np.ones_like(w), back.astype(np.float64), np.full_like(w, dv), np.full_like(w, du)])
        y = follow.astype(np.float64)
        moments += w * r[:, None] * r[None, :]
        rhs += w * r * y
        syy += w * y * y
        count += ok
    n = len(ys)
    m = np.moveaxis(moments.reshape(4, 4, -1)[..., :n], -1, 0) + 1e-9 * np.eye(4)
    inverse = np.linalg.inv(m)                                          # (n, 4, 4)
    b = rhs.reshape(4, -1)[:, :n].T                                      # (n, 4)
    coef = np.einsum("nij,nj->ni", inverse, b)
    sw = np.maximum(m[:, 0, 0], 1e-12)
    count = count.reshape(-1)[:n]
    # residual variance per view, unbiased for the 4 fitted parameters
    residual = (np.maximum(syy.reshape(-1)[:n] - np.einsum("ni,ni->n", coef, b), 0.0) / sw
                * count / np.maximum(count - 4, 1))
    x_spread = 1.0 / np.maximum(inverse[:, 1, 1], 1e-30)              # sum w (x - its fit on 1, dv, du)^2
    stderr = np.sqrt(residual / x_spread)
    covered = 1.0 - coef[:, 1]
    # the centre view's own estimate: the normal points into the near side
    indicator = cv2.GaussianBlur(is_near.astype(np.float32), (0, 0), 1.0)
    normal = np.stack([g[ys, xs] for g in np.gradient(indicator)], axis=1).astype(np.float64)
    normal /= np.maximum(np.hypot(normal[:, 0], normal[:, 1]), 1e-12)[:, None]
    mixed, flatness = two_colour_edge(centre_light, ys, xs, normal)
    agree = mixing_agrees(mixed, covered)
    # a background that varies over the views by less than one 8-bit grey level (beyond a linear trend) is
    # flat: no slope
    textured = x_spread / sw > (1.0 / 255.0) ** 2
    needed = np.where(agree, agreed_significance, significance)
    tested = (count >= min_views) & textured & (np.abs(covered - 0.5) > needed * stderr)
    clean_edge = ~tested & (flatness < flat_edge) & (np.abs(mixed - 0.5) > mixing_margin)
    decided = tested | clean_edge
    estimate = np.where(clean_edge, mixed, covered)
    side = is_near[ys, xs]
    to_near, to_far = decided & ~side & (estimate > 0.5), decided & side & (estimate < 0.5)
    out[ys[to_near], xs[to_near]] = h_near[ys[to_near], xs[to_near]]
    out[ys[to_far], xs[to_far]] = h_far[ys[to_far], xs[to_far]]
    log.debug("coverage relabel: %d edge pixels, %d to the near side, %d to the far side", len(ys),
              int(to_near.sum()), int(to_far.sum()))
    return out


#: Occlusion-edge pass parameters of :func:`run_pipeline`, the same for every method.
EDGE_DEFAULTS: dict[str, Any] = {
    "edge_radius": 4,         # fix_occlusion_edges within this many px of a jump; 0 = off
    "edge_jump": 0.5,         # disparity jump (px per view step) that makes a depth edge
    "edge_ratio": 1.5,        # near-side pixels whose all-view cost exceeds this x the far wedge cost move back
    "edge_wedge": 2,          # the far cost's views: the best wedge of this many of the 8 sectors (2 = 90 deg)
    "edge_median_radius": 5,  # colour-guided weighted median over the edge band (0 = off)
    "edge_visibility": True,  # then every band pixel takes the side its own colour matches (visibility_relabel)
    "edge_coverage": True,    # then edge pixels take the surface covering most of them (coverage_relabel)
}


#: Matching-view parameters of :func:`run_pipeline` that both methods share (see :func:`prepare_views`).
VIEW_DEFAULTS: dict[str, Any] = {
    "contrast_sigma": 1.5,    # local contrast normalisation of the views (Gaussian sigma, px; 0 = off)
    "contrast_eps": 0.005,    # floor of the normalisation's eps
    "contrast_noise": 3.0,    # eps = max(contrast_eps, this x the views' noise sigma); 0 = contrast_eps as given
    "min_view_weight": 0.1,   # views with a lower decoder weight (relative to the centre view) are dropped
    "disparity_range": None,  # (lo, hi) px per view step; None = the metadata's, else estimated
}


def fix_occlusion_edges(views: Views, disparity: np.ndarray, guide: np.ndarray, *, radius: int = 4,
                        jump: float = 0.5, ratio: float = 1.5, wedge: int = 2, median_radius: int = 5,
                        intensities: Views | None = None, visibility: bool = True, coverage: bool = True
                        ) -> np.ndarray:
    """Remove the foreground fattening at depth discontinuities.

    Four steps, all restricted to the band within ``radius`` px of a disparity jump larger than ``jump``
    (:func:`_edge_band`):

    1. **Visibility check.**  A pixel on the near side of a jump (``d > (near + far) / 2``) claims to lie on
       the occluder, and nothing occludes an occluder: every view must then see it, so its cost over *all*
       views (:func:`half_plane_cost_volume` with one sector, views warped per pixel by ``d``) must be small.
       A background pixel fattened by the occluder is seen by all views only on its own surface: its cost at
       the far disparity ``far`` over the views on the un-occluded side is lower.  Those views are the best
       wedge of ``wedge`` of the 8 angular sectors (2: a 90 degree wedge).  A half-plane would do beside a
       straight edge, but in a concave pocket of the occluder's outline (between chin and neck on
       hci-antinous) the background is hidden from views on two sides and every half-plane still looks past
       the occluder.  Pixels with ``C_all(d) > ratio * C_wedge(far)`` take ``far`` (the occlusion reasoning
       of Kang, Szeliski & Chai, CVPR 2001 and Wang, Efros & Ramamoorthi, ICCV 2015, used as a left-right
       style consistency test).
    2. **Edge snapping.**  A weighted median of the disparity guided by the centre view in colour
       (Ma et al., ICCV 2013; ``cv2.ximgproc.weightedMedianFilter``, radius ``median_radius``) replaces the
       band, so the remaining depth edge follows the colour edge.
    3. **Per-pixel visibility** (:func:`visibility_relabel`, when ``intensities`` are given and ``visibility``):
       every band pixel takes the side whose disparity its own colour matches ``ratio`` times better in the
       views that see it.  The median of step 2 puts the edge at the strongest colour edge, which cuts off an
       occluder's silhouette rim when the rim is as dark as the background.
    4. **Coverage** (:func:`coverage_relabel`, when ``intensities`` are given and ``coverage``): a pixel on
       the edge goes to the surface that covers more than half of it, measured by how much of the
       background's motion across the views shows through it and by where its colour lies between its
       neighbours across the edge.

    Parameters
    ----------
    views : Views
        The matching views (the ones the cost volume used).
    disparity : ndarray (Y, X) float32
    guide : ndarray (Y, X, 3) or (Y, X, 1) uint8
        :func:`colour_guide`.
    intensities : Views, optional
        The views without contrast channels, for steps 3 and 4 (None: both are skipped).
    visibility, coverage : bool
        Run step 3, step 4.

    Returns
    -------
    ndarray (Y, X) float32, a new array.
    """
    d = np.ascontiguousarray(disparity, np.float32)
    near, far, band = _edge_band(d, radius, jump)
    if not band.any():
        return d.copy()
    zero = np.zeros(1)
    c_all = half_plane_cost_volume(views, zero, radius=1, base=d, n_sectors=1)[..., 0]
    c_far = half_plane_cost_volume(views, zero, radius=1, base=far, span=wedge)[..., 0]
    switch = band & (d > 0.5 * (near + far)) & (c_all > np.float32(ratio) * c_far)
    d = np.where(switch, far, d).astype(np.float32)
    log.debug("occlusion edges: %.2f %% of pixels in the band, %.2f %% moved to the far side",
              100.0 * band.mean(), 100.0 * switch.mean())
    if median_radius > 0:
        _, _, band = _edge_band(d, radius, jump)
        g = guide if guide.ndim == 2 or guide.shape[-1] in (1, 3) else guide[..., :3]
        # with a colour guide OpenCV clusters the colours by k-means++ from the calling thread's cv::RNG, which is
        # thread-local: seed the RNG of a short-lived thread of its own, so the same input gives the same map and
        # no other RNG of the process is seeded (the thread, and its RNG, end with the call)
        def seeded_weighted_median(guide: np.ndarray, values: np.ndarray) -> np.ndarray:
            cv2.setRNGSeed(0)
            return cv2.ximgproc.weightedMedianFilter(guide, values, int(median_radius), 25.5)

        with ThreadPoolExecutor(max_workers=1) as own_thread:
            wm = own_thread.submit(seeded_weighted_median, np.ascontiguousarray(g), d).result()
        d = np.where(band, wm, d).astype(np.float32)
    if intensities is not None and visibility:
        d = visibility_relabel(intensities, d, radius=radius, jump=jump, ratio=ratio)
    if intensities is not None and coverage:
        d = coverage_relabel(intensities, d, radius=radius, jump=jump)
    return d


# ---------------------------------------------------------------------------------------------------------------
# the pipeline both methods run
# ---------------------------------------------------------------------------------------------------------------
#: Parameters of :func:`run_pipeline` (each method module supplies its own defaults for all of them).
PIPELINE_KEYS = ("label_step", "radius", "p1", "p2", "edge_sigma", "paths", "median_radius", "refine_radius",
                 "refine_range", "refine_samples", "grey", "pattern", "contrast_sigma", "contrast_eps",
                 "contrast_noise", "contrast_weight", "min_view_weight", "disparity_range", *EDGE_DEFAULTS)


def check_params(method: str, defaults: Mapping[str, Any], kw: Mapping[str, Any]) -> dict[str, Any]:
    """Merge keywords into the defaults; ValueError naming an unknown or invalid parameter."""
    unknown = set(kw) - set(defaults)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)} for method {method!r}; valid: {sorted(defaults)}")
    p = {**defaults, **kw}
    for name in ("label_step", "p1", "p2", "edge_sigma", "refine_range", "contrast_eps"):
        if not float(p[name]) > 0:
            raise ValueError(f"{name} must be positive, got {p[name]!r}")
    for name in ("contrast_sigma", "contrast_noise"):
        if not float(p[name]) >= 0:
            raise ValueError(f"{name} must be >= 0, got {p[name]!r}")
    if p["contrast_weight"] is not None and not float(p["contrast_weight"]) > 0:
        raise ValueError(f"contrast_weight must be positive or None, got {p['contrast_weight']!r}")
    if not 1 <= int(p["edge_wedge"]) <= N_SECTORS:
        raise ValueError(f"edge_wedge must be a number of sectors in [1, {N_SECTORS}], got {p['edge_wedge']!r}")
    if not float(p["edge_jump"]) > 0 or not float(p["edge_ratio"]) > 0:
        raise ValueError(f"edge_jump and edge_ratio must be positive, got edge_jump={p['edge_jump']!r}, "
                         f"edge_ratio={p['edge_ratio']!r}")
    for name in ("radius", "median_radius", "refine_radius", "edge_radius", "edge_median_radius"):
        if name == "refine_radius" and p[name] == "auto":
            continue
        if int(p[name]) < 0:
            raise ValueError(f"{name} must be >= 0 (or 'auto' for refine_radius), got {p[name]!r}")
    for name in ("edge_visibility", "edge_coverage"):
        if not isinstance(p[name], (bool, np.bool_)):
            raise ValueError(f"{name} must be True or False, got {p[name]!r}")
    if int(p["refine_samples"]) < 3:
        raise ValueError(f"refine_samples must be >= 3, got {p['refine_samples']!r}")
    return p


def run_pipeline(lf: LightField, p: Mapping[str, Any], *, progress: Progress = None
                 ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Cost volume -> SGM -> winner -> weighted median -> per-pixel refinement (see
    :mod:`plenodecode.depth.costvolume` for the method and its references).

    Returns
    -------
    disparity (Y, X) float32, confidence (Y, X) float32, params (the parameters with the range used)
    """
    plain = prepare_views(lf, min_view_weight=float(p["min_view_weight"]), grey=bool(p["grey"]),
                          pattern=p["pattern"])
    sigma, floor, k = float(p["contrast_sigma"]), float(p["contrast_eps"]), float(p["contrast_noise"])
    weight = None if p["contrast_weight"] is None else float(p["contrast_weight"])
    built: dict[float, Views] = {}

    def matching_views(eps: float) -> Views:
        if eps not in built:
            built[eps] = add_contrast(plain, sigma, eps, weight) if sigma > 0 else plain
        return built[eps]

    (lo, hi), source = disparity_range(lf, lambda: matching_views(floor), p["disparity_range"])
    noise, eps = 0.0, floor
    if sigma > 0 and k > 0:
        # the normalisation's floor above the noise, so that noise in flat areas is not matched as texture
        noise = noise_sigma(plain, lo, hi)
        eps = max(floor, k * noise)
        log.info("view noise sigma %.4f: contrast eps %.4f", noise, eps)
    views = matching_views(eps)
    # the intensity-only views stay alive for the edge pass's relabel only when it runs
    intensities = plain if (p["edge_visibility"] or p["edge_coverage"]) and int(p["edge_radius"]) > 0 else None
    del plain, built
    step = float(p["label_step"])
    labels = make_labels(lo, hi, step, pad=2 * step)
    n_labels, n_paths = len(labels), int(p["paths"])
    refine_radius = p["refine_radius"]
    if refine_radius == "auto":
        # the refinement window grows with the image: 13 x 13 on 512 px views, 7 x 7 below 300 px
        refine_radius = int(np.clip(round(min(lf.shape[2:4]) / 85.0), 3, 6))
    refine_radius = int(refine_radius)
    n_refine = int(p["refine_samples"]) if refine_radius > 0 else 0
    total = n_labels + n_paths + n_refine

    def stage(offset: int) -> Progress:
        if progress is None:
            return None
        return lambda done, _n: progress(offset + done, total)

    log.info("cost volume: %d labels in [%.2f, %.2f] (%s), %d views", n_labels, labels[0], labels[-1], source,
             len(views.used()) + 1)
    cost = half_plane_cost_volume(views, labels, radius=int(p["radius"]), progress=stage(0))
    sub = cost[::4, ::4]
    span = float(np.median(sub.max(axis=-1) - sub.min(axis=-1)))
    cost *= np.float32(1.0 / max(span, 1e-12))
    guide = views.guide()
    agg = sgm(cost, guide, p1=float(p["p1"]), p2=float(p["p2"]), sigma=float(p["edge_sigma"]), paths=n_paths,
              progress=stage(n_labels))
    del cost
    disparity, confidence = winner(agg, labels)
    del agg
    disparity = weighted_median(guide, disparity, int(p["median_radius"]))
    if n_refine:
        half = float(p["refine_range"]) * step
        deltas = np.linspace(-half, half, n_refine)
        fine = half_plane_cost_volume(views, deltas, radius=refine_radius, interpolation=cv2.INTER_CUBIC,
                                      base=disparity, progress=stage(n_labels + n_paths))
        offset, _ = winner(fine, deltas)
        disparity = disparity + offset
    if int(p["edge_radius"]) > 0:
        disparity = fix_occlusion_edges(views, disparity, colour_guide(lf), radius=int(p["edge_radius"]),
                                        jump=float(p["edge_jump"]), ratio=float(p["edge_ratio"]),
                                        wedge=int(p["edge_wedge"]),
                                        median_radius=int(p["edge_median_radius"]),
                                        intensities=intensities, visibility=bool(p["edge_visibility"]),
                                        coverage=bool(p["edge_coverage"]))
    params = {**p, "refine_radius": refine_radius, "disparity_range": [float(lo), float(hi)],
              "noise_sigma": noise, "contrast_eps_used": eps,
              "disparity_range_source": source, "n_labels": n_labels, "views_used": len(views.used()) + 1}
    return disparity.astype(np.float32), confidence, params


__all__ = [
    "Views", "luma", "prepare_views", "disparity_range", "estimate_disparity_range", "metadata_disparity_range",
    "make_labels", "half_plane_cost_volume", "half_plane_groups", "sgm", "add_contrast", "noise_sigma",
    "weighted_median", "shift_view", "remap_view", "sector_of", "N_SECTORS", "view_pattern",
    "winner", "colour_guide", "fix_occlusion_edges", "visibility_relabel", "coverage_relabel", "two_colour_edge",
    "mixing_agrees", "nearest_surface", "EDGE_DEFAULTS", "VIEW_DEFAULTS",
    "run_pipeline", "check_params", "PIPELINE_KEYS",
]
