"""All-in-focus images: every pixel rendered at its own disparity from the views that see it.

Two methods, by name in :data:`ALL_IN_FOCUS_METHODS` (:func:`all_in_focus` dispatches):

* ``'depth'`` (default, :func:`depth_guided_all_in_focus`): the centre view's disparity from the depth stage
  (:func:`plenodecode.depth.estimate_depth`, preset ``'fast'`` by default), and each pixel the weighted mean of
  the views in which no nearer surface covers it and whose colour there agrees with the centre view's
  (:func:`render_visible`).  Sharp where the disparity is right, no halo at occlusion edges, and less noisy
  than the centre view.
* ``'focal-stack'`` (:func:`focal_stack_all_in_focus`): the slope of the sharpest slice of a focal stack per
  pixel (:func:`~plenodecode.render.focalstack.depth_from_focus`), rendered from all views
  (:func:`~plenodecode.render.focalstack.refocus_per_pixel`); Levoy et al. / Ng (2005).  Its 9 x 9 focus window
  straddles depth edges, and all views mix the occluder's colour into the background beside it: halos.

Visibility is a z-buffer per view (Kang, Szeliski & Chai, CVPR 2001; the occlusion stage's
:func:`plenodecode.depth.occlusion.nearest_surface`): the centre pixel ``p`` of disparity ``d(p)`` appears in
view ``t`` (offset ``o_t = (v - vc, u - uc)``) at ``q_t(p) = p - d(p) o_t`` (HCI convention, design.md), and
the view sees it unless a surface nearer by more than ``tolerance`` lands there:

    vis_t(p) = [ Z_t(q_t(p)) <= d(p) + tolerance ],   Z_t(q) = max { d(r) : r - d(r) o_t within 1 px of q }.

A pixel an occluder's outline cuts (a mix of two surfaces) or a wrong disparity makes views disagree with the
centre view beyond the noise; the photo-consistency weight (a range kernel across the views, as a bilateral
filter's) lets those views fade out, so such pixels keep the centre view's colour instead of a blur.
"""

from __future__ import annotations

import logging
import warnings
from typing import Any, Callable

import cv2
import numpy as np

from ..imaging import MIN_DATA_WEIGHT
from ..registry import lookup
from ..types import LightField
from ._common import check_lightfield
from .focalstack import check_per_pixel_args, default_slopes, depth_from_focus, focal_stack, refocus_per_pixel
from .viewpoints import perspective
from ._common import REFOCUS_METHODS

log = logging.getLogger(__name__)

#: Depth method of the default all-in-focus image (a key of :data:`plenodecode.depth.DEPTH_METHODS`); 'fast'
#: renders as well as 'costvolume' here (``python -m bench bench_allinfocus``).
DEFAULT_DEPTH_METHOD = "fast"

#: Smallest noise level (linear units) the photo-consistency weight assumes: a noise-free light field's views
#: still differ by interpolation and quantisation.
NOISE_FLOOR = 1e-3

Progress = Callable[[int, int], None] | None


