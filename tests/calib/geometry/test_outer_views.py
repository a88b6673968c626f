"""The outer views of a decoded checkerboard capture keep their parallax (issue 22: hot-pixel repair at the rim).

A noise-free F01 raw of a board facing the camera at 0.3 m (disparity +1.14 px per view step) is decoded as
geometric calibration decodes its captures (:data:`~plenodecode.calib.geometry.captures.CAPTURE_DECODE`) and its
corners fitted on the lens samples, started at the truth.  The decoder's default hot-pixel rule took sharp board
edges on the micro-images' rims for hot pixels and filled them from inside the disk, which pulled the corners of
the views 2.2-3.6 steps off centre towards the central view's (parallax scale -3.8e-3); the calibration's rule
(``hot_pixels='isolated'``) leaves them (+1.25e-3, as without any repair: the extrapolated demosaiced channels).
"""

from __future__ import annotations

import numpy as np
import pytest

Z_M = 0.3
SQUARE_M = 0.004
N_CORNERS = 40


@pytest.fixture(scope="module")
def capture():
    from scipy.spatial.transform import Rotation

    from plenodecode.calib import calibrate
    from plenodecode.decoding.rectify import decoded_shape
    from plenodecode.raymodel import Board, GeometricCalibration
    from plenodecode.synthetic.checkerboard import (default_intrinsics, pipeline_grid, render_board_mosaic,
                                                    set_sensor_shape)
    from plenodecode.synthetic.forward import _metadata, _resolve, simulate_white
    from plenodecode.synthetic.presets import get_preset
    from plenodecode.synthetic.sensor import levels
    from plenodecode.types import RawCapture

    p = get_preset("f01")
    shape = set_sensor_shape(p)
    p, grid, offset = _resolve(p, None, None, None, shape)
    grid = pipeline_grid(grid)
    lf_shape = decoded_shape(grid, None)
    camera = GeometricCalibration(intrinsics=default_intrinsics(lf_shape), lf_shape=lf_shape)
    board = Board.of((N_CORNERS, N_CORNERS, SQUARE_M))
    turn = Rotation.from_rotvec([0.0, 0.0, 0.2])                 # edges not along the lattice
    centre_view = (lf_shape[0] - 1) / 2.0
    ray = camera.rays(np.array([centre_view, centre_view, (lf_shape[3] - 1) / 2.0, (lf_shape[2] - 1) / 2.0]))
    middle = np.array([ray[0] + ray[2] * Z_M, ray[1] + ray[3] * Z_M, Z_M])
    pose = np.concatenate([middle - turn.apply(np.array([1.0, 1.0, 0.0]) * (N_CORNERS - 1) / 2 * SQUARE_M),
                           turn.as_rotvec()])
    mosaic = render_board_mosaic(p, grid, camera, board, pose, None)
    raw = RawCapture(mosaic=mosaic, cfa=p.cfa, black=levels(p)[0], white=levels(p)[1],
                     metadata=_metadata(p, grid, white=False, seed=0, offset=offset))
    white, _ = simulate_white(p, seed=0, noise=False, shape=shape)
    return raw, white, calibrate(white), camera, board, pose


def _outer_parallax_scale(capture, hot_pixels) -> float:
    """``sum e . d / sum d . d`` over the corners of the searched views 2.2 or more view steps off centre: ``e`` the
    fitted corner's error, ``d`` its true parallax from the central view."""
    from plenodecode.calib.geometry.captures import CAPTURE_DECODE
    from plenodecode.calib.geometry.corners import MIN_VIEW_WEIGHT, refine_corners_on_samples
    from plenodecode.decoding import decode_samples
    from plenodecode.imaging import luma
    from plenodecode.raymodel import pose_transform

    raw, white, grid, camera, board, pose = capture
    _, samples = decode_samples(raw, grid, white=white, **{**CAPTURE_DECODE, "hot_pixels": hot_pixels})
    n_v, n_u, n_y, n_x = camera.lf_shape
    c = (n_v - 1) // 2
    points = pose_transform(pose, board.corners())
    centre = camera.project(points, (c, c))
    inside = ((centre[:, 0] > 6) & (centre[:, 0] < n_x - 7) & (centre[:, 1] > 6) & (centre[:, 1] < n_y - 7))
    rows, cols = np.nonzero(inside.reshape(N_CORNERS, N_CORNERS))
    block = np.zeros((N_CORNERS, N_CORNERS), bool)               # a whole sub-board of rows x cols corners
    block[rows.min() + 1:rows.max(), cols.min() + 1:cols.max()] = True
    block = block.ravel()
    n_rows, n_cols = rows.max() - rows.min() - 1, cols.max() - cols.min() - 1
    weights = samples.weight.mean(axis=(2, 3))
    num = den = 0.0
    for j in range(n_v):
        for i in range(n_u):
            if np.hypot(i - c, j - c) < 2.2 or weights[j, i] < MIN_VIEW_WEIGHT * weights[c, c]:
                continue
            truth = camera.project(points, (i, j))[block]
            found, ok = refine_corners_on_samples(luma(samples.data[j, i]), samples.position, samples.weight[j, i],
                                                  truth, n_rows, n_cols)
            assert ok.mean() > 0.9
            error, parallax = (found - truth)[ok], (truth - centre[block])[ok]
            num += np.sum(error * parallax)
            den += np.sum(parallax * parallax)
    return num / den


def test_outer_views_keep_their_parallax(capture):
    from plenodecode.calib.geometry.captures import CAPTURE_DECODE

    assert CAPTURE_DECODE["hot_pixels"] == "isolated"
    assert abs(_outer_parallax_scale(capture, "isolated")) < 2e-3
    # the default rule: the rim's board edges repaired as hot pixels, the outer views' parallax compressed
    assert _outer_parallax_scale(capture, True) < -2.5e-3


def test_isolated_rule_still_finds_defects(capture):
    from plenodecode.decoding.devignette import find_hot_pixels, normalise

    raw, white = capture[:2]
    x = normalise(raw.mosaic, raw.black, raw.white)
    wn = normalise(white.mosaic, white.black, white.white)
    assert find_hot_pixels(x).sum() > 100                      # board edges on the rims, none a defect
    assert find_hot_pixels(x, isolated=True, white=wn).sum() == 0
    rng = np.random.default_rng(3)
    lit = np.flatnonzero(wn > 0.05)
    defects = rng.choice(lit, 60, replace=False)
    hot = x.copy().ravel()
    hot[defects] = rng.uniform(0.6, 1.0, defects.size)          # as the generator's (0.3-1 of the range)
    hot = hot.reshape(x.shape)
    ring = find_hot_pixels(hot).ravel()
    isolated = find_hot_pixels(hot, isolated=True, white=wn).ravel()
    assert np.count_nonzero(isolated) == np.count_nonzero(isolated[defects])     # nothing but defects
    assert np.count_nonzero(isolated[defects]) >= np.count_nonzero(ring[defects]) - 2
