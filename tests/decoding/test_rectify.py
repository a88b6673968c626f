"""Rectification (plenodecode.decoding.rectify) against light fields whose every sample is a known function
of its ray."""

from __future__ import annotations

import numpy as np
import pytest

from plenodecode.decoding.rectify import centre_sample, decoded_shape, rectified_intrinsics, rectify
from plenodecode.errors import CalibrationError, GeometryMismatchError
from plenodecode.raymodel import GeometricCalibration, intrinsics_from_entries
from plenodecode.depth.metric import disparity_to_depth
from plenodecode.raymodel import pose_transform
from plenodecode.raymodel import Board
from plenodecode.synthetic.checkerboard import board_corners, board_lightfield
from plenodecode.types import LightField
from tests.conftest import shared_path
from tests.geometry_scenes import corner_disparities, detect_corners, line_residual_rms, skewed_calibration

SHAPE = (5, 5, 40, 48)
#: an F01-like camera, x and y slightly different (non-square samples), centre sample on the axis
ENTRIES = (3.5e-4, -5.4e-5, 0.0, 3.2e-4, -6.4e-5, 0.0, -1.4e-3, 1.9e-3, 0.0, -1.25e-3, 1.8e-3, 0.0)
DISTORTION = (2.0, 0.0, 0.0, 0.0, 0.0)


def _calibration(distortion=DISTORTION, entries=ENTRIES, shape=SHAPE) -> GeometricCalibration:
    h = intrinsics_from_entries(entries)
    h[:4, 4] = -h[:4, :4] @ centre_sample(shape)          # the centre sample sees the optical axis
    return GeometricCalibration(h, distortion, shape, info={"source": "test"})


def _scene(rays: np.ndarray) -> np.ndarray:
    """A smooth radiance of rays (..., 4): varies along s, t, u and v (period of several samples)."""
    s, t, u, v = np.moveaxis(rays, -1, 0)
    return (0.5 + 0.2 * np.sin(s / 2.5e-3) * np.cos(t / 3e-3) + 0.2 * np.sin(u / 0.02 + 0.3)
            * np.cos(v / 0.025)).astype(np.float32)


def _sample_grid(shape):
    v, u, y, x = shape
    jj, ii, ll, kk = np.meshgrid(np.arange(v), np.arange(u), np.arange(y), np.arange(x), indexing="ij")
    return np.stack([ii, jj, kk, ll], axis=-1).astype(np.float64)        # (V, U, Y, X, 4) (i, j, k, l)


def _recorded(cal: GeometricCalibration) -> LightField:
    """What the calibrated camera records: sample n holds the scene's radiance along its ideal ray."""
    data = _scene(cal.rays(_sample_grid(cal.lf_shape)))[..., None]
    return LightField(data=data, weight=np.ones(cal.lf_shape, np.float32), colour="camera")


def test_rectified_intrinsics_square_and_centred():
    cal = _calibration()
    h = cal.intrinsics
    rect = rectified_intrinsics(cal)
    for (r1, c1), (r2, c2) in (((0, 0), (1, 1)), ((0, 2), (1, 3)), ((2, 0), (3, 1)), ((2, 2), (3, 3))):
        assert rect[r1, c1] == rect[r2, c2] == pytest.approx(0.5 * (h[r1, c1] + h[r2, c2]), rel=1e-15)
    n_c = centre_sample(SHAPE)
    np.testing.assert_allclose(rect[:4, :4] @ n_c + rect[:4, 4], cal.rays(n_c), atol=1e-15)
    mirrored = h.copy()
    mirrored[1, 3] *= -1
    mirrored[3, 3] *= -1
    with pytest.raises(ValueError, match="opposite signs"):
        rectified_intrinsics(GeometricCalibration(mirrored, None, SHAPE))


def test_rectify_resamples_onto_the_target_rays():
    """Every rectified sample holds the radiance of its target ray H_rect n (where that ray was recorded)."""
    cal = _calibration()
    lf = _recorded(cal)
    out = rectify(lf, cal)
    rect = rectified_intrinsics(cal)
    n = _sample_grid(SHAPE)
    expected = _scene(n @ rect[:4, :4].T + rect[:4, 4])
    got = out.data[..., 0]
    inside = out.weight > 0.999
    assert inside[1:-1, 1:-1].mean() > 0.9          # the inner views are recorded almost everywhere
    err = np.abs(got - expected)[inside]
    assert err.max() < 0.02 and err.mean() < 2e-3
    # without rectification the same comparison is off by the distortion and the non-square samples
    assert np.abs(lf.data[..., 0] - expected)[inside].mean() > 10 * err.mean()
    assert out.geometry.ray_model == {"intrinsics": rect.tolist(), "distortion": [0.0] * 5, "rectified": True,
                                      "calibration": "test"}
    assert out.provenance["rectified"]["target_intrinsics"] == rect.tolist()
    assert np.all(out.data[out.weight == 0] == 0)
    with pytest.raises(ValueError, match="already rectified"):
        rectify(out, cal)


def test_rectify_identity_when_already_square_and_undistorted():
    square = (3.4e-4, -6e-5, 0.0, 3.4e-4, -6e-5, 0.0, -1.3e-3, 1.85e-3, 0.0, -1.3e-3, 1.85e-3, 0.0)
    cal = _calibration(distortion=None, entries=square)
    lf = _recorded(cal)
    out = rectify(lf, cal)
    np.testing.assert_allclose(out.data, lf.data, atol=1e-6)
    np.testing.assert_allclose(out.weight, 1.0, atol=1e-6)


