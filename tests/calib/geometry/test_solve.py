"""The solver against corner observations synthesised by the ray model (known H, distortion, poses)."""

from __future__ import annotations

import numpy as np
import pytest

from plenodecode.calib.geometry.gauge import move_reference_plane, to_solver_gauge
from plenodecode.calib.geometry.initial import initial_estimate
from plenodecode.calib.geometry.solve import Observations, capture_weights, reprojection, solve
from plenodecode.raymodel import correct_directions, pose_transform

from .synthetic_corners import BOARD, DISTORTION, LF_SHAPE, observe, true_intrinsics, true_poses

NOISE_PX = 0.03


@pytest.fixture(scope="module")
def solved():
    h, poses = true_intrinsics(), true_poses(10)
    found = observe(h, DISTORTION, poses, noise_px=NOISE_PX)
    obs = Observations.of(found, BOARD)
    h0, p0 = initial_estimate(found, BOARD)
    return {"truth": (h, poses), "obs": obs, "initial": (h0, p0), "solved": solve(obs, h0, p0)}


def test_initial_estimate_is_close_enough_to_start_from(solved):
    """The closed form ignores the distortion (here up to ~10 % of a direction at the edges)."""
    h, _ = solved["truth"]
    h0, _ = solved["initial"]
    for r, c in ((0, 0), (2, 2), (3, 3)):
        assert h0[r, c] == pytest.approx(h[r, c], rel=0.2)


def test_intrinsics_within_half_a_percent(solved):
    h, _ = solved["truth"]
    h1, _, _ = solved["solved"]
    for r, c in ((0, 0), (2, 0), (2, 2), (1, 1), (3, 1), (3, 3), (0, 4), (1, 4), (2, 4), (3, 4)):
        assert h1[r, c] == pytest.approx(h[r, c], rel=0.005), (r, c)
    # H13 (t per spatial row) is 0 in the truth: below 0.5 % of what one spatial row moves a ray sideways at the
    # nearest board (H33 x 0.15 m)
    assert abs(h1[1, 3]) < 0.005 * abs(h[3, 3]) * 0.15
    assert h1[0, 2] == 0.0


def test_distortion_within_five_percent(solved):
    d1 = solved["solved"][1]
    assert d1[0] == pytest.approx(DISTORTION[0], rel=0.05)
    assert d1[3:] == pytest.approx(DISTORTION[3:], rel=0.05)
    # k2 and k3 trade off against each other; the correction they make together over the field of view is
    # what rectification uses: within 5 % of the largest correction everywhere
    h = solved["truth"][0]
    edge = abs(h[2, 2]) * LF_SHAPE[3] / 2
    grid = np.stack(np.meshgrid(*(np.linspace(-edge, edge, 9),) * 2), axis=-1)
    truth = correct_directions(grid, DISTORTION) - grid
    found = correct_directions(grid, d1) - grid
    assert np.abs(found - truth).max() < 0.05 * np.abs(truth).max()


def test_reprojection_at_the_noise_floor(solved):
    """The floor: the RMS the true parameters give on the same noisy observations."""
    h, poses = solved["truth"]
    floor = reprojection(solved["obs"], h, DISTORTION, poses)
    fit = reprojection(solved["obs"], *solved["solved"])
    assert fit.rms_m() <= 1.5 * floor.rms_m()
    assert fit.rms_px() <= 1.5 * floor.rms_px()
    assert floor.rms_px() == pytest.approx(NOISE_PX * np.sqrt(2), rel=0.05)   # 2-D error of N(0, s^2) per axis
    assert fit.rms_m() > 0.5 * floor.rms_m()                                 # not a degenerate fit


