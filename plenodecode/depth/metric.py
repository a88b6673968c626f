"""Metric depth from disparity.

Both camera models give inverse depth linear in disparity::

    1 / Z = 1 / Z_f + d / G

``Z`` the distance along the optical axis (m), ``Z_f`` the distance of the plane in focus (disparity 0),
``d`` the disparity in spatial samples per view step (HCI sign: positive = closer than the focus plane) and
``G`` a camera constant (px m).

HCI benchmark scenes (a 'shifted-sensor' camera array, ``parameters.cfg``)
-------------------------------------------------------------------------
Neighbouring cameras are ``B = baseline_mm / 1000`` apart; the focal length in pixels is
``f_px = focal_length_mm / sensor_size_mm * max(image_resolution_x_px, image_resolution_y_px)``.  A point at
depth ``Z`` moves ``B f_px / Z`` px between neighbouring views; the sensors are shifted so that the focus
plane has disparity 0, so ``d = B f_px / Z - B f_px / Z_f`` and ``G = B f_px``.  The benchmark's
``[extrinsics] offset`` is exactly ``B f_px / Z_f`` (20.898 px for every scene with f = 100 mm,
35 mm sensor, 512 px, B = 0.1 m, Z_f = 7 m), which the tests check.

Unfocused plenoptic camera (Ng et al. 2005; thin lens)
------------------------------------------------------
Main lens of focal length ``F`` and f-number ``N`` (aperture ``D = F / N``), the micro-lens array (MLA) at
the image distance ``b`` of the focus plane (``1/F = 1/Z_f + 1/b``), lenslets f-number matched to the main
lens.  One view step then samples the aperture ``Du = D * view_step_px / lens_pitch_px`` apart and one
spatial sample is ``Dx = lens_pitch_m * spatial_step_px / lens_pitch_px`` on the MLA.  A point imaged at
``b'`` (``1/F = 1/Z + 1/b'``) is seen from aperture positions ``a`` and ``a + Du`` at MLA positions
``Du (1 - b / b')`` apart; the lenslets invert the aperture, so

    d = K (1 - b / b'),   K = Du / Dx = D view_step_px / (lens_pitch_m spatial_step_px)

(the ``K`` of :func:`plenodecode.render.alpha.slope_per_alpha_unit`, ``alpha = b' / b``).  Eliminating
``b'`` gives ``1/Z = 1/Z_f + d / (K b)``, so ``G = K b``.

Calibrated, rectified light field (Dansereau et al. 2013; :mod:`plenodecode.decoding.rectify`)
-------------------------------------------------------------------------------------------
A light field rectified with a geometric calibration carries its ray model ``H_rect`` in
``lf.geometry.ray_model``: sample ``n = [i, j, k, l, 1]`` records the ray ``(s, t, u, v) = H_rect n``, the
line ``(s + u z, t + v z, z)`` of the calibration's camera frame (z along the optical axis, m).  Along x,
``s = a i + b k + s0`` and ``u = c i + e k + u0`` (``a, b, c, e = H_rect[0, 0], [0, 2], [2, 0], [2, 2]``;
y alike, and equal: the views are square).  A point ``(x, y, z)`` appears in view ``i`` at the ``k`` with
``s + u z = x``::

    k = (x - s0 - u0 z - (a + c z) i) / (b + e z),   dk/di = -(a + c z) / (b + e z)

The HCI convention has the point at ``k_c - d (i - i_c)`` in view ``i``, so

    d = (a + c z) / (b + e z)        z = (a - b d) / (e d - c)

the same at every pixel (one pinhole per view).  All rays of one view cross at ``z_0 = -b / e`` (where
``b + e z = 0``): the views' common pinhole plane (the main lens).  Counted from there, ``z' = z - z_0``,
``d = c / e + (a e - b c) / (e^2 z')``, i.e. the form above, exact::

    1 / z' = 1 / Z_f + d / G,   G = (a e - b c) / e^2,   Z_f = -(a e - b c) / (c e)

(``Z_f + z_0 = -a / c`` is where ``d = 0``).  :func:`depth_constants` returns this ``(G, Z_f)`` (model
'calibrated'; distances from the pinhole plane, as the focus distances of :mod:`plenodecode.render.alpha`),
:func:`disparity_to_depth` adds ``z_0`` back: its depth is the calibration's ``z`` (the frame of the board
poses).  :func:`depth_to_points` intersects the centre view's rays ``H_rect n`` with ``z``.

Every constant is read from ``lf.geometry`` (:class:`plenodecode.types.LightFieldGeometry`; an HCI scene's
``parameters.cfg`` is ``lf.geometry.hci``) unless a keyword overrides it.

``Z_f`` comes from ``focus_distance_m`` (keyword or ``lf.geometry``).  Lytro metadata has no focus
distance but ``devices.lens.infinityLambda``: lambda counts refocus steps of one MLA-sensor gap ``g`` from
the MLA towards the lens, so the film plane of infinity focus is ``lambda_inf g`` in front of the MLA:
``b = F + lambda_inf g``.  **This unit of lambda is an assumption** (the Lytro format is undocumented; it
gives plausible focus distances: 0.24 m for the F01 sample, 1.5 m for the Illum sample); a warning is
logged when it is used, and an explicit ``focus_distance_m`` always wins.

Light-field microscope (Levoy et al. 2006; Broxton et al. 2013)
---------------------------------------------------------------
The MLA sits in the image plane of the objective + tube lens (magnification ``M``), the sensor in the focal
plane of the micro-lenses (distance ``f_mu``).  Depth is linear in disparity, measured from the native object
plane (the plane imaged onto the MLA, ``z = 0``), positive *away from the objective* (the sense of a camera's
depth; disparity > 0 = closer to the objective, as for a camera)::

    z = -d * dx / tan(dtheta)

* ``dx = lens_pitch_m * spatial_step_px / lens_pitch_px / M``: the spatial sample spacing in the specimen
  (one lenslet = ``pitch / M``, 6.25 um for 125 um behind 20x; the pitch in px is the calibration's).
* ``dtheta``: the angle in the specimen between the rays of neighbouring views.  A pixel ``o`` off the centre
  of its micro-image receives the image-space ray of angle ``phi = o / f_mu`` (paraxial: ``phi`` < 2 deg); the
  objective obeys the sine condition, ``n sin(theta) = M sin(phi)``, so one view step (``view_step_px``
  pixels of ``pixel_pitch_m``) adds ``NA_step = M * view_step_px * pixel_pitch_m / f_mu`` to
  ``n sin(theta)``.  Without ``f_mu`` the micro-images are assumed to fill the lens pitch (f-number matched
  MLA: the aperture radius ``NA`` maps to half a pitch), ``NA_step = 2 NA view_step_px pixel_pitch_m /
  lens_pitch_m``.  Then ``sin(dtheta) = NA_step / n`` (``n`` the medium index).
* A point at ``z`` seen along a ray of angle ``theta`` crosses the native object plane ``z tan(theta)`` away
  from its foot, i.e. ``z tan(theta) / dx`` spatial samples; between neighbouring views about the axis that is
  ``z tan(dtheta) / dx``, the disparity up to its sign.

Assumptions: telecentric objective obeying the sine condition, thin micro-lenses, small image-side angles;
the relation is exact for the views about the axis.  Off-axis views see ``tan(theta)`` grow faster than
``sin(theta)``, so a disparity fitted over the whole aperture is larger by ``1 / cos^3`` at its rim: for a
0.5 NA water objective (``NA / n = 0.38``) the least-squares slope over a disk of views is 5 % above the
axial one (the depth is overestimated by 5 %), for 1.2 NA in water 50 %.  The tube lens focal length and the
wavelength do not enter.  ``lens_pitch_m``, ``pixel_pitch_m`` come from the optics, else from ``lf.geometry``
(the pixel pitch also as lens pitch / calibrated pitch in px).  :func:`disparity_to_depth` returns metres;
:func:`depth_unit` says the command line writes micrometres for a microscope.
"""

