"""Refocusing a light field: the method registry and :func:`refocus` (by slope or by Ng's alpha).

Methods: 'shift-sum' (:mod:`plenodecode.render.shiftsum`, direct, bicubic by default) and 'fourier-slice'
(:mod:`plenodecode.render.fourier`, Ng 2005).  The alpha <-> slope conversion is in
:mod:`plenodecode.render.alpha`.  ``refocus(..., upsample=k)`` with 'shift-sum' fuses the views' samples onto the
finer grid (:func:`plenodecode.render.superres.fuse_views`) instead of interpolating each view.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ..registry import lazy, lookup
from ..types import LightField
from ._common import check_lightfield
from .alpha import alpha_to_slope, split_constants

#: Refocusing methods: name -> ``fn(lf, slopes, *, aperture, upsample, progress, **kw) -> (S, Y', X', C)``.
#: Both modules compile numba kernels, so the entries import them on their first call.
REFOCUS_METHODS: dict[str, Callable[..., np.ndarray]] = {
    "shift-sum": lazy("plenodecode.render.shiftsum", "shift_sum"),
    "fourier-slice": lazy("plenodecode.render.fourier", "fourier_slice"),
}


def get_method(method: str) -> Callable[..., np.ndarray]:
    """The function of a refocus method; ValueError listing the valid names otherwise."""
    return lookup(REFOCUS_METHODS, method, param="method")


def refocus(lf: LightField, *, slope: float | None = None, alpha: float | None = None, method: str = "shift-sum",
            aperture: float | np.ndarray = 1.0, upsample: int = 1,
            progress: Callable[[int, int], None] | None = None, **kw: Any) -> np.ndarray:
    """Refocus a light field at a slope or at Ng's relative film depth alpha.

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32; the photograph is weight-normalised when ``lf.weight`` is set.
    slope : float, optional
        Spatial samples per view step (design.md); a surface of disparity ``d`` is sharp at ``slope = d``.
    alpha : float, optional
        Relative film depth (Ng 2005); converted by :func:`alpha_to_slope` with the camera constants of ``lf``
        (keywords ``focal_length_m``, ``f_number``, ``lens_pitch_m``, ``spatial_step_px``, ``view_step_px``
        override them).  Exactly one of ``slope`` and ``alpha``.
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
    if (slope is None) == (alpha is None):
        raise ValueError("pass exactly one of slope and alpha")
    const, opts = split_constants(kw)
    if alpha is not None:
        slope = alpha_to_slope(float(alpha), lf, **const)
    elif const:
        raise ValueError(f"camera constants {sorted(const)} only apply with alpha")
    fn = get_method(method)
    if method == "shift-sum" and upsample != 1:
        if opts:
            raise ValueError(f"options {sorted(opts)} do not apply to shift-sum with upsample > 1 (the views are "
                             "fused with Keys' kernel, not interpolated)")
        from .superres import fuse_views

        fn = fuse_views
    return fn(lf, float(slope), aperture=aperture, upsample=upsample, progress=progress, **opts)[0]


__all__ = ["REFOCUS_METHODS", "get_method", "refocus"]