def test_noise_free_observations_are_fitted_exactly():
    h, poses = true_intrinsics(), true_poses(4, seed=5)
    found = observe(h, np.zeros(5), poses)
    obs = Observations.of(found, BOARD)
    h1, d1, p1 = solve(obs, *initial_estimate(found, BOARD), distortion=False)
    np.testing.assert_allclose(h1, h, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(p1, poses, atol=1e-8)
    assert reprojection(obs, h1, d1, p1).rms_px() < 1e-6


def test_gauge_moves_keep_every_ray():
    """Without distortion, moving the reference plane changes H and the poses but no point-to-ray distance
    (with distortion it does: s is not corrected, so the plane is where positions are undistorted);
    to_solver_gauge undoes a move."""
    h, poses = true_intrinsics(), true_poses(3)
    found = observe(h, np.zeros(5), poses, noise_px=0.1)
    obs = Observations.of(found, BOARD)
    moved_h, moved_poses = move_reference_plane(h, poses, 0.02)
    assert moved_h[0, 2] != 0.0
    np.testing.assert_allclose(reprojection(obs, moved_h, np.zeros(5), moved_poses).ray_m,
                               reprojection(obs, h, np.zeros(5), poses).ray_m, rtol=1e-9, atol=1e-15)
    back_h, back_poses = to_solver_gauge(moved_h, moved_poses, LF_SHAPE)
    np.testing.assert_allclose(back_h, h, atol=1e-15)
    np.testing.assert_allclose(back_poses, poses, atol=1e-12)


def test_levenberg_marquardt_reaches_the_least_squares_minimum():
    """On noisy observations it stops converged, at the cost scipy's dense trust-region solver reaches."""
    from scipy.optimize import least_squares

    from plenodecode.calib.geometry.solve import _Problem, levenberg_marquardt

    h, poses = true_intrinsics(), true_poses(4, seed=3)
    found = observe(h, np.zeros(5), poses, noise_px=NOISE_PX, seed=4)
    obs = Observations.of(found, BOARD)
    h0, p0 = initial_estimate(found, BOARD)
    problem = _Problem.at(obs, h0, np.zeros(5), p0, with_distortion=False)
    y, info = levenberg_marquardt(problem)
    assert info["message"] == "cost change below ftol" and info["iterations"] <= 30
    reference = least_squares(problem.residuals, np.zeros_like(problem.x0), method="trf", tr_solver="exact",
                              xtol=1e-12, ftol=1e-12, gtol=1e-12)
    assert info["cost"] == pytest.approx(reference.cost, rel=1e-7)
    assert info["cost"] == pytest.approx(0.5 * np.sum(problem.residuals(y) ** 2), rel=1e-12)


@pytest.mark.parametrize("seed", [0, 2])
def test_noisier_captures_are_weighted_down(seed):
    """Two of 8 captures with 6x the corner noise (0.12 px against 0.02 px): capture_weights are the inverse
    variances of their ray distances, 1 / (noise z)^2 (measured within 5 %), and the reweighted solve puts
    H within 0.2 % (measured 0.12 / 0.12 %) where the unweighted one is 0.22 / 0.55 % off."""
    h, poses = true_intrinsics(), true_poses(8, seed=3)
    noise = np.full(8, 0.02)
    noise[[0, 3]] = 0.12
    found = [observe(h, np.zeros(5), poses[c:c + 1], noise_px=noise[c], seed=10 * seed + c)[0] for c in range(8)]
    obs = Observations.of(found, BOARD)
    depth = np.array([np.sqrt(np.mean(pose_transform(p, BOARD.corners())[:, 2] ** 2)) for p in poses])
    expected = 1.0 / (noise * depth) ** 2
    expected /= np.exp(np.mean(np.log(expected)))
    np.testing.assert_allclose(capture_weights(obs, h, np.zeros(5), poses), expected, rtol=0.1)
    entries = ((0, 0), (2, 0), (2, 2), (1, 1), (3, 1), (3, 3))
    errors = []
    for passes in (0, 2):
        h1 = solve(obs, *initial_estimate(found, BOARD), distortion=False, reweight=passes)[0]
        errors.append(max(abs(h1[e] / h[e] - 1) for e in entries))
    assert errors[1] < 0.002
    assert errors[1] < errors[0]


def test_flipped_pose_is_the_planar_ambiguity():
    """The flipped board keeps its centre and, seen from the camera, its outline across the line of sight;
    its depths about the centre are reversed; flipping twice gives the pose back."""
    from plenodecode.calib.geometry.solve import flipped_pose

    pose = true_poses(1, seed=5)[0]
    centre = BOARD.corners().mean(axis=0)
    flipped = flipped_pose(pose, centre)
    before, after = pose_transform(pose, BOARD.corners()), pose_transform(flipped, BOARD.corners())
    middle = pose_transform(pose, centre[None])[0]
    w = middle / np.linalg.norm(middle)
    np.testing.assert_allclose(pose_transform(flipped, centre[None])[0], middle, atol=1e-12)
    np.testing.assert_allclose((after - middle) @ w, -(before - middle) @ w, atol=1e-12)
    across = np.eye(3) - np.outer(w, w)
    np.testing.assert_allclose((after - middle) @ across, (before - middle) @ across, atol=1e-12)
    np.testing.assert_allclose(flipped_pose(flipped, centre), pose, atol=1e-10)


def test_a_board_started_at_its_other_tilt_is_flipped_back():
    """Two of 8 captures started at their flipped poses: the solve tries each board's other tilt at its solution
    and ends at the truth (H within 0.5 %, every pose within 0.5 degree), which it misses without."""
    from plenodecode.calib.geometry.solve import flipped_pose
    from plenodecode.raymodel import rotation_matrix

    h, poses = true_intrinsics(), true_poses(8, seed=3)
    found = observe(h, np.zeros(5), poses, noise_px=NOISE_PX, seed=6)
    obs = Observations.of(found, BOARD)
    h0, p0 = initial_estimate(found, BOARD)
    centre = BOARD.corners().mean(axis=0)
    for c in (1, 4):
        p0[c] = flipped_pose(p0[c], centre)
    entries = ((0, 0), (2, 0), (2, 2), (1, 1), (3, 1), (3, 3))

    def worst(result):
        h1, _, p1 = result
        angles = [np.degrees(np.arccos(np.clip((np.trace(rotation_matrix(a[3:]).T @ rotation_matrix(b[3:])) - 1) / 2,
                                               -1, 1))) for a, b in zip(p1, poses)]
        return max(abs(h1[e] / h[e] - 1) for e in entries), max(angles)

    h_error, angle = worst(solve(obs, h0, p0, distortion=False))
    assert h_error < 0.005 and angle < 0.5
    assert worst(solve(obs, h0, p0, distortion=False, flips=False))[1] > 5.0
