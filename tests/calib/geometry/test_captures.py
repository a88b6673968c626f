"""calibrate_geometry on light fields rendered by the checkerboard generator (synthetic.checkerboard)."""

from __future__ import annotations

import numpy as np
import pytest

from plenodecode.calib.geometry.captures import run_geometric_calibration
from plenodecode.errors import CalibrationError
from plenodecode.raymodel import Board, GeometricCalibration

LF_SHAPE = (5, 5, 112, 128)
BOARD = (7, 5, 0.004)


def _camera():
    from plenodecode.synthetic.checkerboard import default_intrinsics

    return GeometricCalibration(intrinsics=default_intrinsics(LF_SHAPE), lf_shape=LF_SHAPE)


@pytest.fixture(scope="module")
def generated():
    from plenodecode.synthetic.checkerboard import board_lightfield, sample_poses

    camera = _camera()
    poses = sample_poses(camera, Board.of(BOARD), 8, np.random.default_rng(4))
    return camera, poses, [board_lightfield(camera, BOARD, pose, supersample=3) for pose in poses]


def test_corners_found_at_the_true_positions(generated):
    from plenodecode.calib.geometry.corners import detect_corners
    from plenodecode.synthetic.checkerboard import board_corners

    camera, poses, lfs = generated
    found = detect_corners(lfs[0], BOARD)
    assert found.count == 25
    truth = board_corners(camera, BOARD, poses[0])
    error = np.array([kl - truth[j, i] for (i, j), kl in zip(found.views, found.corners)])
    if np.abs(error).max() > 5:            # the detector may list the corners from the opposite end
        error = np.array([kl[::-1] - truth[j, i] for (i, j), kl in zip(found.views, found.corners)])
    assert np.sqrt(np.mean(np.sum(error ** 2, axis=-1))) < 0.15


def test_intrinsics_of_generated_captures(generated):
    camera, poses, lfs = generated
    run = run_geometric_calibration(lfs, BOARD, distortion=False)
    h, truth = run.calibration.intrinsics, camera.intrinsics
    for r, c in ((0, 0), (2, 0), (2, 2), (1, 1), (3, 1), (3, 3)):
        assert h[r, c] == pytest.approx(truth[r, c], rel=0.005), (r, c)
    assert abs(h[1, 3]) < 0.005 * truth[3, 3] * 0.3
    assert run.calibration.info["rms_px"] < 0.1
    assert run.calibration.poses[:, 2] == pytest.approx(poses[:, 2], rel=0.01)
    assert len(run.calibration.info["per_capture"]) == 8 and not run.skipped


def test_too_few_captures_with_a_board(generated):
    _, _, lfs = generated
    blank = lfs[0].replace(data=np.full_like(lfs[0].data, 0.35))
    with pytest.raises(CalibrationError, match="found in 2 of 3"):
        run_geometric_calibration([lfs[0], blank, lfs[1]], BOARD)


def test_distortion_of_rendered_captures():
    """A camera whose distortion moves the rays at the edge of the field by 3 % (k1 = 4; the toolbox's F01 file
    moves them by 2 % at its wider field): 8 rendered captures give H within 0.5 % and the distortion field
    within 5 % of its largest correction (as test_solve judges the solver on synthetic corners)."""
    from plenodecode.raymodel import correct_directions
    from plenodecode.synthetic.checkerboard import board_lightfield, default_intrinsics, sample_poses

    distortion = np.array([4.0, 0.0, 0.0, 0.0, 0.0])
    camera = GeometricCalibration(intrinsics=default_intrinsics(LF_SHAPE), distortion=distortion, lf_shape=LF_SHAPE)
    poses = sample_poses(camera, Board.of(BOARD), 8, np.random.default_rng(5))
    lfs = [board_lightfield(camera, BOARD, pose, supersample=3) for pose in poses]
    cal = run_geometric_calibration(lfs, BOARD, distortion=True).calibration
    h, truth = cal.intrinsics, camera.intrinsics
    for r, c in ((0, 0), (2, 0), (2, 2), (1, 1), (3, 1), (3, 3)):
        assert h[r, c] == pytest.approx(truth[r, c], rel=0.005), (r, c)
    edges = abs(truth[2, 2]) * LF_SHAPE[3] / 2, abs(truth[3, 3]) * LF_SHAPE[2] / 2
    grid = np.stack(np.meshgrid(np.linspace(-edges[0], edges[0], 9), np.linspace(-edges[1], edges[1], 9)), axis=-1)
    true_field = correct_directions(grid, distortion) - grid
    assert np.abs(true_field).max() > 0.02 * edges[0]
    found_field = correct_directions(grid, cal.distortion) - grid
    assert np.abs(found_field - true_field).max() < 0.05 * np.abs(true_field).max()


