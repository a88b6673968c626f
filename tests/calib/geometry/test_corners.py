"""Corner ordering, view consistency and the board description."""

from __future__ import annotations

import numpy as np
import pytest

from plenodecode.calib.geometry.corners import canonical_order, consistent_views, parallax_misfit
from plenodecode.raymodel import Board


def _grid(rows, cols):
    r, c = np.mgrid[0:rows, 0:cols]
    return np.stack([10.0 + 5 * c.ravel(), 20.0 + 5 * r.ravel()], axis=-1)


@pytest.mark.parametrize("rows, cols", [(3, 4), (4, 4)])
def test_canonical_order_undoes_every_starting_corner(rows, cols):
    grid = _grid(rows, cols)
    shaped = grid.reshape(rows, cols, 2)
    variants = [shaped[::-1, ::-1], shaped[::-1], shaped[:, ::-1]] + ([shaped.transpose(1, 0, 2)] if rows == cols else [])
    for v in variants:
        np.testing.assert_array_equal(canonical_order(v.reshape(-1, 2), rows, cols), grid)


def test_inconsistent_view_is_dropped():
    grid = _grid(3, 4)
    views = np.array([(0, 0), (1, 0), (2, 0), (3, 0)])
    corners = np.array([grid + [0.7 * n, 0.0] for n in range(4)])   # parallax: a shift per view
    corners[2, 5] += [3.0, 0.0]                                       # one misplaced corner
    np.testing.assert_array_equal(consistent_views(views, corners), [True, True, False, True])


def _tilted_board_views(square=6.0, noise=0.03, seed=0):
    """5 x 5 views of a 4 x 5-corner board of ``square`` px whose disparity grows across it (a tilted plane):
    corner p of view (i, j) at ``grid_p + d_p (i - 2, j - 2)``, ``d_p`` from 0.3 to 0.7 px per step."""
    r, c = np.mgrid[0:4, 0:5]
    grid = np.stack([30.0 + square * c.ravel(), 40.0 + square * r.ravel()], axis=-1)
    disparity = 0.3 + 0.1 * c.ravel() + 0.02 * r.ravel()
    views = np.array([(i, j) for j in range(5) for i in range(5)])
    corners = np.array([grid + disparity[:, None] * [i - 2, j - 2] for i, j in views])
    return views, corners + np.random.default_rng(seed).normal(0.0, noise, corners.shape)


@pytest.mark.parametrize("shift", [(6.0, 0.0), (0.0, -6.0), (6.0, 6.0)])
def test_view_shifted_by_a_whole_square_is_dropped(shift):
    """A detection that slid by one row or column of the board: every corner moved by one square, which an
    affine fit to the other views absorbs exactly; the other views' parallax predicts it 6 px off."""
    views, corners = _tilted_board_views()
    bad = [3, 1]
    n = int(np.flatnonzero((views == bad).all(axis=1))[0])
    corners[n] += shift
    misfit = parallax_misfit(views, corners)
    assert misfit[n] == pytest.approx(np.hypot(*shift), rel=0.1)
    assert np.delete(misfit, n).max() < 0.2                 # noise 0.03 px per coordinate
    keep = consistent_views(views, corners)
    np.testing.assert_array_equal(np.flatnonzero(~keep), [n])


def test_consistent_views_keeps_every_good_view():
    views, corners = _tilted_board_views()
    assert consistent_views(views, corners).all()
    assert consistent_views(views[:2], corners[:2] + [[[9.0, 0.0]], [[0.0, 0.0]]]).all()     # too few


def test_several_misdetections_do_not_hide_each_other():
    """A quarter of the views wrong (slid boards, a reversed corner list): each is found, the others kept."""
    views, corners = _tilted_board_views()
    bad = [0, 6, 12, 13, 19, 24]
    corners[bad[:5]] += np.array([[6.0, 0.0], [0.0, 6.0], [-6.0, 0.0], [6.0, 6.0], [0.0, -12.0]])[:, None]
    corners[bad[5]] = corners[bad[5], ::-1]
    np.testing.assert_array_equal(np.flatnonzero(~consistent_views(views, corners)), bad)


def test_board_parse():
    assert Board.parse("8x6x0.0036") == Board(8, 6, 0.0036)
    assert Board.of((8, 6, 0.01)).corners().shape == (48, 3)
    for bad in ("8x6", "8x6x0", "1x6x0.01", "8x6x-1", "8x6xnan"):
        with pytest.raises(ValueError):
            Board.parse(bad)


