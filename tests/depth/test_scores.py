"""Benchmark scores: BadPix and MSE x 100 as the HCI toolkit defines them."""

import numpy as np
import pytest

from plenodecode.depth.scores import badpix, mse100


def test_badpix_and_mse_follow_the_benchmark_definition():
    gt = np.zeros((40, 40), np.float32)
    est = gt.copy()
    est[15:25, 15:20] = 0.08          # 50 bad pixels inside the 10 x 10 evaluated area ...
    est[0:15, :] = 5.0                # ... and garbage in the border, which is ignored
    assert badpix(est, gt, border=15) == pytest.approx(50.0)
    assert badpix(est, gt, t=0.1, border=15) == 0.0
    assert mse100(est, gt, border=15) == pytest.approx(100 * 50 * 0.08 ** 2 / 100, rel=1e-5)
    assert badpix(est, gt, border=0) == pytest.approx(100 * (15 * 40 + 50) / 1600)


def test_metrics_mask_nonfinite_and_errors():
    gt = np.zeros((10, 10))
    gt[0, 0] = np.nan                   # not evaluated
    est = np.zeros((10, 10))
    est[5, 5] = np.nan                  # counts as bad, MSE infinite
    assert badpix(est, gt, border=0) == pytest.approx(100 / 99)
    assert mse100(est, gt, border=0) == np.inf
    mask = np.zeros((10, 10), bool)
    mask[:3] = True
    assert badpix(est, gt, border=0, mask=mask) == 0.0
    with pytest.raises(ValueError, match="same shape"):
        badpix(np.zeros((4, 4)), np.zeros((5, 5)))
    with pytest.raises(ValueError, match="border"):
        badpix(np.zeros((10, 10)), np.zeros((10, 10)), border=5)


def test_depth_edge_band_is_two_pixels_each_side_of_a_jump_and_ignores_slopes():
    from plenodecode.depth.scores import badpix_in_band, depth_edge_band

    gt = np.tile(np.linspace(0.0, 0.5, 30), (20, 1))   # a slant: 0.017 per px, no edge
    assert not depth_edge_band(gt).any()
    gt[:, 12:] += 1.0                                   # a vertical depth edge between columns 11 and 12
    gt[0, 0] = np.nan                                   # never makes an edge
    band = depth_edge_band(gt)
    cols = np.flatnonzero(band.any(axis=0))
    assert cols.tolist() == [10, 11, 12, 13] and band[:, 10:14].all()
    assert depth_edge_band(gt, radius=1.0).any(axis=0).nonzero()[0].tolist() == [11, 12]
    assert not depth_edge_band(gt, jump=1.5).any()
    est = gt.copy()
    est[:, 11] = gt[:, 12]          # edge fattening: one column takes the other side
    est[:, 25] += 0.5               # a far-away error, outside the band
    assert badpix_in_band(est, gt, border=0) == pytest.approx(25.0)     # 1 of the 4 band columns
    assert badpix(est, gt, border=0) == pytest.approx(100 * 40 / 599)    # gt[0, 0] is not evaluated
    assert np.isnan(badpix_in_band(est, np.zeros_like(gt), border=2))
    with pytest.raises(ValueError, match="radius"):
        depth_edge_band(gt, radius=0.2)
