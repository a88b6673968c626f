"""Focal stacks, focus measures, the sharpest slope of a region, and rendering each pixel at its own slope.

The focus measure is the gradient energy (Tenengrad with Sobel derivatives; Krotkov 1988, Subbarao et al.
1993): a refocused surface is sharpest, i.e. has the most gradient energy, at the slope equal to its disparity.
The all-in-focus images built on these (the sharpest slice's slope per pixel, or a disparity map, rendered by
:func:`refocus_per_pixel`) are in :mod:`plenodecode.render.allinfocus`.
"""

from __future__ import annotations

import logging
import math
from typing import Any, Callable

import cv2
import numpy as np

from ..imaging import remap_view
from ..types import LightField
from ._common import aperture_mask, check_lightfield, check_slope_reach, check_slopes
from ._common import get_method

log = logging.getLogger(__name__)

#: Default slopes of a focal stack when neither the caller nor ``lf.geometry.disparity_range`` gives any.
DEFAULT_SLOPE_RANGE = (-2.0, 2.0)


def default_slopes(lf: LightField, n: int = 33) -> np.ndarray:
    """``n`` slopes over ``lf.geometry.disparity_range`` (widened by 10 %) or :data:`DEFAULT_SLOPE_RANGE`."""
    rng = lf.geometry.disparity_range
    if rng is not None and len(rng) == 2 and np.all(np.isfinite(rng)) and rng[1] > rng[0]:
        lo, hi = float(rng[0]), float(rng[1])
        pad = 0.1 * (hi - lo) + 0.05
        lo, hi = lo - pad, hi + pad
    else:
        lo, hi = DEFAULT_SLOPE_RANGE
    return np.linspace(lo, hi, n)


def focal_stack(lf: LightField, slopes: np.ndarray | list[float], *, method: str = "shift-sum",
                aperture: float | np.ndarray = 1.0, upsample: int = 1,
                progress: Callable[[int, int], None] | None = None, **kw: Any) -> np.ndarray:
    """Photographs refocused at each slope.

    Parameters
    ----------
    lf : LightField
    slopes : array_like (S,)
        Spatial samples per view step.
    method : str
        A key of :data:`plenodecode.render.REFOCUS_METHODS`.  'shift-sum' computes every slice in one pass
        over the light field; 'fourier-slice' computes one 4D transform (or reuses ``refocuser=``).  With
        'shift-sum' and ``upsample > 1`` (and no ``interp``) the views are fused at their sub-pixel positions
        (:func:`plenodecode.render.superres.fuse_views`).
    aperture, upsample, **kw
        As :func:`plenodecode.render.refocus`.
    progress : callable(done, total), optional
        Called as the work advances (a few steps per pass; per view and per slice for 'fourier-slice').

    Returns
    -------
    ndarray, shape (S, upsample Y, upsample X, C), float32
    """
    check_lightfield(lf)
    s = check_slopes(slopes)
    check_slope_reach(lf, s, name="slopes")
    fn = get_method(method)
    if method == "shift-sum" and upsample != 1 and not kw:
        from .superres import fuse_views

        fn = fuse_views
    return fn(lf, s, aperture=aperture, upsample=upsample, progress=progress, **kw)


def _grey(img: np.ndarray) -> np.ndarray:
    img = np.asarray(img, np.float32)
    return img.mean(axis=-1) if img.ndim == 3 else img


def gradient_energy(img: np.ndarray) -> np.ndarray:
    """Squared gradient magnitude of the grey image (Sobel, border replicated).

    Parameters
    ----------
    img : ndarray (Y, X) or (Y, X, C)

    Returns
    -------
    ndarray, shape (Y, X), float32
    """
    g = _grey(img)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)
    return gx * gx + gy * gy


def focus_measure(img: np.ndarray, *, window: int = 9) -> np.ndarray:
    """Local Tenengrad focus measure: gradient energy averaged over a ``window`` x ``window`` box.

    Returns
    -------
    ndarray, shape (Y, X), float32
    """
    if int(window) != window or window < 1:
        raise ValueError(f"window must be a positive integer, got {window}")
    return cv2.boxFilter(gradient_energy(img), -1, (int(window), int(window)), borderType=cv2.BORDER_REFLECT)


def _parabolic_peak(values: np.ndarray, i: np.ndarray) -> np.ndarray:
    """Sub-sample offset in [-0.5, 0.5] of the vertex of the parabola through values[i-1], values[i], values[i+1]
    (along axis 0; 0 at the ends)."""
    n = values.shape[0]
    im = np.clip(i - 1, 0, n - 1)
    ip = np.clip(i + 1, 0, n - 1)
    take = lambda k: np.take_along_axis(values, k[None], 0)[0] if values.ndim > 1 else values[k]  # noqa: E731
    f0, fm, fp = take(i), take(im), take(ip)
    den = fm - 2 * f0 + fp
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.where((den < 0) & (i > 0) & (i < n - 1), 0.5 * (fm - fp) / den, 0.0)
    return np.clip(off, -0.5, 0.5)


