"""Checkerboard captures with exact geometric ground truth (issue 22: calibration sets).

A planar checkerboard of ``rows x cols`` inner corners and square size ``S`` (m) lies in its own
frame at ``z_b = 0``, inner corner ``(r, c)`` at ``(c S, r S)`` (:func:`plenodecode.raymodel.board_points`).
Its ``(rows + 1) x (cols + 1)`` squares cover ``-S <= x_b <= cols S``, ``-S <= y_b <= rows S``;
square ``(floor(x_b / S), floor(y_b / S))`` is dark when the sum of the two is even (so the four
outer corner squares are dark), light otherwise.  A light margin of :attr:`Board.margin` squares
surrounds the checkers, and the rest of the board's plane is mid-grey (:data:`BOARD_LEVELS`).

The camera is the ray model of :mod:`plenodecode.raymodel` (Dansereau, Pizarro & Williams 2013): a
sample ``n = (i, j, k, l)`` of ``lf.data[j, i, l, k]`` records the ray ``H n`` with its direction
corrected by the distortion.  The radiance of a continuous sample is the checker value where its ray
meets the board plane (pose ``[tx, ty, tz, rx, ry, rz]``: ``X_cam = R X_b + t``)::

    z* = n_b . (t - o) / n_b . d,   o = (s, t, 0),  d = (u, v, 1),  n_b = R e_z
    (x_b, y_b) = first two entries of R^T (o + z* d - t)

(rays parallel to the plane or meeting it behind the camera see the grey).  A sample's value is
the mean over its 4-D footprint (:func:`footprint_offsets`): a 1 x 1 box in ``(i, j)`` (the
2 x 2 Gauss-Legendre rule of the raw generator's pixel box) times a 1 x 1 box in ``(k, l)``
(``supersample`` x ``supersample`` midpoints), so edges are anti-aliased like a real lenslet image.

:func:`board_lightfield` renders the ideal light field; :func:`board_corners` gives the true
corner positions ``(k, l)`` in every view (:func:`plenodecode.raymodel.project_points`);
:func:`default_intrinsics` gives a plausible ``H`` for a decoded shape.

Raws of a preset camera (:func:`render_board_mosaic`) give every sensor pixel the radiance of the decoded
sample ``(i, j, k, l)`` it becomes (:func:`pixel_samples`: the generator's sampling contract, on the lens
block the calibration fit makes, :func:`pipeline_grid`), so light fields decoded by the real pipeline
from them show the board where the truth puts it.  :func:`simulate_checkerboard_set` makes a calibration
set (poses from :func:`sample_poses`), :func:`write_checkerboard_set` writes it with its truth.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..raymodel import (Board, GeometricCalibration, check_distortion, check_intrinsics, pose_transform,
                        project_points, rotation_matrix, sample_rays)
from ..io.atomic import refuse_existing
from ..types import LensletGrid, LightField, RawCapture, cfa_channel_map
from .forward import _metadata, _resolve, simulate_white
from .kernels import SUBSAMPLES, board_radiance_kernel
from .lattice import assign_pixels
from .presets import Preset, get_preset
from .sensor import Progress, levels, render_sensor
from .truth import simulation_files, write_camera_file

#: Linear radiance of the board's dark squares, light squares (and margin) and the grey beyond.
BOARD_LEVELS = {"dark": 0.06, "light": 0.82, "background": 0.35}
#: Samples (continuous ``(i, j, k, l)``) evaluated per batch: bounds memory to a few hundred MB.
_BATCH = 1 << 20


def board_values(board: Board, xy: np.ndarray) -> np.ndarray:
    """Radiance of board-frame points: ``xy`` (..., 2) ``(x_b, y_b)`` (m) -> (...) float64, levels of
    :data:`BOARD_LEVELS` (non-finite points get the background)."""
    s = board.square_m
    x, y = xy[..., 0] / s, xy[..., 1] / s
    inside = (x >= -1.0) & (x < board.cols) & (y >= -1.0) & (y < board.rows)
    margin = board.margin
    on_board = (x >= -1.0 - margin) & (x < board.cols + margin) & (y >= -1.0 - margin) & (y < board.rows + margin)
    with np.errstate(invalid="ignore"):
        dark = (np.floor(x) + np.floor(y)) % 2 == 0
    out = np.full(x.shape, BOARD_LEVELS["background"])
    out[on_board] = BOARD_LEVELS["light"]
    out[inside & dark] = BOARD_LEVELS["dark"]
    return out


def footprint_offsets(supersample: int = 4) -> np.ndarray:
    """Sub-sample offsets (M, 4) float64 in ``(i, j, k, l)`` of a sample's footprint.

    ``(i, j)``: the 2 x 2 Gauss-Legendre points of a 1 x 1 box (:data:`~plenodecode.synthetic.kernels.SUBSAMPLES`,
    the raw generator's pixel rule); ``(k, l)``: ``n = supersample`` squared points of a 1 x 1 box on a
    sheared grid, ``k = (n a + b + 1/2) / n^2 - 1/2``, ``l = (n b + a + 1/2) / n^2 - 1/2`` for
    ``a, b = 0 .. n-1`` (one point per row and per column of the ``n^2 x n^2`` sub-grid and per cell of
    the ``n x n`` one, so a near-axis-aligned edge is located to ``1 / n^2`` of a sample, not ``1 / n``:
    detected corners move by 0.04 px instead of 0.12 px at ``n = 4``).  ``M = 4 n^2``.
    """
    n = int(supersample)
    if n < 1 or n != supersample:
        raise ValueError(f"supersample must be a positive integer, got {supersample!r}")
    a, b = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    k = ((n * a + b).ravel() + 0.5) / (n * n) - 0.5
    l_ = ((n * b + a).ravel() + 0.5) / (n * n) - 0.5
    i, j = np.meshgrid(SUBSAMPLES, SUBSAMPLES, indexing="ij")
    return np.column_stack([np.repeat(i.ravel(), k.size), np.repeat(j.ravel(), k.size),
                            np.tile(k, i.size), np.tile(l_, i.size)])


def board_radiance(intrinsics: np.ndarray, distortion: Any, board: Board, pose: Sequence[float],
                   samples: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Mean board radiance over the footprint of continuous samples (see the module docstring).

    The compiled kernel :func:`~plenodecode.synthetic.kernels.board_radiance_kernel`, which skips the
    sub-samples of footprints inside one square; tested equal to :func:`board_radiance_numpy`, the
    documented model (``make bench``: ratio in ``bench/bench_synthetic.py``).

    Parameters
    ----------
    intrinsics : (5, 5) float64
        ``H`` (0-based samples).
    distortion : (5,) or None
    board : Board
    pose : [tx, ty, tz, rx, ry, rz]
    samples : (N, 4) float
        Continuous ``(i, j, k, l)``.
    offsets : (M, 4) float
        Footprint sub-sample offsets (:func:`footprint_offsets`).

    Returns
    -------
    (N,) float64
        ``mean_m value(board point hit by the ray of samples + offsets[m])``.
    """
    pose = np.asarray(pose, dtype=np.float64)
    samples = np.ascontiguousarray(samples, dtype=np.float64).reshape(-1, 4)
    out = np.empty(samples.shape[0])
    levels = np.array([BOARD_LEVELS["dark"], BOARD_LEVELS["light"], BOARD_LEVELS["background"]])
    board_radiance_kernel(samples, np.ascontiguousarray(offsets, dtype=np.float64).reshape(-1, 4),
                          check_intrinsics(intrinsics), check_distortion(distortion), rotation_matrix(pose[3:]),
                          np.ascontiguousarray(pose[:3]), float(board.rows), float(board.cols), board.square_m,
                          float(board.margin), levels, out)
    return out


def board_radiance_numpy(intrinsics: np.ndarray, distortion: Any, board: Board, pose: Sequence[float],
                         samples: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """The plain-numpy model of :func:`board_radiance` (same arguments and result, (N,) float64): every
    sub-sample's ray (:func:`plenodecode.raymodel.sample_rays`) is met with the board plane as in the module
    docstring and :func:`board_values` gives its radiance; processed in batches of :data:`_BATCH` rays."""
    h = check_intrinsics(intrinsics)
    dist = check_distortion(distortion)
    pose = np.asarray(pose, dtype=np.float64)
    rot = rotation_matrix(pose[3:])
    trans = pose[:3]
    normal = rot[:, 2]
    samples = np.asarray(samples, dtype=np.float64).reshape(-1, 4)
    offsets = np.asarray(offsets, dtype=np.float64).reshape(-1, 4)
    out = np.empty(samples.shape[0])
    step = max(1, _BATCH // offsets.shape[0])
    for start in range(0, samples.shape[0], step):
        n = samples[start:start + step, None, :] + offsets[None]
        rays = sample_rays(h, dist, n)
        origin = np.stack([rays[..., 0], rays[..., 1], np.zeros(rays.shape[:-1])], axis=-1)
        direction = np.stack([rays[..., 2], rays[..., 3], np.ones(rays.shape[:-1])], axis=-1)
        along = direction @ normal
        with np.errstate(divide="ignore", invalid="ignore"):
            z = ((trans - origin) @ normal) / along
        z = np.where((np.abs(along) > 1e-12) & (z > 0), z, np.nan)
        hit = origin + z[..., None] * direction - trans
        xy = hit @ rot[:, :2]
        out[start:start + step] = board_values(board, xy).mean(axis=-1)
    return out


def _as_calibration(calibration: GeometricCalibration | np.ndarray, distortion: Any = None) -> GeometricCalibration:
    if isinstance(calibration, GeometricCalibration):
        return calibration
    return GeometricCalibration(intrinsics=np.asarray(calibration), distortion=check_distortion(distortion))


def _check_lf_shape(lf_shape: Sequence[int]) -> tuple[int, int, int, int]:
    try:
        shape = tuple(int(v) for v in lf_shape)
    except (TypeError, ValueError):
        raise ValueError(f"lf_shape must be (V, U, Y, X), got {lf_shape!r}") from None
    if len(shape) != 4 or min(shape) < 1:
        raise ValueError(f"lf_shape must be 4 positive sizes (V, U, Y, X), got {lf_shape!r}")
    return shape  # type: ignore[return-value]


def board_lightfield(calibration: GeometricCalibration | np.ndarray, board: Board | Sequence[float],
                     pose: Sequence[float], lf_shape: Sequence[int] | None = None, *, distortion: Any = None,
                     supersample: int = 4) -> LightField:
    """The ideal (noise-free) light field of a checkerboard at a pose.

    ``LF[j, i, l, k, 0] = mean over the footprint of sample (i, j, k, l) of the board radiance along its
    ray`` (:func:`board_radiance` with :func:`footprint_offsets`).

    Parameters
    ----------
    calibration : GeometricCalibration or (5, 5) array
        The camera: ``H`` and distortion (an array is ``H``, with ``distortion``).
    board : Board or (rows, cols, square_m)
    pose : [tx, ty, tz, rx, ry, rz]
        Board -> camera frame (m, Rodrigues rad).
    lf_shape : (V, U, Y, X), optional
        Default ``calibration.lf_shape``.
    distortion : (5,), optional
        Only with an array ``calibration``.
    supersample : int
        Spatial footprint points ``supersample**2`` (:func:`footprint_offsets`; 4: 16 x 4 = 64 rays per sample).

    Returns
    -------
    LightField
        data (V, U, Y, X, 1) float32 in [0.06, 0.82], colour 'linear-srgb', no weight; metadata
        ``checkerboard`` (board, pose, H, distortion).
    """
    cal = _as_calibration(calibration, distortion)
    board = Board.of(board)
    shape = _check_lf_shape(cal.lf_shape if lf_shape is None else lf_shape)
    n_v, n_u, n_y, n_x = shape
    jj, ii, ll, kk = np.meshgrid(*(np.arange(n, dtype=np.float64) for n in shape), indexing="ij")
    samples = np.stack([ii.ravel(), jj.ravel(), kk.ravel(), ll.ravel()], axis=-1)
    values = board_radiance(cal.intrinsics, cal.distortion, board, pose, samples, footprint_offsets(supersample))
    data = values.reshape(n_v, n_u, n_y, n_x, 1).astype(np.float32)
    meta = {"source": "plenodecode.synthetic.checkerboard",
            "checkerboard": {"board": board.to_dict(), "pose": [float(v) for v in pose],
                             "intrinsics": cal.intrinsics.tolist(), "distortion": cal.distortion.tolist()}}
    return LightField(data=data, colour="linear-srgb", metadata=meta)


def board_corners(calibration: GeometricCalibration | np.ndarray, board: Board | Sequence[float],
                  pose: Sequence[float], lf_shape: Sequence[int] | None = None, *,
                  distortion: Any = None) -> np.ndarray:
    """True positions of the inner corners in every view.

    Returns
    -------
    (V, U, rows * cols, 2) float64
        ``(k, l)`` (spatial column, row) of corner ``r * cols + c`` in view ``lf.data[j, i]``
        (:func:`plenodecode.raymodel.project_points` of the posed :meth:`Board.corners`).
    """
    cal = _as_calibration(calibration, distortion)
    board = Board.of(board)
    n_v, n_u, _, _ = _check_lf_shape(cal.lf_shape if lf_shape is None else lf_shape)
    points = pose_transform(pose, board.corners())
    out = np.empty((n_v, n_u, points.shape[0], 2))
    for j in range(n_v):
        for i in range(n_u):
            out[j, i] = project_points(cal.intrinsics, cal.distortion, points, (i, j))
    return out


def default_intrinsics(lf_shape: Sequence[int], *, field_of_view: float = 0.18, focus_distance_m: float = 0.42,
                       disparity_per_dioptre: float = 1.2) -> np.ndarray:
    """A plausible ``H`` (0-based, 5 x 5 float64) for light fields of shape ``(V, U, Y, X)``.

    A thin main lens whose aperture is the plane ``z = 0``, focused at ``z_f = focus_distance_m``: view
    ``i`` looks through the aperture point ``s = a (i - i_c)`` and spatial sample ``k`` at the point
    ``x_f = c z_f (k - k_c)`` of the plane in focus, so the ray's slope is ``u = (x_f - s) / z_f``::

        s = a (i - i_c),        u = c (k - k_c) - (a / z_f) (i - i_c)

    (``t``, ``v`` alike with ``j``, ``l``), centred so the middle sample is the ray 0 (as the toolbox's
    re-centring).  A point at depth ``z`` then has the disparity (HCI convention, px per view step)
    ``d = (a / c) (1 / z - 1 / z_f)``: positive in front of the focus.

    ``c = field_of_view / X`` (rad per spatial sample) and ``a = disparity_per_dioptre * c`` (m per view).
    The defaults give ``d`` = +1.1 px at 0.3 m and -0.9 px at 0.6 m and a field of 54 mm at 0.3 m.  For
    comparison the real F01 calibration (``CalInfo.json`` of ``lytro-f01-gridmodel``) has ``c = 1.9e-3``,
    ``a = 3.5e-4`` m (``a / c = 0.19`` px per dioptre: its focal length 6.45 mm at f/2 is the same
    ``a = f / N / (2 r)``, ``c = lens pitch / f``) and a field of 0.71 rad over 379 samples.

    Parameters
    ----------
    lf_shape : (V, U, Y, X)
    field_of_view : float
        Angle (rad) covered by the ``X`` spatial samples.
    focus_distance_m : float
        Distance (m) of zero disparity.
    disparity_per_dioptre : float
        ``a / c``: disparity change (px per view step) per 1/m of inverse depth.
    """
    n_v, n_u, n_y, n_x = _check_lf_shape(lf_shape)
    for name, value in (("field_of_view", field_of_view), ("focus_distance_m", focus_distance_m),
                        ("disparity_per_dioptre", disparity_per_dioptre)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be positive, got {value!r}")
    c = field_of_view / n_x
    a = disparity_per_dioptre * c
    h = np.zeros((5, 5))
    h[4, 4] = 1.0
    for pos, slope, view, spatial, n_view, n_spatial in ((0, 2, 0, 2, n_u, n_x), (1, 3, 1, 3, n_v, n_y)):
        view_c, spatial_c = (n_view - 1) / 2.0, (n_spatial - 1) / 2.0
        h[pos, view] = a
        h[pos, 4] = -a * view_c
        h[slope, spatial] = c
        h[slope, view] = -a / focus_distance_m
        h[slope, 4] = -c * spatial_c + a * view_c / focus_distance_m
    return check_intrinsics(h)


# ---------------------------------------------------------------------------------------
# raws of a preset camera
# ---------------------------------------------------------------------------------------
def pipeline_grid(grid: LensletGrid) -> LensletGrid:
    """The same lattice as ``grid``, cut into the block of lenses the calibration's fit makes of it.

    :func:`~plenodecode.synthetic.lattice.make_grid` and :func:`plenodecode.calib.grid.lens_block` both keep
    every lens whose centre is on the sensor, but may describe a hexagonal block differently (first lens on
    an even or an odd row, ``odd_row_shift`` +-0.5), which moves the decoded sample ``x = 0`` by half a
    pitch.  Raws rendered on this block decode, with the grid :func:`plenodecode.calib.calibrate` fits to
    their white image, to light fields whose samples are the truth's (``pixel_samples``).
    """
    from ..calib.grid import LatticeFit, lens_block

    fit = LatticeFit(lattice=grid.lattice, pitch=grid.pitch, row_spacing=grid.row_spacing, rotation=grid.rotation,
                     origin=np.asarray(grid.origin, dtype=np.float64), shift=0.5 if grid.lattice == "hex" else 0.0,
                     indices=np.zeros((0, 2), np.int64), inlier=np.zeros(0, bool), residuals=np.zeros((0, 2)),
                     rms=0.0, sigma=0.0)
    _, rows, _, cols, shift, origin = lens_block(fit, grid.sensor_shape)
    return grid.replace(origin=(float(origin[0]), float(origin[1])), shape=(rows, cols), odd_row_shift=shift)


def pixel_samples(grid: LensletGrid, rows: np.ndarray, cols: np.ndarray, n_views: int) -> np.ndarray:
    """The decoded sample ``(i, j, k, l)`` (continuous) whose ray each sensor pixel records.

    The decoder (:func:`plenodecode.decode`) puts the pixel at lattice offset ``o = (o_a, o_b)`` from the
    centre of its lens into view ``(v, u) = (v_c + o_a, u_c + o_b)`` (``v_c = u_c = (n_views - 1) / 2``) at
    the lens's decoded position ``(y, x)`` (:func:`~plenodecode.synthetic.lattice.assign_pixels`,
    :meth:`LensletGrid.decoded_sampling`): the generator's sampling contract (see
    :meth:`~plenodecode.synthetic.Simulation.ground_truth_lightfield`).  So ``i = u_c + o_b``,
    ``j = v_c + o_a``, ``k = x``, ``l = y``.

    Returns
    -------
    (..., 4) float64, the shape of ``rows``.
    """
    lens = assign_pixels(grid, rows, cols)
    centre = (n_views - 1) / 2.0
    return np.stack([lens.ob + centre, lens.oa + centre, lens.x, lens.y], axis=-1)


def render_board_mosaic(p: Preset, grid: LensletGrid, calibration: GeometricCalibration, board: Board,
                        pose: Sequence[float], rng: np.random.Generator | None, *, supersample: int = 4,
                        progress: Progress = None) -> np.ndarray:
    """The sensor mosaic of a checkerboard capture (uint16 (H, W), the preset's levels and noise).

    Each pixel records ``exposure * vignetting * D(o)`` (the white image's signal,
    :func:`~plenodecode.synthetic.sensor.render_sensor`) times the board radiance of the decoded sample its
    ray belongs to (:func:`pixel_samples`), averaged over that sample's footprint (:func:`board_radiance`:
    the pixel's 1 x 1 px box in ``o`` and the lens's 1 x 1 footprint in ``(k, l)``), in the camera RGB of
    the pixel's CFA channel: a grey ``g`` (linear sRGB) is ``g * (M 1)_c`` with ``M`` the preset's
    :meth:`~plenodecode.synthetic.Preset.camera_matrix`, so decoding to linear sRGB gives back ``g``.
    Pixels outside every lenslet disk are not evaluated (their signal is 0).
    """
    h, w = grid.sensor_shape
    rows, cols = np.meshgrid(np.arange(h, dtype=np.float64), np.arange(w, dtype=np.float64), indexing="ij")
    samples = pixel_samples(grid, rows, cols, calibration.lf_shape[0])
    centre = (calibration.lf_shape[0] - 1) / 2.0
    reach = grid.radius + 0.5 * p.edge_px + 1.0
    lit = np.hypot(samples[..., 0] - centre, samples[..., 1] - centre) < reach
    channel_gain = np.ones(3) if p.mono else p.camera_matrix().sum(axis=1)
    chmap = cfa_channel_map(p.cfa).astype(np.int64)
    gain = np.zeros((h, w))
    radiance = board_radiance(calibration.intrinsics, calibration.distortion, board, pose, samples[lit],
                              footprint_offsets(supersample))
    gain[lit] = radiance * channel_gain[chmap[rows[lit].astype(np.int64) % 2, cols[lit].astype(np.int64) % 2]]
    return render_sensor(grid, p, None, rng, progress, gain=gain)



# ---------------------------------------------------------------------------------------
# calibration sets
# ---------------------------------------------------------------------------------------
#: Decoded spatial size ``(Y, X)`` a calibration set's sensor is cut to when no ``shape`` is given: an
#: 8 x 6 board of 3.6 mm squares keeps >= 4.8 samples per square at 0.6 m and fits at 0.3 m (default H).
SET_SAMPLES = (112, 128)
#: Default distances (m) of the board in a set, and its largest tilt (rad).
SET_DISTANCES = (0.3, 0.6)
SET_MAX_TILT = math.radians(35.0)
#: Free decoded samples kept between the board's outline and the edge of every view.
SET_BORDER = 2.0


@dataclass(frozen=True)
class CheckerboardSet:
    """A simulated calibration set: checkerboard raws of one camera, its white image and the truth.

    Attributes
    ----------
    raws : tuple of RawCapture
        One capture per pose (uint16 mosaics in the preset's levels).
    white : RawCapture
        The camera's white image (same grid, zoom and focus).
    grid : LensletGrid
        The true lenslet grid.
    truth : GeometricCalibration
        ``H``, distortion, ``lf_shape`` of the decoded light fields and the pose of each capture; ``info``:
        ``board`` (rows, cols, square_m, margin), ``preset``, ``seed``, ``noise``, ``generator``.
    board : Board
    preset : Preset
    """

    raws: tuple[RawCapture, ...]
    white: RawCapture
    grid: LensletGrid
    truth: GeometricCalibration
    board: Board
    preset: Preset


def set_sensor_shape(preset: str | Preset, samples: tuple[int, int] = SET_SAMPLES) -> tuple[int, int]:
    """Sensor ``(H, W)`` px whose decoded light field has about ``samples = (Y, X)`` spatial samples, both
    spaced by the lattice's row spacing (:meth:`LensletGrid.decoded_sampling`): ``(Y, X + 1) * row_spacing``,
    rounded up to even sizes (whole Bayer tiles, packable rows)."""
    p = get_preset(preset)
    row_spacing = p.pitch_px * (math.sqrt(3.0) / 2.0 if p.lattice == "hex" else 1.0)
    return tuple(2 * int(math.ceil(n * row_spacing / 2.0)) for n in (samples[0], samples[1] + 1))  # type: ignore


def _fits(calibration: GeometricCalibration, outline: np.ndarray, border: float) -> bool:
    """Do the posed outline's 4 corners project inside every view (``border`` samples from the edges)?"""
    n_v, n_u, n_y, n_x = calibration.lf_shape
    for j in range(n_v):
        for i in range(n_u):
            kl = calibration.project(outline, (i, j))
            if not (np.all(np.isfinite(kl)) and kl[:, 0].min() >= border and kl[:, 0].max() <= n_x - 1 - border
                    and kl[:, 1].min() >= border and kl[:, 1].max() <= n_y - 1 - border):
                return False
    return True


#: ``placement`` of :func:`sample_poses`.
PLACEMENTS = ("centre", "field")
#: Where ``placement='field'`` aims the boards, ``(tx, ty)`` fractions of the half field (x, y): the farther
#: half of the poses (small boards) at the four corners in turn, the nearer half at the centre and the edges.
FIELD_TARGETS = {"far": ((-1.0, -1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, 1.0)),
                 "near": ((0.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (0.0, 1.0), (1.0, 0.0))}


def _aimed_pose(calibration: GeometricCalibration, outline: np.ndarray, border: float, rot: Any,
                board_centre: np.ndarray, centre_ray: np.ndarray, z: float, target: tuple[float, float],
                size: tuple[float, float], steps: int = 8) -> np.ndarray | None:
    """The pose (6,) of a board turned by ``rot`` whose centre, at depth ``z``, is moved from the centre ray
    towards ``target`` (fractions of the half field ``size / 2``, rad) by the largest fraction that still
    fits every view (bisection); None when it does not fit even on the centre ray."""
    def pose_at(f: float) -> np.ndarray:
        centre = np.array([centre_ray[0] + (centre_ray[2] + f * target[0] * size[0] / 2.0) * z,
                           centre_ray[1] + (centre_ray[3] + f * target[1] * size[1] / 2.0) * z, z])
        return np.concatenate([centre - rot.apply(board_centre), rot.as_rotvec()])

    def fits(f: float) -> bool:
        with np.errstate(over="ignore", invalid="ignore"):      # far outside, the distortion polynomial overflows
            return _fits(calibration, pose_transform(pose_at(f), outline), border)

    if not fits(0.0):
        return None
    if fits(1.0):
        return pose_at(1.0)
    lo, hi = 0.0, 1.0
    for _ in range(int(steps)):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return pose_at(lo)


def sample_poses(calibration: GeometricCalibration, board: Board, n_poses: int, rng: np.random.Generator, *,
                 distances: tuple[float, float] = SET_DISTANCES, max_tilt: float = SET_MAX_TILT,
                 border: float = SET_BORDER, attempts: int = 400, placement: str = "centre") -> np.ndarray:
    """Board poses ``[tx, ty, tz, rx, ry, rz]`` (n_poses, 6) for a calibration set, the whole board (with its
    margin) inside every view.

    Pose ``q`` puts the board's centre at depth ``z_q`` (spread evenly over ``distances``, in random order,
    jittered within its share) near the ray of the centre sample, moved sideways at random; the board is
    turned by ``rz`` (uniform within +-15 degrees) about its normal, then tilted by an angle spread evenly
    over ``[max_tilt / 3, max_tilt]`` about a random axis in the image plane: ``R = R_tilt R_z``.  A draw
    whose outline leaves a view (:func:`_fits`) is drawn again, then without the sideways shift, then at
    other depths of the range; ValueError when the board fits nowhere.

    ``placement`` (:data:`PLACEMENTS`): 'centre' as above (the boards stay near the middle of the field: the
    sets of issue 22's measurements reached 68-76 % of its radius); 'field' as a calibration guide asks of a
    user, to cover the field up to its corners, where the distortion is largest: the pose of depth rank ``r``
    (0 the nearest) aims at a target of :data:`FIELD_TARGETS` (fractions ``(tx, ty)`` of the half field) -- the
    farther half, whose boards are small enough to reach them, at the four corners in turn, the nearer half
    at the centre and the four edges -- and is moved from the centre ray towards it by the largest fraction
    of the way (bisection, 8 steps) at which it still fits.  The board's outer squares and margin keep its
    corners about two squares inside the view, so even then they reach ~75 % of the field's radius.
    """
    from scipy.spatial.transform import Rotation

    if placement not in PLACEMENTS:
        raise ValueError(f"placement must be one of {PLACEMENTS}, got {placement!r}")
    near, far = (float(v) for v in distances)
    if not 0 < near <= far:
        raise ValueError(f"distances must be 0 < near <= far (m), got {distances!r}")
    n_v, n_u, n_y, n_x = calibration.lf_shape
    centre_ray = calibration.rays(np.array([(n_u - 1) / 2.0, (n_v - 1) / 2.0, (n_x - 1) / 2.0, (n_y - 1) / 2.0]))
    width = abs(calibration.intrinsics[2, 2]) * n_x
    height = abs(calibration.intrinsics[3, 3]) * n_y
    board_centre = np.array([(board.cols - 1) / 2.0, (board.rows - 1) / 2.0, 0.0]) * board.square_m
    outline = board.outline()
    order = rng.permutation(n_poses)
    tilts = np.linspace(max_tilt / 3.0, max_tilt, n_poses)[rng.permutation(n_poses)]
    poses = np.empty((n_poses, 6))
    for q in range(n_poses):
        share = (far - near) / n_poses
        for attempt in range(attempts):
            wide = attempt >= attempts // 2              # the second half: anywhere in the range
            z = rng.uniform(near, far) if wide else near + share * (order[q] + rng.uniform())
            axis_angle = rng.uniform(0.0, 2.0 * math.pi)
            tilt = Rotation.from_rotvec(tilts[q] * np.array([math.cos(axis_angle), math.sin(axis_angle), 0.0]))
            rot = tilt * Rotation.from_rotvec([0.0, 0.0, rng.uniform(-1.0, 1.0) * math.radians(15.0)])
            if placement == "field":
                half = n_poses // 2
                targets = FIELD_TARGETS["far"] if order[q] >= half else FIELD_TARGETS["near"]
                rank = order[q] - half if order[q] >= half else order[q]
                pose = _aimed_pose(calibration, outline, border, rot, board_centre, centre_ray, z,
                                   targets[rank % len(targets)], (width, height))
                if pose is not None:
                    poses[q] = pose
                    break
                continue
            shift = 0.0 if attempt % 4 == 3 else 0.3       # every 4th try: centred
            centre = np.array([centre_ray[0] + centre_ray[2] * z + shift * rng.uniform(-1, 1) * width * z,
                               centre_ray[1] + centre_ray[3] * z + shift * rng.uniform(-1, 1) * height * z, z])
            pose = np.concatenate([centre - rot.apply(board_centre), rot.as_rotvec()])
            if _fits(calibration, pose_transform(pose, outline), border):
                poses[q] = pose
                break
        else:
            raise ValueError(f"a {board.rows} x {board.cols} board of {board.square_m * 1e3:g} mm squares "
                             f"does not fit every view at {near:g}-{far:g} m with tilts up to "
                             f"{math.degrees(tilts[q]):.0f} degrees; use a smaller board or other distances")
    return poses


def simulate_checkerboard_set(preset: str | Preset, board: Board | Sequence[float], n_captures: int = 12, *,
                              intrinsics: np.ndarray | None = None, distortion: Any = None, seed: int = 0,
                              shape: tuple[int, int] | None = None, pitch: float | None = None,
                              rotation: float | None = None, offset: tuple[float, float] | None = None,
                              n_views: int | None = None, distances: tuple[float, float] = SET_DISTANCES,
                              max_tilt: float = SET_MAX_TILT, noise: bool = True, supersample: int = 4,
                              placement: str = "centre", progress: Progress = None) -> CheckerboardSet:
    """Simulate a geometric calibration set: ``n_captures`` raws of a checkerboard at varied poses.

    Each raw is :func:`render_board_mosaic` of the board at one pose of :func:`sample_poses`, through
    the camera ``(H, distortion)``; decoding it with :func:`plenodecode.decode` (default ``n_views``) gives
    a light field in which the board's corners lie at :func:`board_corners` of the truth.

    Parameters
    ----------
    preset : str or Preset
        An unfocused preset (its lattice, levels, CFA, colour and noise).
    board : Board or (rows, cols, square_m)
    n_captures : int
        Number of raws (1 to 100; 10-20 make a calibration set).
    intrinsics : (5, 5), optional
        ``H`` (0-based); default :func:`default_intrinsics` of the decoded shape.
    distortion : (5,), optional
        ``[k1, k2, k3, b1, b2]``; default none.
    seed : int
        Seeds the poses and the noise.
    shape : (H, W), optional
        Sensor size; default :func:`set_sensor_shape` (decoded about :data:`SET_SAMPLES`).
    pitch, rotation, offset : optional
        Lattice overrides, as in :func:`~plenodecode.synthetic.simulate`.
    n_views : int, optional
        Views per angular axis of the decoded light fields the truth is for (odd; default
        ``grid.n_views()``, the decoder's default; decode with the same ``n_views``).
    distances : (near, far)
        Range of board distances (m).
    max_tilt : float
        Largest tilt of the board (rad).
    noise : bool
        False: noise-free raws and white (values only rounded).
    supersample : int
        Spatial footprint points per axis (:func:`footprint_offsets`).
    placement : {'centre', 'field'}
        Where the boards go (:func:`sample_poses`): 'centre' (the default, the sets measured so far) keeps
        them near the middle; 'field' aims them at the centre, corners and edges of the field in turn, as a
        calibration guide asks, so that the distortion is measured up to the field's corners.
    progress : callable(done, total), optional
        Called after each raw and after the white image (``total = n_captures + 1``).

    Returns
    -------
    CheckerboardSet
    """
    p = get_preset(preset)
    if p.focused:
        raise ValueError(f"preset must be an unfocused camera for a checkerboard set, got {p.name!r} (focused)")
    board = Board.of(board)
    if not (isinstance(n_captures, (int, np.integer)) and 1 <= n_captures <= 100):
        raise ValueError(f"n_captures must be an integer from 1 to 100, got {n_captures!r}")
    if not 0.0 <= max_tilt < math.pi / 2:
        raise ValueError(f"max_tilt must be in [0, pi/2) rad, got {max_tilt!r}")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    shape = set_sensor_shape(p) if shape is None else shape
    p, grid, off = _resolve(p, pitch, rotation, offset, shape)
    grid = pipeline_grid(grid)
    if n_views is not None and not (isinstance(n_views, (int, np.integer)) and n_views >= 1 and n_views % 2 == 1):
        raise ValueError(f"n_views must be a positive odd number, got {n_views!r}")
    from ..decoding.rectify import decoded_shape

    lf_shape = decoded_shape(grid, n_views)
    h = default_intrinsics(lf_shape) if intrinsics is None else check_intrinsics(intrinsics)
    camera = GeometricCalibration(intrinsics=h, distortion=check_distortion(distortion), lf_shape=lf_shape)
    streams = np.random.SeedSequence(int(seed)).spawn(1 + int(n_captures))
    poses = sample_poses(camera, board, int(n_captures), np.random.default_rng(streams[0]), distances=distances,
                         max_tilt=max_tilt, placement=placement)
    raws = []
    for q, pose in enumerate(poses):
        rng = np.random.default_rng(streams[1 + q]) if noise else None
        mosaic = render_board_mosaic(p, grid, camera, board, pose, rng, supersample=supersample)
        raws.append(RawCapture(mosaic=mosaic, cfa=p.cfa, black=levels(p)[0], white=levels(p)[1],
                               metadata=_metadata(p, grid, white=False, seed=int(seed), offset=off)))
        if progress is not None:
            progress(q + 1, len(poses) + 1)
    white, _ = simulate_white(p, seed=int(seed), pitch=pitch, rotation=rotation, offset=offset, noise=noise,
                              shape=shape)
    if progress is not None:
        progress(len(poses) + 1, len(poses) + 1)
    info = {"generator": "plenodecode.synthetic.checkerboard", "board": board.to_dict(), "preset": p.name,
            "seed": int(seed), "noise": bool(noise), "placement": placement, "sensor_shape": list(grid.sensor_shape)}
    truth = GeometricCalibration(intrinsics=h, distortion=camera.distortion, lf_shape=lf_shape, poses=poses, info=info)
    return CheckerboardSet(raws=tuple(raws), white=white, grid=grid, truth=truth, board=board, preset=p)


#: File name of a set's ground truth (a :class:`~plenodecode.raymodel.GeometricCalibration` document).
SET_TRUTH_NAME = "geometry_truth.json"


def write_checkerboard_set(cset: CheckerboardSet, out_dir: str | os.PathLike, *, name: str = "board",
                           overwrite: bool = False) -> dict[str, Path]:
    """Write a calibration set: every raw in the preset camera's format (:func:`write_camera_file`), the white
    image once (``MOD_0000.RAW`` + ``.TXT`` for Lytro presets, ``<name>_white.png`` + json otherwise) and the
    truth :data:`SET_TRUTH_NAME` (:func:`plenodecode.io.calinfo.save_geometric_calibration`, whose ``info``
    also lists the files).  Nothing is replaced unless ``overwrite``: existing targets raise FileExistsError
    before anything is written.

    Returns
    -------
    dict
        ``raw_00`` ..., ``white``, ``truth`` -> Path (sidecars are written beside their image).
    """
    from ..io.calinfo import save_geometric_calibration

    p = cset.preset
    out = Path(out_dir)
    raw_names = [simulation_files(p, f"{name}_{q:02d}")["raw"] for q in range(len(cset.raws))]
    white_name = simulation_files(p, name)["white"]
    paths = {f"raw_{q:02d}": out / n for q, n in enumerate(raw_names)}
    paths["white"] = out / white_name
    paths["truth"] = out / SET_TRUTH_NAME
    refuse_existing(paths.values(), overwrite)
    out.mkdir(parents=True, exist_ok=True)
    for q, raw in enumerate(cset.raws):
        write_camera_file(p, paths[f"raw_{q:02d}"], raw, cset.grid, overwrite=overwrite)
    write_camera_file(p, paths["white"], cset.white, cset.grid, overwrite=overwrite)
    info = {**cset.truth.info, "captures": raw_names, "white": white_name, "grid": cset.grid.to_dict()}
    truth = GeometricCalibration(intrinsics=cset.truth.intrinsics, distortion=cset.truth.distortion,
                                 lf_shape=cset.truth.lf_shape, poses=cset.truth.poses, info=info)
    save_geometric_calibration(truth, paths["truth"], overwrite=overwrite)
    return paths

__all__ = ["BOARD_LEVELS", "Board", "board_values", "footprint_offsets", "board_radiance",
           "board_radiance_numpy",
           "board_lightfield", "board_corners", "default_intrinsics", "pipeline_grid", "pixel_samples",
           "render_board_mosaic", "SET_SAMPLES", "SET_DISTANCES", "SET_MAX_TILT", "SET_BORDER", "SET_TRUTH_NAME",
           "PLACEMENTS", "FIELD_TARGETS",
           "CheckerboardSet", "set_sensor_shape", "sample_poses", "simulate_checkerboard_set", "write_checkerboard_set"]
