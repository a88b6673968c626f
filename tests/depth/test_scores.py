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