from __future__ import annotations

import logging
import math
from typing import Any, Mapping

import numpy as np

from ..errors import MetadataError
from ..optics import OPTICS_OPTIONS, OPTICS_SUPPLY, MicroscopeOptics
from ..types import HCIParameters, LightField

log = logging.getLogger(__name__)

#: Keyword overrides of :func:`depth_constants` for HCI scenes.
HCI_KEYS = ("baseline_mm", "focal_length_mm", "sensor_size_mm", "image_resolution_px", "focus_distance_m")
#: Keyword overrides for plenoptic cameras.
PLENOPTIC_KEYS = ("focal_length_m", "f_number", "lens_pitch_m", "spatial_step_px", "view_step_px",
                  "focus_distance_m", "infinity_lambda", "mla_sensor_gap_m")
#: Keyword overrides for light-field microscopes: the fields of MicroscopeOptics and the sampling steps.
MICROSCOPE_KEYS = (*OPTICS_OPTIONS, "spatial_step_px", "view_step_px")
#: How a missing constant of a camera light field is supplied (errors name the MicroscopeOptics fields; the command
#: line rewrites them in its options).
_CAMERA_HINT = ("it comes with the camera's metadata (decode the raw itself, with its metadata); for a "
                "light-field microscope give its optics instead: magnification, numerical_aperture, medium_index, "
                f"lens_pitch_m, pixel_pitch_m ({OPTICS_SUPPLY})")


