"""Refocusing the real HCI benchmark scene 'antinous' against its ground-truth disparity (skipped without data)."""

import functools

import numpy as np
import pytest

from tests.conftest import shared_path
from plenodecode.io.hci import read_hci
from plenodecode.render import FourierRefocuser, refocus, sharpest_slope
from plenodecode.render.focalstack import gradient_energy

pytestmark = pytest.mark.realdata


@functools.lru_cache(maxsize=1)
def scene():
    return read_hci(shared_path("hci-antinous"))


def test_view_interpolation_at_integers_and_slope_zero_mean():
    sc = scene()
    from plenodecode.render import perspective

    np.testing.assert_array_equal(perspective(sc.lightfield, 2.0, 7.0, interp="cubic"), sc.lightfield.data[2, 7])
    np.testing.assert_allclose(refocus(sc.lightfield, slope=0.0), sc.lightfield.data.mean((0, 1)), atol=1e-6)


def planar_regions(disp, texture, size=24, max_range=0.15):
    """The most textured ``size`` px patch per disparity band whose ground truth (with a 6 px margin) varies
    by less than ``max_range``: regions where 'the' disparity is well defined."""
    best = {}
    for y in range(40, disp.shape[0] - 40 - size, 8):
        for x in range(40, disp.shape[1] - 40 - size, 8):
            dd = disp[y - 6:y + size + 6, x - 6:x + size + 6]
            if dd.max() - dd.min() >= max_range:
                continue
            band = int(np.floor(disp[y:y + size, x:x + size].mean()))
            score = texture[y:y + size, x:x + size].mean()
            if band not in best or score > best[band][0]:
                best[band] = (score, (slice(y, y + size), slice(x, x + size)))
    return [r for _, r in best.values()]


@pytest.mark.parametrize("method", ["shift-sum", "fourier-slice"])
def test_sharpest_slope_is_the_ground_truth_disparity(method):
    sc = scene()
    lf, disp = sc.lightfield, sc.disparity
    regions = planar_regions(disp, gradient_energy(lf.centre_view()))
    assert len(regions) >= 2                       # the background wall (~ -2.8) and the statue (~ +1.3)
    truths = [float(disp[r].mean()) for r in regions]
    assert max(truths) - min(truths) > 3.0
    for r, truth in zip(regions, truths):
        s = sharpest_slope(lf, region=r, slopes=np.linspace(-3.5, 3.0, 27), method=method)
        assert abs(s - truth) < 0.05, (r, truth, s)


def test_fourier_slice_agrees_with_shift_sum_over_the_scene_range():
    lf = scene().lightfield
    ref = FourierRefocuser(lf, max_slope=3.2)
    for s in (-3.0, -1.4, 0.0, 0.6, 1.3, 2.6):
        a, b = ref.photograph(s), refocus(lf, slope=s)
        inner = (slice(15, -15), slice(15, -15))
        psnr = 10 * np.log10(1.0 / np.mean((a[inner].astype(np.float64) - b[inner]) ** 2))
        assert psnr >= 35.0, (s, psnr)
