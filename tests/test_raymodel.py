"""The ray model of plenodecode.calib.geometry.model against closed-form facts."""

import json
from pathlib import Path

import numpy as np
import pytest

from plenodecode import raymodel as model
from plenodecode.raymodel import GeometricCalibration
from tests.conftest import shared_path

# An F01-like intrinsic matrix for 0-based indices of an 11 x 11 x 379 x 379 light field (toolbox values,
# rounded) and a strong, decentred distortion.
H_TB = np.array([[3.5e-4, 0, -5.4e-5, 0, 8.2e-3],
                 [0, 3.2e-4, 0, -6.4e-5, 1.0e-2],
                 [-1.4e-3, 0, 1.88e-3, 0, -0.35],
                 [0, -1.25e-3, 0, 1.89e-3, -0.35],
                 [0, 0, 0, 0, 1]])
DISTORTION = np.array([0.18, -0.5, 1.9, -0.011, -0.0016])


def test_projection_puts_the_point_on_the_ray_of_the_projected_sample():
    h = model.from_toolbox_intrinsics(H_TB)
    rng = np.random.default_rng(1)
    points = np.column_stack([rng.uniform(-0.05, 0.05, 50), rng.uniform(-0.05, 0.05, 50), rng.uniform(0.15, 0.6, 50)])
    for view in [(0, 0), (5, 5), (10, 3), (2.5, 7.25)]:
        kl = model.project_points(h, DISTORTION, points, view)
        samples = np.column_stack([np.full(50, view[0]), np.full(50, view[1]), kl])
        rays = model.sample_rays(h, DISTORTION, samples)
        assert model.point_ray_distance(points, rays).max() < 1e-12


def test_samples_of_rays_inverts_sample_rays():
    h = model.from_toolbox_intrinsics(H_TB)
    rng = np.random.default_rng(2)
    samples = rng.uniform([0, 0, 0, 0], [10, 10, 378, 378], size=(200, 4))
    back = model.samples_of_rays(h, DISTORTION, model.sample_rays(h, DISTORTION, samples))
    assert np.abs(back - samples).max() < 1e-8


def test_distortion_correction_matches_its_formula_and_inverse():
    theta = np.array([[0.1, -0.05], [0.0, 0.0], [-0.2, 0.15]])
    k1, k2, k3, b1, b2 = DISTORTION
    c = theta - [b1, b2]
    r2 = (c ** 2).sum(1, keepdims=True)
    expected = (1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3) * c + [b1, b2]
    assert np.allclose(model.correct_directions(theta, DISTORTION), expected, atol=1e-15)
    assert np.allclose(model.correct_directions(model.distort_directions(theta, DISTORTION), DISTORTION), theta,
                       atol=1e-12)


def test_point_ray_distance_is_euclidean():
    # ray along z through (0.01, 0, 0): a point 3 mm to its side is 3 mm away
    assert model.point_ray_distance([[0.013, 0.0, 0.5]], [[0.01, 0.0, 0.0, 0.0]])[0] == pytest.approx(0.003)
    # slanted ray x = z: the point (0, 0, 1) is 1/sqrt(2) from it
    assert model.point_ray_distance([[0.0, 0.0, 1.0]], [[0.0, 0.0, 1.0, 0.0]])[0] == pytest.approx(2 ** -0.5)


def test_toolbox_indices_are_one_based():
    h = model.from_toolbox_intrinsics(H_TB)
    n0 = np.array([3.0, 4.0, 100.0, 200.0])
    assert np.allclose(model.measured_rays(h, n0), (H_TB @ np.append(n0 + 1, 1.0))[:4])
    assert np.allclose(model.to_toolbox_intrinsics(h), H_TB)


def test_pose_and_board_points():
    pts = model.board_points(2, 3, 0.01)
    assert pts.shape == (6, 3) and np.allclose(pts[-1], [0.02, 0.01, 0.0])
    pose = [0.1, 0.0, 0.5, 0.0, 0.0, np.pi / 2]       # 90 degrees about z: x_b -> y
    assert np.allclose(model.pose_transform(pose, [[1.0, 0, 0]]), [[0.1, 1.0, 0.5]])


def test_calibration_round_trips_and_rejects_malformed_intrinsics():
    cal = GeometricCalibration(model.from_toolbox_intrinsics(H_TB), DISTORTION, (11, 11, 379, 379),
                               poses=[[0, 0, 0.2, 0, 0, 0]], info={"rms_m": 1e-4})
    back = GeometricCalibration.from_dict(json.loads(json.dumps(cal.to_dict())))
    assert np.array_equal(back.intrinsics, cal.intrinsics) and back.lf_shape == (11, 11, 379, 379)
    bad = H_TB.copy()
    bad[0, 1] = 1e-3                                  # s must not depend on j
    with pytest.raises(ValueError, match="couple"):
        GeometricCalibration(bad)


def test_the_real_toolbox_calibration_has_the_model_form():
    path = shared_path("lytro-f01-gridmodel", "CalInfo.json")
    doc = json.loads(Path(path).read_text())
    h = model.from_toolbox_intrinsics(doc["EstCamIntrinsicsH"])
    # the centre sample of its 11 x 11 x 379 x 379 light field looks near the optical axis
    centre = model.sample_rays(h, doc["EstCamDistortionV"], np.array([5.0, 5.0, 189.0, 189.0]))
    assert np.abs(centre).max() < 0.05
