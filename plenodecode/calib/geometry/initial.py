"""Initial estimate of the plenoptic intrinsics ``H`` and the board poses, in closed form.

Derivation (this project's; notation of :mod:`plenodecode.raymodel`).  With ``H`` re-centred so
that the central sample ``n_c = (i_c, j_c, k_c, l_c)`` (the middle of the light field) maps to the
ray ``(0, 0, 0, 0)``, and with ``di = i - i_c``, ``dk = k - k_c`` (``dj``, ``dl`` alike), a sample's
ray is::

    s = H00 di + H02 dk,   u = H20 di + H22 dk
    t = H11 dj + H13 dl,   v = H31 dj + H33 dl

For a fixed view ``(i, j)`` all its rays cross the plane ``z = -H02 / H22`` at one point, so each
sub-aperture view is a pinhole camera with focal length ``1 / H22`` (px per unit slope) looking
along ``z``; the central view's pinhole lies on the optical axis.  The reference plane ``z = 0`` can
be moved along ``z`` by any ``d`` without changing a single ray (rows 0, 1 of ``H`` gain ``d`` times
rows 2, 3 and every pose's ``tz`` loses ``d``), so the data cannot fix it: the solver puts it through
the central view's centre of projection, ``H02 = 0`` (see :mod:`.gauge`).

1. **Poses.**  The view of each capture nearest the centre is a pinhole at the origin: OpenCV's
   planar calibration (``cv2.calibrateCamera``, Zhang's homography initialisation then
   Levenberg-Marquardt, with OpenCV's radial ``k1`` free and its other distortion terms at zero) on those views
   of all captures gives a focal length
   and each board's pose ``[t, r]`` in the camera frame.
2. **H.**  A board corner ``P = (x, y, z)`` seen at sample ``(i, j, k, l)`` lies on its ray:
   ``x = s + u z`` and ``y = t + v z``, i.e. ::

       x = H00 di + H20 di z + H22 dk z              (H02 = 0)
       y = H11 dj + H13 dl + H31 dj z + H33 dl z

   which is linear in the entries of ``H`` once ``P`` is known from step 1; every observation of
   every view of every capture gives one row of each least-squares system.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ...errors import CalibrationError
from ...raymodel import Board, pose_transform
from .corners import ViewCorners
from .gauge import lf_centre, recentred_intrinsics


def stacked_observations(captures: Sequence[ViewCorners], n_points: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All observations of all captures as flat arrays, grouped by capture.

    Returns
    -------
    samples : (M, 4) float64
        ``(i, j, k, l)`` of each observed corner.
    point : (M,) int64
        Index of the corner in :meth:`Board.points`.
    capture : (M,) int64
        Index of the capture in ``captures``.
    """
    samples, point, capture = [], [], []
    for c, found in enumerate(captures):
        n = found.count
        ij = np.repeat(found.views.astype(np.float64), n_points, axis=0)
        samples.append(np.concatenate([ij, found.corners.reshape(-1, 2)], axis=1))
        point.append(np.tile(np.arange(n_points), n))
        capture.append(np.full(n * n_points, c))
    return (np.concatenate(samples).reshape(-1, 4), np.concatenate(point).astype(np.int64),
            np.concatenate(capture).astype(np.int64))


def initial_poses(captures: Sequence[ViewCorners], board: Board) -> tuple[np.ndarray, float]:
    """Step 1: board poses (N, 6) ``[tx, ty, tz, rx, ry, rz]`` and the focal length (px) of the central views.

    Raises
    ------
    CalibrationError
        OpenCV's calibration fails (too few or degenerate captures).
    """
    import cv2

    V, U, Y, X = captures[0].lf_shape
    centre = lf_centre(captures[0].lf_shape)[:2]
    object_points, image_points = [], []
    board_points = board.corners().astype(np.float32)
    for found in captures:
        nearest = int(np.argmin(np.sum((found.views - centre) ** 2, axis=1)))
        object_points.append(board_points)
        image_points.append(found.corners[nearest].astype(np.float32))
    # k1 free: with it fixed at 0, 8 rendered captures of a camera whose distortion moves the edge rays by 3 %
    # started H00 at -5 % of its value (wrong sign) and the refinement never recovered (H 1.7 % off after it)
    flags = (cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST)
    try:
        _, camera, _, rvecs, tvecs = cv2.calibrateCamera(object_points, image_points, (X, Y), None, None,
                                                         flags=flags)
    except cv2.error as exc:
        raise CalibrationError(f"the initial pinhole calibration of the central views failed ({exc}); "
                               "take more captures with the board at different tilts") from exc
    poses = np.array([np.concatenate([np.ravel(t), np.ravel(r)]) for r, t in zip(rvecs, tvecs)])
    return poses, float(camera[0, 0])


def initial_intrinsics(samples: np.ndarray, points: np.ndarray, lf_shape: Sequence[int]) -> np.ndarray:
    """Step 2: the 5 x 5 ``H`` (re-centred, ``H02 = 0``) from camera-frame points (M, 3) of samples (M, 4)."""
    d = samples - lf_centre(lf_shape)
    di, dj, dk, dl = d.T
    x, y, z = points.T
    h00, h20, h22 = np.linalg.lstsq(np.stack([di, di * z, dk * z], axis=1), x, rcond=None)[0]
    h11, h13, h31, h33 = np.linalg.lstsq(np.stack([dj, dl, dj * z, dl * z], axis=1), y, rcond=None)[0]
    return recentred_intrinsics([h00, h20, h22, h11, h13, h31, h33], lf_shape)


def initial_estimate(captures: Sequence[ViewCorners], board: Board) -> tuple[np.ndarray, np.ndarray]:
    """``(H (5, 5), poses (N, 6))`` from the corners of N captures (steps 1 and 2 above)."""
    poses, _ = initial_poses(captures, board)
    samples, point, capture = stacked_observations(captures, board.rows * board.cols)
    board_points = board.corners()
    world = np.empty((len(samples), 3))
    for c, pose in enumerate(poses):
        rows = capture == c
        world[rows] = pose_transform(pose, board_points[point[rows]])
    return initial_intrinsics(samples, world, captures[0].lf_shape), poses