def _positive(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a positive number, got {value!r}") from exc
    if not (v > 0 and math.isfinite(v)):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return v


def hci_constants(params: HCIParameters | Mapping[str, Mapping[str, Any]], **overrides: float
                  ) -> tuple[float, float]:
    """``(G, Z_f)`` of an HCI scene from its camera parameters (see the module docstring).

    Parameters
    ----------
    params : HCIParameters or dict
        ``lf.geometry.hci``, or a parsed ``parameters.cfg`` ``{section: {key: value}}``.
    **overrides : float
        Any of :data:`HCI_KEYS`.

    Raises
    ------
    MetadataError
        A needed value is neither in ``params`` nor among the overrides.
    """
    if not isinstance(params, HCIParameters):
        params = HCIParameters.from_cfg(params) or HCIParameters()
    res = overrides.get("image_resolution_px", params.image_resolution_px)
    found = {name: overrides.get(name, getattr(params, name))
             for name in ("baseline_mm", "focal_length_mm", "sensor_size_mm", "focus_distance_m")}
    found["image_resolution_px"] = res
    for name, value in found.items():
        if value is None:
            how = "pass --focus-distance METRES" if name == "focus_distance_m" else "add it to the scene's parameters.cfg"
            raise MetadataError(f"metric depth of an HCI scene needs '{name}', which parameters.cfg does not have; "
                                f"{how}")
    v = {k: _positive(k, x) for k, x in found.items()}
    f_px = v["focal_length_mm"] / v["sensor_size_mm"] * v["image_resolution_px"]
    return v["baseline_mm"] / 1000.0 * f_px, v["focus_distance_m"]


def _camera_constants(lf: LightField, overrides: Mapping[str, Any]) -> dict[str, float]:
    """Focal length, f-number, lens pitch (m), spatial and view step (px) from the overrides or ``lf.geometry``
    (the constants of :func:`plenodecode.render.alpha.slope_per_alpha_unit`)."""
    found = {name: getattr(lf.geometry, name)
             for name in ("focal_length_m", "f_number", "lens_pitch_m", "spatial_step_px", "view_step_px")}
    found.update({k: v for k, v in overrides.items() if k in found and v is not None})
    out = {}
    for name, value in found.items():
        if value is None:
            raise MetadataError(f"metric depth needs the camera constant '{name}', which the light field's metadata "
                                f"does not have; {_CAMERA_HINT}")
        out[name] = _positive(name, value)
    return out


def plenoptic_constants(lf: LightField, **overrides: float) -> tuple[float, float]:
    """``(G, Z_f)`` of a decoded plenoptic light field (see the module docstring).

    Raises
    ------
    MetadataError
        Naming the missing constant (focal length, f-number, lens pitch, spatial/view step, focus distance
        or infinityLambda + MLA gap).
    """
    c = _camera_constants(lf, overrides)
    k = (c["focal_length_m"] / c["f_number"]) * c["view_step_px"] / (c["lens_pitch_m"] * c["spatial_step_px"])
    geometry = lf.geometry
    f = c["focal_length_m"]
    zf = overrides.get("focus_distance_m", geometry.focus_distance_m)
    if zf is not None:
        zf = _positive("focus_distance_m", zf)
        if zf <= f:
            raise ValueError(f"focus_distance_m ({zf} m) must exceed the focal length ({f} m)")
        b = f * zf / (zf - f)
        return k * b, zf
    lam = overrides.get("infinity_lambda")
    if lam is None:
        lam = geometry.infinity_lambda
    gap = overrides.get("mla_sensor_gap_m")
    if gap is None:
        gap = geometry.mla_sensor_gap_m
    if lam is None or gap is None:
        what = "no infinityLambda" if lam is None else "no MLA-sensor gap"
        raise MetadataError(f"metric depth needs the focus distance: the light field's metadata has no "
                            f"focus_distance_m and {what} to derive it; pass --focus-distance METRES")
    lam = float(lam)
    gap = _positive("mla_sensor_gap_m", gap)
    b = f + lam * gap
    if not b > f:
        raise MetadataError(f"infinityLambda {lam} gives a film distance {b} m not beyond the focal length {f} m; "
                            f"pass --focus-distance METRES")
    zf = f * b / (b - f)
    log.warning("focus distance %.3f m derived from infinityLambda=%g and the MLA gap (assumed lambda unit = one "
                "MLA-sensor gap); pass --focus-distance to override", zf, lam)
    return k * b, zf


def _microscope_value(name: str, optics: MicroscopeOptics, lf: LightField, overrides: Mapping[str, Any]) -> float:
    """A microscope constant from the overrides, the optics, else the light field's geometry (pitches)."""
    value = overrides.get(name, getattr(optics, name))
    if value is None and name in ("lens_pitch_m", "pixel_pitch_m"):
        value = getattr(lf.geometry, name)
    if value is None:
        raise MetadataError(f"metric depth of a light-field microscope needs {name}, which its optics do not "
                            f"give; pass {name} ({OPTICS_SUPPLY})")
    return getattr(MicroscopeOptics(**{name: value}), name)      # checked: a ValueError names the field


def microscope_constants(lf: LightField, **overrides: float) -> tuple[float, float]:
    """``(K, dx)`` of a light-field microscope: axial offset per unit disparity ``K = dx / tan(dtheta)`` (m per
    px/view) and the spatial sample spacing in the specimen ``dx`` (m); ``z = -K d`` (module docstring).

    Parameters
    ----------
    lf : LightField
        ``lf.geometry.microscope`` (:class:`~plenodecode.optics.MicroscopeOptics`) and the sampling steps.
    **overrides : float
        Any of :data:`MICROSCOPE_KEYS` (fields of MicroscopeOptics in metres, ``spatial_step_px``,
        ``view_step_px``).

    Raises
    ------
    MetadataError
        A constant is missing; the message names its :class:`MicroscopeOptics` field (``magnification``, ...).
    """
    geometry = lf.geometry
    optics = geometry.microscope or MicroscopeOptics()
    mag = _microscope_value("magnification", optics, lf, overrides)
    n = _microscope_value("medium_index", optics, lf, overrides)
    pitch = _microscope_value("lens_pitch_m", optics, lf, overrides)
    steps = {}
    for name in ("spatial_step_px", "view_step_px"):
        value = overrides.get(name, getattr(geometry, name))
        if value is None:
            raise MetadataError(f"metric depth needs the light field's sampling ('{name}'), which its metadata "
                                "does not have; decode the raw with plenodecode")
        steps[name] = _positive(name, value)
    pitch_px = (geometry.calibration or {}).get("pitch")
    pixel = overrides.get("pixel_pitch_m", optics.pixel_pitch_m) or geometry.pixel_pitch_m
    if pixel is None and pitch_px:
        pixel = pitch / float(pitch_px)
    if pixel is None:
        pixel = _microscope_value("pixel_pitch_m", optics, lf, overrides)     # raises naming pixel_pitch_m
    pixel = _positive("pixel_pitch_m", pixel)
    if pitch_px is None:
        pitch_px = pitch / pixel
    dx = pitch * steps["spatial_step_px"] / float(pitch_px) / mag
    f_mu = overrides.get("microlens_focal_length_m", optics.microlens_focal_length_m)
    if f_mu is not None:
        na_step = mag * steps["view_step_px"] * pixel / _positive("microlens_focal_length_m", f_mu)
    else:
        na = _microscope_value("numerical_aperture", optics, lf, overrides)
        na_step = 2.0 * na * steps["view_step_px"] * pixel / pitch
    if not na_step < n:
        raise ValueError(f"one view step spans n sin(theta) = {na_step:.3g}, not below medium_index {n:g}: "
                         "check magnification, pixel_pitch_m and microlens_focal_length_m")
    dtheta = math.asin(na_step / n)
    return dx / math.tan(dtheta), dx


def calibrated_constants(lf: LightField) -> tuple[float, float, float]:
    """``(G, Z_f, z_0)`` of a rectified light field from ``lf.geometry.ray_model`` (module docstring):
    ``1 / (z - z_0) = 1 / Z_f + d / G``, ``z`` in the calibration's camera frame (m).

    Raises
    ------
    MetadataError
        The light field carries no rectified ray model, or one whose views look nowhere (``a e = b c``).
    """
    model = lf.geometry.ray_model or {}
    if not model.get("rectified"):
        raise MetadataError("calibrated metric depth needs a rectified light field; decode with --geometry CAL.json")
    h = np.asarray(model["intrinsics"], np.float64)
    a, b, c, e = h[0, 0], h[0, 2], h[2, 0], h[2, 2]
    det = a * e - b * c
    if det == 0.0 or c == 0.0 or e == 0.0:
        raise MetadataError(f"the light field's ray model gives no depth from disparity (H_rect entries a={a:g}, "
                            f"b={b:g}, c={c:g}, e={e:g}); rectify with a valid geometric calibration")
    return det / (e * e), -det / (c * e), -b / e


def depth_model(lf: LightField, overrides: Mapping[str, Any] | None = None) -> str:
    """The conversion that applies to ``lf``: 'hci' (``lf.geometry.hci``), 'calibrated' (a rectified light field:
    ``lf.geometry.ray_model``), 'microscope' (``lf.geometry.microscope`` or a microscope override) or
    'plenoptic'."""
    overrides = overrides or {}
    if lf.geometry.hci is not None:
        return "hci"
    if (lf.geometry.ray_model or {}).get("rectified"):
        return "calibrated"
    if lf.geometry.microscope is not None or any(k in OPTICS_OPTIONS and k not in PLENOPTIC_KEYS for k in overrides):
        return "microscope"
    return "plenoptic"


def depth_unit(lf: LightField, **overrides: float) -> tuple[str, float]:
    """``(unit, scale)`` in which metric depth is written: ``('um', 1e6)`` for a light-field microscope,
    ``('m', 1.0)`` otherwise (depth in metres times ``scale``)."""
    return ("um", 1e6) if depth_model(lf, overrides) == "microscope" else ("m", 1.0)


def depth_constants(lf: LightField, **overrides: float) -> tuple[float, float, str]:
    """``(G, Z_f, model)`` with model 'hci' (``lf.geometry.hci``), 'plenoptic' or 'microscope'
    (``lf.geometry.microscope``; then ``G`` is ``-K`` of :func:`microscope_constants` and ``Z_f = 0``, the
    native object plane: ``z = -K d``, linear, not ``1 / Z = 1 / Z_f + d / G``)."""
    model = depth_model(lf, overrides)
    if model == "microscope":
        bad = set(overrides) - set(MICROSCOPE_KEYS)
        if bad:
            hint = ("; --focus-distance does not apply to a microscope (depth is measured from the native object "
                    "plane)") if "focus_distance_m" in bad else ""
            raise ValueError(f"unknown override(s) {sorted(bad)} for a light-field microscope; valid: "
                             f"{', '.join(MICROSCOPE_KEYS)}{hint}")
        k, _ = microscope_constants(lf, **overrides)
        return -k, 0.0, model
    if model == "calibrated":
        if overrides:
            raise ValueError(f"unknown override(s) {sorted(overrides)}: a rectified light field's metric geometry "
                             "comes from its calibration (--geometry) alone")
        g, zf, _ = calibrated_constants(lf)
        return g, zf, model
    hci = lf.geometry.hci
    if hci is not None:
        bad = set(overrides) - set(HCI_KEYS)
        if bad:
            raise ValueError(f"unknown override(s) {sorted(bad)} for an HCI scene; valid: {', '.join(HCI_KEYS)}")
        g, zf = hci_constants(hci, **overrides)
        return g, zf, "hci"
    bad = set(overrides) - set(PLENOPTIC_KEYS)
    if bad:
        raise ValueError(f"unknown override(s) {sorted(bad)}; valid: {', '.join(PLENOPTIC_KEYS)}")
    g, zf = plenoptic_constants(lf, **overrides)
    return g, zf, "plenoptic"


def disparity_to_depth(depth_map: Any, lf: LightField, **overrides: float) -> np.ndarray:
    """Metric depth (m) along the optical axis from disparity: ``Z = 1 / (1 / Z_f + d / G)``; for a light-field
    microscope the axial position from the native object plane, ``z = -d dx / tan(dtheta)`` (module docstring).

    Parameters
    ----------
    depth_map : DepthMap or ndarray (Y, X)
        Disparity in px per view step (HCI sign convention).
    lf : LightField
        Supplies the camera geometry, ``lf.geometry``: ``hci`` (HCI scenes), ``microscope`` (light-field
        microscopes) or the camera constants of a decoded plenoptic light field (the module docstring derives
        all three).
    **overrides : float
        Constants that win over the metadata: HCI ``baseline_mm, focal_length_mm, sensor_size_mm,
        image_resolution_px, focus_distance_m``; plenoptic ``focal_length_m, f_number, lens_pitch_m,
        spatial_step_px, view_step_px, focus_distance_m, infinity_lambda, mla_sensor_gap_m``; microscope
        :data:`MICROSCOPE_KEYS`.

    Returns
    -------
    ndarray (Y, X) float32
        Depth in metres (a rectified light field: the calibration's ``z``); ``inf`` where the disparity lies at or beyond infinity (``d <= -G / Z_f``),
        NaN where the disparity is NaN.  Microscope: signed, 0 at the native object plane, positive away
        from the objective.

    Raises
    ------
    MetadataError
        A needed camera constant is missing (the message names it).
    """
    d = np.asarray(getattr(depth_map, "disparity", depth_map), np.float64)
    if d.ndim != 2:
        raise ValueError(f"depth_map must be a DepthMap or a 2-D disparity array, got shape {d.shape}")
    g, zf, model = depth_constants(lf, **overrides)
    if model == "microscope":
        return np.where(np.isnan(d), np.nan, g * d).astype(np.float32)
    inv = 1.0 / zf + d / g
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(inv > 0, 1.0 / inv, np.inf)
    z = np.where(np.isnan(d), np.nan, z)
    if model == "calibrated":
        z = z + calibrated_constants(lf)[2]
    log.debug("disparity_to_depth (%s): G = %.6g px m, Z_f = %.4g m", model, g, zf)
    return z.astype(np.float32)


def focal_length_px(lf: LightField, **overrides: float) -> float:
    """Focal length of the centre view in spatial samples, for back-projecting pixels to 3-D points.

    HCI: ``f_px`` of the module docstring.  Plenoptic: the centre view is a pinhole at the main lens with the
    MLA at ``b`` as its film, so ``f = b / Dx`` samples (``Dx`` the spatial sample spacing on the MLA).
    Overrides as :func:`disparity_to_depth`.
    """
    g, zf, model = depth_constants(lf, **overrides)
    if model == "microscope":
        raise ValueError("a light-field microscope is telecentric in the specimen: it has no focal length in "
                         "pixels (depth_to_points projects orthographically)")
    if model == "hci":
        b_m = _positive("baseline_mm", overrides.get("baseline_mm", lf.geometry.hci.baseline_mm))
        return g / (b_m / 1000.0)
    if model == "calibrated":                     # x = (k - k_c) e (z - z_0) about the centre ray
        return 1.0 / abs(float(lf.geometry.ray_model["intrinsics"][2][2]))
    c = _camera_constants(lf, overrides)
    geometry = lf.geometry
    pitch_px = (geometry.calibration or {}).get("pitch")
    if pitch_px is None and geometry.pixel_pitch_m:
        pitch_px = c["lens_pitch_m"] / geometry.pixel_pitch_m
    if pitch_px is None:
        raise MetadataError("3-D points need the lenslet pitch in pixels (the calibration's pitch or the camera's "
                            "pixel_pitch_m); decode with a calibration")
    dx = c["lens_pitch_m"] * c["spatial_step_px"] / float(pitch_px)
    f = c["focal_length_m"]
    b = f * zf / (zf - f)
    return b / dx


def depth_to_points(depth: np.ndarray, lf: LightField, **overrides: float) -> np.ndarray:
    """3-D points (m) of a depth map, camera frame: x right, y down, z forward (optical axis).

    ``X = (x - cx) Z / f``, ``Y = (y - cy) Z / f`` with the principal point at the image centre and ``f`` from
    :func:`focal_length_px`; a light-field microscope is telecentric in the specimen, so there
    ``X = (x - cx) dx``, ``Y = (y - cy) dx`` (``dx`` of :func:`microscope_constants`) and ``Z = z``.

    Returns
    -------
    ndarray (Y, X, 3) float32 (non-finite where the depth is).
    """
    z = np.asarray(depth, np.float64)
    if z.ndim != 2:
        raise ValueError(f"depth must be 2-D, got shape {z.shape}")
    h, w = z.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    if depth_model(lf, overrides) == "microscope":          # object-side telecentric: orthographic
        _, dx = microscope_constants(lf, **overrides)
        pts = np.stack([(xx - (w - 1) / 2.0) * dx, (yy - (h - 1) / 2.0) * dx, z], axis=-1)
        return np.where(np.isfinite(z)[..., None], pts, np.nan).astype(np.float32)
    if depth_model(lf, overrides) == "calibrated":          # the centre view's rays H_rect n at depth z
        h = np.asarray(lf.geometry.ray_model["intrinsics"], np.float64)
        vc, uc = lf.centre_index
        n = np.stack([np.full_like(xx, uc), np.full_like(xx, vc), xx, yy], axis=-1)
        rays = n @ h[:4, :4].T + h[:4, 4]
        pts = np.stack([rays[..., 0] + rays[..., 2] * z, rays[..., 1] + rays[..., 3] * z, z], axis=-1)
        return np.where(np.isfinite(z)[..., None], pts, np.nan).astype(np.float32)
    f = focal_length_px(lf, **overrides)
    pts = np.stack([(xx - (w - 1) / 2.0) * z / f, (yy - (h - 1) / 2.0) * z / f, z], axis=-1)
    return pts.astype(np.float32)


def depth_to_disparity(depth: np.ndarray, lf: LightField, **overrides: float) -> np.ndarray:
    """Inverse of :func:`disparity_to_depth`: ``d = G (1 / Z - 1 / Z_f)`` (px per view step), float32;
    microscope ``d = -z / K``."""
    z = np.asarray(depth, np.float64)
    g, zf, model = depth_constants(lf, **overrides)
    if model == "microscope":
        return (z / g).astype(np.float32)
    if model == "calibrated":
        z = z - calibrated_constants(lf)[2]
    with np.errstate(divide="ignore"):
        return (g * (1.0 / z - 1.0 / zf)).astype(np.float32)


__all__ = ["disparity_to_depth", "depth_to_disparity", "focal_length_px", "depth_to_points", "depth_constants",
           "hci_constants", "plenoptic_constants", "calibrated_constants", "microscope_constants", "depth_model", "depth_unit",
           "MICROSCOPE_KEYS"]
