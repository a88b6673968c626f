"""The 'focus' depth method (depth from focus over a focal stack) through estimate_depth."""

import numpy as np
import pytest
import scipy.ndimage as ndi

from plenodecode.depth import DepthMap, estimate_depth


def _interior(gt, d, iterations=7, border=6):
    """Pixels of the plane of disparity ``d`` farther than ``iterations`` px from its edge (the focus
    measure's 9 x 9 window and the 5 x 5 median blur the map across depth edges) and from the border."""
    m = ndi.binary_erosion(gt == np.float32(d), iterations=iterations)
    m[:border], m[-border:], m[:, :border], m[:, -border:] = False, False, False, False
    return m


def test_focus_method_recovers_both_planes(planes):
    lf, gt = planes                                     # background -0.6, square in front at 1.0
    dm = estimate_depth(lf, method="focus")
    assert isinstance(dm, DepthMap) and dm.method == "focus" and dm.disparity.dtype == np.float32
    assert dm.params["disparity_range_source"] == "metadata"
    for d in (-0.6, 1.0):
        err = np.abs(dm.disparity - d)[_interior(gt, d)]
        assert err.size > 100
        # measured median 0.003 px (background) and 0.0 (square), every pixel within 0.1
        assert np.median(err) < 0.05 and np.mean(err < 0.1) > 0.9, d
    assert 0.0 <= dm.confidence.min() and dm.confidence.max() < 1.0


def test_focus_method_parameters(planes):
    lf, _ = planes
    with pytest.raises(ValueError, match="unknown parameter"):
        estimate_depth(lf, method="focus", paths=4)
    dm = estimate_depth(lf, method="focus", disparity_range=(-1.0, 1.2), label_step=0.2, smooth=1)
    assert dm.params["disparity_range"] == [-1.0, 1.2] and dm.params["disparity_range_source"] == "argument"
    assert dm.params["n_labels"] == 16                  # [-1.4, 1.6] in 15 steps of 0.2