def test_detection_is_reproducible_whatever_ran_before():
    """cv2.findChessboardCornersSB draws random numbers: the same view gives the same corners every time."""
    import cv2

    from plenodecode.calib.geometry.corners import detect_view
    from plenodecode.raymodel import Board

    board = Board(3, 4, 0.01)
    y, x = np.mgrid[0:60, 0:72]
    image = 0.8 - 0.6 * (((x - 6) // 12 + (y - 6) // 12) % 2 == 0) * ((x >= 6) & (x < 66) & (y >= 6) & (y < 54))
    image = image + np.random.default_rng(1).normal(0, 0.02, image.shape)
    first = detect_view(image, board)
    assert first is not None
    for seed in (1, 2, 3):
        cv2.setRNGSeed(seed)
        cv2.randu(np.empty(100, np.float32), 0, 1)      # move the RNG as other OpenCV calls would
        np.testing.assert_array_equal(detect_view(image, board), first)


def test_window_radii_reach_the_far_side_of_the_squares():
    """A sheared grid (rows along (10, 0), columns along (3, 8)): the outer edge parallel to the rows is 8 px
    from each corner, the one parallel to the columns 80 / |(3, 8)| px."""
    from plenodecode.calib.geometry.corners import _window_radii

    r, c = np.mgrid[0:4, 0:5]
    grid = 50.0 + c[..., None] * np.array([10.0, 0.0]) + r[..., None] * np.array([3.0, 8.0])
    np.testing.assert_allclose(_window_radii(grid), min(8.0, 80.0 / np.hypot(3.0, 8.0)))
    np.testing.assert_allclose(_window_radii(grid * 0.5), 4.0)


@pytest.mark.parametrize("tilt_deg, depth_m, max_rms", [(34.0, 0.44, 0.055), (20.0, 0.5, 0.03)])
def test_refined_corners_follow_a_tilted_board(tilt_deg, depth_m, max_rms):
    """The central view of a board rendered by the ray model (F01-like set geometry, 113 x 128 px, squares
    of 5-7 px foreshortened): the sector detector is off by 0.076 px RMS (0.19 px at worst, at the board's
    edge); fitted to the image, the corners are within ``max_rms`` (measured 0.043 / 0.022 px), and
    unbiased on average."""
    from scipy.spatial.transform import Rotation

    from plenodecode.calib.geometry.corners import detect_view
    from plenodecode.raymodel import GeometricCalibration
    from plenodecode.synthetic.checkerboard import board_corners, board_lightfield, default_intrinsics

    board, shape = Board(7, 5, 0.004), (9, 9, 113, 128)
    camera = GeometricCalibration(intrinsics=default_intrinsics(shape), lf_shape=shape)
    tilt = np.radians(tilt_deg)
    rot = Rotation.from_rotvec([0.8 * tilt, 0.6 * tilt, 0.1])
    pose = np.r_[np.array([0.0, 0.0, depth_m]) - rot.apply([0.008, 0.012, 0.0]), rot.as_rotvec()]
    image = board_lightfield(camera, board, pose).data[4, 4, :, :, 0]
    truth = board_corners(camera, board, pose)[4, 4]
    detected = detect_view(image, board, refine=False) - truth
    refined = detect_view(image, board) - truth
    rms = lambda e: float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))    # noqa: E731
    assert rms(refined) < max_rms
    assert rms(refined) < 0.6 * rms(detected)
    assert np.abs(refined).max() < 0.1
    assert np.all(np.abs(refined.mean(axis=0)) < 0.005)


def test_sample_fit_beats_the_rect_view_fit_near_the_focus():
    """A generated F01 capture near the focus plane (0.39 m, 35 degrees of tilt; seed 0's second), decoded as
    calibration decodes: every view samples the board at the same lens positions and its edges are sharp, so
    the junction fitted to the hex -> rect interpolated view is off by a part shared by the views (measured
    0.066 px RMS, 0.029 px shared over the 5 x 5 central views); fitted to the lens samples at their lattice
    positions with the box-footprint edge it is 0.009 px RMS, 0.004 px shared."""
    from plenodecode.calib import calibrate
    from plenodecode.calib.geometry.captures import CAPTURE_DECODE
    from plenodecode.calib.geometry.corners import detect_view, refine_corners, refine_corners_on_samples
    from plenodecode.decoding.decoder import decode_samples
    from plenodecode.imaging import luma
    from plenodecode.synthetic.checkerboard import board_corners, simulate_checkerboard_set

    board = Board(7, 5, 0.004)
    cset = simulate_checkerboard_set("f01", board, 2, seed=0)
    lf, samples = decode_samples(cset.raws[1], calibrate(cset.white), white=cset.white, **CAPTURE_DECODE)
    truth = board_corners(cset.truth, board, cset.truth.poses[1])
    rect, values = luma(lf.data), luma(samples.data)
    on_rect, on_samples = [], []
    for j, i in [(j, i) for j in range(3, 6) for i in range(3, 6)]:
        start = detect_view(rect[j, i], board, refine=False)
        assert start is not None
        fitted, _ = refine_corners(rect[j, i], start, board.rows, board.cols)
        on_rect.append(fitted - truth[j, i])
        fitted, ok = refine_corners_on_samples(values[j, i], samples.position, samples.weight[j, i], start,
                                               board.rows, board.cols)
        assert ok.all()
        on_samples.append(fitted - truth[j, i])
    rms = lambda e: float(np.sqrt(np.mean(np.sum(np.asarray(e) ** 2, axis=-1))))    # noqa: E731
    assert rms(on_samples) < 0.02
    assert rms(on_samples) < 0.4 * rms(on_rect)
    assert rms(np.mean(on_samples, axis=0)) < 0.4 * rms(np.mean(on_rect, axis=0))    # the part shared by the views
