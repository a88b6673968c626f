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
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..raymodel import (GeometricCalibration, board_points, check_distortion, check_intrinsics, pose_transform,
                        project_points, rotation_matrix, sample_rays)
from ..types import LensletGrid, LightField, cfa_channel_map
from .kernels import SUBSAMPLES, board_radiance_kernel
from .lattice import assign_pixels
from .presets import Preset
from .sensor import Progress, render_sensor

#: Linear radiance of the board's dark squares, light squares (and margin) and the grey beyond.
BOARD_LEVELS = {"dark": 0.06, "light": 0.82, "background": 0.35}
#: Samples (continuous ``(i, j, k, l)``) evaluated per batch: bounds memory to a few hundred MB.
_BATCH = 1 << 20


@dataclass(frozen=True)
class Board:
    """A planar checkerboard target.

    Attributes
    ----------
    rows, cols : int
        Inner corners per column and per row (OpenCV's ``patternSize`` is ``(cols, rows)``).
    square_m : float
        Side of one square (m).
    margin : float
        Width of the light border around the checkers, in squares (>= 1, which OpenCV's
        detectors need).
    """

    rows: int
    cols: int
    square_m: float
    margin: float = 1.0

    def __post_init__(self) -> None:
        if int(self.rows) != self.rows or int(self.cols) != self.cols or self.rows < 2 or self.cols < 2:
            raise ValueError(f"board needs at least 2 x 2 inner corners, got {self.rows} x {self.cols}")
        if not (math.isfinite(self.square_m) and self.square_m > 0):
            raise ValueError(f"board square size must be a positive length in m, got {self.square_m!r}")
        if not self.margin >= 1.0:
            raise ValueError(f"board margin must be at least one square, got {self.margin!r}")
        object.__setattr__(self, "rows", int(self.rows))
        object.__setattr__(self, "cols", int(self.cols))
        object.__setattr__(self, "square_m", float(self.square_m))
        object.__setattr__(self, "margin", float(self.margin))

    def corners(self) -> np.ndarray:
        """Inner corners in the board frame, (rows * cols, 3) float64, row-major (:func:`raymodel.board_points`)."""
        return board_points(self.rows, self.cols, self.square_m)

    def outline(self) -> np.ndarray:
        """The 4 corners (4, 3) float64 of the board including its light margin, in the board frame."""
        s, m = self.square_m, self.margin
        x0, x1 = -(1.0 + m) * s, (self.cols + m) * s
        y0, y1 = -(1.0 + m) * s, (self.rows + m) * s
        return np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])

    def to_dict(self) -> dict[str, Any]:
        return {"rows": self.rows, "cols": self.cols, "square_m": self.square_m, "margin": self.margin}


def as_board(board: Board | Sequence[float]) -> Board:
    """A :class:`Board` from a Board or ``(rows, cols, square_m)``; ValueError naming ``board`` otherwise."""
    if isinstance(board, Board):
        return board
    try:
        rows, cols, square = board
    except (TypeError, ValueError):
        raise ValueError(f"board must be (rows, cols, square_m), got {board!r}") from None
    return Board(rows, cols, float(square))


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

    The compiled kernel :func:`~plenodecode.synthetic.kernels.board_radiance_kernel` (about 15x faster
    than :func:`board_radiance_numpy`, the documented model it is tested against).

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
                          board.margin, levels, out)
    return out


def board_radiance_numpy(intrinsics: np.ndarray, distortion: Any, board: Board, pose: Sequence[float],
                   samples: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Mean board radiance over the footprint of continuous samples (see the module docstring): the
    plain-numpy model that :func:`board_radiance` computes with a compiled kernel (same arguments).

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
    board = as_board(board)
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
    board = as_board(board)
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
def decoded_shape(grid: LensletGrid, n_views: int | None = None) -> tuple[int, int, int, int]:
    """``(V, U, Y, X)`` of the light field :func:`plenodecode.decode` makes from raws on ``grid``
    (``n_views`` per angular axis, default ``grid.n_views()``; spatial size :meth:`LensletGrid.decoded_sampling`)."""
    smp = grid.decoded_sampling()
    n = grid.n_views() if n_views is None else int(n_views)
    return (n, n, int(smp["Y"]), int(smp["X"]))


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


__all__ = ["BOARD_LEVELS", "Board", "as_board", "board_values", "footprint_offsets", "board_radiance", "board_radiance_numpy",
           "board_lightfield", "board_corners", "default_intrinsics", "decoded_shape", "pixel_samples",
           "render_board_mosaic"]
