"""Ng's relative film depth alpha <-> refocus slope, from the camera constants.

Slope (design.md): ``E_s(y, x) = mean_{v,u} L[v, u](y - s (v - vc), x - s (u - uc))`` with ``s`` in spatial
samples per view step; a surface of disparity ``d`` is sharpest at ``s = d``.

From Ng's alpha to a slope
--------------------------
Ng's photographic imaging equation (Fourier Slice Photography, SIGGRAPH 2005) images a virtual film at
``alpha * F`` as ``E(x') ~ integral L_F(u (1 - 1/alpha) + x'/alpha, u) du``, with ``x`` (m) on the microlens
plane and ``u`` (m) on the main-lens aperture.  Dropping the magnification ``1/alpha``, the ray through ``u`` is
read ``u (1 - 1/alpha)`` metres away from the output position.

1. Aperture: ``D = focal_length_m / f_number``.  With f-number matched lenslets the aperture's image fills one lens
   pitch (``pitch_px`` pixels), so one pixel behind a lenslet sees ``D / pitch_px`` metres of aperture and one view
   step sees ``du = -D * view_step_px / pitch_px`` (the lenslet inverts the aperture, hence the minus).
2. Space: ``pitch_px`` pixels under the lenses span ``lens_pitch_m``, so a spatial sample (``spatial_step_px``
   pixels of the lattice) is ``dx = lens_pitch_m * spatial_step_px / pitch_px`` metres.
3. View ``a = v - vc`` is read at ``x + a du (1 - 1/alpha) / dx`` samples, i.e. ``x - s a`` with
   ``s = K (1 - 1/alpha)``, ``K = |du| / dx = (focal_length_m / f_number) * view_step_px /
   (lens_pitch_m * spatial_step_px)``; ``pitch_px`` cancels.
4. Check of the sign: a point closer than the focused plane images behind the microlenses, so it is refocused at
   ``alpha > 1`` and appears in view ``a`` displaced by ``-d a`` with ``d > 0``: the disparity of design.md.
5. Inverse: ``alpha = 1 / (1 - s / K)``, defined for ``s < K`` (``s -> K`` is a film plane at infinity).

Constants and where they are read: the fields of the same names of ``lf.geometry``
(:class:`plenodecode.types.LightFieldGeometry`; from the camera metadata, ``lens_pitch_m`` falling back to the
calibration's pitch times the pixel pitch, ``spatial_step_px`` to the calibration's row spacing, the decoded
sampling step).  Every constant can be passed as a keyword, which wins over the metadata.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import MetadataError
from ..types import LightField, LightFieldGeometry

#: Constants of :func:`slope_per_alpha_unit` (keyword overrides of :func:`alpha_to_slope`).
REFOCUS_CONSTANTS = ("focal_length_m", "f_number", "lens_pitch_m", "spatial_step_px", "view_step_px")


def refocus_constants(lf: LightField | None = None, **overrides: float) -> dict[str, float]:
    """The camera constants of the alpha <-> slope conversion (see the module docstring).

    Parameters
    ----------
    lf : LightField, optional
        Source of the constants (``lf.geometry``).
    **overrides : float
        Any of :data:`REFOCUS_CONSTANTS`; wins over the metadata.

    Returns
    -------
    dict
        Every name of :data:`REFOCUS_CONSTANTS` -> float.

    Raises
    ------
    MetadataError
        A constant is neither in the metadata nor among the keywords.
    ValueError
        An unknown keyword, or a constant that is not a positive number.
    """
    unknown = set(overrides) - set(REFOCUS_CONSTANTS)
    if unknown:
        raise ValueError(f"unknown refocus constant(s) {sorted(unknown)}; valid: {', '.join(REFOCUS_CONSTANTS)}")
    geometry = lf.geometry if lf is not None else LightFieldGeometry()
    found: dict[str, Any] = {name: getattr(geometry, name) for name in REFOCUS_CONSTANTS}
    found.update({k: v for k, v in overrides.items() if v is not None})
    out = {}
    for name in REFOCUS_CONSTANTS:
        value = found[name]
        if value is None:
            raise MetadataError(
                f"alpha needs the camera constant '{name}', which the light field's metadata does not have; "
                f"pass {name}=... or use a slope instead of alpha")
        value = float(value)
        if not (value > 0 and math.isfinite(value)):
            raise ValueError(f"{name} must be a positive number, got {value}")
        out[name] = value
    return out


def slope_per_alpha_unit(lf: LightField | None = None, **constants: float) -> float:
    """``K`` of ``s = K (1 - 1/alpha)``: ``(focal_length_m / f_number) * view_step_px / (lens_pitch_m *
    spatial_step_px)``.

    Parameters and errors as :func:`refocus_constants`.
    """
    c = refocus_constants(lf, **constants)
    aperture_m = c["focal_length_m"] / c["f_number"]
    return aperture_m * c["view_step_px"] / (c["lens_pitch_m"] * c["spatial_step_px"])


def alpha_to_slope(alpha: float | np.ndarray, lf: LightField | None = None, **constants: float) -> float | np.ndarray:
    """Ng's relative film depth ``alpha`` -> refocus slope ``s = K (1 - 1/alpha)`` (px per view step).

    Parameters
    ----------
    alpha : float or array_like
        Relative film depth, > 0; 1 is the focus as captured.
    lf : LightField, optional
        Source of the camera constants (see the module docstring).
    **constants : float
        Overrides of :data:`REFOCUS_CONSTANTS`.

    Returns
    -------
    float or ndarray (float64)
    """
    a = np.asarray(alpha, np.float64)
    if not np.all(a > 0):
        raise ValueError(f"alpha must be > 0, got {alpha}")
    s = slope_per_alpha_unit(lf, **constants) * (1.0 - 1.0 / a)
    return float(s) if s.ndim == 0 else s


def slope_to_alpha(slope: float | np.ndarray, lf: LightField | None = None, **constants: float) -> float | np.ndarray:
    """Inverse of :func:`alpha_to_slope`: ``alpha = 1 / (1 - s / K)``, for slopes ``s < K``."""
    k = slope_per_alpha_unit(lf, **constants)
    s = np.asarray(slope, np.float64)
    if not np.all(s < k):
        raise ValueError(f"slope must be < {k:.4g} (a film plane at infinity) for this camera, got {slope}")
    a = 1.0 / (1.0 - s / k)
    return float(a) if a.ndim == 0 else a


def split_constants(kw: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Split keywords into refocus constants (:data:`REFOCUS_CONSTANTS`) and the rest."""
    const = {k: v for k, v in kw.items() if k in REFOCUS_CONSTANTS}
    return const, {k: v for k, v in kw.items() if k not in REFOCUS_CONSTANTS}
