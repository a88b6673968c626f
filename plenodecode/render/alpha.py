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

The refocusable range
---------------------
Refocusing aligns the views, it cannot undo the blur inside one view.  A decoded plenoptic sample integrates
two footprints: one lenslet in space (``pitch_px`` sensor pixels, ``w_x = pitch_px / spatial_step_px`` spatial
samples) and one sensor pixel of the aperture (``w_u = 1 / view_step_px`` view steps).  A plane of disparity
``d`` (samples per view step) is smeared over ``|d| w_u`` samples inside every view, so the photograph at
``s = d`` is as sharp as the views themselves only while ``|d| w_u <= w_x``::

    |s| <= s_max = view_step_px * pitch_px / spatial_step_px

This is Ng's range of exact refocusing (Fourier Slice Photography, 2005) in the decoder's units: the slice
of slope ``s`` through the band-limited 4-D spectrum (``|k_u| <= 1 / (2 w_u)``) keeps spatial frequencies
up to ``1 / (2 |s| w_u)``, all the views hold while ``|s| <= s_max``.  Hex grids (row spacing = pitch *
sqrt(3) / 2): ``s_max = 2 / sqrt(3) = 1.155``; square grids ``1``; Illum-like constants (K = 60.8) give
alpha 0.981 - 1.019.  HCI scenes are pinhole renders: every plane is sharp in every view, so no slope is
blurred by the views themselves; their range is the scene's disparities (``parameters.cfg`` ``disp_min``,
``disp_max``: ``lf.geometry.disparity_range``), else the slopes at which the outermost view still overlaps
half of the centre view's shorter side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from ..errors import MetadataError
from ..types import CameraMetadata, LightField, LightFieldGeometry

#: Constants of :func:`slope_per_alpha_unit` (keyword overrides of :func:`alpha_to_slope`).
REFOCUS_CONSTANTS = ("focal_length_m", "f_number", "lens_pitch_m", "spatial_step_px", "view_step_px")


def _geometry(lf: LightField | LightFieldGeometry | None) -> LightFieldGeometry:
    """The geometry of a light field, or the geometry itself (e.g. of a raw not decoded yet)."""
    if lf is None:
        return LightFieldGeometry()
    return lf if isinstance(lf, LightFieldGeometry) else lf.geometry