def _bbox(region: Any, shape: tuple[int, int]) -> tuple[slice, slice, np.ndarray | None]:
    """Bounding box (row slice, col slice) of a region given as a pair of slices or a boolean (Y, X) mask."""
    if isinstance(region, np.ndarray):
        if region.shape != shape or region.dtype != bool:
            raise ValueError(f"region mask must be a boolean array of shape {shape}, got {region.dtype} {region.shape}")
        rows, cols = np.flatnonzero(region.any(1)), np.flatnonzero(region.any(0))
        if rows.size == 0:
            raise ValueError("region mask selects no pixel")
        rs, cs = slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)
        return rs, cs, region[rs, cs]
    if isinstance(region, tuple) and len(region) == 2 and all(isinstance(r, slice) for r in region):
        rs = slice(*region[0].indices(shape[0])[:2])
        cs = slice(*region[1].indices(shape[1])[:2])
        if rs.stop <= rs.start or cs.stop <= cs.start:
            raise ValueError(f"region {region} is empty")
        return rs, cs, None
    raise ValueError("region must be (row_slice, col_slice) or a boolean (Y, X) mask")


def focus_curve(lf: LightField, slopes: np.ndarray | list[float], *, region: Any = None, method: str = "shift-sum",
                aperture: float | np.ndarray = 1.0, **kw: Any) -> np.ndarray:
    """Gradient energy of a region of the photograph refocused at each slope.

    Only the region's bounding box plus the margin the largest shift needs is refocused.

    Parameters
    ----------
    lf : LightField
    slopes : array_like (S,)
    region : (row_slice, col_slice) or ndarray (Y, X) bool, optional
        Default: the whole image.
    method, aperture, **kw
        As :func:`focal_stack`.

    Returns
    -------
    ndarray, shape (S,), float64
        Mean gradient energy over the region per slope.
    """
    check_lightfield(lf)
    s = np.atleast_1d(np.asarray(slopes, np.float64)).ravel()
    nv, nu, ny, nx, _ = lf.shape
    rs, cs, mask = _bbox(region if region is not None else (slice(None), slice(None)), (ny, nx))
    vc, uc = lf.centre_index
    reach = max(vc, uc, nv - 1 - vc, nu - 1 - uc)
    m = int(math.ceil(np.max(np.abs(s)) * reach)) + 3
    y0, y1 = max(0, rs.start - m), min(ny, rs.stop + m)
    x0, x1 = max(0, cs.start - m), min(nx, cs.stop + m)
    sub = lf.replace(data=lf.data[:, :, y0:y1, x0:x1],
                     weight=None if lf.weight is None else lf.weight[:, :, y0:y1, x0:x1])
    stack = focal_stack(sub, s, method=method, aperture=aperture, **kw)
    inner = (slice(rs.start - y0, rs.stop - y0), slice(cs.start - x0, cs.stop - x0))
    out = np.empty(len(s))
    for i in range(len(s)):
        e = gradient_energy(stack[i])[inner]
        out[i] = float(e[mask].mean() if mask is not None else e.mean())
    return out


def sharpest_slope(lf: LightField, *, region: Any = None, slopes: np.ndarray | list[float] | None = None,
                   method: str = "shift-sum", aperture: float | np.ndarray = 1.0, refine: bool = True,
                   **kw: Any) -> float:
    """The slope at which a region of the refocused photograph is sharpest (its disparity, design.md).

    A coarse focus curve over ``slopes`` (default :func:`default_slopes`, 33 values), its maximum refined by a
    parabola; with ``refine`` a second curve at a tenth of the step around it, refined the same way.

    Returns
    -------
    float
        Spatial samples per view step.
    """
    s = default_slopes(lf) if slopes is None else np.atleast_1d(np.asarray(slopes, np.float64)).ravel()
    if s.size < 3:
        raise ValueError(f"slopes must hold at least 3 values, got {s.size}")
    s = np.sort(s)
    curve = focus_curve(lf, s, region=region, method=method, aperture=aperture, **kw)
    i = int(np.argmax(curve))
    step = float(np.median(np.diff(s)))
    best = float(s[i] + _parabolic_peak(curve, np.array(i)) * (s[min(i + 1, len(s) - 1)] - s[max(i - 1, 0)]) / 2)
    if not refine:
        return best
    fine = best + np.linspace(-1.5 * step, 1.5 * step, 31)
    curve = focus_curve(lf, fine, region=region, method=method, aperture=aperture, **kw)
    j = int(np.argmax(curve))
    return float(fine[j] + _parabolic_peak(curve, np.array(j)) * (fine[1] - fine[0]))


