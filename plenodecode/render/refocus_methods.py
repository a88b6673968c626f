"""Refocusing a light field: the method registry and :func:`refocus` (by slope, by Ng's alpha, at a point of the
picture or at a distance).

Methods: 'shift-sum' (:mod:`plenodecode.render.shiftsum`, direct, bicubic by default) and 'fourier-slice'
(:mod:`plenodecode.render.fourier`, Ng 2005).  The alpha <-> slope <-> metres conversions are in
:mod:`plenodecode.render.alpha`; :func:`focus_slope` turns any of the four ways of saying where to focus
(``slope``, ``alpha``, ``at``, ``distance_m``) into a slope.  ``refocus(..., upsample=k)`` with 'shift-sum' fuses
the views' samples onto the finer grid (:func:`plenodecode.render.superres.fuse_views`) instead of interpolating
each view.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Optional

import numpy as np

from ..registry import lookup
from ..types import LightField
from ._common import REFOCUS_METHODS, check_lightfield, check_slope_reach, get_method
from .alpha import alpha_to_slope, distance_to_slope, refocus_range, split_constants

#: Side of the window around a point ``at`` whose depth decides the slope (:func:`slope_at`), samples.
FOCUS_WINDOW = 7
#: Side of the window whose sharpness decides the slope when depth is not used, samples.
SHARPNESS_WINDOW = 15


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    """The value below which half of the total weight lies (1-D arrays, weights >= 0, sum > 0)."""
    order = np.argsort(values)
    cumulative = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])


def _slope_at_from_depth(lf: LightField, y: int, x: int, progress: Progress = None) -> float:
    """Median of the 'fast' disparity over :data:`FOCUS_WINDOW` around ``(y, x)``, weighted by its confidence;
    ``progress`` is the depth map's (seconds on a large light field)."""
    from ..depth import estimate_depth

    dm = estimate_depth(lf, method="fast", progress=progress)
    h = FOCUS_WINDOW // 2
    win = (slice(max(y - h, 0), y + h + 1), slice(max(x - h, 0), x + h + 1))
    d = np.asarray(dm.disparity[win], np.float64).ravel()
    w = np.asarray(dm.confidence[win], np.float64).ravel() if dm.confidence is not None else np.ones_like(d)
    ok = np.isfinite(d) & np.isfinite(w) & (w > 0)
    if not ok.any():
        return _slope_at_from_sharpness(lf, y, x)
    return _weighted_median(d[ok], w[ok])


def _slope_at_from_sharpness(lf: LightField, y: int, x: int, progress: Progress = None) -> float:
    """The sharpest slope of :data:`SHARPNESS_WINDOW` around ``(y, x)`` over a 25-slice focal stack spanning the
    refocusable range (:func:`~plenodecode.render.focalstack.sharpest_slope`, parabola-refined; a small region,
    so without progress)."""
    from .focalstack import default_slopes, sharpest_slope

    lo, hi = refocus_range(lf)
    slopes = np.linspace(lo, hi, 25) if math.isfinite(lo) and math.isfinite(hi) else default_slopes(lf, 25)
    h = SHARPNESS_WINDOW // 2
    region = (slice(max(y - h, 0), y + h + 1), slice(max(x - h, 0), x + h + 1))
    return sharpest_slope(lf, region=region, slopes=slopes)


#: A ``callback(done, total)``, or None.
Progress = Optional[Callable[[int, int], None]]
#: How :func:`slope_at` reads the slope of a point: name -> ``fn(lf, y, x, progress) -> slope``.
FOCUS_AT_METHODS: dict[str, Callable[[LightField, int, int, Progress], float]] = {
    "depth": _slope_at_from_depth,
    "sharpness": _slope_at_from_sharpness,
}


def slope_at(lf: LightField, at: tuple[float, float], *, at_method: str = "depth", progress: Progress = None) -> float:
    """The slope that brings the point ``at = (y, x)`` of the centre view into focus.

    'depth': the median of ``estimate_depth(lf, method='fast')`` over a 7 x 7 window around the point, weighted
    by the confidence (robust to a click on an edge); 'sharpness': the slope at which a 15 x 15 window around it
    is sharpest in a focal stack over :func:`~plenodecode.render.alpha.refocus_range`.

    Parameters
    ----------
    lf : LightField
    at : (float, float)
        Row and column of the centre view, samples (rounded to the nearest sample).
    at_method : str
        A key of :data:`FOCUS_AT_METHODS`.
    progress : callable(done, total), optional
        Progress of the depth map ('depth').

    Returns
    -------
    float
        px per view step.

    Raises
    ------
    ValueError
        ``at`` outside the picture (naming ``at``); an unknown ``at_method``.
    """
    fn = lookup(FOCUS_AT_METHODS, at_method, param="at_method")
    y, x = check_point(at, lf.shape[2:4])
    return float(fn(lf, int(round(y)), int(round(x)), progress))


def check_point(at: Any, shape: tuple[int, int]) -> tuple[float, float]:
    """``at`` as ``(y, x)`` floats inside an image of ``shape`` (Y, X); ValueError naming ``at`` otherwise."""
    try:
        y, x = (float(v) for v in at)
    except (TypeError, ValueError):
        raise ValueError(f"at must be a (row, column) pair, got {at!r}") from None
    if not (0 <= y <= shape[0] - 1 and 0 <= x <= shape[1] - 1):
        raise ValueError(f"at = (row {y:g}, column {x:g}) lies outside the {shape[0]} x {shape[1]} picture")
    return y, x