def test_rectify_weights_missing_samples_out():
    """A missing sample (weight 0, NaN data) does not bleed into its neighbours."""
    cal = _calibration(distortion=None)
    lf = _recorded(cal)
    data, weight = lf.data.copy(), lf.weight.copy()
    data[2, 2, 20, 24] = np.nan
    weight[2, 2, 20, 24] = 0.0
    out = rectify(lf.replace(data=data, weight=weight), cal)
    assert np.all(np.isfinite(out.data))
    clean = rectify(lf, cal)
    near = out.weight > 0.5
    np.testing.assert_allclose(out.data[near], clean.data[near], atol=0.03)


def test_rectify_refuses_another_shape():
    cal = _calibration()
    lf = _recorded(_calibration(shape=(5, 5, 40, 40)))
    with pytest.raises(GeometryMismatchError, match="5x5x40x48") as info:
        rectify(lf, cal)
    assert isinstance(info.value, CalibrationError)


def test_decode_with_geometry_rectifies_and_refuses_another_shape():
    from plenodecode.decoding import decode
    from plenodecode.synthetic import simulate

    sim = simulate(preset="square", seed=3, noise=False)
    plain = decode(sim.raw, sim.grid, white=sim.white)
    shape = decoded_shape(sim.grid)
    assert shape == plain.shape[:4]
    cal = _calibration(shape=shape)
    rectified = decode(sim.raw, sim.grid, white=sim.white, geometry=cal)
    expected = rectify(plain, cal)
    np.testing.assert_array_equal(rectified.data, expected.data)
    assert rectified.geometry.ray_model["rectified"]
    with pytest.raises(GeometryMismatchError):
        decode(sim.raw, sim.grid, white=sim.white, geometry=_calibration(shape=(3, 3, *shape[2:])))


# ------------------------------------------------------------------------------------- checkerboards
@pytest.fixture(scope="module")
def tilted_board():
    """A tilted board through the skewed, strongly distorted camera: (calibration, board, pose, lf, rectified)."""
    cal = skewed_calibration()
    board = Board(7, 8, 0.0055)
    pose = [-0.019, -0.016, 0.30, 0.15, -0.2, 0.03]
    lf = board_lightfield(cal, board, pose, supersample=2)
    return cal, board, pose, lf, rectify(lf, cal)


def test_rectified_board_corners_lie_on_straight_lines(tilted_board):
    cal, board, pose, lf, out = tilted_board
    before, after = [], []
    for j, i in ((2, 2), (1, 1), (1, 3), (3, 1), (3, 3), (2, 1), (1, 2)):
        assert out.weight[j, i].min() > 0.99
        before.append(line_residual_rms(detect_corners(lf.data[j, i], board)))
        after.append(line_residual_rms(detect_corners(out.data[j, i], board)))
    assert max(after) < 0.05                              # issue 22: residual below 0.05 px
    assert min(before) > 0.08                             # the distorted lines bend (measured 0.115-0.12 px)


def test_rectified_board_disparity_matches_the_pose(tilted_board):
    """Each corner's disparity across views is the one its depth in the pose gives through H_rect,
    d = (a + c z) / (b + e z), and converts back to that depth within 1 %."""
    cal, board, pose, lf, out = tilted_board
    measured = corner_disparities(out.data, board, (-1, 0, 1))
    z = pose_transform(pose, board.corners())[:, 2]
    rect = out.geometry.ray_model["intrinsics"]
    a, b, c, e = rect[0][0], rect[0][2], rect[2][0], rect[2][2]
    expected = (a + c * z) / (b + e * z)
    error = measured - expected                            # corner detection noise: about 0.01 px
    assert np.sqrt(np.mean(error ** 2)) < 0.01 and np.abs(error).max() < 0.03
    depth = disparity_to_depth(measured[None, :], out)[0]
    assert np.abs(depth / z - 1.0).max() < 0.01


def test_toolbox_calinfo_rectifies_a_generated_f01_board():
    """The real LFToolbox calibration (F01) read from CalInfo.json: a board rendered with its H and distortion
    (on a crop of its 11 x 11 x 379 x 379 light fields: views 3-7, spatial 140-239, the same rays) lies on
    straight lines after rectification, where each corner is where the pinhole model H_rect puts it."""
    from plenodecode.io.calinfo import load_geometric_calibration

    full = load_geometric_calibration(shared_path("lytro-f01-gridmodel", "CalInfo.json"))
    assert full.lf_shape == (11, 11, 379, 379)
    first = np.array([3, 3, 140, 140], np.float64)              # crop origin (i, j, k, l)
    h = full.intrinsics.copy()
    h[:4, 4] += h[:4, :4] @ first                                # crop sample n -> full sample n + first
    cal = GeometricCalibration(h, full.distortion, (5, 5, 100, 100), info={"source": "CalInfo.json crop"})
    np.testing.assert_allclose(cal.rays(np.array([1.0, 2.0, 30.0, 70.0])),
                               full.rays(np.array([4.0, 5.0, 170.0, 210.0])), atol=1e-15)
    board = Board(8, 8, 0.0032)
    pose = [-0.0112, -0.0112, 0.2, 0.12, -0.15, 0.02]
    lf = board_lightfield(cal, board, pose, supersample=2)
    out = rectify(lf, cal)
    truth = board_corners(np.asarray(out.geometry.ray_model["intrinsics"]), board, pose, cal.lf_shape)
    for j, i in ((2, 2), (1, 1), (3, 3), (1, 3)):
        found = detect_corners(out.data[j, i], board)
        assert line_residual_rms(found) < 0.05
        assert np.sqrt(np.mean((found.reshape(-1, 2) - truth[j, i]) ** 2)) < 0.1
