"""Focal stacks, depth from focus and all-in-focus images on the analytic two-plane scene and a generated scene."""

import numpy as np
import pytest
import scipy.ndimage as ndi

from plenodecode.render import all_in_focus, focal_stack, refocus, sharpest_slope
from plenodecode.render.focalstack import depth_from_focus, focus_measure, refocus_per_pixel
from tests.render.test_refocus import psnr, two_planes


@pytest.mark.parametrize("method", ["shift-sum", "fourier-slice"])
def test_focal_stack_equals_single_refocus(method):
    lf, _ = two_planes(n=5, shape=(30, 36))
    slopes = [-0.6, 0.0, 0.45, 0.8]
    calls = []
    stack = focal_stack(lf, slopes, method=method, progress=lambda d, t: calls.append((d, t)))
    assert stack.shape == (4, 30, 36, 3) and stack.dtype == np.float32
    for i, s in enumerate(slopes):
        np.testing.assert_allclose(stack[i], refocus(lf, slope=s, method=method), atol=1e-6)
    assert calls and calls[-1] == (4, 4)


def test_focal_stack_rejects_empty_or_non_finite_slopes():
    lf, _ = two_planes(n=3, shape=(10, 12))
    for bad in ([], [0.1, np.nan]):
        with pytest.raises(ValueError, match="slopes"):
            focal_stack(lf, bad)


def _interior(disp, d, iterations=7):
    m = ndi.binary_erosion(disp == np.float32(d), iterations=iterations)
    m[:6], m[-6:], m[:, :6], m[:, -6:] = False, False, False, False
    return m


def test_depth_from_focus_recovers_both_planes():
    lf, disp = two_planes()
    slopes = np.linspace(-1.2, 1.4, 27)
    est, conf = depth_from_focus(focal_stack(lf, slopes), slopes)
    assert est.shape == disp.shape and conf.shape == disp.shape
    for d in (-0.6, 0.8):
        m = _interior(disp, d)
        assert np.median(np.abs(est[m] - d)) < 0.05
        assert np.mean(np.abs(est[m] - d) < 0.1) > 0.9


@pytest.mark.parametrize("method", ["shift-sum", "fourier-slice"])
def test_all_in_focus_is_sharp_on_both_planes(method):
    lf, disp = two_planes()
    centre = lf.centre_view()          # the pinhole view: sharp everywhere
    aif = all_in_focus(lf, slopes=np.linspace(-1.2, 1.4, 27), method="focal-stack", refocus_method=method)
    bg, fg = _interior(disp, -0.6), _interior(disp, 0.8)
    err_aif = [np.sqrt(np.mean((aif - centre)[m] ** 2)) for m in (bg, fg)]
    assert max(err_aif) < 0.015
    # each single photograph is blurred on one of the two planes
    for s in (-0.6, 0.8):
        photo = refocus(lf, slope=s)
        worst = max(np.sqrt(np.mean((photo - centre)[m] ** 2)) for m in (bg, fg))
        assert worst > 3 * max(err_aif)


def test_all_in_focus_from_a_depth_map():
    lf, disp = two_planes()
    aif = all_in_focus(lf, depth=disp)
    inner = np.zeros(disp.shape, bool)
    inner[6:-6, 6:-6] = True
    edges = ndi.binary_dilation(ndi.morphological_gradient(disp, size=3) > 0, iterations=6)
    assert psnr(aif[inner & ~edges], lf.centre_view()[inner & ~edges]) > 38.0
    with pytest.raises(ValueError, match="slope_map"):
        refocus_per_pixel(lf, disp[:10])
    with pytest.raises(ValueError, match="not both"):
        all_in_focus(lf, depth=disp, slopes=[0, 1])


def test_focus_measure_prefers_the_sharp_image():
    lf, _ = two_planes(n=5, shape=(30, 36))
    sharp = lf.centre_view()
    blurred = ndi.gaussian_filter(sharp, (1.5, 1.5, 0))
    assert np.all(focus_measure(sharp)[5:-5, 5:-5] > focus_measure(blurred)[5:-5, 5:-5])
    with pytest.raises(ValueError, match="window"):
        focus_measure(sharp, window=0)


def test_sharpest_slope_on_a_generated_scene():
    """Planes rendered by the synthetic generator (plenodecode.synthetic) with their exact disparity."""
    from plenodecode import synthetic
    from plenodecode.synthetic import Plane

    g = 0.3 / 26
    scene = [Plane(d0=-0.5, support=("all",), depth_order=2, texture_seed=1),
             Plane(d0=0.75, support=("rect", 6, 36, 40, 62), depth_order=0, texture_seed=2),
             Plane(d0=0.1 - g * 4, gradient=(0.0, g), support=("rect", 28, 4, 46, 30), depth_order=1, texture_seed=3)]
    sim = synthetic.simulate("illum-mini", noise=False, shape=(620, 900), scene=scene)
    lf = sim.ground_truth_lightfield()
    assert lf.weight is not None                   # weight-normalised refocusing is exercised
    regions = {"background": (slice(8, 18), slice(8, 28)), "front": (slice(14, 32), slice(42, 56)),
               "slanted": (slice(34, 42), slice(10, 24))}
    for name, region in regions.items():
        truth = float(sim.disparity[region].mean())
        methods = ("shift-sum", "fourier-slice") if name == "front" else ("shift-sum",)
        for method in methods:
            assert abs(sharpest_slope(lf, region=region, method=method) - truth) < 0.05, (name, method)
