"""Helpers shared by the rendering modules: the refocus method registry, argument checks and synthetic apertures.

Interpolation taps and view warps are in :mod:`plenodecode.imaging` (shared with decoding and depth).
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ..registry import lazy, lookup
from ..types import LightField


#: A photograph's pixel that less than this share of the aperture's light reaches (weight sum over ``sum m``)
#: is a gap at the frame's edge, filled from its neighbours (:func:`fill_empty_pixels`): the column of a
#: microscope's lenses half off the sensor got 0.1-5 % of it, from one side of the aperture, and read up to 25x
#: too bright.
MIN_APERTURE_SHARE = 0.1


def fill_empty_pixels(photos: np.ndarray) -> np.ndarray:
    """Photographs (S, Y, X, C) float32 with their pixels that no view has data for (NaN: a weight sum below
    :data:`MIN_APERTURE_SHARE` of the aperture's) filled by :func:`~plenodecode.imaging.fill_gaps` (the frame's
    edge) or else 0, in place."""
    from ..imaging import fill_gaps

    empty = np.isnan(photos[..., 0])
    for i in np.flatnonzero(empty.any(axis=(1, 2))):
        photos[i] = fill_gaps(photos[i], ~empty[i])
    return np.nan_to_num(photos, copy=False, nan=0.0)


def aperture_mask(shape: tuple[int, int], aperture: float | np.ndarray = 1.0) -> np.ndarray:
    """Per-view weights of a synthetic aperture.

    Parameters
    ----------
    shape : (V, U)
        Angular size of the light field.
    aperture : float or ndarray (V, U)
        A float ``r`` in (0, 1] keeps the views inside a circle of radius ``r`` times the distance from the
        centre view to the corner view (normalised per axis, so 1 = all views, ``1/sqrt(2)`` = the inscribed disk);
        or a boolean / non-negative float mask over the views.

    Returns
    -------
    ndarray, shape (V, U), float32
        Weight of each view (0 = unused).
    """
    nv, nu = shape
    if isinstance(aperture, (bool, np.bool_)) or (np.ndim(aperture) == 0 and not isinstance(aperture, np.ndarray)):
        if isinstance(aperture, (bool, np.bool_)):
            raise ValueError(f"aperture must be a radius in (0, 1] or a (V, U) mask, got {aperture!r}")
        r = float(aperture)
        if not (0 < r <= 1):
            raise ValueError(f"aperture radius must be in (0, 1], got {r}")
        vc, uc = nv // 2, nu // 2
        dv = (np.arange(nv) - vc) / max(vc, nv - 1 - vc, 1)
        du = (np.arange(nu) - uc) / max(uc, nu - 1 - uc, 1)
        rho = np.hypot(dv[:, None], du[None, :]) / math.sqrt(2.0)
        return (rho <= r + 1e-9).astype(np.float32)
    m = np.asarray(aperture)
    if m.shape != (nv, nu):
        raise ValueError(f"aperture mask must have shape (V, U) = {(nv, nu)}, got {m.shape}")
    m = m.astype(np.float32)
    if not np.all(np.isfinite(m)) or np.any(m < 0) or not np.any(m > 0):
        raise ValueError("aperture mask must be finite, non-negative and select at least one view")
    return m


#: Refocusing methods: name -> ``fn(lf, slopes, *, aperture, upsample, progress, **kw) -> (S, Y', X', C)``.
#: Both modules compile numba kernels, so the entries import them on their first call.
REFOCUS_METHODS: dict[str, Callable[..., np.ndarray]] = {
    "shift-sum": lazy("plenodecode.render.shiftsum", "shift_sum"),
    "fourier-slice": lazy("plenodecode.render.fourier", "fourier_slice"),
}


def get_method(method: str) -> Callable[..., np.ndarray]:
    """The function of a refocus method; ValueError listing the valid names otherwise."""
    return lookup(REFOCUS_METHODS, method, param="method")


def check_lightfield(lf: Any) -> LightField:
    """Raise ValueError unless ``lf`` is a :class:`LightField`."""
    if not isinstance(lf, LightField):
        raise ValueError(f"lf must be a plenodecode LightField, got {type(lf).__name__}")
    return lf


def check_slopes(slopes: Any) -> np.ndarray:
    """Refocus slopes as a (S,) float64 array; ValueError unless non-empty and finite."""
    s = np.atleast_1d(np.asarray(slopes, np.float64)).ravel()
    if s.size == 0 or not np.all(np.isfinite(s)):
        raise ValueError(f"slopes must be a non-empty sequence of finite numbers, got {slopes}")
    return s


def slope_reach(lf: LightField | tuple[int, ...]) -> float:
    """The largest ``|slope|`` (px per view step) at which the outermost views still overlap the centre one:
    ``max(Y, X) / max(vc, uc)`` (inf for a single view); ``lf`` may be the shape ``(V, U, Y, X[, C])``."""
    shape = tuple(lf) if isinstance(lf, tuple) else lf.shape
    steps = max(shape[0] // 2, shape[1] // 2)
    return float(max(shape[2:4])) / steps if steps > 0 else math.inf


def check_slope_reach(lf: LightField | tuple[int, ...], slopes: Any, *, name: str = "slope") -> None:
    """Raise ValueError naming ``name`` when a slope moves the outermost views past the whole picture
    (``|s| * max(vc, uc) > max(Y, X)`` samples): no view then overlaps the centre one, the photograph means
    nothing, and the padded shifts would ask for memory in proportion to the slope (``--slope 2000`` on a
    15 x 15 x 87 x 125 light field was killed for lack of memory).  ``lf`` may be the light field's shape
    ``(V, U, Y, X[, C])`` alone (a raw's, before decoding it: :func:`plenodecode.decoding.rectify.decoded_shape`)."""
    s = np.atleast_1d(np.asarray(slopes, np.float64))
    shape = tuple(lf) if isinstance(lf, tuple) else lf.shape
    ny, nx = shape[2:4]
    steps = max(shape[0] // 2, shape[1] // 2)
    worst = float(np.max(np.abs(s))) if s.size else 0.0
    reach = slope_reach(shape)
    if worst > reach:
        lead = f"slope {worst:.4g} px/view" + ("" if name in ("slope", "slopes") else f" (from {name})")
        raise ValueError(f"{lead} moves the outermost views {worst * steps:.3g} px, past the whole {ny} x {nx} "
                         f"picture (|slope| <= {reach:.3g} here): no view would overlap the centre one; "
                         "refocus within the refocusable range")


def check_upsample(upsample: Any) -> int:
    """The spatial upsampling factor as an int ``k >= 1``; ValueError otherwise."""
    k = int(upsample)
    if k < 1 or k != upsample:
        raise ValueError(f"upsample must be a positive integer, got {upsample}")
    return k
