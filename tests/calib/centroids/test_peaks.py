"""Window maxima and window contrast (:mod:`plenodecode.calib.centroids.peaks`) against brute force."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.lib.stride_tricks import sliding_window_view

from plenodecode.calib.centroids.peaks import window_contrast, window_contrast_reference, window_maxima


def _window_extreme(g: np.ndarray, half: int, fn, fill: float) -> np.ndarray:
    """Maximum or minimum of each pixel's (2 half + 1)^2 window clipped to the image, by brute force."""
    padded = np.pad(g.astype(np.float64), half, constant_values=fill)
    return fn(sliding_window_view(padded, (2 * half + 1, 2 * half + 1)), axis=(2, 3))


@pytest.mark.parametrize("half,margin", [(1, 0), (3, 2), (5, 7), (4, 40)])
def test_window_maxima_are_the_pixels_equal_to_their_window_maximum(half, margin):
    rng = np.random.default_rng(half)
    g = rng.integers(0, 12, (47, 61)).astype(np.float32)        # few levels: many ties, which count as maxima
    want = g >= _window_extreme(g, half, np.max, -np.inf)
    want[:margin] = want[g.shape[0] - margin:] = False
    want[:, :margin] = want[:, g.shape[1] - margin:] = False
    got = window_maxima(g, half, margin)
    assert got.dtype == bool
    np.testing.assert_array_equal(got, want)
    assert got.any() == (margin < 23)


@pytest.mark.parametrize("half", [1, 4])
def test_window_contrast_kernel_matches_the_opencv_reference_and_brute_force(half):
    rng = np.random.default_rng(10 + half)
    g = rng.random((53, 64)).astype(np.float32)
    rr = np.r_[0, 52, 0, 52, rng.integers(0, 53, 200)]
    cc = np.r_[0, 63, 63, 0, rng.integers(0, 64, 200)]
    want = (g - _window_extreme(g, half, np.min, np.inf))[rr, cc]
    fast = window_contrast(g, rr, cc, half)
    assert fast.dtype == np.float32 and fast.shape == rr.shape
    np.testing.assert_array_equal(fast, want.astype(np.float32))
    np.testing.assert_array_equal(window_contrast_reference(g, rr, cc, half), fast)
