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


def test_sparsification_of_an_informative_a_constant_and_an_inverted_confidence():
    from plenodecode.depth.scores import sparsification

    rng = np.random.default_rng(3)
    gt = rng.uniform(-1, 1, (60, 60))
    est = gt.copy()
    bad = np.zeros(gt.shape, bool)
    bad[:, :18] = True                      # 30 % of the columns wrong by 0.5 px
    est[bad] += 0.5
    conf = np.where(bad, 0.2, 0.9)
    s = sparsification(est, gt, conf, border=0)
    np.testing.assert_allclose(s["fractions"], np.arange(1, 11) / 10)
    # the 70 % most confident are exact, then the wrong ones come in
    np.testing.assert_allclose(s["curve"][:7], 0.0, atol=1e-12)
    np.testing.assert_allclose(s["curve"][7:], 100 * (1 - np.array([0.7, 0.7, 0.7]) / [0.8, 0.9, 1.0]))
    assert s["random_area"] == pytest.approx(30.0)
    assert s["area"] == pytest.approx(np.mean(s["curve"]))
    assert s["area"] == pytest.approx(s["oracle_area"])      # this confidence is an oracle
    assert s["ratio"] == pytest.approx((100 / 8 + 200 / 9 + 30) / 10 / 30)
    # a constant confidence is a random ordering: every fraction has the overall error (ties averaged)
    flat = sparsification(est, gt, np.full(gt.shape, 0.5), border=0)
    np.testing.assert_allclose(flat["curve"], 30.0)
    assert flat["ratio"] == pytest.approx(1.0)
    # the inverted confidence puts the errors first
    inv = sparsification(est, gt, 1 - conf, border=0)
    assert inv["curve"][0] == pytest.approx(100.0) and inv["ratio"] > 2
    # MSE: the squared error x 100, the same ordering
    m = sparsification(est, gt, conf, border=0, error="mse")
    assert m["random_area"] == pytest.approx(100 * 0.3 * 0.25)
    assert m["curve"][-1] == pytest.approx(m["random_area"])


def test_sparsification_rejects_bad_arguments():
    from plenodecode.depth.scores import sparsification

    z = np.zeros((20, 20))
    with pytest.raises(ValueError, match="error"):
        sparsification(z, z, z, error="mae", border=0)
    with pytest.raises(ValueError, match="fractions"):
        sparsification(z, z, z, border=0, fractions=(0.5, 0.2))
    with pytest.raises(ValueError, match="confidence"):
        sparsification(z, z, np.zeros((10, 10)), border=0)