def refocus_constants(lf: LightField | LightFieldGeometry | None = None, **overrides: float) -> dict[str, float]:
    """The camera constants of the alpha <-> slope conversion (see the module docstring).

    Parameters
    ----------
    lf : LightField or LightFieldGeometry, optional
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
    geometry = _geometry(lf)
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


def decoded_geometry_stand_in(camera: CameraMetadata) -> LightFieldGeometry:
    """The geometry of the light field a raw with metadata ``camera`` decodes to, before calibration and
    decoding, to ask which constants exist (not their values): the decoder always sets ``spatial_step_px``
    (the grid's row spacing) and ``view_step_px`` (1), and ``lens_pitch_m`` falls back to the calibrated pitch
    times ``pixel_pitch_m`` (:meth:`~plenodecode.types.LightFieldGeometry.from_camera`); those three are
    placeholders (1.0) here."""
    return LightFieldGeometry.from_camera(camera, {"pitch": 1.0}, spatial_step_px=1.0, view_step_px=1.0)


def missing_refocus_constants(lf: LightField | LightFieldGeometry | CameraMetadata) -> tuple[str, ...]:
    """The names of :data:`REFOCUS_CONSTANTS` that :func:`refocus_constants` would not find (empty: alpha works).

    A :class:`~plenodecode.types.CameraMetadata` (a raw, before calibration and decoding) stands for the light
    field it decodes to (:func:`decoded_geometry_stand_in`), so only the camera's own constants are asked.
    """
    geometry = decoded_geometry_stand_in(lf) if isinstance(lf, CameraMetadata) else _geometry(lf)
    return tuple(name for name in REFOCUS_CONSTANTS if getattr(geometry, name) is None)


def slope_per_alpha_unit(lf: LightField | LightFieldGeometry | None = None, **constants: float) -> float:
    """``K`` of ``s = K (1 - 1/alpha)``: ``(focal_length_m / f_number) * view_step_px / (lens_pitch_m *
    spatial_step_px)``.

    Parameters and errors as :func:`refocus_constants`.
    """
    c = refocus_constants(lf, **constants)
    aperture_m = c["focal_length_m"] / c["f_number"]
    return aperture_m * c["view_step_px"] / (c["lens_pitch_m"] * c["spatial_step_px"])


def alpha_to_slope(alpha: float | np.ndarray, lf: LightField | LightFieldGeometry | None = None, **constants: float) -> float | np.ndarray:
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
    if not np.all((a > 0) & np.isfinite(a)):
        raise ValueError(f"alpha must be a finite number > 0, got {alpha}")
    s = slope_per_alpha_unit(lf, **constants) * (1.0 - 1.0 / a)
    return float(s) if s.ndim == 0 else s


def slope_to_alpha(slope: float | np.ndarray, lf: LightField | LightFieldGeometry | None = None, **constants: float) -> float | np.ndarray:
    """Inverse of :func:`alpha_to_slope`: ``alpha = 1 / (1 - s / K)``, for slopes ``s < K``."""
    k = slope_per_alpha_unit(lf, **constants)
    s = np.asarray(slope, np.float64)
    if not np.all(s < k):
        raise ValueError(f"slope must be < {k:.4g} (a film plane at infinity) for this camera, got {slope}")
    a = 1.0 / (1.0 - s / k)
    return float(a) if a.ndim == 0 else a


def lens_footprint_samples(lf: LightField | LightFieldGeometry) -> float | None:
    """``w_x = pitch_px / spatial_step_px``: one lenslet in spatial samples (see "The refocusable range"); None
    when the spatial step is unknown.  The pitch comes from the calibration, else lens / pixel pitch, else the
    spatial step itself (a square grid)."""
    g = _geometry(lf)
    if not g.spatial_step_px:
        return None
    pitch_px = (g.calibration or {}).get("pitch")
    if pitch_px is None and g.lens_pitch_m and g.pixel_pitch_m:
        pitch_px = g.lens_pitch_m / g.pixel_pitch_m
    return float(pitch_px or g.spatial_step_px) / float(g.spatial_step_px)


def refocus_range(lf: LightField | LightFieldGeometry) -> tuple[float, float]:
    """The slopes refocusing can bring to sharp focus, ``(slope_lo, slope_hi)`` px per view step (module docstring,
    "The refocusable range").

    Decoded plenoptic light fields: ``+-view_step_px * pitch_px / spatial_step_px`` (Ng's range of exact
    refocusing).  HCI scenes (pinhole views, ``lf.geometry.hci``): the scene's ``disparity_range``, else
    ``+-min(Y, X) / (4 r)`` with ``r`` the largest view offset (the outermost view overlaps half the shorter
    side), unbounded without a shape.  Without any sampling metadata: the decoder's default, ``+-1``.

    Returns
    -------
    (float, float)
        ``slope_lo < 0 < slope_hi`` (a pinhole scene's range need not contain 0).
    """
    g = _geometry(lf)
    if g.hci is not None:
        scene = g.hci.disparity_range or g.disparity_range
        if scene is not None:
            return float(scene[0]), float(scene[1])
        shape = getattr(lf, "shape", None)
        if shape is None:
            return -math.inf, math.inf
        reach = min(shape[2], shape[3]) / (4.0 * max(shape[0] // 2, shape[1] // 2, 1))
        return -reach, reach
    footprint = lens_footprint_samples(g)
    s_max = 1.0 if footprint is None else float(g.view_step_px or 1.0) * footprint
    return -s_max, s_max


def _with_geometry(lf: LightField | LightFieldGeometry) -> Any:
    """Something with ``.geometry`` (what :mod:`plenodecode.depth.metric` reads)."""
    return SimpleNamespace(geometry=lf) if isinstance(lf, LightFieldGeometry) else lf


def _distance_constants(lf: LightField | LightFieldGeometry, **overrides: float) -> tuple[float, float]:
    """``(G, Z_f)`` of :func:`plenodecode.depth.metric.depth_constants` for a camera; a light-field microscope
    has no focus distance (its depth is an axial offset from the native object plane, ``z = -K d``)."""
    from ..depth.metric import depth_constants

    g, zf, model = depth_constants(_with_geometry(lf), **overrides)
    if model == "microscope":
        raise MetadataError("a focus distance does not apply to a light-field microscope (its depth is measured "
                            "from the native object plane); refocus by slope instead")
    return g, zf


def slope_to_distance(slope: float | np.ndarray, lf: LightField | LightFieldGeometry,
                      **overrides: float) -> float | np.ndarray:
    """Distance (m) of the plane in focus at ``slope``: ``Z = 1 / (1 / Z_f + s / G)``
    (:mod:`plenodecode.depth.metric`; ``inf`` at or beyond infinity).

    Raises
    ------
    MetadataError
        The geometry lacks a constant (the focus distance, most often; the message names it), or is a
        light-field microscope's.
    """
    g, zf = _distance_constants(lf, **overrides)
    inv = 1.0 / zf + np.asarray(slope, np.float64) / g
    with np.errstate(divide="ignore"):
        z = np.where(inv > 0, 1.0 / inv, np.inf)
    return float(z) if z.ndim == 0 else z


def distance_to_slope(distance_m: float, lf: LightField | LightFieldGeometry, **overrides: float) -> float:
    """The slope that focuses at ``distance_m`` metres: ``s = G (1 / Z - 1 / Z_f)`` (inverse of
    :func:`slope_to_distance`; :mod:`plenodecode.depth.metric` gives ``G`` and ``Z_f``).

    Raises
    ------
    ValueError
        ``distance_m`` is not a finite number > 0.
    MetadataError
        The geometry lacks a constant (the message names it), or is a light-field microscope's.
    """
    z = float(distance_m)
    if not (z > 0 and math.isfinite(z)):
        raise ValueError(f"distance_m must be a finite number > 0 (metres), got {distance_m}")
    g, zf = _distance_constants(lf, **overrides)
    return g * (1.0 / z - 1.0 / zf)


@dataclass(frozen=True)
class RefocusRange:
    """The refocusable range (:func:`refocus_range`) in every unit the geometry allows.

    Attributes
    ----------
    slope : (float, float)
        px per view step.
    alpha : (float, float) or None
        Ng's relative film depth; None without the camera constants.
    distance_m : (float, float) or None
        ``(near, far)`` metres (far may be ``inf``); None without the focus distance.
    """

    slope: tuple[float, float]
    alpha: tuple[float, float] | None = None
    distance_m: tuple[float, float] | None = None

    def contains(self, slope: float) -> bool:
        """True when ``slope`` lies in the range (within 1e-9)."""
        return self.slope[0] - 1e-9 <= slope <= self.slope[1] + 1e-9

    def describe(self) -> str:
        """One phrase, e.g. ``'alpha 0.9814-1.0194 = slope -1.15..+1.15 px/view = 0.82-1.6 m'``."""
        parts = [f"slope {self.slope[0]:+.2f}..{self.slope[1]:+.2f} px/view"]
        if self.alpha is not None:
            parts.insert(0, f"alpha {self.alpha[0]:.4f}-{self.alpha[1]:.4f}")
        if self.distance_m is not None:
            parts.append(f"{self.distance_m[0]:.3g}-{self.distance_m[1]:.3g} m")
        return " = ".join(parts)


def refocus_range_units(lf: LightField | LightFieldGeometry) -> RefocusRange:
    """:func:`refocus_range` with its alphas (:func:`slope_to_alpha`) and distances (:func:`slope_to_distance`)
    where the geometry has the constants."""
    lo, hi = refocus_range(lf)
    alpha = distance = None
    if math.isfinite(lo) and math.isfinite(hi):
        try:
            alpha = (float(slope_to_alpha(lo, lf)), float(slope_to_alpha(hi, lf)))
        except (MetadataError, ValueError):
            pass
        try:
            distance = (float(slope_to_distance(hi, lf)), float(slope_to_distance(lo, lf)))
        except (MetadataError, ValueError):
            pass
    return RefocusRange((lo, hi), alpha, distance)


def split_constants(kw: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Split keywords into refocus constants (:data:`REFOCUS_CONSTANTS`) and the rest."""
    const = {k: v for k, v in kw.items() if k in REFOCUS_CONSTANTS}
    return const, {k: v for k, v in kw.items() if k not in REFOCUS_CONSTANTS}
