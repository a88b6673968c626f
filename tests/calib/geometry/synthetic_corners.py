"""Corner observations synthesised with the ray model (no images): the solver's ground truth."""

from __future__ import annotations

import numpy as np

from plenodecode.calib.geometry.corners import ViewCorners
from plenodecode.raymodel import Board
from plenodecode.calib.geometry.gauge import lf_centre
from plenodecode.raymodel import pose_transform, project_points, rotation_matrix

#: (V, U, Y, X) of the synthetic light fields: 5 x 5 views of 160 x 160 samples.
LF_SHAPE = (5, 5, 160, 160)
BOARD = Board(8, 6, 0.01)
#: ``[k1, k2, k3, b1, b2]`` of the truth: strong enough for every term to show.
DISTORTION = np.array([0.35, -0.6, 1.2, 0.012, -0.008])


def true_intrinsics(lf_shape=LF_SHAPE) -> np.ndarray:
    """A Lytro-like ``H`` (F01's entries at 0-based samples, directions a little wider), re-centred, H02 = 0."""
    h = np.zeros((5, 5))
    h[0, 0], h[2, 0], h[2, 2] = 3.5e-4, -1.4e-3, 3.0e-3
    h[1, 1], h[3, 1], h[3, 3] = 3.2e-4, -1.25e-3, 2.9e-3
    h[4, 4] = 1.0
    h[:4, 4] = -h[:4, :4] @ lf_centre(lf_shape)
    return h


def true_poses(n: int, seed: int = 1) -> np.ndarray:
    """``n`` board poses 0.15-0.3 m away, tilted up to ~35 degrees, the board roughly centred in view."""
    rng = np.random.default_rng(seed)
    poses = np.empty((n, 6))
    centre = np.array([BOARD.cols - 1, BOARD.rows - 1, 0.0]) * BOARD.square_m / 2
    for c in range(n):
        tilt = rng.uniform(-0.6, 0.6, 3) * np.array([1.0, 1.0, 0.5])
        z = rng.uniform(0.15, 0.3)
        offset = rng.uniform(-0.25, 0.25, 2) * z * 0.4
        poses[c, :3] = np.array([offset[0], offset[1], z]) - rotation_matrix(tilt) @ centre
        poses[c, 3:] = tilt
    return poses


def observe(h, distortion, poses, *, noise_px: float = 0.0, seed: int = 2, lf_shape=LF_SHAPE,
            board: Board = BOARD) -> list[ViewCorners]:
    """The corners of every view of every pose, projected by the ray model, plus Gaussian noise (px)."""
    rng = np.random.default_rng(seed)
    V, U, Y, X = lf_shape
    views = np.array([(i, j) for j in range(V) for i in range(U)])
    found = []
    for pose in poses:
        points = pose_transform(pose, board.corners())
        corners = np.array([project_points(h, distortion, points, (i, j)) for i, j in views])
        corners = corners + rng.normal(0.0, noise_px, corners.shape)
        found.append(ViewCorners(views=views, corners=corners, searched=len(views), lf_shape=lf_shape))
    return found
