"""Sub-pixel centre estimators (:mod:`plenodecode.calib.centroids.subpixel`)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from plenodecode.calib import centroids as C
from plenodecode.synthetic import simulate_white


@pytest.mark.parametrize("method,tol", [("dog", 0.03), ("parabolic", 0.08)])
def test_subpixel_centres_of_single_lenses(method, tol):
    """Per-lens accuracy (noise-free white, interior lenses): DoG ~0.01 px, parabola ~0.03 px."""
    white, truth = simulate_white("f01-mini", seed=0, rotation=0.004, offset=(0.3, 0.6), noise=False,
                                  shape=(300, 340))
    p = truth.pitch
    img = C.devignette(C.flatten_white(white), p)
    peaks, contrast = C.detect_peaks(img, p)
    cen, ok = C.refine_peaks(img, peaks, p, method=method)
    cen = cen[ok]
    t = truth.centres()
    d, idx = cKDTree(t).query(cen)
    tt = t[idx]
    H, W = white.shape
    inner = (tt[:, 0] > 1.5 * p) & (tt[:, 1] > 1.5 * p) & (tt[:, 0] < H - 1.5 * p) & (tt[:, 1] < W - 1.5 * p)
    assert inner.sum() > 500
    assert np.sqrt(np.mean(d[inner] ** 2)) < tol
    with pytest.raises(ValueError, match="method"):
        C.refine_peaks(img, peaks, p, method="centroid-ish")