def pair_noise(lf: LightField, disparity: np.ndarray, *, interp: int = cv2.INTER_CUBIC, border: int = 4) -> float:
    """Robust standard deviation of a view's difference to the centre view where the disparity aligns them.

    The four views next to the centre view are warped onto it by the disparity; the differences ``r`` of all
    their samples (``border`` px excluded) give ``sigma = 1.4826 median |r - median r|`` (twice the noise
    variance of one view where the disparity is right; the outliers of occlusions and edges barely move it).

    Parameters
    ----------
    lf : LightField
    disparity : ndarray (Y, X) float32
    interp : int
        OpenCV interpolation flag.
    border : int

    Returns
    -------
    float
        ``sigma`` in the light field's units; :data:`NOISE_FLOOR` at least (also for a single view).
    """
    nv, nu, ny, nx, nc = lf.shape
    vc, uc = lf.centre_index
    yy, xx = np.mgrid[0:ny, 0:nx].astype(np.float32)
    inner = (slice(border, max(border, ny - border)), slice(border, max(border, nx - border)))
    centre = perspective(lf, vc, uc).reshape(ny, nx, nc)          # its edge gaps filled
    diffs = []
    for dv, du in ((0, 1), (1, 0), (0, -1), (-1, 0)):
        if 0 <= vc + dv < nv and 0 <= uc + du < nu:
            img = cv2.remap(lf.data[vc + dv, uc + du], xx - disparity * np.float32(du),
                            yy - disparity * np.float32(dv), interp, borderMode=cv2.BORDER_REPLICATE)
            diffs.append((img.reshape(ny, nx, nc) - centre)[inner].ravel())
    if not diffs or sum(map(len, diffs)) == 0:
        return NOISE_FLOOR
    r = np.concatenate(diffs)
    return max(float(1.4826 * np.median(np.abs(r - np.median(r)))), NOISE_FLOOR)


def _weighted_remap(img: np.ndarray, data: np.ndarray, weight: np.ndarray, mx: np.ndarray, my: np.ndarray,
                    flags: int) -> tuple[np.ndarray, np.ndarray]:
    """A view resampled at ``(my, mx)`` by normalised convolution, ``remap(w L) / remap(w)``, so that its samples
    without data (weight 0, holding 0: the decode's edge gaps) do not darken their neighbours, and where it has
    data (``remap(w)`` at least :data:`~plenodecode.imaging.MIN_DATA_WEIGHT`; elsewhere ``img``, the plain
    ``remap(L)``).  (Y, X, C) float32 and (Y, X) bool."""
    if np.all(weight > 0):
        return img, np.ones(weight.shape, bool)
    ny, nx = weight.shape
    premultiplied = cv2.remap(data * weight[..., None], mx, my, flags, borderMode=cv2.BORDER_REPLICATE)
    premultiplied = premultiplied.reshape(ny, nx, -1)         # (OpenCV drops a single channel's axis)
    norm = cv2.remap(weight, mx, my, flags, borderMode=cv2.BORDER_REPLICATE)
    ok = norm >= MIN_DATA_WEIGHT
    out = img.reshape(premultiplied.shape).copy()
    out[ok] = premultiplied[ok] / norm[ok][:, None]
    return out, ok


