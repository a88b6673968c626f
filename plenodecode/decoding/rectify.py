"""Rectification: resample a decoded light field so that every view is an undistorted pinhole camera.

A :class:`~plenodecode.raymodel.GeometricCalibration` (Dansereau, Pizarro & Williams, CVPR 2013; the ray
model of :mod:`plenodecode.raymodel`) says which ray ``phi = (s, t, u, v)`` each decoded sample
``n = [i, j, k, l, 1]`` (of ``lf.data[j, i, l, k]``, 0-based) records: ``phi = D(H n)``, ``D`` the
correction of the measured direction by the lens distortion.  The rectified light field has the same
shape and records, at sample ``n``, the ray of a *target* model without distortion::

    phi_rect(n) = H_rect n

For every output sample the measured sample that saw the same ray is ``n' = H^-1 D^-1(H_rect n)``
(:func:`plenodecode.raymodel.samples_of_rays`: the direction distorted back by
:data:`DISTORTION_ITERATIONS` fixed-point iterations, then ``H^-1``), and the output is the input
interpolated there (:func:`rectify`).

The target intrinsics (:func:`rectified_intrinsics`)
----------------------------------------------------
``s = H00 i + H02 k + H04`` and ``u = H20 i + H22 k + H24`` (and ``t, v`` alike from ``j, l`` with
``H11, H13, H31, H33``).  A view ``i`` fixed, a step in ``k`` moves the ray by ``(H02, H22)`` in
``(s, u)`` and a step in ``l`` by ``(H13, H33)`` in ``(t, v)``; a calibrated camera has slightly
different values along x and y (non-square pixels of the sub-aperture images: the hexagonal lenslet
rows, a rotated grid).  ``H_rect`` takes the mean of each pair::

    H_rect[0, 0] = H_rect[1, 1] = (H00 + H11) / 2      s per view step
    H_rect[0, 2] = H_rect[1, 3] = (H02 + H13) / 2      s per spatial step
    H_rect[2, 0] = H_rect[3, 1] = (H20 + H31) / 2      u per view step
    H_rect[2, 2] = H_rect[3, 3] = (H22 + H33) / 2      u per spatial step

so the same step moves a ray equally along x and y (square samples), and rays are uniformly spaced
because the model is linear (no distortion).  The offsets ``H_rect[0:4, 4]`` re-centre it: the centre
sample ``n_c = ((U - 1) / 2, (V - 1) / 2, (X - 1) / 2, (Y - 1) / 2)`` keeps the ideal ray the
calibration gives it, ``H_rect n_c = D(H n_c)`` (the Light Field Toolbox's calibrations put that ray at
0, the optical axis, so there both conventions agree).

In the rectified light field a point ``(x, y, z)`` (m, camera frame) appears in view ``i`` at the ``k``
with ``s + u z = x``, so its disparity is the same in every view and at every position of the picture:
``d = (H00 + H20 z) / (H02 + H22 z)`` px per view step in the HCI convention
(:mod:`plenodecode.depth.metric` inverts it).

Interpolation
-------------
Quadrilinear in ``(j, i, l, k)`` (:func:`scipy.ndimage.map_coordinates`, ``order=1``, one output view
at a time): distortion moves ``n'`` across views as well (for the F01 calibration up to 1.5 views at
the corners), so the views cannot be warped one by one.  Samples are weighted by ``lf.weight``
(normalised: ``out = L(w x) / L(w)``, ``L`` the interpolation), so missing samples (weight 0) do not
bleed into their neighbours; the output weight is ``L(w)``, and 0 for rays that fall outside the
input.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from typing import Any, Callable

import numpy as np

from ..errors import GeometryMismatchError
from ..raymodel import GeometricCalibration, check_intrinsics, samples_of_rays
from ..types import LightField

log = logging.getLogger(__name__)

#: (x-axis entry, y-axis entry) pairs of H that :func:`rectified_intrinsics` averages.
SQUARE_PAIRS = (((0, 0), (1, 1)), ((0, 2), (1, 3)), ((2, 0), (3, 1)), ((2, 2), (3, 3)))
#: Interpolated weight below which an output sample counts as missing (data 0).
MIN_WEIGHT = 1e-6
#: Fixed-point iterations that distort the target directions back: the error shrinks about 7x per iteration
#: for the F01 calibration (2: 2e-4 = 0.1 px, the toolbox's choice; 8: 5e-10, sample positions within 2e-6 px
#: of the converged ones at 0.73 of the time of iterating to 1e-12).
DISTORTION_ITERATIONS = 8


def centre_sample(lf_shape: tuple[int, int, int, int]) -> np.ndarray:
    """The centre sample ``(i, j, k, l)`` (4,) float64 of light fields of shape ``(V, U, Y, X)``."""
    v, u, y, x = lf_shape
    return np.array([(u - 1) / 2.0, (v - 1) / 2.0, (x - 1) / 2.0, (y - 1) / 2.0])


def rectified_intrinsics(calibration: GeometricCalibration,
                         lf_shape: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """The default target ``H_rect`` (5, 5) float64: square, distortion-free, re-centred (module docstring).

    Parameters
    ----------
    calibration : GeometricCalibration
        The calibrated ``H`` and distortion.
    lf_shape : (V, U, Y, X), optional
        Shape whose centre sample is kept on its ray; default ``calibration.lf_shape``.

    Raises
    ------
    ValueError
        An x entry and its y partner have opposite signs (a mirrored axis: no square target exists).
    """
    h = calibration.intrinsics
    rect = h.copy()
    for (rx, cx), (ry, cy) in SQUARE_PAIRS:
        if h[rx, cx] * h[ry, cy] < 0:
            raise ValueError(f"H[{rx}, {cx}] = {h[rx, cx]:.4g} and H[{ry}, {cy}] = {h[ry, cy]:.4g} have opposite "
                             "signs: the calibration mirrors one axis; pass target_intrinsics")
        rect[rx, cx] = rect[ry, cy] = 0.5 * (h[rx, cx] + h[ry, cy])
    n_c = centre_sample(lf_shape or calibration.lf_shape)
    ray_c = calibration.rays(n_c)
    rect[:4, 4] = 0.0
    rect[:4, 4] = ray_c - rect[:4, :4] @ n_c
    return rect


def decoded_shape(grid: Any, n_views: int | None = None) -> tuple[int, int, int, int]:
    """``(V, U, Y, X)`` of the light field :func:`plenodecode.decoding.decode` makes from ``grid``
    (a :class:`~plenodecode.types.LensletGrid`) with ``n_views`` views per axis (default ``grid.n_views()``)."""
    from .resample import output_shape

    nv = grid.n_views() if n_views is None else int(n_views)
    return (nv, nv, *output_shape(grid))


def decoded_geometry(raw: Any, grid: Any) -> Any:
    """The :class:`~plenodecode.types.LightFieldGeometry` :func:`plenodecode.decoding.decode` gives the light
    field of ``raw`` (a :class:`~plenodecode.types.RawCapture`) decoded with ``grid``, known before decoding: its
    camera constants, spatial step (the grid's row spacing, px) and one pixel per view step."""
    from ..types import LightFieldGeometry

    return LightFieldGeometry.from_camera(raw.metadata, grid.to_dict(),
                                          spatial_step_px=float(grid.decoded_sampling()["step"]), view_step_px=1.0,
                                          source=raw.path)


def check_shape(calibration: GeometricCalibration, lf_shape: tuple[int, ...], what: str = "light field") -> None:
    """Raise GeometryMismatchError (a CalibrationError) unless ``lf_shape[:4]`` is the calibration's
    ``(V, U, Y, X)``."""
    shape = tuple(int(v) for v in lf_shape[:4])
    if tuple(calibration.lf_shape) != shape:
        source = calibration.info.get("source")
        raise GeometryMismatchError(
            f"the geometric calibration{f' {source}' if source else ''} is for light fields of "
            f"{'x'.join(map(str, calibration.lf_shape))} (V x U x Y x X) but the {what} is {'x'.join(map(str, shape))}; "
            "calibrate from captures decoded with the same white image and number of views")


def source_coordinates(calibration: GeometricCalibration, target: np.ndarray, view: tuple[int, int],
                       spatial_shape: tuple[int, int]) -> np.ndarray:
    """Where the samples of one output view ``view = (j, i)`` come from in the input.

    Returns
    -------
    (4, Y, X) float64
        ``(j', i', l', k')``, the array coordinates of ``lf.data`` for :func:`scipy.ndimage.map_coordinates`.
    """
    j, i = view
    ny, nx = spatial_shape
    ll, kk = np.mgrid[0:ny, 0:nx].astype(np.float64)
    samples = np.stack([np.full_like(kk, i), np.full_like(kk, j), kk, ll], axis=-1)
    rays = samples @ target[:4, :4].T + target[:4, 4]
    src = samples_of_rays(calibration.intrinsics, calibration.distortion, rays,
                          iterations=DISTORTION_ITERATIONS)      # (Y, X, 4) (i', j', k', l')
    return np.stack([src[..., 1], src[..., 0], src[..., 3], src[..., 2]])


def rectify(lf: LightField, calibration: GeometricCalibration, target_intrinsics: Any = None, *,
            progress: Callable[[int, int], None] | None = None) -> LightField:
    """Resample ``lf`` so that every view is an undistorted pinhole with square, uniform rays.

    Implements ``out(n) = lf(H^-1 D^-1(H_rect n))`` (module docstring), quadrilinear and weighted.

    Parameters
    ----------
    lf : LightField
        Decoded, not rectified: ``data`` (V, U, Y, X, C) float32, shape ``calibration.lf_shape``.
    calibration : GeometricCalibration
        ``H`` and distortion of the camera that recorded ``lf`` (same white image and views).
    target_intrinsics : (5, 5) array_like, optional
        ``H_rect``; default :func:`rectified_intrinsics`.
    progress : callable(done, total), optional
        Called after each output view.

    Returns
    -------
    LightField
        Same shape, ``data`` float32 and ``weight`` (V, U, Y, X) float32 in [0, 1] (0 where the ray was
        not recorded); ``geometry.ray_model`` = ``{'intrinsics': H_rect, 'distortion': 0, 'rectified':
        True, ...}``.

    Raises
    ------
    GeometryMismatchError
        ``lf`` does not have the calibration's shape.
    ValueError
        ``lf`` is already rectified, or ``target_intrinsics`` is not of the model's form.
    """
    from scipy.ndimage import map_coordinates

    if lf.geometry.ray_model is not None and lf.geometry.ray_model.get("rectified"):
        raise ValueError("the light field is already rectified; rectify the decoded (unrectified) light field")
    check_shape(calibration, lf.shape)
    target = rectified_intrinsics(calibration) if target_intrinsics is None else check_intrinsics(target_intrinsics)
    nv, nu, ny, nx, nc = lf.shape
    finite = np.isfinite(lf.data).all(axis=-1)
    w_in = finite.astype(np.float32) if lf.weight is None else np.where(finite, lf.weight, 0.0).astype(np.float32)
    weighted = [np.where(w_in > 0, lf.data[..., c] * w_in, 0.0).astype(np.float32) for c in range(nc)]
    data = np.zeros(lf.shape, np.float32)
    weight = np.zeros((nv, nu, ny, nx), np.float32)
    upper = np.array([nv - 1, nu - 1, ny - 1, nx - 1], np.float64).reshape(4, 1, 1)
    tol = 1e-9
    for index, (j, i) in enumerate(np.ndindex(nv, nu)):
        coords = source_coordinates(calibration, target, (j, i), (ny, nx))
        inside = np.all((coords >= -tol) & (coords <= upper + tol), axis=0)
        coords = np.clip(coords, 0.0, upper)
        w = map_coordinates(w_in, coords, order=1, mode="nearest", prefilter=False)
        w = np.where(inside, w, 0.0)
        ok = w > MIN_WEIGHT
        for c in range(nc):
            num = map_coordinates(weighted[c], coords, order=1, mode="nearest", prefilter=False)
            data[j, i, ..., c] = np.where(ok, num / np.where(ok, w, 1.0), 0.0)
        weight[j, i] = np.where(ok, w, 0.0)
        if progress is not None:
            progress(index + 1, nv * nu)
    ray_model = {"intrinsics": target, "distortion": np.zeros(5), "rectified": True,
                 "calibration": calibration.info.get("source")}
    log.info("rectified %dx%d views of %dx%d: %.1f %% of the samples recorded", nv, nu, ny, nx,
             100.0 * float(np.mean(weight > 0)))
    provenance = {**lf.provenance, "rectified": {"calibration": calibration.info.get("source"),
                                                "target_intrinsics": target.tolist()}}
    return lf.replace(data=data, weight=weight, metadata=provenance,
                      geometry=replace(lf.geometry, ray_model=ray_model))


__all__ = ["rectify", "rectified_intrinsics", "check_shape", "decoded_shape", "centre_sample", "source_coordinates"]
