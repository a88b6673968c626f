"""Photographs above the lenslet resolution (render.superres): the 2x photograph against the generator's exact 2x
ground truth, compared with bicubic upsampling of the 1x photograph; the fusion's kernel scale and normalisation."""

import functools

import numpy as np
import pytest

import plenodecode.synthetic as syn
from bench.bench_superres import bicubic_upsample, psnr
from plenodecode.decoding import decode
from plenodecode.imaging import interpolation_taps
from plenodecode.render import refocus, shift_sum
from plenodecode.render.superres import KEYS_A, fuse_views, kernel_scales, phase_gap, scaled_keys_taps
from plenodecode.types import LightField


@functools.lru_cache(maxsize=8)
def chart(d, preset="f01-mini", shape=(320, 400), decoded=False):
    """(light field, 2x truth) of the generator's dot chart at disparity d, noise-free; cached, do not modify."""
    grid = syn.make_grid(preset, shape=shape)
    smp = grid.decoded_sampling()
    sim = syn.simulate(preset, noise=False, shape=shape, scene=syn.dot_chart(int(smp["Y"]), int(smp["X"]), d, seed=1))
    lf = decode(sim.raw, sim.grid, white=sim.white) if decoded else sim.ground_truth_lightfield()
    return lf, sim.ground_truth_photograph(2)


def gains(d, **kw):
    """PSNR gain (dB) over bicubic upsampling of the 1x photograph: (fused, per-view interpolation)."""
    lf, truth = chart(d, **kw)
    base = psnr(bicubic_upsample(refocus(lf, slope=d), 2), truth)
    fused = psnr(refocus(lf, slope=d, upsample=2), truth)
    per_view = psnr(shift_sum(lf, d, upsample=2)[0], truth)
    return fused - base, per_view - base


@pytest.mark.parametrize("d", [0.5, -0.5])
def test_fused_2x_photograph_beats_bicubic_at_half_a_pixel_per_view(d):
    # ground-truth light field: the views sample the half-pixel positions exactly (bicubic 42.2 dB, fused > 140 dB);
    # interpolating each view and averaging (the previous upsample) gains 3.7 dB
    fused, per_view = gains(d)
    assert fused >= 6.0
    assert per_view < 6.0


def test_fused_2x_photograph_beats_bicubic_on_a_decoded_raw():
    # the real path: a square-lattice raw decoded with its white image (bicubic 53.1 dB, fused +7.7 dB,
    # per-view interpolation +1.7 dB)
    fused, per_view = gains(0.5, preset="square", shape=(440, 550), decoded=True)
    assert fused >= 4.0
    assert per_view < 4.0


def test_fused_2x_photograph_at_slope_0_is_bicubic():
    # every view samples the same points: nothing to fuse, the result is bicubic upsampling (OpenCV's kernel)
    lf, truth = chart(0.0)
    fused, _ = gains(0.0)
    assert fused >= -0.2
    inner = (slice(8, -8), slice(8, -8))
    np.testing.assert_allclose(refocus(lf, slope=0.0, upsample=2)[inner],
                               bicubic_upsample(refocus(lf, slope=0.0), 2)[inner], atol=1e-5)


def test_ground_truth_photograph_is_the_centre_view_and_finer_samples_lie_between():
    sim = syn.simulate("f01-mini", noise=False, shape=(96, 128), scene=[syn.Plane(0.3, texture_seed=3)])
    lf = sim.ground_truth_lightfield(n_views=3)
    one, two = sim.ground_truth_photograph(1), sim.ground_truth_photograph(2)
    np.testing.assert_array_equal(one, lf.data[1, 1])
    np.testing.assert_array_equal(two[::2, ::2], one)
    assert two.shape == (2 * one.shape[0], 2 * one.shape[1], 3)
    with pytest.raises(ValueError, match="scale"):
        sim.ground_truth_photograph(0)