def render_visible(lf: LightField, disparity: np.ndarray, *, confidence: np.ndarray | None = None,
                   aperture: float | np.ndarray = 1.0, tolerance: float = 0.25, consistency: float = 2.5,
                   min_visible: float = 0.2, min_confidence: float = 0.0, interp: str = "cubic",
                   progress: Progress = None) -> np.ndarray:
    """Every centre pixel rendered at its own disparity from the views that see it.

    .. math::

        E(p) = \\frac{\\sum_t a_t\\, w_t(p)\\, vis_t(p)\\, c_t(p)\\, L_t(q_t(p))}
                     {\\sum_t a_t\\, w_t(p)\\, vis_t(p)\\, c_t(p)},
        \\qquad c_t(p) = \\exp\\Big(-\\frac{\\lVert L_t(q_t(p)) - L_c(p) \\rVert^2}{2\\, C\\, (k \\sigma)^2}\\Big)

    with ``q_t(p) = p - d(p) o_t``, ``a_t`` the aperture mask, ``w_t`` ``lf.weight`` sampled at ``q_t(p)``,
    ``vis_t`` the z-buffer visibility of the module docstring, ``C`` channels, ``k = consistency`` and ``sigma``
    the views' difference noise (:func:`pair_noise`).  The centre view ``L_c`` always sees ``p`` (``c = 1``).
    Where the views that see ``p`` carry less than ``min_visible`` of the weight all views would
    (``sum_t a_t w_t``), or the depth confidence is below ``min_confidence``, the pixel is the centre view's
    (:func:`~plenodecode.render.perspective`'s: its edge gaps filled).

    Parameters
    ----------
    lf : LightField
        (V, U, Y, X, C) float32, optional weight (V, U, Y, X).
    disparity : ndarray (Y, X)
        Disparity of the centre view, px per view step (positive = nearer).
    confidence : ndarray (Y, X), optional
        Depth confidence in [0, 1] (:class:`plenodecode.depth.DepthMap`), for ``min_confidence``.
    aperture : float or ndarray (V, U)
        :func:`plenodecode.render.aperture_mask`.
    tolerance : float
        A surface nearer than ``d(p) + tolerance`` at ``q_t(p)`` hides ``p`` in view ``t``.
    consistency : float
        ``k``: the range kernel's width in noise standard deviations; 0 = no photo-consistency weight.
    min_visible : float
        Fraction of the weight below which the centre view is used.
    min_confidence : float
        Confidence below which the centre view is used (0: never).
    interp : {'cubic', 'linear'}
        Interpolation of the views (the weights are bilinear, the z-buffers nearest).
    progress : callable(done, total), optional
        Called after each view.

    Returns
    -------
    ndarray, shape (Y, X, C), float32
    """
    from ..depth.occlusion import nearest_surface

    nv, nu, ny, nx, nc = lf.shape
    d, flags, mask = check_per_pixel_args(lf, disparity, interp, aperture, name="disparity")
    if consistency < 0 or tolerance < 0:
        raise ValueError(f"consistency and tolerance must be >= 0, got {consistency}, {tolerance}")
    vc, uc = lf.centre_index
    centre = perspective(lf, vc, uc).reshape(ny, nx, nc)          # its edge gaps filled
    yy, xx = np.mgrid[0:ny, 0:nx].astype(np.float32)
    near_enough = d + np.float32(tolerance)
    if consistency > 0:
        spread = np.float32(2.0 * nc * (consistency * pair_noise(lf, d, interp=flags)) ** 2)
    num = np.zeros((ny, nx, nc), np.float32)
    seen = np.zeros((ny, nx), np.float32)
    possible = np.zeros((ny, nx), np.float32)
    views = [(v, u) for v in range(nv) for u in range(nu) if mask[v, u] > 0 or (v, u) == (vc, uc)]
    for i, (v, u) in enumerate(views):
        dv, du = v - vc, u - uc
        mx, my = xx - d * np.float32(du), yy - d * np.float32(dv)
        # the centre view takes part even outside a mask that leaves it out, with a vanishing weight
        w = np.full((ny, nx), mask[v, u] if mask[v, u] > 0 else 1e-6, np.float32)
        img = cv2.remap(lf.data[v, u], mx, my, flags, borderMode=cv2.BORDER_REPLICATE).reshape(ny, nx, nc)
        if lf.weight is not None:
            w *= cv2.remap(lf.weight[v, u], mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            img, has_data = _weighted_remap(img, lf.data[v, u], lf.weight[v, u], mx, my, flags)
            img = img.reshape(ny, nx, nc)
            w *= has_data
        used = w
        if (dv, du) != (0, 0):
            z = cv2.remap(nearest_surface(d, dv, du), mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
            used = w * (z <= near_enough)
            if consistency > 0:
                used = used * np.exp(-np.square(img - centre).sum(axis=-1) / spread)
        num += img * used[..., None]
        seen += used
        possible += w
        if progress is not None:
            progress(i + 1, len(views))
    centre_only = (seen < np.float32(min_visible) * possible) | (seen <= 1e-12)
    if confidence is not None and min_confidence > 0:
        centre_only |= np.asarray(confidence, np.float32) < np.float32(min_confidence)
    log.debug("render_visible: %.2f %% of the pixels from the centre view alone", 100.0 * centre_only.mean())
    out = num / np.maximum(seen, 1e-12)[..., None]
    return np.where(centre_only[..., None], centre, out).astype(np.float32)


def _phase(progress: Progress, phase: int, phases: int) -> Progress:
    """``progress`` of one of ``phases`` equal parts of a job, reported in per cent of the whole."""
    if progress is None:
        return None
    return lambda done, total: progress(round(100 * (phase + done / max(total, 1)) / phases), 100)


def depth_guided_all_in_focus(lf: LightField, *, depth: Any = None, depth_method: str = DEFAULT_DEPTH_METHOD,
                              aperture: float | np.ndarray = 1.0, progress: Progress = None,
                              depth_options: dict[str, Any] | None = None, **render: Any) -> np.ndarray:
    """All-in-focus image from a disparity map: :func:`render_visible` at the depth stage's disparity.

    Parameters
    ----------
    lf : LightField
    depth : ndarray (Y, X) or DepthMap, optional
        The centre view's disparity (a :class:`plenodecode.depth.DepthMap` brings its confidence); default
        :func:`plenodecode.depth.estimate_depth` with ``depth_method`` and ``depth_options``.
    depth_method : str
        A key of :data:`plenodecode.depth.DEPTH_METHODS`.
    aperture : float or ndarray (V, U)
    progress : callable(done, total), optional
        Per cent of the depth estimate and the rendering.
    **render
        :func:`render_visible` parameters (``tolerance``, ``consistency``, ``min_visible``, ``min_confidence``,
        ``interp``).

    Returns
    -------
    ndarray, shape (Y, X, C), float32
    """
    check_lightfield(lf)
    confidence = None
    if depth is None:
        from ..depth import estimate_depth

        depth = estimate_depth(lf, method=depth_method, progress=_phase(progress, 0, 2), **(depth_options or {}))
    if hasattr(depth, "disparity"):
        depth, confidence = depth.disparity, depth.confidence
    return render_visible(lf, depth, confidence=confidence, aperture=aperture,
                          progress=_phase(progress, 1, 2), **render)


def all_in_focus_from_stack(lf: LightField, stack: np.ndarray, slopes: np.ndarray, *, window: int = 9,
                            aperture: float | np.ndarray = 1.0, progress: Progress = None) -> np.ndarray:
    """All-in-focus image from a computed focal stack: each pixel refocused at its sharpest slice's slope.

    :func:`~plenodecode.render.focalstack.depth_from_focus` (Tenengrad in a ``window`` box, parabolic
    refinement, 5 x 5 median) gives the slope map, resized to the light field when the stack is upsampled,
    and :func:`~plenodecode.render.focalstack.refocus_per_pixel` renders it from all views.

    Parameters
    ----------
    lf : LightField
    stack : ndarray (S, Y', X', C)
        Photographs at ``slopes`` (any order; ``Y', X'`` a multiple of the light field's).
    slopes : ndarray (S,)

    Returns
    -------
    ndarray, shape (Y, X, C), float32
    """
    s = np.asarray(slopes, np.float64).ravel()
    order = np.argsort(s)
    slope_map, _ = depth_from_focus(stack[order], s[order], window=window)
    ny, nx = lf.shape[2:4]
    if slope_map.shape != (ny, nx):
        slope_map = cv2.resize(slope_map, (nx, ny), interpolation=cv2.INTER_AREA)
    return refocus_per_pixel(lf, slope_map, aperture=aperture, progress=progress)


def focal_stack_all_in_focus(lf: LightField, *, slopes: np.ndarray | list[float] | None = None,
                             depth: np.ndarray | None = None, refocus_method: str = "shift-sum",
                             aperture: float | np.ndarray = 1.0, window: int = 9, progress: Progress = None,
                             **kw: Any) -> np.ndarray:
    """All-in-focus image from a focal stack over ``slopes`` (default :func:`default_slopes`), or, given a
    disparity map ``depth``, every pixel refocused at its own disparity from all views
    (:func:`~plenodecode.render.focalstack.refocus_per_pixel`).

    Parameters
    ----------
    lf : LightField
    slopes : array_like (S,), optional
    depth : ndarray (Y, X), optional
    refocus_method : str
        Refocus method of the stack (a key of :data:`plenodecode.render.REFOCUS_METHODS`); ``**kw`` go to it.
    aperture, window, progress :
        As :func:`all_in_focus_from_stack`.

    Returns
    -------
    ndarray, shape (Y, X, C), float32
    """
    if depth is not None:
        return refocus_per_pixel(lf, depth, aperture=aperture, progress=progress)
    s = default_slopes(lf) if slopes is None else np.sort(np.atleast_1d(np.asarray(slopes, np.float64)).ravel())
    if s.size < 2:
        raise ValueError("slopes must hold at least 2 values")
    stack = focal_stack(lf, s, method=refocus_method, aperture=aperture, progress=_phase(progress, 0, 2), **kw)
    return all_in_focus_from_stack(lf, stack, s, window=window, aperture=aperture, progress=_phase(progress, 1, 2))


#: All-in-focus methods: name -> ``fn(lf, *, aperture, progress, **options) -> (Y, X, C) float32``.
ALL_IN_FOCUS_METHODS: dict[str, Callable[..., np.ndarray]] = {
    "depth": depth_guided_all_in_focus,
    "focal-stack": focal_stack_all_in_focus,
}


def all_in_focus(lf: LightField, *, method: str = "depth", slopes: np.ndarray | list[float] | None = None,
                 depth: Any = None, aperture: float | np.ndarray = 1.0, progress: Progress = None,
                 **options: Any) -> np.ndarray:
    """An image sharp everywhere.

    Parameters
    ----------
    lf : LightField
    method : str
        A key of :data:`ALL_IN_FOCUS_METHODS`: 'depth' (default, :func:`depth_guided_all_in_focus`) or
        'focal-stack' (:func:`focal_stack_all_in_focus`).  A refocus method's name ('shift-sum',
        'fourier-slice'), the meaning of ``method`` before the depth-guided default, still selects
        'focal-stack' with that refocus method (deprecated: pass ``refocus_method=``).
    slopes : array_like (S,), optional
        The focal stack's slopes ('focal-stack' only).
    depth : ndarray (Y, X) or DepthMap, optional
        The centre view's disparity, instead of estimating it ('depth') or of the focal stack ('focal-stack').
    aperture : float or ndarray (V, U)
    progress : callable(done, total), optional
    **options
        The method's own: ``depth_method``, ``depth_options`` and :func:`render_visible` parameters for
        'depth'; ``refocus_method``, ``window`` and refocus parameters for 'focal-stack'.

    Returns
    -------
    ndarray, shape (Y, X, C), float32
    """
    check_lightfield(lf)
    if method in REFOCUS_METHODS and method not in ALL_IN_FOCUS_METHODS:
        warnings.warn(f"all_in_focus(method={method!r}) is the focal-stack method: pass method='focal-stack', "
                      f"refocus_method={method!r}", DeprecationWarning, stacklevel=2)
        method, options = "focal-stack", {**options, "refocus_method": method}
    render = lookup(ALL_IN_FOCUS_METHODS, method, param="method")
    if depth is not None and slopes is not None:
        raise ValueError("pass slopes or depth, not both")
    if slopes is not None:
        if method != "focal-stack":
            raise ValueError(f"slopes are the focal stack's: pass method='focal-stack' (method is {method!r})")
        options["slopes"] = slopes
    return render(lf, depth=depth, aperture=aperture, progress=progress, **options)


__all__ = ["ALL_IN_FOCUS_METHODS", "DEFAULT_DEPTH_METHOD", "all_in_focus", "all_in_focus_from_stack",
           "depth_guided_all_in_focus", "focal_stack_all_in_focus", "pair_noise", "render_visible"]