def depth_from_focus(stack: np.ndarray, slopes: np.ndarray | list[float], *, window: int = 9,
                     smooth: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel slope of the sharpest slice of a focal stack.

    Parameters
    ----------
    stack : ndarray (S, Y, X, C) or (S, Y, X)
    slopes : array_like (S,), increasing
    window : int
        Box size of the focus measure (:func:`focus_measure`).
    smooth : int
        Size of the median filter applied to the slope map: 1 (none), 3 or 5.

    Returns
    -------
    slope : ndarray (Y, X) float32
        Sharpest slope, refined between slices by a parabola, median-filtered.
    confidence : ndarray (Y, X) float32
        Peak focus measure over its mean across the stack, minus 1 (0 = flat curve, e.g. no texture).
    """
    s = np.asarray(slopes, np.float64).ravel()
    if stack.shape[0] != s.size:
        raise ValueError(f"slopes has {s.size} values for a stack of {stack.shape[0]} slices")
    if s.size > 1 and not np.all(np.diff(s) > 0):
        raise ValueError("slopes must be strictly increasing")
    if smooth not in (1, 3, 5):
        raise ValueError(f"smooth must be 1, 3 or 5, got {smooth}")
    fm = np.stack([focus_measure(stack[i], window=window) for i in range(s.size)])
    idx = np.argmax(fm, axis=0)
    off = _parabolic_peak(fm, idx)
    pos = np.clip(idx + off, 0, s.size - 1)
    slope = np.interp(pos.ravel(), np.arange(s.size), s).reshape(pos.shape).astype(np.float32)
    if smooth > 1:
        slope = cv2.medianBlur(slope, int(smooth))
    peak = np.take_along_axis(fm, idx[None], 0)[0]
    conf = (peak / np.maximum(fm.mean(0), 1e-12) - 1.0).astype(np.float32)
    return slope, conf


def check_per_pixel_args(lf: LightField, slope_map: Any, interp: str, aperture: float | np.ndarray, *,
                         name: str) -> tuple[np.ndarray, int, np.ndarray]:
    """The checked arguments of a per-pixel rendering: ``(slope map (Y, X) float32 C-contiguous, OpenCV
    interpolation flag, aperture mask (V, U) float32)``; ValueError names ``name`` for a map that is not a
    finite (Y, X) array, and a bad ``interp`` ('linear' or 'cubic') or aperture."""
    check_lightfield(lf)
    nv, nu, ny, nx, _ = lf.shape
    d = np.ascontiguousarray(slope_map, np.float32)
    if d.shape != (ny, nx) or not np.all(np.isfinite(d)):
        raise ValueError(f"{name} must be a finite (Y, X) = {(ny, nx)} array, got {d.shape}")
    flags = {"linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC}.get(interp)
    if flags is None:
        raise ValueError(f"interp must be 'linear' or 'cubic', got {interp!r}")
    return d, flags, aperture_mask((nv, nu), aperture)


def refocus_per_pixel(lf: LightField, slope_map: np.ndarray, *, aperture: float | np.ndarray = 1.0,
                      interp: str = "linear", progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Every pixel refocused at its own slope: ``E(y, x) = mean_{v,u} L_vu(y - d(y,x) a, x - d(y,x) b)``.

    Weight-normalised like the shift-sum: each view's data premultiplied by its weight is interpolated, then
    divided by the interpolated weight; one :func:`plenodecode.imaging.remap_view` per view (bilinear or bicubic,
    border replicated).

    Parameters
    ----------
    lf : LightField
    slope_map : ndarray (Y, X)
        Slope (disparity) per output pixel, spatial samples per view step.

    Returns
    -------
    ndarray, shape (Y, X, C), float32
    """
    nv, nu, ny, nx, nc = lf.shape
    d, flags, mask = check_per_pixel_args(lf, slope_map, interp, aperture, name="slope_map")
    vc, uc = lf.centre_index
    grid = np.mgrid[0:ny, 0:nx].astype(np.float32)
    num = np.zeros((ny, nx, nc), np.float32)
    den = np.zeros((ny, nx), np.float32)
    views = [(v, u) for v in range(nv) for u in range(nu) if mask[v, u] > 0]
    for i, (v, u) in enumerate(views):
        if lf.weight is not None:
            # premultiplied: a sample of almost no weight (the ant leg's edge column, divided by a nearly black
            # white: 27 x the background at weight 0.04) must not count in full where it is interpolated
            weight = lf.weight[v, u]
            img = remap_view(lf.data[v, u] * weight[..., None], d, v - vc, u - uc, grid, flags).reshape(ny, nx, nc)
            num += img * mask[v, u]
            den += remap_view(weight, d, v - vc, u - uc, grid, flags) * mask[v, u]
        else:
            num += remap_view(lf.data[v, u], d, v - vc, u - uc, grid, flags).reshape(ny, nx, nc) * mask[v, u]
            den += mask[v, u]
        if progress is not None:
            progress(i + 1, len(views))
    return np.where(den[..., None] > 1e-12, num / np.maximum(den, 1e-12)[..., None], 0).astype(np.float32)
