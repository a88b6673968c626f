"""Calibrated cameras and checkerboard measurements shared by the rectification, metric-depth and CLI tests
(boards rendered by plenodecode.synthetic.checkerboard)."""

from __future__ import annotations

import cv2
import numpy as np

from plenodecode.decoding.rectify import centre_sample
from plenodecode.raymodel import GeometricCalibration
from plenodecode.synthetic.checkerboard import Board, default_intrinsics

#: A small decoded shape (V, U, Y, X) for fast boards.
SMALL_SHAPE = (5, 5, 96, 96)
#: Strong radial distortion: board lines bend by about 0.1 px RMS over the small field.
STRONG_DISTORTION = (5.0, 0.0, 0.0, 0.0, 0.0)


def skewed_calibration(shape=SMALL_SHAPE, distortion=STRONG_DISTORTION) -> GeometricCalibration:
    """:func:`default_intrinsics` made non-square (y view slopes +6 %, y spatial slopes -3 %) with ``s``
    depending on ``k`` (the views' pinhole plane 27 mm in front of ``z = 0``, as the F01's), re-centred so
    the centre sample sees the optical axis."""
    h = default_intrinsics(shape)
    h[1, 1] *= 1.06
    h[3, 1] *= 1.06
    h[1, 3] *= 0.97
    h[3, 3] *= 0.97
    h[0, 2] = -0.027 * h[2, 2]
    h[1, 3] = -0.027 * h[3, 3]
    h[:4, 4] = 0.0
    h[:4, 4] = -h[:4, :4] @ centre_sample(shape)
    return GeometricCalibration(h, distortion, shape, info={"source": "skewed test camera"})


def facing_board(z_m: float, *, corners: int = 9, square_at_03m: float = 0.0055, tilt=(0.0, 0.0, 0.0)):
    """A ``corners x corners`` board whose squares cover about the same pixels at any distance, centred on the
    optical axis at ``z_m``: ``(Board, pose)``."""
    board = Board(corners, corners, square_at_03m * z_m / 0.3)
    half = (corners - 1) / 2.0 * board.square_m
    return board, [-half, -half, z_m, *tilt]


def detect_corners(view: np.ndarray, board: Board) -> np.ndarray | None:
    """Inner corners of ``board`` in one view (Y, X) or (Y, X, 1): (rows, cols, 2) ``(k, l)`` float64 in the
    board's row-major order (flipped to it when OpenCV returns them reversed), or None when not found."""
    img = np.clip(np.asarray(view, np.float64).squeeze() / 0.9 * 255.0, 0, 255).astype(np.uint8)
    found, corners = cv2.findChessboardCornersSB(img, (board.cols, board.rows), flags=cv2.CALIB_CB_ACCURACY)
    if not found:
        return None
    c = corners.reshape(board.rows, board.cols, 2).astype(np.float64)
    if c[-1, -1, 0] + c[-1, -1, 1] < c[0, 0, 0] + c[0, 0, 1]:      # the board's first corner is top-left here
        c = c[::-1, ::-1]
    return c


def line_residual_rms(corners: np.ndarray) -> float:
    """RMS distance (px) of corners (rows, cols, 2) from the straight lines fitted (total least squares) to
    every row and every column of them."""
    residuals = []
    for lines in (corners, corners.transpose(1, 0, 2)):
        for points in lines:
            centred = points - points.mean(axis=0)
            normal = np.linalg.svd(centred)[2][1]
            residuals.append(centred @ normal)
    return float(np.sqrt(np.mean(np.concatenate(residuals) ** 2)))


def corner_disparities(lf_views: np.ndarray, board: Board, views) -> np.ndarray:
    """Disparity (px per view step, HCI sign) of every corner, from the slope of its ``k`` over ``i`` along the
    centre row of views and of its ``l`` over ``j`` down the centre column, averaged: (rows * cols,) float64.

    ``views`` lists the angular offsets from the centre to use (e.g. ``(-1, 0, 1)``)."""
    nv, nu = lf_views.shape[:2]
    vc, uc = nv // 2, nu // 2
    offsets = np.asarray(views, np.float64)
    along_i = np.stack([detect_corners(lf_views[vc, uc + o], board)[..., 0].ravel() for o in views])
    along_j = np.stack([detect_corners(lf_views[vc + o, uc], board)[..., 1].ravel() for o in views])
    slope_i = np.polyfit(offsets, along_i, 1)[0]
    slope_j = np.polyfit(offsets, along_j, 1)[0]
    return -0.5 * (slope_i + slope_j)


def write_board_raw(folder, z_m: float = 0.5):
    """A 600 x 600 F01-like raw of a board facing the camera at ``z_m``, written into ``folder`` with its white
    and lenslet grid, and the calibration it was rendered with (distorted, non-square) as ``cal.json``.

    Returns ``(paths, calibration, board)``, ``paths`` a dict of str: 'raw', 'white', 'grid', 'cal'.
    """
    from dataclasses import replace
    from pathlib import Path

    from plenodecode import synthetic
    from plenodecode.decoding.rectify import decoded_shape
    from plenodecode.io.calinfo import save_geometric_calibration
    from plenodecode.io.generic import write_mosaic
    from plenodecode.synthetic.checkerboard import render_board_mosaic

    folder = Path(folder)
    sim = synthetic.simulate("f01", shape=(600, 600), seed=1, noise=False)
    cal = skewed_calibration(decoded_shape(sim.grid), distortion=(3.0, 0.0, 0.0, 0.0, 0.0))
    board, pose = facing_board(z_m, corners=7, square_at_03m=0.004)
    raw = replace(sim.raw, mosaic=render_board_mosaic(sim.preset, sim.grid, cal, board, pose, None))
    paths = {"raw": write_mosaic(folder / "board.png", raw), "white": write_mosaic(folder / "white.png", sim.white),
             "grid": folder / "grid.json", "cal": save_geometric_calibration(cal, folder / "cal.json")}
    paths["grid"].write_text(sim.grid.to_json(), encoding="utf-8")
    return {k: str(v) for k, v in paths.items()}, cal, board