def focus_slope(lf: LightField, *, slope: float | None = None, alpha: float | None = None,
                at: tuple[float, float] | None = None, distance_m: float | None = None, at_method: str = "depth",
                progress: Progress = None, **constants: float) -> float:
    """The refocus slope of whichever way the focus is given (exactly one of the four).

    Parameters
    ----------
    lf : LightField
    slope : float, optional
        px per view step, finite.
    alpha : float, optional
        Ng's relative film depth, finite and > 0 (:func:`~plenodecode.render.alpha.alpha_to_slope`).
    at : (float, float), optional
        ``(y, x)`` of the centre view (:func:`slope_at`, with ``at_method`` and ``progress``).
    distance_m : float, optional
        Metres (:func:`~plenodecode.render.alpha.distance_to_slope`; needs the focus distance in the geometry).
    **constants : float
        Overrides of :data:`~plenodecode.render.alpha.REFOCUS_CONSTANTS` (with ``alpha`` only).

    Returns
    -------
    float

    Raises
    ------
    ValueError
        Not exactly one given, a value that is not finite (or alpha <= 0); the message names the parameter.
    """
    given = {k: v for k, v in (("slope", slope), ("alpha", alpha), ("at", at), ("distance_m", distance_m))
             if v is not None}
    if len(given) != 1:
        raise ValueError(f"pass exactly one of slope, alpha, at and distance_m, got {sorted(given) or 'none'}")
    if constants and alpha is None:
        raise ValueError(f"camera constants {sorted(constants)} only apply with alpha")
    if slope is not None:
        if not math.isfinite(float(slope)):
            raise ValueError(f"slope must be a finite number, got {slope}")
        return float(slope)
    if alpha is not None:
        return float(alpha_to_slope(float(alpha), lf, **constants))
    if at is not None:
        return slope_at(lf, at, at_method=at_method, progress=progress)
    return float(distance_to_slope(distance_m, lf))


def refocus(lf: LightField, *, slope: float | None = None, alpha: float | None = None,
            at: tuple[float, float] | None = None, distance_m: float | None = None, at_method: str = "depth",
            method: str = "shift-sum", aperture: float | np.ndarray = 1.0, upsample: int = 1,
            progress: Callable[[int, int], None] | None = None, **kw: Any) -> np.ndarray:
    """Refocus a light field at a slope, at Ng's relative film depth alpha, at a point or at a distance.

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32; the photograph is weight-normalised when ``lf.weight`` is set.
    slope : float, optional
        Spatial samples per view step (design.md); a surface of disparity ``d`` is sharp at ``slope = d``.
    alpha : float, optional
        Relative film depth (Ng 2005); converted by :func:`alpha_to_slope` with the camera constants of ``lf``
        (keywords ``focal_length_m``, ``f_number``, ``lens_pitch_m``, ``spatial_step_px``, ``view_step_px``
        override them).
    at : (float, float), optional
        ``(y, x)`` of the centre view: focus on what is there (:func:`slope_at`; ``at_method`` 'depth' or
        'sharpness').
    distance_m : float, optional
        Focus at this distance, metres (:func:`~plenodecode.render.alpha.distance_to_slope`).
        Exactly one of ``slope``, ``alpha``, ``at`` and ``distance_m`` (:func:`focus_slope`).
    method : str
        A key of :data:`REFOCUS_METHODS`: 'shift-sum' (direct, bicubic by default) or 'fourier-slice' (Ng 2005;
        a 4D transform, several seconds for a full-size light field, after which each photograph is cheap:
        build it once, ``ref = FourierRefocuser(lf)``, and pass ``refocuser=ref`` to every call).
    aperture : float or ndarray (V, U)
        Synthetic aperture: a radius in (0, 1] (1 = all views) or a mask over the views (:func:`aperture_mask`).
    upsample : int
        Spatial upsampling factor ``k``: output sample ``(j, i)`` is the photograph at ``(j / k, i / k)``.  With
        'shift-sum' the views' samples are fused at their true positions ``(y + s a, x + s b)``
        (:func:`~plenodecode.render.superres.fuse_views`): surfaces at the refocus slope come out sharper than
        bicubic upsampling of the 1x photograph when ``|slope|`` is a few tenths of a pixel per view or more (the
        views then sample between each other's pixels; README, refocus section); at slope 0 every view samples the
        same points and the result is bicubic upsampling (one INFO log line says so).  'fourier-slice' zero-pads
        the spectrum (band-limited interpolation).
    progress : callable(done, total), optional
    **kw
        Refocus constants, then method options (shift-sum: ``interp``; fourier-slice: ``refocuser`` or
        ``oversample``, ``kernel_width``, ``pad``).

    Returns
    -------
    ndarray, shape (upsample Y, upsample X, C), float32
    """
    check_lightfield(lf)
    const, opts = split_constants(kw)
    fn = get_method(method)
    given = next((k for k, v in (("slope", slope), ("alpha", alpha), ("at", at), ("distance_m", distance_m))
                  if v is not None), "slope")
    slope = focus_slope(lf, slope=slope, alpha=alpha, at=at, distance_m=distance_m, at_method=at_method, **const)
    check_slope_reach(lf, slope, name=given)
    if method == "shift-sum" and upsample != 1:
        if opts:
            raise ValueError(f"options {sorted(opts)} do not apply to shift-sum with upsample > 1 (the views are "
                             "fused with Keys' kernel, not interpolated)")
        from .superres import fuse_views

        fn = fuse_views
    return fn(lf, slope, aperture=aperture, upsample=upsample, progress=progress, **opts)[0]


__all__ = ["REFOCUS_METHODS", "FOCUS_AT_METHODS", "get_method", "refocus", "focus_slope", "slope_at", "check_point"]