def test_kernel_scale_is_the_phase_gap_of_the_views():
    assert phase_gap(np.array([0.0, 0.0])) == 1.0
    assert phase_gap(0.5 * np.arange(-2, 3)) == pytest.approx(0.5)
    assert phase_gap(0.3 * np.arange(-4, 5)) == pytest.approx(0.2)
    assert phase_gap(0.05 * np.arange(-4, 5)) == pytest.approx(0.6)
    lf = LightField(np.zeros((9, 9, 8, 8, 1), np.float32))
    h = kernel_scales(lf, np.array([0.0, 0.05, 0.3, 0.5]), 2)
    np.testing.assert_allclose(h, [[1, 1], [0.6, 0.6], [0.5, 0.5], [0.5, 0.5]])
    # views outside the aperture do not count: the centre row and column alone sample one phase
    cross = np.zeros((9, 9), bool)
    cross[4, 4] = True
    np.testing.assert_allclose(kernel_scales(lf, np.array([0.5]), 2, cross), [[1, 1]])


def test_scaled_keys_taps():
    t = np.array([-1.3, 0.0, 0.25, 2.5])
    first, w = scaled_keys_taps(t, 1.0)
    # h = 1: Keys interpolation (weights sum to 1, exact at integers), OpenCV's a
    np.testing.assert_allclose(w.sum(-1), 1.0, atol=1e-6)
    np.testing.assert_allclose(w[1], [0, 1, 0, 0], atol=1e-7)
    np.testing.assert_array_equal(first, interpolation_taps(t, "cubic")[0])
    assert KEYS_A == -0.75
    # h = 1/2: the kernel vanishes at 1/2 and 1 lenslet px (Keys at 1 and 2), so at a half-integer position no
    # integer sample contributes (other views sample it), and at 1/4 only the two nearest do
    _, w = scaled_keys_taps(np.array([0.5]), 0.5)
    np.testing.assert_allclose(w, 0.0, atol=1e-7)
    _, w = scaled_keys_taps(np.array([0.25]), 0.5)
    np.testing.assert_allclose(w[0, [0, 3]], 0.0, atol=1e-7)


def test_fusion_is_weight_normalised():
    rng = np.random.default_rng(5)
    data = rng.random((5, 5, 12, 14, 3), dtype=np.float32)
    plain = LightField(data)
    ones = LightField(data, np.full((5, 5, 12, 14), 0.7, np.float32))
    for s in (0.0, 0.3, -0.5):
        np.testing.assert_allclose(fuse_views(ones, s)[0], fuse_views(plain, s)[0], atol=2e-6)
    # a constant light field stays constant, whatever the weights and the aperture
    const = LightField(np.full((5, 5, 12, 14, 1), 0.25, np.float32), rng.random((5, 5, 12, 14), dtype=np.float32))
    for s in (0.2, 0.5, 1.3):
        out = fuse_views(const, [s, -s], upsample=3, aperture=0.8)
        assert out.shape == (2, 36, 42, 1)
        np.testing.assert_allclose(out, 0.25, atol=1e-6)


def test_refocus_upsample_uses_the_fusion():
    lf, _ = chart(0.3)
    np.testing.assert_array_equal(refocus(lf, slope=0.3, upsample=2), fuse_views(lf, 0.3)[0])
    np.testing.assert_array_equal(refocus(lf, slope=0.3, upsample=1), shift_sum(lf, 0.3)[0])
    with pytest.raises(ValueError, match="interp"):
        refocus(lf, slope=0.3, upsample=2, interp="linear")
    with pytest.raises(ValueError, match="upsample"):
        fuse_views(lf, 0.3, upsample=1.5)


def test_fused_2x_photograph_has_no_pattern_out_of_focus():
    # default scene refocused on its front disk (0.9): the background (d = -0.5) is out of focus; each output phase
    # of the plain fusion averages a different subset of views there (about 1600x the bicubic's energy at the 2x
    # Nyquist frequencies); the photo-consistency gain drops that detail (ratio ~1.5)
    from bench.bench_superres import checker_ratio

    sim = syn.simulate("f01-mini", noise=False, shape=(656, 656))
    lf = sim.ground_truth_lightfield()
    assert checker_ratio(lf, sim.disparity, 0.9) < 2.0
    assert checker_ratio(lf, sim.disparity, -0.5) < 2.0
