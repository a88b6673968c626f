"""Confidence of the depth pipeline: noise, texture along the baselines, view agreement, and the confidence of
whole estimates against synthetic ground truth (featureless, textured and occluded regions)."""

import numpy as np
import pytest
from scipy import ndimage

from plenodecode.depth import estimate_depth
from plenodecode.depth.confidence import NOISE_TEXTURE, epipolar_texture, estimate_confidence, image_noise
from plenodecode.depth.scores import sparsification
from plenodecode.depth.views import Views
from plenodecode.types import LightField


def test_image_noise_ignores_smooth_content():
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:200, 0:240]
    smooth = 0.5 + 0.3 * np.sin(xx / 17.0) * np.cos(yy / 23.0)
    assert image_noise(smooth) < 0.002
    assert image_noise(smooth + rng.normal(0, 0.02, smooth.shape)) == pytest.approx(0.02, rel=0.05)


def _views(V, U, img):
    data = np.repeat(np.repeat(img[None, None, :, :, None], V, 0), U, 1).astype(np.float32)
    return Views(data, np.ones((V, U), np.float32), (V // 2, U // 2))


def test_epipolar_texture_follows_the_baselines():
    yy, xx = np.mgrid[0:64, 0:64].astype(np.float32)
    stripes = 0.5 + 0.2 * np.sin(xx / 2.0)            # varies along x only: d/dx = 0.1 cos(x / 2)
    inner = (slice(16, 48), slice(16, 48))
    row = epipolar_texture(stripes, _views(1, 5, stripes), 3.0)       # horizontal baselines see it all
    col = epipolar_texture(stripes, _views(5, 1, stripes), 3.0)       # vertical ones see nothing
    grid = epipolar_texture(stripes, _views(5, 5, stripes), 3.0)      # a square grid: half of it
    # mean of (0.1 cos)^2 = 0.005, less the Sobel's attenuation of a period of 4 pi px (about 3 %)
    assert np.mean(row[inner]) == pytest.approx(0.005, rel=0.1)
    assert np.max(np.abs(col[inner])) < 1e-6
    np.testing.assert_allclose(grid[inner], 0.5 * row[inner], rtol=1e-4, atol=1e-7)
    # white noise of unit variance: NOISE_TEXTURE
    noise = np.random.default_rng(1).normal(0, 1, (128, 128)).astype(np.float32)
    assert np.mean(epipolar_texture(noise, _views(5, 5, noise), 2.0)) == pytest.approx(NOISE_TEXTURE, rel=0.05)


def half_featureless_scene(n=7, size=64, d_back=-0.5, d_front=0.8, noise=0.004, seed=2):
    """A background plane, textured on its left half and uniform on its right, behind a textured square
    (centre-view rows and columns 22..42); the HCI convention view[v, u](y - d dv, x - d du) = centre(y, x)."""
    rng = np.random.default_rng(seed)
    pad = 16
    tex = ndimage.gaussian_filter(rng.uniform(0, 1, (2, size + 2 * pad, size + 2 * pad)), (0, 1.2, 1.2))
    tex = 0.2 + 0.6 * (tex - tex.min()) / (tex.max() - tex.min())
    back, front = tex[0].copy(), tex[1]
    back[:, pad + size // 2:] = 0.5
    c = n // 2
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    data = np.empty((n, n, size, size, 1), np.float32)
    sq = (22, 42)
    for v in range(n):
        for u in range(n):
            fy, fx = yy + d_front * (v - c), xx + d_front * (u - c)
            inside = (fy >= sq[0]) & (fy < sq[1]) & (fx >= sq[0]) & (fx < sq[1])
            b = ndimage.map_coordinates(back, [yy + d_back * (v - c) + pad, xx + d_back * (u - c) + pad], order=3,
                                        mode="nearest")
            f = ndimage.map_coordinates(front, [fy + pad, fx + pad], order=3, mode="nearest")
            data[v, u, :, :, 0] = np.where(inside, f, b) + rng.normal(0, noise, (size, size))
    square = (yy >= sq[0]) & (yy < sq[1]) & (xx >= sq[0]) & (xx < sq[1])
    gt = np.where(square, d_front, d_back).astype(np.float32)
    return LightField(data, None, "srgb", {"disparity_range": [-1.0, 1.3]}), gt, square


@pytest.fixture(scope="module")
def featureless():
    lf, gt, square = half_featureless_scene()
    return lf, gt, square, estimate_depth(lf, method="costvolume")


def test_confidence_is_low_on_featureless_areas_and_occlusions(featureless):
    lf, gt, square, dm = featureless
    conf = dm.confidence
    assert conf.dtype == np.float32 and 0.0 <= conf.min() and conf.max() <= 1.0
    near_square = ndimage.binary_dilation(square, iterations=4)
    border = np.zeros(conf.shape, bool)
    border[4:-4, 4:-4] = True
    flat = border & ~near_square & (np.arange(64) >= 38)[None, :]      # the uniform half of the background
    textured_back = border & ~near_square & (np.arange(64) < 26)[None, :]
    textured_front = ndimage.binary_erosion(square, iterations=4)
    # the occluded side of the square's left edge: background pixels hidden in the views on the right
    occluded = border & ~square & ndimage.binary_dilation(square, iterations=2) & (np.arange(64) < 32)[None, :]
    assert np.median(conf[flat]) < 0.05
    assert np.median(conf[textured_back]) > 0.4 and np.median(conf[textured_front]) > 0.4
    assert np.median(conf[occluded]) < 0.5 * np.median(conf[textured_back])
    # the ranking: the most confident pixels are the accurate ones
    s = sparsification(dm.disparity, gt, conf, border=4)
    assert s["ratio"] < 0.5


def test_confidence_of_the_generated_scene_ranks_its_errors():
    from plenodecode.synthetic import simulate

    sim = simulate("illum-mini", seed=1)
    dm = estimate_depth(sim.ground_truth_lightfield(), method="fast")
    for error in ("badpix", "mse"):
        assert sparsification(dm.disparity, sim.disparity, dm.confidence, border=5, error=error)["ratio"] < 0.5


def test_estimate_confidence_rejects_unknown_parameters(featureless):
    from plenodecode.depth.views import prepare_views

    lf, _, _, dm = featureless
    views = prepare_views(lf)
    with pytest.raises(ValueError, match="k_textur"):
        estimate_confidence(views, dm.confidence, dm.disparity, k_textur=1.0)


def test_cost_consistency_against_exact_parabolas():
    """Cost curves ``a (d - d0)^2 + F`` per pixel: the matching winner is ``d0`` (the parabola fit is exact),
    ``kappa = 2 a`` and ``C_min = a r^2 + F`` (``r`` the distance of ``d0`` to its nearest label), so
    ``c_cons = exp(-(d - d0)^2 / (tau^2 + C_min / (2 a))) * P^p_raw``."""
    from plenodecode.depth.aggregation import winner
    from plenodecode.depth.confidence import CONFIDENCE_DEFAULTS, cost_consistency

    rng = np.random.default_rng(3)
    labels = np.linspace(-1.0, 1.0, 41)                            # step 0.05
    d0 = rng.uniform(-0.5, 0.5, (20, 30)).astype(np.float32)
    a = 40.0
    floor = np.where(np.arange(30)[None, :] < 15, 0.0, 1.6).astype(np.float32)   # right half: C_min / kappa ~ 0.02
    cost = (a * (labels[None, None, :] - d0[..., None]) ** 2 + floor[..., None]).astype(np.float32)
    tau, kf, pr = (CONFIDENCE_DEFAULTS[k] for k in ("tau", "k_floor", "p_raw"))
    peak = winner(cost, labels)[1]
    r = np.abs(labels[np.argmin(cost, axis=-1)] - d0)
    for offset in (0.0, 0.05, 0.1):
        got = cost_consistency(cost, labels, d0 + offset, tau=tau, k_floor=kf, p_raw=pr)
        want = np.exp(-offset ** 2 / (tau ** 2 + kf * (a * r * r + floor) / (2 * a))) * peak ** pr
        np.testing.assert_allclose(got, want, rtol=2e-3, atol=1e-5)
    # on the clean left half a 0.1 px disagreement is ruled out, on the floored right half it is tolerated
    off = cost_consistency(cost, labels, d0 + 0.1, tau=tau, k_floor=kf, p_raw=pr)
    on = cost_consistency(cost, labels, d0, tau=tau, k_floor=kf, p_raw=pr)
    assert np.max(off[:, :15] / on[:, :15]) < 0.04
    assert np.min(off[:, 15:] / on[:, 15:]) > 0.6


def test_competitor_ratio_at_a_depth_edge():
    """Two surfaces, left 0.5 and right -0.5 px; every pixel's cost has minima ``m_own`` at its own disparity
    and ``m_other`` at the other's.  On the two columns along the edge c_comp = (m_other - m_own) / m_other
    (with the costs at the exact labels), elsewhere 1."""
    from plenodecode.depth.confidence import competitor_ratio

    labels = np.linspace(-1.0, 1.0, 21)                            # 0.5 and -0.5 are labels
    Y, X = 8, 12
    disp = np.where(np.arange(X)[None, :] < 6, 0.5, -0.5).astype(np.float32) * np.ones((Y, 1), np.float32)
    own = np.full((Y, X), 0.2, np.float32)
    other = np.full((Y, X), 1.0, np.float32)
    other[:, 5] = 0.25                                              # the left edge column: nearly a tie
    cost = np.full((Y, X, 21), 3.0, np.float32)
    k_own = np.rint((disp - labels[0]) / 0.1).astype(int)
    k_other = np.rint((-disp - labels[0]) / 0.1).astype(int)
    np.put_along_axis(cost, k_own[..., None], own[..., None], -1)
    np.put_along_axis(cost, k_other[..., None], other[..., None], -1)
    c = competitor_ratio(cost, labels, disp, jump=0.1)
    np.testing.assert_allclose(c[:, 5], (0.25 - 0.2) / 0.25, rtol=1e-4)
    np.testing.assert_allclose(c[:, 6], (1.0 - 0.2) / 1.0, rtol=1e-4)
    assert np.all(c[:, :5] == 1.0) and np.all(c[:, 7:] == 1.0)
    # no depth edge above the jump: all 1
    assert np.all(competitor_ratio(cost, labels, disp, jump=1.5) == 1.0)