# ------------------------------------------------------------------------------ field coverage
def _central_view_board(k_range, l_range, shape=(9, 9, 113, 128)):
    """ViewCorners of one capture: a 5 x 5 grid of corners spanning ``k_range`` x ``l_range`` in the central view."""
    from plenodecode.calib.geometry.corners import ViewCorners

    k, l_ = np.meshgrid(np.linspace(*k_range, 5), np.linspace(*l_range, 5))
    corners = np.stack([k.ravel(), l_.ravel()], axis=-1)[None]
    return ViewCorners(views=np.array([[shape[1] // 2, shape[0] // 2]]), corners=corners, searched=1, lf_shape=shape)


def test_field_coverage_of_known_boards():
    from plenodecode.calib.geometry.captures import field_coverage
    from plenodecode.synthetic.checkerboard import default_intrinsics

    shape = (9, 9, 113, 128)
    h = default_intrinsics(shape)
    whole = field_coverage([_central_view_board((-0.5, 127.5), (-0.5, 112.5))], h)
    assert whole == pytest.approx({"area": 1.0, "radius": 1.0, "beyond_radius": 0.0})
    # the left half of the view, corner to corner: half the area, the field's full radius
    left = field_coverage([_central_view_board((-0.5, 63.5), (-0.5, 112.5))], h)
    assert left["area"] == pytest.approx(0.5, abs=1 / 128) and left["radius"] == pytest.approx(1.0)
    # the centred half-size rectangle: a quarter of the area, half the radius; beyond it lies all but a disk of
    # half the field's half-diagonal (H22 = H33: square samples): 1 - pi (X^2 + Y^2) / 16 / (X Y)
    centre = field_coverage([_central_view_board((31.5, 95.5), (27.75, 84.25))], h)
    assert centre["area"] == pytest.approx(0.25, abs=0.01)
    assert centre["radius"] == pytest.approx(0.5, abs=0.005)
    assert centre["beyond_radius"] == pytest.approx(1 - np.pi * (128 ** 2 + 113 ** 2) / 16 / (128 * 113), abs=0.01)
    # the union of two captures; a board seen in another view is moved to the central view by its direction
    both = field_coverage([_central_view_board((-0.5, 63.5), (-0.5, 112.5)),
                           _central_view_board((63.5, 127.5), (-0.5, 112.5))], h)
    assert both["area"] == pytest.approx(1.0, abs=1 / 128)
    from plenodecode.calib.geometry.corners import ViewCorners

    board = _central_view_board((31.5, 95.5), (27.75, 84.25))
    # the same directions seen from view (i, j) = (6, 2): k moves by -H20 (i - 4) / H22, l by -H31 (j - 4) / H33
    moved = board.corners + np.array([-h[2, 0] * 2 / h[2, 2], -h[3, 1] * -2 / h[3, 3]])
    other = ViewCorners(views=np.array([[6, 2]]), corners=moved, searched=1, lf_shape=shape)
    assert field_coverage([other], h) == pytest.approx(centre)


def test_coverage_is_reported(generated, caplog):
    camera, poses, lfs = generated
    with caplog.at_level("WARNING", logger="plenodecode.calib.geometry.captures"):
        run = run_geometric_calibration(lfs[:4], BOARD, distortion=True)
    cover = run.calibration.info["coverage"]
    assert 0.0 < cover["area"] < 1.0 and 0.0 < cover["radius"] < 1.0
    assert cover["beyond_radius"] > 0.05 and "extrapolated" in caplog.text
    from plenodecode.report.geometry import geometry_report_html

    html = geometry_report_html(run)
    assert "field covered by the boards" in html and "the distortion is extrapolated" in html


def test_field_placement_reaches_farther_than_centre_placement():
    """'field' aims the boards at the field's corners and edges: together they reach farther out."""
    from plenodecode.calib.geometry.captures import field_coverage
    from plenodecode.calib.geometry.corners import ViewCorners
    from plenodecode.synthetic.checkerboard import board_corners, sample_poses

    camera = _camera()
    cover = {}
    for placement in ("centre", "field"):
        poses = sample_poses(camera, Board.of(BOARD), 9, np.random.default_rng(3), placement=placement)
        found = []
        for pose in poses:
            truth = board_corners(camera, BOARD, pose)
            found.append(ViewCorners(views=np.array([[2, 2]]), corners=truth[2, 2][None], searched=1,
                                     lf_shape=LF_SHAPE))
        cover[placement] = field_coverage(found, camera.intrinsics)
    assert cover["field"]["radius"] > cover["centre"]["radius"] + 0.05
    assert cover["field"]["area"] > cover["centre"]["area"] + 0.05
    with pytest.raises(ValueError, match="placement"):
        sample_poses(camera, Board.of(BOARD), 2, np.random.default_rng(3), placement="corners")
