"""All-in-focus images on a generated scene with occlusions: the depth-guided default against the focal-stack
method and the centre view, scored against the generator's noise-free centre view."""

import numpy as np
import pytest

from bench.bench_allinfocus import edge_band, psnr
from plenodecode.render import ALL_IN_FOCUS_METHODS, all_in_focus
from plenodecode.render.allinfocus import pair_noise, render_visible


@pytest.fixture(scope="module")
def noisy_scene():
    """The illum-mini default scene (background, slanted plane, front disk; 15 x 15 x 51 x 72): its ideal
    light field plus Gaussian noise (sigma 0.02), the noise-free centre view, the true disparity, the masks
    (5 px border excluded; the band within 3 px of a depth edge)."""
    from plenodecode.synthetic import simulate

    sim = simulate("illum-mini", seed=3, noise=False, shape=(620, 900))
    ideal = sim.ground_truth_lightfield()
    lf = ideal.replace(data=ideal.data + np.random.default_rng(0).normal(0, 0.02, ideal.shape).astype(np.float32))
    inner = np.zeros(sim.disparity.shape, bool)
    inner[5:-5, 5:-5] = True
    return lf, ideal.centre_view(), sim.disparity, inner, inner & edge_band(sim.disparity)


def test_depth_guided_has_no_halo_and_beats_the_centre_view(noisy_scene):
    # measured (seeds 0-2 of the noise): band PSNR centre 33.9, focal-stack 29.4, depth-guided 36.7-37.1 dB;
    # overall centre 34.0, focal-stack 32.1, depth-guided 39.7-40.0 dB
    lf, truth, _, inner, band = noisy_scene
    new = all_in_focus(lf)
    old = all_in_focus(lf, method="focal-stack")
    centre = lf.centre_view()
    assert new.shape == centre.shape and new.dtype == np.float32
    assert psnr(new, truth, band) >= psnr(old, truth, band) + 5.0
    assert psnr(new, truth, band) >= psnr(centre, truth, band)
    assert psnr(new, truth, inner) >= psnr(centre, truth, inner) - 0.1


def test_visibility_alone_and_a_given_depth(noisy_scene):
    lf, truth, disparity, inner, band = noisy_scene
    everyone = all_in_focus(lf, method="focal-stack", depth=disparity)         # all views at the true disparity
    visible = render_visible(lf, disparity, consistency=0.0)                  # the views that see each pixel
    assert psnr(visible, truth, band) > psnr(everyone, truth, band) + 1.0
    np.testing.assert_array_equal(all_in_focus(lf, depth=disparity), render_visible(lf, disparity))
    # the noise of a view difference where the disparity is right: sqrt(2) x 0.02
    assert pair_noise(lf, disparity) == pytest.approx(0.02 * np.sqrt(2), rel=0.1)


def test_few_visible_views_or_low_confidence_give_the_centre_view(noisy_scene):
    lf, _, disparity, _, _ = noisy_scene
    centre = lf.centre_view()
    np.testing.assert_array_equal(render_visible(lf, disparity, min_visible=1.01), centre)
    low = np.zeros(disparity.shape, np.float32)
    np.testing.assert_array_equal(render_visible(lf, disparity, confidence=low, min_confidence=0.5), centre)


def test_methods_by_name():
    from tests.render.test_refocus import two_planes

    lf, disp = two_planes(n=3, shape=(20, 24))
    assert set(ALL_IN_FOCUS_METHODS) == {"depth", "focal-stack"}
    with pytest.raises(ValueError, match="'depth', 'focal-stack'"):
        all_in_focus(lf, method="sharpest")
    with pytest.raises(ValueError, match="method='focal-stack'"):
        all_in_focus(lf, slopes=[0.0, 0.5])
    with pytest.raises(ValueError, match="not both"):
        all_in_focus(lf, method="focal-stack", depth=disp, slopes=[0.0, 0.5])
    with pytest.warns(DeprecationWarning, match="refocus_method='shift-sum'"):
        before = all_in_focus(lf, method="shift-sum", slopes=[-0.5, 0.0, 0.5])
    np.testing.assert_array_equal(before, all_in_focus(lf, method="focal-stack", slopes=[-0.5, 0.0, 0.5]))
    with pytest.raises(ValueError, match="disparity"):
        render_visible(lf, disp[:5])
